"""Agent-side observation helpers and read-only views of entity states (docs/agents.md).

Observation helpers take `(observation, team, num_cameras, num_targets, num_obstacles)`; the
observation may be one row (D,) or a batch (..., D), and may carry extra trailing columns
beyond the standard dimension D, which pass through unchanged.

* `convert_coordinates`: coordinates relative to the agent's own location;
* `normalize_observation` / `rescale_observation`: box-bounded fields mapped onto [-1, 1];
* `split_observation`: the five parts (preserved, own state, opponents, obstacles, teammates).

State views (`CameraStatePublic`, `CameraStatePrivate`, `TargetStatePublic`,
`TargetStatePrivate`, `ObstacleState`) wrap one entity's slice of an observation and decode
its fields lazily: lengths in world units, angles in degrees. `a - b` is the `Vector2D` from
b's location to a's.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from gymnasium import spaces as gym_spaces

from ..constants import (
    CAMERA_STATE_DIM_PRIVATE,
    CAMERA_STATE_DIM_PUBLIC,
    NUM_WAREHOUSES,
    OBSTACLE_STATE_DIM,
    PRESERVED_DIM,
    TARGET_STATE_DIM_PRIVATE,
    TARGET_STATE_DIM_PUBLIC,
)
from ..core.arrays import array_namespace, copied, float64_copy, on_device_of
from ..messages import Team
from ..spaces import coordinate_mask_of, observation_indices_of, observation_space_of
from .geometry import RAD2DEG, Vector2D

__all__ = [
    'box_scaling', 'convert_coordinates', 'normalize_observation', 'observation_scaling', 'relative_in_place',
    'relative_layout', 'rescale_observation', 'scale_in_place', 'split_observation', 'StateBase', 'CameraStatePublic',
    'CameraStatePrivate', 'TargetStatePublic', 'TargetStatePrivate', 'ObstacleState',
]


# ---------------------------------------------------------------------------- observation helpers

@functools.cache
def relative_layout(team: Team, num_cameras: int, num_targets: int, num_obstacles: int):
    """Positions of the x entries of every coordinate pair (y = x + 1) and of the flag that gates each
    pair (-1 for the warehouse centres, which are always converted). Two read-only int64 arrays."""
    mask = coordinate_mask_of(team, num_cameras, num_targets, num_obstacles)
    xs = np.flatnonzero(mask)[::2]
    indices = observation_indices_of(team, num_cameras, num_targets, num_obstacles)
    if Team(team) is Team.CAMERA:
        dims = (TARGET_STATE_DIM_PUBLIC, OBSTACLE_STATE_DIM, CAMERA_STATE_DIM_PUBLIC)
    else:
        dims = (CAMERA_STATE_DIM_PUBLIC, OBSTACLE_STATE_DIM, TARGET_STATE_DIM_PUBLIC)
    flags = np.full(xs.shape, -1, dtype=np.int64)
    for k, x in enumerate(xs):
        for part, dim in enumerate(dims):
            begin, end = int(indices[2 + part]), int(indices[3 + part])
            if begin <= x < end:
                flags[k] = x + dim   # records are (state..., flag) with x first
    for array in (xs, flags):
        array.setflags(write=False)
    return xs, flags


def relative_in_place(out, team, num_cameras: int, num_targets: int, num_obstacles: int):
    """`convert_coordinates` on a float64 array or tensor `out` (..., D[+extra]), in place; returns it."""
    xs, ys, safe_flags, gated = _relative_constants(Team(team), num_cameras, num_targets, num_obstacles)
    xs, ys, safe_flags, gated = (on_device_of(c, out) for c in (xs, ys, safe_flags, gated))
    origin_x = copied(out[..., PRESERVED_DIM:PRESERVED_DIM + 1])
    origin_y = copied(out[..., PRESERVED_DIM + 1:PRESERVED_DIM + 2])
    gate = ~gated | (out[..., safe_flags] == 1.0)
    out[..., xs] -= gate * origin_x
    out[..., ys] -= gate * origin_y
    return out


@functools.cache
def _relative_constants(team: Team, num_cameras: int, num_targets: int, num_obstacles: int):
    """(x positions, y positions, gating flags (0 where none), gated) of `relative_layout`, read-only."""
    xs, flags = relative_layout(team, num_cameras, num_targets, num_obstacles)
    constants = (xs, xs + 1, np.maximum(flags, 0), flags >= 0)
    for array in constants:
        array.setflags(write=False)
    return constants


def convert_coordinates(observation, team, num_cameras: int, num_targets: int, num_obstacles: int):
    """A float64 copy of `observation` (..., D[+extra]) with coordinates relative to the agent's own (x, y).

    Warehouse centres always become relative; an opponent/obstacle/teammate record only when its
    flag is 1, so invisible (all-zero) records stay zero. The agent's own state block is untouched.
    A numpy array (or anything array-like) gives a numpy array, a torch tensor a tensor on its device.
    """
    return relative_in_place(float64_copy(observation), team, num_cameras, num_targets, num_obstacles)


def box_scaling(observation_space: gym_spaces.Box, additional_mask=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(shift, span, scaled) (D,) of `normalize_observation` for `observation_space`: what is subtracted, what the
    shifted value is divided by, and which fields are mapped onto [-1, 1]."""
    low, high = observation_space.low, observation_space.high
    below, above = observation_space.bounded_below, observation_space.bounded_above
    scaled = below & above & (high > low)
    if additional_mask is not None:
        scaled = scaled & np.asarray(additional_mask, dtype=bool)
    return np.where(below, low, 0.0), np.where(scaled, high - low, 1.0), scaled


