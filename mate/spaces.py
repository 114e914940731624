"""Observation and state spaces of MATE, the team (joint) space, and index helpers into observation vectors.

Every function is memoised on its integer arguments `(num_cameras, num_targets, num_obstacles)`
(N_c, N_t, N_o), so a space or index array is built once per team sizes; cached arrays are read-only.
Layouts and bounds (docs/environment/observations.md):

* camera observation (D_c = 22 + 5 N_t + 4 N_o + 7 N_c): preserved (13) + own private state (9)
  + N_t x (target public + flag) + N_o x (obstacle + flag) + N_c x (camera public + flag);
* target observation (D_t = 27 + 7 N_c + 4 N_o + 5 N_t): preserved (13) + own private state (14)
  + N_c x (camera public + flag) + N_o x (obstacle + flag) + N_t x (target public + flag);
* state (29 + 9 N_c + 16 N_t + 3 N_o): preserved + private states of all cameras, targets, obstacles
  + freight (N_t) + bounty (N_t) + remaining cargo (16).

Coordinates are bounded by +-2 x TERRAIN_SIZE so that relative coordinates fit too; flags and boolean
entries use [-1, 1] so that a later rescale to [-1, 1] leaves them unchanged.
"""

from __future__ import annotations

import functools
import operator

import numpy as np
from gymnasium import spaces

from mate.constants import (
    CAMERA_STATE_DIM_PRIVATE,
    CAMERA_STATE_DIM_PUBLIC,
    MAX_CAMERA_VIEWING_ANGLE,
    NUM_WAREHOUSES,
    OBSTACLE_STATE_DIM,
    PRESERVED_DIM,
    TARGET_STATE_DIM_PRIVATE,
    TARGET_STATE_DIM_PUBLIC,
    TERRAIN_SIZE,
    TERRAIN_WIDTH,
)
from mate.messages import Team

__all__ = [
    'LayoutBox', 'TeamSample', 'TeamSpace',
    'camera_state_space', 'target_state_space', 'obstacle_state_space',
    'camera_observation_space_of', 'target_observation_space_of', 'observation_space_of', 'state_space_of',
    'camera_observation_indices_of', 'target_observation_indices_of', 'observation_indices_of',
    'camera_observation_slices_of', 'target_observation_slices_of', 'observation_slices_of',
    'camera_coordinate_mask_of', 'target_coordinate_mask_of', 'coordinate_mask_of',
]

INF = np.inf
C = TERRAIN_WIDTH
"""Bound of coordinates: 2 x terrain size, so that relative coordinates fit too."""
A = MAX_CAMERA_VIEWING_ANGLE
_WAREHOUSE_COORDINATES = slice(4, 4 + 2 * NUM_WAREHOUSES)
"""Warehouse coordinates inside the preserved part (indices 4..11)."""

# (low, high) bounds of each part of the vectors
_PRESERVED = ([0.0] * 4 + [-C] * (2 * NUM_WAREHOUSES) + [0.0], [INF] * 4 + [C] * (2 * NUM_WAREHOUSES) + [TERRAIN_SIZE])
_CAMERA_PUBLIC = ([-C, -C, 0.0, -C, -C, 0.0], [C, C, TERRAIN_SIZE, C, C, A])
_CAMERA_EXTRA = ([0.0, 0.0, 0.0], [C, A, A])
_TARGET_PUBLIC = ([-C, -C, 0.0, -1.0], [C, C, C, 1.0])
_TARGET_EXTRA = ([0.0, 1.0] + [0.0] * NUM_WAREHOUSES + [-1.0] * NUM_WAREHOUSES,
                 [C, 2.0] + [INF] * NUM_WAREHOUSES + [1.0] * NUM_WAREHOUSES)
_OBSTACLE = ([-C, -C, 0.0], [C, C, TERRAIN_SIZE])
_FLAG = ([-1.0], [1.0])

assert len(_PRESERVED[0]) == PRESERVED_DIM
assert len(_CAMERA_PUBLIC[0]) + len(_CAMERA_EXTRA[0]) == CAMERA_STATE_DIM_PRIVATE
assert len(_TARGET_PUBLIC[0]) + len(_TARGET_EXTRA[0]) == TARGET_STATE_DIM_PRIVATE


