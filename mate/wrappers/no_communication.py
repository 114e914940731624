"""NoCommunication: silence one team, both teams, or neither."""

from __future__ import annotations

from mate.messages import Message, Team

from .base import check_choice
from .message_filter import MessageFilter

__all__ = ['NoCommunication']

_SILENCED = {'both': (Team.CAMERA, Team.TARGET), 'camera': (Team.CAMERA,), 'target': (Team.TARGET,), 'none': ()}


class NoCommunication(MessageFilter):
    """Drop every message of the chosen team(s): `team` in {'both', 'camera', 'target', 'none'}."""

    def __init__(self, env, team: str = 'both') -> None:
        check_choice('team', team, tuple(_SILENCED))
        silenced = _SILENCED[team]

        def audible(_env, message: Message) -> bool:
            return Team(message.team) not in silenced

        super().__init__(env, filter=audible)
        self.team = team

    def _arguments(self) -> str:
        return f'team={self.team}'