def scale_in_place(out, scaling):
    """`normalize_observation` on a float64 array or tensor `out` (..., D[+extra]) with `box_scaling`'s constants,
    in place; returns it."""
    shift, span, scaled = (on_device_of(c, out) for c in scaling)
    core = out[..., :shift.shape[0]]
    core -= shift
    core[...] = array_namespace(out).where(scaled, 2.0 * core / span - 1.0, core)
    return out


def normalize_observation(observation, observation_space: gym_spaces.Box, additional_mask=None):
    """Map every box-bounded field of `observation` (..., D[+extra]) onto [-1, 1]: `2 (v - low) / (high - low) - 1`.

    Fields bounded below only are shifted by `-low`; unbounded fields and extra trailing columns
    are unchanged. `additional_mask` (D,) bool restricts the scaling step further. Returns a float64 copy (a
    tensor for a tensor).
    """
    return scale_in_place(float64_copy(observation), box_scaling(observation_space, additional_mask))


@functools.cache
def observation_scaling(team: Team, num_cameras: int, num_targets: int, num_obstacles: int):
    """`box_scaling` of the team's standard observation space (read-only arrays, one set per game)."""
    constants = box_scaling(observation_space_of(team, num_cameras, num_targets, num_obstacles))
    for array in constants:
        array.setflags(write=False)
    return constants


def rescale_observation(observation, team, num_cameras: int, num_targets: int, num_obstacles: int):
    """`normalize_observation` with the team's standard observation space."""
    return scale_in_place(float64_copy(observation), observation_scaling(Team(team), num_cameras, num_targets,
                                                                         num_obstacles))


def split_observation(observation, team, num_cameras: int, num_targets: int, num_obstacles: int):
    """The five parts of a standard observation (..., D) along the last axis: preserved data, own
    state, opponents with flags, obstacles with flags, teammates with flags (views, not copies)."""
    observation = np.asarray(observation, dtype=np.float64)
    indices = observation_indices_of(Team(team), num_cameras, num_targets, num_obstacles)
    if observation.shape[-1] != indices[-1]:
        raise ValueError(f'expected an observation of dimension {int(indices[-1])} for team {Team(team).name} '
                         f'with ({num_cameras}, {num_targets}, {num_obstacles}) entities, '
                         f'got shape {observation.shape}')
    return tuple(observation[..., int(begin):int(end)] for begin, end in zip(indices[:-1], indices[1:]))


# ---------------------------------------------------------------------------- state views