class TeamSample(tuple):
    """A `TeamSpace` sample: the tuple of per-agent samples, and `array`, the (count, ...) array they are
    views of. It reads as that array too: `shape`, `dtype` and `np.asarray(sample)` are the array's."""

    array: np.ndarray

    @property
    def shape(self) -> tuple[int, ...]:
        return self.array.shape

    @property
    def dtype(self) -> np.dtype:
        return self.array.dtype

    def __array__(self, dtype=None, copy=None):
        return np.array(self.array, dtype=dtype, copy=copy)


class TeamSpace(spaces.Tuple):
    """`Tuple((space,) * count)`: one space per agent of a team, all alike, that samples the whole team
    with one draw.

    Gymnasium's `Tuple.sample` asks every agent's space in turn (~12 us per `Box`), which cost the
    README's random loop ten times the step itself. Here `sample()` takes a `(count, ...)` array from
    the team space's own generator (`Box`: uniform within the bounds, `low + (high - low) * U[0, 1)`;
    `Discrete`: uniform integers), drawn `BLOCK` samples at a time (for a Box the same numbers as one
    draw per sample), and returns it as the usual tuple of per-agent samples (views of that array), a
    `TeamSample` whose `array` is the whole team's array (the env takes it without re-stacking). Seeding as
    `Tuple`: `seed(int)` (or seeding an enclosing `Tuple`) makes samples reproducible, `seed([s0, s1, ...])`
    seeds the team generator from the list, `seed(None)` from entropy. Masked samples and other kinds of
    space fall back to `Tuple.sample`.

    Args:
        space: the space of one agent.
        count: number of agents (>= 0).
    """

    def __init__(self, space: spaces.Space, count: int, seed=None) -> None:
        super().__init__((space,) * int(count), seed=seed)
        self.agent_space, self.count = space, int(count)
        self._shape = (self.count, *space.shape) if space.shape is not None else (self.count,)
        if isinstance(space, spaces.Box) and space.is_bounded('both') and np.issubdtype(space.dtype, np.floating):
            self._kind = 'box'
            self._low = space.low.astype(np.float64)
            self._span = space.high.astype(np.float64) - self._low
        elif type(space) is spaces.Discrete:
            self._kind = 'discrete'
        else:
            self._kind = None          # Tuple.sample, agent by agent

    BLOCK = 64
    """Team samples drawn from the generator at once."""

    _block: np.ndarray | None = None     # (BLOCK, count, ...) drawn samples; a new array every refill
    _taken = 0                           # of them handed out

    def _draw(self) -> np.ndarray:
        """Every agent's sample at once, (count, *agent shape): the next one of the current block."""
        block = self._block
        if block is None or self._taken == len(block):
            rng = self.np_random
            if self._kind == 'box':
                block = rng.random((self.BLOCK, *self._shape))     # low + span * U[0, 1), scaled in place
                block *= self._span
                block += self._low
                block = block.astype(self.agent_space.dtype, copy=False)
            else:
                space = self.agent_space
                block = (space.start + rng.integers(space.n, size=(self.BLOCK, self.count))).astype(space.dtype,
                                                                                                  copy=False)
            self._block, self._taken = block, 0
        self._taken += 1
        return block[self._taken - 1]

    def seed(self, seed=None) -> tuple:
        """Seed the team generator and the agents' spaces as `Tuple.seed`; returns the agents' seeds."""
        self._block = None                   # samples drawn before the seed are dropped
        if isinstance(seed, (list, tuple)):
            seeds = super().seed(seed)
            entropy = [int(s) & 0xFFFFFFFFFFFFFFFF for s in seed if s is not None]
            spaces.Space.seed(self, int(np.random.SeedSequence(entropy or None).generate_state(1, np.uint64)[0] >> 1))
            return seeds
        if seed is None:
            spaces.Space.seed(self, None)
        return super().seed(seed)

    def sample(self, mask=None, probability=None) -> tuple:
        if self._kind is None or mask is not None or probability is not None:
            return super().sample(mask=mask, probability=probability)
        values = self._draw()
        sample = TeamSample(values)
        sample.array = values
        return sample

    def __repr__(self) -> str:
        return f'TeamSpace({self.agent_space!r} x {self.count})'


