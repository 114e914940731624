"""Naive agents: a camera that keeps turning and widening; a target that tours the warehouses."""

from __future__ import annotations

import math

import numpy as np

from ..constants import NUM_WAREHOUSES, PRESERVED_DIM, WAREHOUSE_RADIUS, WAREHOUSES
from ..teams import rules
from ..teams.rules import INITIAL_NOISE_SCALE, NOISE_REFRESH_MOVING, NOISE_REFRESH_STUCK  # noqa: F401
from .base import CameraAgentBase, TargetAgentBase

__all__ = ['NaiveCameraAgent', 'NaiveTargetAgent']

_WAREHOUSES = WAREHOUSES.tolist()
_OWN = PRESERVED_DIM
"""Offset of the own state in an observation."""
ARRIVAL_DISTANCE = 0.9 * WAREHOUSE_RADIUS
"""A target this close to a warehouse centre (67.5) counts as arrived."""


class NaiveCameraAgent(CameraAgentBase):
    """Turn counter-clockwise and widen the view by u x the step limits, u ~ U(0, 0.4) each step
    (one u for both components): about one degree of rotation per step with a 5-degree step.

    Args:
        seed: seed of the agent's generator.
    """

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None) -> np.ndarray:
        self._accept(observation)
        u = 0.4 * self._draw()
        high = self._action_high
        return np.array([u * high[0], u * high[1]])


ONE_ROW = np.ones(1, dtype=bool)
"""The `rows` mask of an agent calling the shared rules on its own row."""


def as_row(observation: np.ndarray) -> np.ndarray:
    """One agent's observation (D,) as the (1, 1, D) C-contiguous float64 array the shared rules take."""
    return np.ascontiguousarray(observation, dtype=np.float64).reshape(1, 1, -1)


class NoisyWalker:
    """Shared machinery of the built-in targets: head for a point at full speed plus sticky noise.

    The noise is redrawn (`noise_scale` x a uniform action-box sample) with probability 0.05 per
    step while the target moves freely and 0.75 after a blocked step (moved <= 0.2 step sizes);
    otherwise last step's noise is reused. The sum is clipped to the action box. The walk is
    `mate.teams.rules.walk_towards` on the agent's own row (the batched teams run the same code).
    """

    noise_scale = INITIAL_NOISE_SCALE

    def _start_walk(self, observation: np.ndarray) -> None:
        """At reset: the walk's (1, 1, ...) arrays, the location and the first noise (scale 0.5)."""
        self._walk_location, self._walk_noise = np.zeros((1, 1, 2)), np.zeros((1, 1, 2))
        self._walk_high = np.array([[self._action_high]], dtype=np.float64)
        self._walk_action = np.zeros((1, 1, 2))
        space = self._space_draw
        if space.left[0, 0] < 2:
            space.refill()
        rules.walk_start(as_row(observation), ONE_ROW, self._walk_high, self._walk_location,
                                  self._walk_noise, space.values, space.left)
        self._prev_source = observation

    def _walk(self, observation: np.ndarray, x: float, y: float, step: float, gx: float, gy: float) -> list:
        """Action towards (gx, gy) given the own location (x, y) and step size; updates the noise."""
        space, draws = self._space_draw, self._draw
        if space.left[0, 0] < 2:
            space.refill()
        walk_towards = rules.walk_towards
        arguments = (0, 0, x, y, step, gx, gy, self.noise_scale, self._walk_high, self._walk_location,
                     self._walk_noise, draws.values, draws.left, space.values, space.left, self._walk_action)
        if walk_towards(*arguments):   # the stream ran out: refill it where the agent's _draw() would
            draws.refill()
            walk_towards(*arguments)
        self._prev_source = observation
        return self._walk_action[0, 0].tolist()

    @property
    def prev_state(self):
        """Own state view at the previous decision (reset or act)."""
        source = getattr(self, '_prev_source', None)
        return None if source is None else self.STATE_CLASS(source[_OWN:_OWN + self.STATE_CLASS.DIM], self.index)

    @property
    def prev_noise(self) -> np.ndarray:
        """The noise added to the last action, float64 (2,)."""
        return self._walk_noise[0, 0].copy()


class NaiveTargetAgent(NoisyWalker, TargetAgentBase):
    """Visit the warehouses in turn (direction +1 or -1 drawn at reset), skipping the ones seen empty
    while unloaded. The cargo's destination is ignored: deliveries happen on the way.

    Args:
        seed: seed of the agent's generator.
    """

    def __init__(self, seed: int | None = None) -> None:
        self.goal = 0
        self.inc = 1
        super().__init__(seed=seed)

    def reset(self, observation) -> None:
        super().reset(observation)
        self._start_walk(np.asarray(observation, dtype=np.float64))
        self.goal = min(int(self._draw() * NUM_WAREHOUSES), NUM_WAREHOUSES - 1)
        self.inc = 1 if self._draw() < 0.5 else -1

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None) -> np.ndarray:
        observation = self._accept(observation)
        own = observation[_OWN:_OWN + 14].tolist()
        x, y, step = own[0], own[1], own[4]
        goal_bits, empty_bits = own[6:10], own[10:14]
        gx, gy = _WAREHOUSES[self.goal]
        if math.hypot(gx - x, gy - y) <= ARRIVAL_DISTANCE:
            if any(goal_bits) or all(empty_bits):
                self.goal = (self.goal + self.inc) % NUM_WAREHOUSES
            else:   # unloaded: stay while this warehouse may still have cargo, else the next non-empty one
                while empty_bits[self.goal]:
                    self.goal = (self.goal + self.inc) % NUM_WAREHOUSES
            gx, gy = _WAREHOUSES[self.goal]
        return np.array(self._walk(observation, x, y, step, gx, gy))