class StateBase:
    """Read-only view of one entity's state vector (length `DIM`) with lazily decoded fields.

    Args:
        state: the state vector (a slice of an observation; not copied).
        index: the entity's index in the current episode, or None.
    """

    DIM: int = 0
    __slots__ = ('_state', '_index', '_values')

    def __init__(self, state, index=None) -> None:
        state = np.asarray(state, dtype=np.float64)
        if state.shape != (self.DIM,):
            raise ValueError(f'{type(self).__name__} needs a vector of length {self.DIM}, got shape {state.shape}')
        self._state, self._index, self._values = state, index, None

    @classmethod
    def from_values(cls, values, index=None):
        """A view over a tuple/list of Python floats (no array until `.state` is read)."""
        view = cls.__new__(cls)
        view._state, view._index, view._values = None, index, values
        return view

    @property
    def state(self) -> np.ndarray:
        """The state vector, float64 (DIM,)."""
        if self._state is None:
            self._state = np.array(self._values, dtype=np.float64)
        return self._state

    @property
    def values(self) -> list:
        """The state vector as Python floats."""
        if self._values is None:
            self._values = self._state.tolist()
        return self._values

    @property
    def index(self):
        return self._index

    @property
    def location(self) -> np.ndarray:
        """(x, y), float64 (2,)."""
        return self.state[0:2]

    @property
    def x(self) -> float:
        return self.values[0]

    @property
    def y(self) -> float:
        return self.values[1]

    def copy(self):
        """A view over a copy of the state vector."""
        return type(self)(self.state.copy(), self._index)

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        return self.state.astype(dtype) if dtype is not None else self.state.copy()

    def __sub__(self, other: StateBase) -> Vector2D:
        """The vector from `other`'s location to this one's (origin = other's location)."""
        return Vector2D(vector=self.location - other.location, origin=other.location)

    def __len__(self) -> int:
        return self.DIM

    def __eq__(self, other) -> bool:
        """Views are equal when they are of one class, of the same entity index and hold the same vector."""
        if not isinstance(other, StateBase):
            return NotImplemented
        return type(self) is type(other) and self._index == other._index and self.values == other.values

    __hash__ = None

    def __repr__(self) -> str:
        return f'{type(self).__name__}({self.values}, index={self._index})'


class CameraStatePublic(StateBase):
    """A camera as others see it: x, y, radius, R cos(phi), R sin(phi), viewing angle theta."""

    DIM = CAMERA_STATE_DIM_PUBLIC
    __slots__ = ()

    @property
    def radius(self) -> float:
        return abs(self.values[2])

    @property
    def sight_range(self) -> float:
        """Current sight range R."""
        v = self.values
        return math.hypot(v[3], v[4])

    @property
    def orientation(self) -> float:
        """Orientation phi in degrees, (-180, 180]."""
        v = self.values
        return math.atan2(v[4], v[3]) * RAD2DEG

    @property
    def viewing_angle(self) -> float:
        """Viewing angle theta in degrees."""
        return self.values[5]


class CameraStatePrivate(CameraStatePublic):
    """A camera's own state: the public part plus R_max, rotation step and zooming step."""

    DIM = CAMERA_STATE_DIM_PRIVATE
    __slots__ = ()

    @property
    def max_sight_range(self) -> float:
        return self.values[6]

    @property
    def rotation_step(self) -> float:
        return self.values[7]

    @property
    def zooming_step(self) -> float:
        return self.values[8]

    @property
    def min_viewing_angle(self) -> float:
        """The viewing angle at full range: theta (R / R_max)^2 (the sector area is constant)."""
        return self.viewing_angle * (self.sight_range / self.max_sight_range) ** 2

    @property
    def action_space(self) -> gym_spaces.Box:
        """Box([-rotation_step, -zooming_step], [rotation_step, zooming_step]), float64."""
        high = np.array([self.rotation_step, self.zooming_step])
        return gym_spaces.Box(low=-high, high=high, dtype=np.float64)


class TargetStatePublic(StateBase):
    """A target as others see it: x, y, sight range, is_loaded."""

    DIM = TARGET_STATE_DIM_PUBLIC
    __slots__ = ()

    @property
    def sight_range(self) -> float:
        return self.values[2]

    @property
    def is_loaded(self) -> bool:
        return bool(self.values[3])


class TargetStatePrivate(TargetStatePublic):
    """A target's own state: the public part plus step size, capacity, goal bits (cargo weight per destination
    warehouse) and empty bits (warehouses seen without cargo)."""

    DIM = TARGET_STATE_DIM_PRIVATE
    __slots__ = ()

    @property
    def step_size(self) -> float:
        return self.values[4]

    @property
    def capacity(self) -> float:
        return self.values[5]

    @property
    def goal_bits(self) -> np.ndarray:
        """int64 (4,): units carried for each destination warehouse."""
        return self.state[6:6 + NUM_WAREHOUSES].astype(np.int64)

    @property
    def empty_bits(self) -> np.ndarray:
        """bool (4,): warehouses this target has seen without cargo."""
        return self.state[6 + NUM_WAREHOUSES:6 + 2 * NUM_WAREHOUSES].astype(bool)

    @property
    def action_space(self) -> gym_spaces.Box:
        """Box([-step_size] * 2, [step_size] * 2), float64."""
        high = np.full(2, self.step_size)
        return gym_spaces.Box(low=-high, high=high, dtype=np.float64)


class ObstacleState(StateBase):
    """An obstacle: x, y, radius."""

    DIM = OBSTACLE_STATE_DIM
    __slots__ = ()

    @property
    def radius(self) -> float:
        return self.values[2]
