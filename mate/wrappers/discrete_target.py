"""DiscreteTarget: each target chooses one of `levels**2` moves on a grid squashed onto the unit disk.

The square grid of `DiscreteCamera` is mapped onto the disk, `p / sqrt(1 + min(|x/y|, |y/x|)**2)` (the
square's boundary lands on the unit circle, the centre stays 0), and scaled by each target's current
speed `step_size / capacity`. With levels=5: 0 is (-0.7071, -0.7071), 1 is (-0.4472, -0.8944),
7 is (0, -0.5), 12 is (0, 0).
"""

from __future__ import annotations

import functools

import numpy as np
from gymnasium import spaces

from mate.spaces import TeamSpace

from .base import MateWrapper, assert_base_environment, forbid_twice
from .discrete_camera import (
    check_levels,
    discrete_indices,
    grid_actions,
    nearest_grid_indices,
    square_grid,
)

__all__ = ['DiscreteTarget', 'disk_grid']


@functools.cache
def disk_grid(levels: int) -> np.ndarray:
    """Read-only (levels**2, 2): `square_grid(levels)` with each point divided by sqrt(1 + r**2), where r is
    the ratio of its smaller to its larger absolute coordinate (0 on the axes)."""
    square = square_grid(levels)
    small, large = np.abs(square).min(axis=1), np.abs(square).max(axis=1)
    ratio = np.divide(small, large, out=np.zeros_like(small), where=large > 0.0)
    grid = square / np.sqrt(1.0 + ratio ** 2)[:, None]
    grid.flags.writeable = False
    return grid


class DiscreteTarget(MateWrapper):
    """Discrete target moves: `Discrete(levels**2)` per target (levels odd, >= 3) on a disk-shaped grid scaled
    by each target's speed.

    Spaces: `target_action_space = Discrete(levels**2)`, `target_joint_action_space` = Tuple of Nt of them,
    `action_space = Tuple(camera_joint_action_space, target_joint_action_space)`. `action_high` (Nt, 2) is
    each target's current step size (`target_step_size / capacity`, read from the env at every step).
    `reverse_action` maps continuous target moves to the nearest grid indices (it works; the original's raised
    TypeError).

    Order: before (inside) any single-team wrapper; once only.
    """

    def __init__(self, env, levels: int = 5) -> None:
        assert_base_environment(env, type(self).__name__)
        forbid_twice(env, DiscreteTarget)
        levels = check_levels(levels)
        super().__init__(env)
        base = env.unwrapped
        self.levels = levels
        self.num_targets = base.num_targets
        self.target_action_space = spaces.Discrete(levels ** 2)
        self.target_joint_action_space = TeamSpace(self.target_action_space, self.num_targets)
        self.action_space = spaces.Tuple((env.camera_joint_action_space, self.target_joint_action_space))
        self.grid = disk_grid(levels)

    def _arguments(self) -> str:
        return f'levels={self.levels}'

    @property
    def action_high(self) -> np.ndarray:
        """(Nt, 2): each target's step size (config step size / capacity) on both axes."""
        base = self.env.unwrapped
        speed = base.target_step_size / np.asarray(base.target_capacities, dtype=np.float64)
        return np.repeat(speed[:, None], 2, axis=1)

    def action(self, action):
        """(camera actions, target indices) -> (camera actions, (Nt, 2) continuous target moves)."""
        camera_action, target_action = action
        indices = discrete_indices(target_action, self.num_targets, self.levels, 'target')
        return camera_action, grid_actions(indices, self.grid, self.action_high)

    def reverse_action(self, action):
        """(camera actions, continuous target moves (Nt, 2)) -> (camera actions, nearest grid indices (Nt,))."""
        camera_action, target_action = action
        target_action = np.asarray(target_action, dtype=np.float64).reshape(self.num_targets, 2)
        return camera_action, nearest_grid_indices(target_action, self.grid, self.action_high)

    def step(self, action):
        return self.env.step(self.action(action))
