"""RenderCommunication: draw recent messages as arrows between teammates in rendered frames, and count them by kind."""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from mate.messages import Message, Team

from .base import MateWrapper, assert_mate_environment, private_states

__all__ = ['KIND_COLORS', 'KINDS', 'TEAM_COLORS', 'CommunicationArrow', 'RenderCommunication', 'arrow_geometry']

TEAM_COLORS = {Team.CAMERA: (0.0, 0.0, 1.0), Team.TARGET: (1.0, 0.0, 0.0)}
"""Arrow colours: blue for cameras, red for targets."""
KINDS = ('request', 'reply', 'broadcast')
"""Kinds of a delivered message: peer-to-peer in the request round, peer-to-peer in the response round, or a
copy of a broadcast (either round)."""
KIND_COLORS = {'request': (1.0, 0.5, 0.0), 'reply': (0.55, 0.0, 0.75)}
"""Arrow colours with `kinds=True`: orange dashed requests, purple solid replies; broadcasts keep the team
colour (dashed)."""
SIDE_OFFSET = 10.0
"""Sideways shift (world units) of each arrow of a pair that talks both ways."""
MAX_BARB = 50.0


@dataclass(frozen=True)
class CommunicationArrow:
    """One arrow to draw (world units): from `start` to `end`, `barbs` the barb tips at `end`."""

    team: Team
    sender: int
    recipient: int
    start: np.ndarray
    end: np.ndarray
    barbs: tuple[np.ndarray, ...]
    color: tuple[float, float, float]
    alpha: float
    kind: str = 'any'
    dashed: bool = True


_LEFT_BARB = np.array([[0.04, 0.015], [-0.015, 0.04]])
_RIGHT_BARB = np.array([[0.04, -0.015], [0.015, 0.04]])


def arrow_geometry(start, end, both_ways: bool) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
    """(start, end, barb tips) of an arrow between two entity locations.

    The vector is shortened by `max(0.9, (|v| - 50) / |v|)` about its midpoint, so the arrow stops short of
    both entities; each barb is the vector mapped by a small rotation-scale matrix (about 4.3% of |v|, at
    most 50 units long) and points back from the tip. When both directions are active the arrow is shifted
    10 units to its right and keeps only its outer barb, so the two arrows of a pair do not overlap.
    """
    start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    vector = end - start
    length = float(np.hypot(*vector))
    if length == 0.0:
        return start, end, ()
    factor = max(0.9, (length - 50.0) / length)
    middle = (start + end) / 2.0
    start, end = middle - factor * vector / 2.0, middle + factor * vector / 2.0
    if both_ways:
        normal = np.array([vector[1], -vector[0]]) / length            # to the right of the direction
        start, end = start + SIDE_OFFSET * normal, end + SIDE_OFFSET * normal
    barbs = []
    for matrix in ((_RIGHT_BARB,) if both_ways else (_LEFT_BARB, _RIGHT_BARB)):
        barb = matrix @ vector
        size = float(np.hypot(*barb))
        if size > MAX_BARB:
            barb = barb * (MAX_BARB / size)
        barbs.append(end - barb)
    return start, end, tuple(barbs)


