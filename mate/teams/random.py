"""Batched random team: `RandomCameraAgent` / `RandomTargetAgent` for every agent of B games at once."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from . import rules
from .greedy import RuleTeam
from .interface import as_team

__all__ = ['RandomTeam']


class RandomTeam(RuleTeam):
    """A uniform action in each agent's action box, drawn at steps 0, frame_skip, 2 frame_skip, ... of the
    row's episode and held in between, from the agent's action-space stream: row b of a team seeded with
    s plays draw for draw as `RandomCameraAgent(seed=s + b, frame_skip=...).spawn(N)` (or the targets').

    Args:
        team: Team.CAMERA / Team.TARGET (or 'camera' / 'target').
        num_envs: B.
        counts: (num_cameras, num_targets, num_obstacles) of the game.
        seed: an integer s (row b: s + b), B integers, or None (fresh entropy).
        frame_skip: env steps each drawn action is held (20).
    """

    def __init__(self, team, num_envs: int, counts, seed: int | Sequence[int] | None = None,
                 frame_skip: int = 20) -> None:
        if isinstance(frame_skip, bool) or not isinstance(frame_skip, (int, np.integer)) or frame_skip < 1:
            raise ValueError(f'frame_skip must be a positive integer, got {frame_skip!r}')
        self.TEAM = as_team(team)
        self.frame_skip = int(frame_skip)
        super().__init__(num_envs, counts, seed)
        self.step = np.zeros(self.num_envs, dtype=np.int64)

    def reset(self, observation, rows) -> None:
        """Start an episode in the rows `rows` (B,) bool from their raw observations (B, N, D)."""
        observation, rows = self._observation(observation), self._rows(rows)
        self._start(observation, rows)
        self.step[rows] = 0

    def act(self, observation) -> np.ndarray:
        """(B, N, 2) actions (zeros in rows out of play)."""
        self._observation(observation)
        drawing = self.active & (self.step % self.frame_skip == 0)
        if drawing.any():
            self.streams.top_up_space(drawing)
            todo = np.repeat(drawing[:, None], self.num_agents, axis=1)
            rules.random_act(todo, self.high, self.streams.space, self.streams.space_left, self.action)
        self.step += self.active
        return self._actions()
