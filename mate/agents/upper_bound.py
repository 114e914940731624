"""Upper-bound camera agent: the centralised, fully observing camera rule of `mate.teams.upper_bound`, one camera.

Every camera computes the whole team's plan from its own fully observing observation (all cameras see
the same entities, so all compute the same plan) and plays its own part: no messages. It needs the
`EnhancedObservation` wrapper on the cameras (`mate evaluate --camera-agent upper-bound` adds it).
"""

from __future__ import annotations

import numpy as np

from ..teams import upper_bound
from ..teams.upper_bound import DISCOUNT, HORIZON
from .base import CameraAgentBase

__all__ = ['UpperBoundCameraAgent']


class UpperBoundCameraAgent(CameraAgentBase):
    """A reference camera that sees the true state: the rule of `mate.teams.UpperBoundTeam` (a centralised
    plan of every camera's pose a few steps ahead, from every target's true position) computed by each
    camera for the whole team, which then plays its own part. Same seeds, same episodes as the batched team.

    What it reads beyond a normal camera: its observation must show every target and every camera (and
    every obstacle): the `EnhancedObservation` wrapper on the cameras (`EnhancedObservation(env,
    team='camera')`; `mate evaluate --camera-agent upper-bound` adds it). A partial observation is a
    ValueError. It sends no messages and draws no random numbers (`seed` is unused).

    Args:
        seed: seed of the agent's generator (unused by the rule).
        horizon: the plan's look-ahead in env steps (40).
        discount: discount per step of the look-ahead's weights (0.9).
    """

    def __init__(self, seed: int | None = None, horizon: int = HORIZON, discount: float = DISCOUNT) -> None:
        self._times, self._weights = upper_bound.lookahead_times(horizon, discount)    # checks them
        self.horizon, self.discount = int(horizon), float(discount)
        self._allocate(0, 0)
        super().__init__(seed=seed)

    def _allocate(self, num_cameras: int, num_targets: int) -> None:
        """The team state the rule works on, for one game (1, ...)."""
        self._previous = np.zeros((1, num_targets, 2))
        self._has_previous = np.zeros(1, dtype=bool)
        self._aim = np.zeros((1, num_cameras, 2))
        self._has_aim = np.zeros(1, dtype=bool)
        self._action = np.zeros((1, num_cameras, 2))
        self._rows = np.ones(1, dtype=bool)

    def reset(self, observation) -> None:
        super().reset(observation)
        if self.num_targets > upper_bound.MAX_TARGETS:
            raise ValueError(f'UpperBoundCameraAgent plans for at most {upper_bound.MAX_TARGETS} targets, '
                             f'got {self.num_targets}')
        self._counts = (self.num_cameras, self.num_targets, self.num_obstacles)
        upper_bound.check_full_view(np.asarray(observation, dtype=np.float64), self._counts, 'UpperBoundCameraAgent')
        self._allocate(self.num_cameras, self.num_targets)

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None) -> np.ndarray:
        observation = self._accept(observation)
        counts = self._counts
        upper_bound.check_full_view(observation, counts, 'UpperBoundCameraAgent')
        row = observation[None]
        upper_bound.plan(upper_bound.teammate_records(row, counts), upper_bound.target_records(row, counts),
                         upper_bound.obstacle_records(row, counts), self._rows, self._previous, self._has_previous,
                         self._aim, self._has_aim, self._times, self._weights, self._action)
        return self._action[0, self.index].copy()