def _concat(*parts: tuple[list, list]) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate (low, high) part bounds into two float64 vectors of equal length."""
    low = np.concatenate([np.asarray(part[0], dtype=np.float64) for part in parts])
    high = np.concatenate([np.asarray(part[1], dtype=np.float64) for part in parts])
    return low, high


class LayoutBox(spaces.Box):
    """A `Box` of one of mate's vector layouts (an observation, the state) whose repr says its shape and the range
    of its per-entry bounds instead of printing the bounds of every entry (`low` and `high` hold them)."""

    def __repr__(self) -> str:
        return f'Box(per-entry bounds in [{self.low.min():g}, {self.high.max():g}], {self.shape}, {self.dtype})'


def _box(*parts: tuple[list, list]) -> spaces.Box:
    """float64 Box (a `LayoutBox`) whose bounds are the concatenation of `parts`."""
    low, high = _concat(*parts)
    return LayoutBox(low=low, high=high, dtype=np.float64)


def _with_flag(part: tuple[list, list]) -> tuple[list, list]:
    """Bounds of a masked block: the part followed by its [-1, 1] flag."""
    return part[0] + _FLAG[0], part[1] + _FLAG[1]


def _repeat(part: tuple[list, list], count: int) -> tuple[list, list]:
    """Bounds of `count` consecutive copies of `part`."""
    return part[0] * count, part[1] * count


def _counts(num_cameras, num_targets, num_obstacles) -> tuple[int, int, int]:
    """Validated (N_c, N_t, N_o) as non-negative Python ints."""
    counts = tuple(operator.index(n) for n in (num_cameras, num_targets, num_obstacles))
    if min(counts) < 0:
        raise ValueError(f'entity counts must be non-negative, got {counts}')
    return counts


def _team(team) -> Team:
    """`team` as a Team member (ValueError otherwise)."""
    return Team(team)


# ---------------------------------------------------------------------------- per-entity state spaces

@functools.lru_cache(maxsize=None)
def camera_state_space(private: bool = True) -> spaces.Box:
    """Box of one camera's state: private (9,) or public (6,)."""
    return _box(_CAMERA_PUBLIC, _CAMERA_EXTRA) if private else _box(_CAMERA_PUBLIC)


@functools.lru_cache(maxsize=None)
def target_state_space(private: bool = True) -> spaces.Box:
    """Box of one target's state: private (14,) or public (4,)."""
    return _box(_TARGET_PUBLIC, _TARGET_EXTRA) if private else _box(_TARGET_PUBLIC)


@functools.lru_cache(maxsize=None)
def obstacle_state_space() -> spaces.Box:
    """Box of one obstacle's state (3,): x, y, radius."""
    return _box(_OBSTACLE)


# ---------------------------------------------------------------------------- observation and state spaces

def _camera_parts(num_cameras: int, num_targets: int, num_obstacles: int) -> list[tuple[list, list]]:
    return [_PRESERVED, _CAMERA_PUBLIC, _CAMERA_EXTRA,
            _repeat(_with_flag(_TARGET_PUBLIC), num_targets),
            _repeat(_with_flag(_OBSTACLE), num_obstacles),
            _repeat(_with_flag(_CAMERA_PUBLIC), num_cameras)]


def _target_parts(num_cameras: int, num_targets: int, num_obstacles: int) -> list[tuple[list, list]]:
    return [_PRESERVED, _TARGET_PUBLIC, _TARGET_EXTRA,
            _repeat(_with_flag(_CAMERA_PUBLIC), num_cameras),
            _repeat(_with_flag(_OBSTACLE), num_obstacles),
            _repeat(_with_flag(_TARGET_PUBLIC), num_targets)]


@functools.lru_cache(maxsize=None)
def camera_observation_space_of(num_cameras: int, num_targets: int, num_obstacles: int) -> spaces.Box:
    """Box of one camera's observation, shape (D_c,) = (22 + 5 N_t + 4 N_o + 7 N_c,)."""
    return _box(*_camera_parts(*_counts(num_cameras, num_targets, num_obstacles)))


@functools.lru_cache(maxsize=None)
def target_observation_space_of(num_cameras: int, num_targets: int, num_obstacles: int) -> spaces.Box:
    """Box of one target's observation, shape (D_t,) = (27 + 7 N_c + 4 N_o + 5 N_t,)."""
    return _box(*_target_parts(*_counts(num_cameras, num_targets, num_obstacles)))