class RenderCommunication(MateWrapper):
    """Show who talked to whom: for `duration` steps after a message from s to r (s, r teammates), rendered
    frames show a dashed arrow from s to r (blue between cameras, red between targets) whose alpha is
    `min(1, 1.2 * remaining / duration)`.

    Bookkeeping: `camera_remaining` (Nc, Nc) and `target_remaining` (Nt, Nt) count the frames left per
    (sender, recipient); `step` first lowers every entry by 1 (not below 0), then sets the pairs that
    exchanged a message since the previous step (read from the env's per-step communication edges, so after
    any filtering) to `duration`. `reset` clears both. The drawing is a render callback named
    'communication' (`env.add_render_callback`), drawn under cameras and targets.

    `kinds=True` (`mate evaluate --render-communication`) draws each kind of message (`KINDS`) in its own
    style instead: requests orange dashed, replies purple solid, broadcasts dashed in the team colour, from
    the messages the agents received (`receive_messages` through this wrapper), per kind in
    `remaining[kind][team]`. With `duration=1` a frame shows exactly the messages delivered during the step
    that led to it.

    Either way the wrapper counts, per step and team, the messages of each kind: `sent[team][kind]` (N,)
    messages sent through this wrapper (a broadcast counts once) and `received[team][kind]` (N, N)
    [sender, recipient] messages received from teammates (a broadcast's copy to its own sender left out),
    for the last completed step (`step` moves the counts of the communication before it there). The round
    of a message is told by the team's receive calls before it in the step: `mate.group_communicate`
    receives once per agent after the request round and once after the response round.
    """

    def __init__(self, env, duration: int = 20, kinds: bool = False) -> None:
        assert_mate_environment(env, type(self).__name__)
        if not isinstance(duration, numbers.Real) or isinstance(duration, bool) or duration <= 0:
            raise ValueError(f'duration must be a positive number of steps, got {duration!r}')
        super().__init__(env)
        self.duration = int(duration) if float(duration).is_integer() else float(duration)
        self.kinds = bool(kinds)
        base = env.unwrapped
        self._sizes = {Team.CAMERA: base.num_cameras, Team.TARGET: base.num_targets}
        self.camera_remaining = np.zeros((base.num_cameras, base.num_cameras), dtype=np.int64)
        self.target_remaining = np.zeros((base.num_targets, base.num_targets), dtype=np.int64)
        self.remaining = {kind: {team: np.zeros((n, n), dtype=np.int64) for team, n in self._sizes.items()}
                          for kind in KINDS}
        self._clear_counts()
        self.sent, self.received = self._sent, self._received     # zeros until the first step
        self._clear_counts()
        if hasattr(base, 'add_render_callback'):
            base.add_render_callback('communication', self.draw)

    def _arguments(self) -> str:
        return f'duration={self.duration}' + (', kinds=True' if self.kinds else '')

    def _clear_counts(self) -> None:
        """Fresh counters for the communication of the coming step."""
        self._sent = {team: {kind: np.zeros(n, dtype=np.int64) for kind in KINDS} for team, n in self._sizes.items()}
        self._received = {team: {kind: np.zeros((n, n), dtype=np.int64) for kind in KINDS}
                          for team, n in self._sizes.items()}
        self._receive_calls = {team: 0 for team in Team}

    def _round(self, team: Team) -> str:
        """'request' until every agent of `team` has received once this step, 'reply' after."""
        return 'request' if self._receive_calls[team] < self._sizes[team] else 'reply'

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self.camera_remaining[...] = 0
        self.target_remaining[...] = 0
        for per_team in self.remaining.values():
            for remaining in per_team.values():
                remaining[...] = 0
        self._clear_counts()
        self.sent, self.received = self._sent, self._received
        self._clear_counts()
        return self.env.reset(seed=seed, options=options)

    def send_messages(self, messages) -> None:
        listed = [messages] if isinstance(messages, Message) else list(messages)
        self.env.send_messages(listed)
        for message in listed:
            team = Team(message.team)
            kind = 'broadcast' if message.recipient is None else self._round(team)
            self._sent[team][kind][message.sender] += 1

    def receive_messages(self, agent_id=None, agent=None):
        received = self.env.receive_messages(agent_id=agent_id, agent=agent)
        if agent_id is None and agent is None:       # everything: (camera lists, target lists), one pass each
            for team, lists in zip(Team, received):
                self._count(team, [m for messages in lists for m in messages])
                self._receive_calls[team] += self._sizes[team]
        else:
            key = agent if agent is not None else agent_id
            team = Team(key.TEAM if hasattr(key, 'TEAM') else key[0])
            self._count(team, received)
            self._receive_calls[team] += 1
        return received

    def _count(self, team: Team, messages) -> None:
        round_kind = self._round(team)
        for message in messages:
            if message.sender != message.recipient:
                kind = 'broadcast' if message.broadcasting else round_kind
                self._received[team][kind][message.sender, message.recipient] += 1

    def step(self, action):
        base = self.env.unwrapped
        for remaining, edges in ((self.camera_remaining, base.camera_communication_edges),
                                 (self.target_remaining, base.target_communication_edges)):
            np.maximum(remaining - 1, 0, out=remaining)
            remaining[edges > 0] = self.duration
        for kind, per_team in self.remaining.items():
            for team, remaining in per_team.items():
                np.maximum(remaining - 1, 0, out=remaining)
                remaining[self._received[team][kind] > 0] = self.duration
        self.sent, self.received = self._sent, self._received
        self._clear_counts()
        return self.env.step(action)

    def arrows(self) -> list[CommunicationArrow]:
        """The arrows of the current frame, cameras first, in (sender, recipient) order (with `kinds`:
        requests, then replies, then broadcasts, per team)."""
        cameras, targets = private_states(self.env)
        arrows = []
        for team, states in ((Team.CAMERA, cameras), (Team.TARGET, targets)):
            if self.kinds:
                layers = [(kind, self.remaining[kind][team]) for kind in KINDS]
            else:
                layers = [('any', self.camera_remaining if team is Team.CAMERA else self.target_remaining)]
            active_any = np.logical_or.reduce([remaining > 0 for _, remaining in layers])
            for kind, remaining in layers:
                color = KIND_COLORS.get(kind, TEAM_COLORS[team])
                for sender, recipient in zip(*np.nonzero(remaining > 0)):
                    if sender == recipient:
                        continue
                    start, end, barbs = arrow_geometry(states[sender, :2], states[recipient, :2],
                                                       both_ways=bool(active_any[recipient, sender]))
                    alpha = min(1.0, 1.2 * float(remaining[sender, recipient]) / self.duration)
                    arrows.append(CommunicationArrow(team, int(sender), int(recipient), start, end, barbs,
                                                     color, alpha, kind, kind != 'reply'))
        return arrows

    def draw(self, env, renderer) -> None:
        """Render callback: queue every arrow (dashed, or solid for replies) under the entities."""
        for arrow in self.arrows():
            draw_line = renderer.dashed_line if arrow.dashed else renderer.line
            draw_line(arrow.start, arrow.end, arrow.color, alpha=arrow.alpha, width=2.5, layer='below')
            for tip in arrow.barbs:
                renderer.line(arrow.end, tip, arrow.color, alpha=arrow.alpha, width=2.5, layer='below')
