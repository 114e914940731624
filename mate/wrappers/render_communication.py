"""RenderCommunication: draw recent messages as dashed arrows between teammates in rendered frames."""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from mate.messages import Team

from .base import MateWrapper, assert_mate_environment, private_states

__all__ = ['TEAM_COLORS', 'CommunicationArrow', 'RenderCommunication', 'arrow_geometry']

TEAM_COLORS = {Team.CAMERA: (0.0, 0.0, 1.0), Team.TARGET: (1.0, 0.0, 0.0)}
"""Arrow colours: blue for cameras, red for targets."""
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
    """

    def __init__(self, env, duration: int = 20) -> None:
        assert_mate_environment(env, type(self).__name__)
        if not isinstance(duration, numbers.Real) or isinstance(duration, bool) or duration <= 0:
            raise ValueError(f'duration must be a positive number of steps, got {duration!r}')
        super().__init__(env)
        self.duration = int(duration) if float(duration).is_integer() else float(duration)
        base = env.unwrapped
        self.camera_remaining = np.zeros((base.num_cameras, base.num_cameras), dtype=np.int64)
        self.target_remaining = np.zeros((base.num_targets, base.num_targets), dtype=np.int64)
        if hasattr(base, 'add_render_callback'):
            base.add_render_callback('communication', self.draw)

    def _arguments(self) -> str:
        return f'duration={self.duration}'

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self.camera_remaining[...] = 0
        self.target_remaining[...] = 0
        return self.env.reset(seed=seed, options=options)

    def step(self, action):
        base = self.env.unwrapped
        for remaining, edges in ((self.camera_remaining, base.camera_communication_edges),
                                 (self.target_remaining, base.target_communication_edges)):
            np.maximum(remaining - 1, 0, out=remaining)
            remaining[edges > 0] = self.duration
        return self.env.step(action)

    def arrows(self) -> list[CommunicationArrow]:
        """The arrows of the current frame, cameras first, in (sender, recipient) order."""
        cameras, targets = private_states(self.env)
        arrows = []
        for team, remaining, states in ((Team.CAMERA, self.camera_remaining, cameras),
                                        (Team.TARGET, self.target_remaining, targets)):
            active = remaining > 0
            for sender, recipient in zip(*np.nonzero(active)):
                if sender == recipient:
                    continue
                start, end, barbs = arrow_geometry(states[sender, :2], states[recipient, :2],
                                                   both_ways=bool(active[recipient, sender]))
                alpha = min(1.0, 1.2 * float(remaining[sender, recipient]) / self.duration)
                arrows.append(CommunicationArrow(team, int(sender), int(recipient), start, end, barbs,
                                                 TEAM_COLORS[team], alpha))
        return arrows

    def draw(self, env, renderer) -> None:
        """Render callback: queue every arrow as dashed lines under the entities."""
        for arrow in self.arrows():
            renderer.dashed_line(arrow.start, arrow.end, arrow.color, alpha=arrow.alpha, width=2.5, layer='below')
            for tip in arrow.barbs:
                renderer.line(arrow.end, tip, arrow.color, alpha=arrow.alpha, width=2.5, layer='below')