def observation_space_of(team: Team, num_cameras: int, num_targets: int, num_obstacles: int) -> spaces.Box:
    """Box of one observation of an agent of `team` (dispatches to the two functions above)."""
    if _team(team) is Team.CAMERA:
        return camera_observation_space_of(num_cameras, num_targets, num_obstacles)
    return target_observation_space_of(num_cameras, num_targets, num_obstacles)


@functools.lru_cache(maxsize=None)
def state_space_of(num_cameras: int, num_targets: int, num_obstacles: int) -> spaces.Box:
    """Box of the global state, shape (29 + 9 N_c + 16 N_t + 3 N_o,).

    Freight (N_t), bounty (N_t) and the remaining cargo matrix (16) are bounded in [0, inf).
    """
    num_cameras, num_targets, num_obstacles = _counts(num_cameras, num_targets, num_obstacles)
    tail = 2 * num_targets + NUM_WAREHOUSES * NUM_WAREHOUSES
    return _box(_PRESERVED,
                _repeat((_CAMERA_PUBLIC[0] + _CAMERA_EXTRA[0], _CAMERA_PUBLIC[1] + _CAMERA_EXTRA[1]), num_cameras),
                _repeat((_TARGET_PUBLIC[0] + _TARGET_EXTRA[0], _TARGET_PUBLIC[1] + _TARGET_EXTRA[1]), num_targets),
                _repeat(_OBSTACLE, num_obstacles),
                ([0.0] * tail, [INF] * tail))


# ---------------------------------------------------------------------------- indices and slices

def _layout(self_dim: int, blocks: tuple[tuple[int, int], ...]) -> np.ndarray:
    """Start offsets [0, 13, 13 + self_dim, ...] then the end, for blocks of (state_dim, count); int64 (6,)."""
    sizes = [PRESERVED_DIM, self_dim] + [(dim + 1) * count for dim, count in blocks]
    indices = np.cumsum([0] + sizes, dtype=np.int64)
    indices.setflags(write=False)
    return indices


def _camera_blocks(num_cameras: int, num_targets: int, num_obstacles: int) -> tuple[tuple[int, int], ...]:
    """(state dim, count) of the opponent, obstacle and teammate blocks of a camera observation."""
    return ((TARGET_STATE_DIM_PUBLIC, num_targets), (OBSTACLE_STATE_DIM, num_obstacles),
            (CAMERA_STATE_DIM_PUBLIC, num_cameras))


def _target_blocks(num_cameras: int, num_targets: int, num_obstacles: int) -> tuple[tuple[int, int], ...]:
    """(state dim, count) of the opponent, obstacle and teammate blocks of a target observation."""
    return ((CAMERA_STATE_DIM_PUBLIC, num_cameras), (OBSTACLE_STATE_DIM, num_obstacles),
            (TARGET_STATE_DIM_PUBLIC, num_targets))


@functools.lru_cache(maxsize=None)
def camera_observation_indices_of(num_cameras: int, num_targets: int, num_obstacles: int) -> np.ndarray:
    """Read-only int64 (6,): [0, 13, 22, 22 + 5 N_t, 22 + 5 N_t + 4 N_o, D_c]."""
    counts = _counts(num_cameras, num_targets, num_obstacles)
    return _layout(CAMERA_STATE_DIM_PRIVATE, _camera_blocks(*counts))


@functools.lru_cache(maxsize=None)
def target_observation_indices_of(num_cameras: int, num_targets: int, num_obstacles: int) -> np.ndarray:
    """Read-only int64 (6,): [0, 13, 27, 27 + 7 N_c, 27 + 7 N_c + 4 N_o, D_t]."""
    counts = _counts(num_cameras, num_targets, num_obstacles)
    return _layout(TARGET_STATE_DIM_PRIVATE, _target_blocks(*counts))


def observation_indices_of(team: Team, num_cameras: int, num_targets: int, num_obstacles: int) -> np.ndarray:
    """The 6 part offsets of an observation of `team` (dispatch)."""
    if _team(team) is Team.CAMERA:
        return camera_observation_indices_of(num_cameras, num_targets, num_obstacles)
    return target_observation_indices_of(num_cameras, num_targets, num_obstacles)


_SLICE_NAMES = ('opponent', 'obstacle', 'teammate')


