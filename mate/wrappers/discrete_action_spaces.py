"""Discrete action spaces: `DiscreteCamera` and `DiscreteTarget`, each agent choosing one of `levels**2` actions.

`DiscreteCamera`: each camera chooses a (rotation, zoom) action on a square grid. Index `k = i + levels * j` is the
normalised point `(x_i, y_j)`, `x_i = -1 + 2 i / (levels - 1)` (rotation) and `y_j = -1 + 2 j / (levels - 1)` (zoom);
the continuous action is `grid[k] * [rotation_step, zooming_step]`. The array functions (`square_grid`,
`grid_actions`, `nearest_grid_indices`) take index or action arrays with any leading batch axes.

`DiscreteTarget`: each target chooses a move on a grid squashed onto the unit disk: the square grid is mapped onto
the disk, `p / sqrt(1 + min(|x/y|, |y/x|)**2)` (the square's boundary lands on the unit circle, the centre stays 0),
and scaled by each target's current speed `step_size / capacity`. With levels=5: 0 is (-0.7071, -0.7071), 1 is
(-0.4472, -0.8944), 7 is (0, -0.5), 12 is (0, 0).
"""

from __future__ import annotations

import functools
import operator

import numpy as np
from gymnasium import spaces

from mate.spaces import TeamSpace

from .base import MateWrapper, assert_base_environment, forbid_twice

__all__ = ['DiscreteCamera', 'DiscreteTarget', 'check_levels', 'discrete_indices', 'disk_grid', 'grid_actions',
           'nearest_grid_indices', 'square_grid']


def check_levels(levels) -> int:
    """`levels` as an int; ValueError unless it is odd and at least 3 (so that 0 is a grid value)."""
    try:
        levels = operator.index(levels)
    except TypeError:
        raise TypeError(f'levels must be an integer, got {levels!r}') from None
    if levels < 3 or levels % 2 == 0:
        raise ValueError(f'levels must be an odd integer >= 3 (so that "no change" is on the grid), got {levels}')
    return levels


@functools.cache
def square_grid(levels: int) -> np.ndarray:
    """Read-only (levels**2, 2) grid over [-1, 1]^2; row `i + levels * j` is `(x_i, y_j)`."""
    axis = np.linspace(-1.0, 1.0, levels)
    grid = np.stack(np.meshgrid(axis, axis, indexing='xy'), axis=-1).reshape(-1, 2)
    grid.flags.writeable = False
    return grid


def grid_actions(indices: np.ndarray, grid: np.ndarray, action_high: np.ndarray) -> np.ndarray:
    """(..., N, 2) continuous actions `grid[indices] * action_high` for int indices (..., N).

    `action_high` broadcasts against the result: (2,) for one scale, (..., N, 2) per agent.
    """
    return grid[indices] * action_high


def nearest_grid_indices(actions: np.ndarray, grid: np.ndarray, action_high: np.ndarray) -> np.ndarray:
    """(..., N) int64 index of the grid point nearest (Euclidean) to `actions / action_high`, actions (..., N, 2)."""
    normalized = np.asarray(actions, dtype=np.float64) / action_high
    distances = np.square(normalized[..., None, :] - grid).sum(axis=-1)     # (..., N, K)
    return distances.argmin(axis=-1).astype(np.int64)


def discrete_indices(value, count: int, levels: int, team: str) -> np.ndarray:
    """The team part of a discrete joint action as int64 (count,); ValueError if it is not one."""
    try:
        array = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{team} joint action is not an array of indices: {exc}') from None
    flat = array.reshape(-1)
    if flat.size != count:
        raise ValueError(f'{team} joint action has {flat.size} entries (shape {array.shape}); expected {count} '
                         f'discrete indices in [0, {levels ** 2})')
    if flat.dtype.kind == 'f' and not np.array_equal(flat, np.round(flat)):
        raise ValueError(f'{team} joint action must hold integer indices, got {flat.tolist()}')
    if flat.dtype.kind not in 'iuf' and count:
        raise ValueError(f'{team} joint action must hold integer indices, got {flat.tolist()}')
    indices = flat.astype(np.int64)
    bad = (indices < 0) | (indices >= levels ** 2)
    if bad.any():
        raise ValueError(f'{team} joint action {indices.tolist()} is outside Discrete({levels ** 2}) '
                         f'(agents {np.flatnonzero(bad).tolist()})')
    return indices


class DiscreteCamera(MateWrapper):
    """Discrete camera actions: `Discrete(levels**2)` per camera (levels odd, >= 3), mapped onto a square grid
    of (rotation, zoom) scaled by the configured `rotation_step` and `zooming_step`.

    Spaces: `camera_action_space = Discrete(levels**2)`, `camera_joint_action_space` = Tuple of Nc of them,
    `action_space = Tuple(camera_joint_action_space, target_joint_action_space)`. `step((camera_indices,
    target_actions))`; `reverse_action` maps continuous camera actions to the nearest grid indices.
    With levels=5: 0 is (-rot, -zoom), 12 is (0, 0), 24 is (+rot, +zoom).

    Order: before (inside) any single-team wrapper; once only; needs at least one camera.
    """

    def __init__(self, env, levels: int = 5) -> None:
        name = type(self).__name__
        assert_base_environment(env, name)
        forbid_twice(env, DiscreteCamera)
        levels = check_levels(levels)
        base = env.unwrapped
        if base.num_cameras == 0:
            raise ValueError(f'{name} needs at least one camera; the environment has none')
        super().__init__(env)
        self.levels = levels
        self.num_cameras = base.num_cameras
        self.camera_action_space = spaces.Discrete(levels ** 2)
        self.camera_joint_action_space = TeamSpace(self.camera_action_space, self.num_cameras)
        self.action_space = spaces.Tuple((self.camera_joint_action_space, env.target_joint_action_space))
        self.action_high = np.array([base.camera_rotation_step, base.camera_zooming_step], dtype=np.float64)
        self.action_high.flags.writeable = False
        self.grid = square_grid(levels)

    def _arguments(self) -> str:
        return f'levels={self.levels}'

    def action(self, action):
        """(camera indices, target actions) -> ((Nc, 2) continuous camera actions, target actions)."""
        camera_action, target_action = action
        indices = discrete_indices(camera_action, self.num_cameras, self.levels, 'camera')
        return grid_actions(indices, self.grid, self.action_high), target_action

    def reverse_action(self, action):
        """(continuous camera actions (Nc, 2), target actions) -> (nearest grid indices (Nc,), target actions)."""
        camera_action, target_action = action
        camera_action = np.asarray(camera_action, dtype=np.float64).reshape(self.num_cameras, 2)
        return nearest_grid_indices(camera_action, self.grid, self.action_high), target_action

    def step(self, action):
        return self.env.step(self.action(action))


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
