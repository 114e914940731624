"""RestrictedCommunicationRange: teammates farther apart than a range limit cannot talk."""

from __future__ import annotations

import numpy as np

from mate.messages import Message, Team

from .base import private_states
from .message_filter import MessageFilter

__all__ = ['RestrictedCommunicationRange', 'within_range']


def within_range(positions: np.ndarray, senders: np.ndarray, recipients: np.ndarray, range_limit: float) -> np.ndarray:
    """(M,) bool: |positions[sender] - positions[recipient]| <= range_limit; positions (..., N, 2)."""
    gaps = positions[..., senders, :] - positions[..., recipients, :]
    return np.hypot(gaps[..., 0], gaps[..., 1]) <= range_limit


class RestrictedCommunicationRange(MessageFilter):
    """Deliver a message only if the sender's and the recipient's entities are at most `range_limit` apart
    (Euclidean, world units; the docs example uses `mate.TERRAIN_WIDTH / 3`)."""

    def __init__(self, env, range_limit: float) -> None:
        self.range_limit = float(range_limit)
        super().__init__(env, filter=self._in_range)

    def _in_range(self, env, message: Message) -> bool:
        return bool(self.keep([message])[0])

    def keep(self, messages: list[Message]) -> list[bool]:
        cameras, targets = private_states(self.env)
        teams = np.array([int(message.team) for message in messages])
        senders = np.array([message.sender for message in messages], dtype=np.int64)
        recipients = np.array([message.recipient for message in messages], dtype=np.int64)
        kept = np.zeros(len(messages), dtype=bool)
        for team, states in ((Team.CAMERA, cameras), (Team.TARGET, targets)):
            chosen = teams == int(team)
            if chosen.any():
                kept[chosen] = within_range(states[:, :2], senders[chosen], recipients[chosen], self.range_limit)
        return kept.tolist()

    def _arguments(self) -> str:
        return f'range_limit={self.range_limit}'