def _slices(indices: np.ndarray, blocks: tuple[tuple[int, int], ...]) -> tuple[tuple[str, slice], ...]:
    """Named slices of every part; each `*_mask` is strided over the flag column of its blocks."""
    start = [int(i) for i in indices]
    items = [('preserved_data', slice(start[0], start[1])), ('self_state', slice(start[1], start[2]))]
    for k, (name, (dim, _)) in enumerate(zip(_SLICE_NAMES, blocks)):
        begin, end = start[2 + k], start[3 + k]
        items.append((f'{name}_states_with_mask', slice(begin, end)))
        items.append((f'{name}_mask', slice(begin + dim, end, dim + 1)))
    return tuple(items)


@functools.lru_cache(maxsize=None)
def _camera_slices(num_cameras: int, num_targets: int, num_obstacles: int) -> tuple[tuple[str, slice], ...]:
    counts = _counts(num_cameras, num_targets, num_obstacles)
    return _slices(camera_observation_indices_of(*counts), _camera_blocks(*counts))


@functools.lru_cache(maxsize=None)
def _target_slices(num_cameras: int, num_targets: int, num_obstacles: int) -> tuple[tuple[str, slice], ...]:
    counts = _counts(num_cameras, num_targets, num_obstacles)
    return _slices(target_observation_indices_of(*counts), _target_blocks(*counts))


def camera_observation_slices_of(num_cameras: int, num_targets: int, num_obstacles: int) -> dict[str, slice]:
    """Slices of a camera observation: preserved_data, self_state, {opponent,obstacle,teammate}_states_with_mask
    and the strided {opponent,obstacle,teammate}_mask (opponents = targets, teammates = cameras).

    A fresh dict each call (built from a memoised tuple), so callers may modify it.
    """
    return dict(_camera_slices(num_cameras, num_targets, num_obstacles))


def target_observation_slices_of(num_cameras: int, num_targets: int, num_obstacles: int) -> dict[str, slice]:
    """Slices of a target observation, keys as for cameras (opponents = cameras, teammates = targets)."""
    return dict(_target_slices(num_cameras, num_targets, num_obstacles))


def observation_slices_of(team: Team, num_cameras: int, num_targets: int, num_obstacles: int) -> dict[str, slice]:
    """Slices of an observation of `team` (dispatch)."""
    if _team(team) is Team.CAMERA:
        return camera_observation_slices_of(num_cameras, num_targets, num_obstacles)
    return target_observation_slices_of(num_cameras, num_targets, num_obstacles)


# ---------------------------------------------------------------------------- coordinate masks

def _coordinate_mask(indices: np.ndarray, blocks: tuple[tuple[int, int], ...]) -> np.ndarray:
    """Read-only bool (D,): warehouse coordinates and the x, y of every opponent/obstacle/teammate block."""
    mask = np.zeros(int(indices[-1]), dtype=bool)
    mask[_WAREHOUSE_COORDINATES] = True
    for begin, (dim, count) in zip(indices[2:5], blocks):
        starts = int(begin) + (dim + 1) * np.arange(count)
        mask[starts] = True
        mask[starts + 1] = True
    mask.setflags(write=False)
    return mask


@functools.lru_cache(maxsize=None)
def camera_coordinate_mask_of(num_cameras: int, num_targets: int, num_obstacles: int) -> np.ndarray:
    """Read-only bool (D_c,) marking coordinate entries of a camera observation (not its own x, y)."""
    counts = _counts(num_cameras, num_targets, num_obstacles)
    return _coordinate_mask(camera_observation_indices_of(*counts), _camera_blocks(*counts))


@functools.lru_cache(maxsize=None)
def target_coordinate_mask_of(num_cameras: int, num_targets: int, num_obstacles: int) -> np.ndarray:
    """Read-only bool (D_t,) marking coordinate entries of a target observation (not its own x, y)."""
    counts = _counts(num_cameras, num_targets, num_obstacles)
    return _coordinate_mask(target_observation_indices_of(*counts), _target_blocks(*counts))


def coordinate_mask_of(team: Team, num_cameras: int, num_targets: int, num_obstacles: int) -> np.ndarray:
    """Coordinate mask of an observation of `team` (dispatch)."""
    if _team(team) is Team.CAMERA:
        return camera_coordinate_mask_of(num_cameras, num_targets, num_obstacles)
    return target_coordinate_mask_of(num_cameras, num_targets, num_obstacles)
