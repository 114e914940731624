"""What the vector envs of both devices share: the autoreset modes, the info keys, the spaces, the action draws, the
seeds of a reset and the checks of the actions with their refusals (`mate.envs.vector`'s CPU env and
`mate.envs.device_vector`'s device env have one API)."""

from __future__ import annotations

from enum import Enum
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import VectorEnv
from gymnasium.vector.utils import batch_space

from ..core.arrays import array_namespace, copied
from ..core.world import EPISODE_STATISTICS, episode_statistics, obstacle_states
from .multi_agent_tracking import GameDescription, MultiAgentTracking, team_shape_error

__all__ = ['ADDED_FIELDS', 'AutoresetMode', 'FINAL_WORLD_KEYS', 'INFO_KEYS', 'VectorGames', 'autoreset_mode_of',
           'checked_team_actions', 'env_listing', 'is_seed', 'row_seeds_of', 'uniform_actions', 'vector_spaces']

try:
    from gymnasium.vector import AutoresetMode
except ImportError:  # gymnasium 1.0 has next-step autoreset only, and no enum for it
    class AutoresetMode(Enum):
        NEXT_STEP = 'NextStep'
        SAME_STEP = 'SameStep'
        DISABLED = 'Disabled'

ADDED_FIELDS = frozenset({'target_reward_parts', 'camera_reward_parts', 'coverage_rate_sum',
                          'real_coverage_rate_sum'})
"""World arrays an earlier version did not have: a state saved by it still loads (they start at zero; the
episode sums of coverage then count from the resume, unless the caller has them: `TrainingEnv` restores its own)."""
INFO_KEYS = ('coverage_rate', 'real_coverage_rate', 'mean_transport_rate', 'num_delivered_cargoes', 'episode_step',
             *EPISODE_STATISTICS)
"""The (B,) arrays of a vector step's infos: World fields of the same names, and the episode so far
(`mate.core.world.episode_statistics`: its mean coverage rates and the target team's raw return)."""
FINAL_WORLD_KEYS = ('target_reward_parts', 'camera_reward_parts', 'camera_target_view_mask')
"""World arrays of the ended step that `same_step` autoreset keeps in `final_info` (each target's part of the team
reward (B, Nt), each camera's difference credit (B, Nc), which camera tracks which target (B, Nc, Nt)): the reset
overwrites them."""


def autoreset_mode_of(mode) -> AutoresetMode:
    """`mode` (an `AutoresetMode`, another library's enum of the same values, or a name such as 'same_step') as
    an `AutoresetMode`; ValueError naming the modes otherwise."""
    if isinstance(mode, AutoresetMode):
        return mode
    if isinstance(mode, Enum):  # another library's enum with the same values (gymnasium's vs ours)
        mode = mode.value
    key = str(mode).replace('_', '').replace('-', '').lower()
    for member in AutoresetMode:
        if key in (member.name.replace('_', '').lower(), member.value.lower()):
            return member
    names = ', '.join(repr(m.name.lower()) for m in AutoresetMode)
    raise ValueError(f'autoreset_mode={mode!r} is not one of {names}')


def _box(low: np.ndarray, high: np.ndarray, dtype) -> spaces.Box:
    dtype = np.dtype(dtype)
    return spaces.Box(low.astype(dtype), high.astype(dtype), dtype=dtype)


def vector_spaces(template: MultiAgentTracking, num_envs: int, dtype) -> dict[str, spaces.Space]:
    """The spaces of a vector env of `num_envs` games of `template`'s, observations in `dtype` (the CPU's and the
    device's vector envs have the same): each agent's (`camera_action_space`, ..., `target_observation_space`), the
    joint ones of one game (`single_action_space` Tuple(Box(Nc, 2), Box(Nt, 2)), `single_observation_space`
    Tuple(Box(Nc, D_c), Box(Nt, D_t)), `single_state_space` Box(S)) and their batched forms (`action_space`,
    `observation_space`, `state_space`)."""
    nc, nt = template.params.num_cameras, template.params.num_targets
    camera_obs = _box(template.camera_observation_space.low, template.camera_observation_space.high, dtype)
    target_obs = _box(template.target_observation_space.low, template.target_observation_space.high, dtype)
    camera_act, target_act = template.camera_action_space, template.target_action_space
    single_action = spaces.Tuple((
        _box(np.tile(camera_act.low, (nc, 1)), np.tile(camera_act.high, (nc, 1)), np.float64),
        _box(np.tile(target_act.low, (nt, 1)), np.tile(target_act.high, (nt, 1)), np.float64)))
    single_observation = spaces.Tuple((
        _box(np.tile(camera_obs.low, (nc, 1)), np.tile(camera_obs.high, (nc, 1)), dtype),
        _box(np.tile(target_obs.low, (nt, 1)), np.tile(target_obs.high, (nt, 1)), dtype)))
    single_state = _box(template.state_space.low, template.state_space.high, dtype)
    return dict(camera_action_space=camera_act, target_action_space=target_act, camera_observation_space=camera_obs,
                target_observation_space=target_obs, single_action_space=single_action,
                single_observation_space=single_observation, single_state_space=single_state,
                action_space=batch_space(single_action, num_envs),
                observation_space=batch_space(single_observation, num_envs),
                state_space=batch_space(single_state, num_envs))


def uniform_actions(rng: np.random.Generator, box: spaces.Box, shape: tuple[int, ...]) -> np.ndarray:
    """Uniform draws over `box` (bounds of the last axes) in a fresh float64 array of `shape`.

    The same numbers as `rng.uniform(box.low, box.high, shape)`, drawn and then scaled in place
    over rows of all the agents' values (numpy's inner loops are slow over a last axis of 2):
    0.26 against 0.66 ms for a (4096, 12, 2) joint action.
    """
    out = rng.random(shape)
    rows = out.reshape(shape[0], -1)
    repeats = rows.shape[1] // box.low.size
    rows *= np.tile(box.high - box.low, repeats)
    rows += np.tile(box.low, repeats)
    return out


def is_seed(value) -> bool:
    """Whether `value` is one game's seed: a non-negative integer (not a bool)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 0


def row_seeds_of(seed, num_envs: int) -> list[int | None]:
    """The seed of every game of `reset(seed=...)`, one rule for both vector envs: None (every stream goes on), an
    int s (game b: s + b) or a sequence of `num_envs` ints and Nones (game b: seed[b]). ValueError (one line)
    otherwise."""
    if seed is None:
        return [None] * num_envs
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        if seed < 0:
            raise ValueError(f'seed must be a non-negative integer or None, got {seed!r}')
        return [int(seed) + b for b in range(num_envs)]
    if not isinstance(seed, (list, tuple, np.ndarray)):
        raise ValueError(f'seed must be a non-negative integer, a list of {num_envs} seeds or None, got {seed!r}')
    seeds = list(seed)
    if len(seeds) != num_envs:
        raise ValueError(f'reset(seed=...) got {len(seeds)} seeds for num_envs={num_envs}: pass an int, None or a '
                         f'list of {num_envs} seeds')
    if not all(s is None or is_seed(s) for s in seeds):
        raise ValueError(f'reset(seed=...): each seed must be a non-negative integer or None, got {seed!r}')
    return [None if s is None else int(s) for s in seeds]


def checked_team_actions(value, count: int, team: str, box: spaces.Box, num_envs: int, convert):
    """One team's actions as `step` takes them, one rule for both vector envs: (B, N, 2) or (B, 2N) of any real
    dtype, finite; returned as (B, N, 2) float64, `convert(value)` the env's array of them (a numpy array, or a
    tensor on the device). ValueError (one line) for a ragged, non-numeric, misshapen or non-finite input (which
    reads a device's actions back once)."""
    expected = (num_envs, count, 2)
    try:
        array = convert(value)
    except (TypeError, ValueError, RuntimeError) as exc:
        if 'inhomogeneous' in str(exc):   # rows of different lengths
            raise ValueError(team_shape_error(team, expected, 'a ragged sequence', batched='num_envs x ',
                                              alternative=(num_envs, 2 * count))) from None
        raise ValueError(f'{team} actions are not numeric: {exc}') from None
    if array.shape != expected:                            # (a torch.Size is a tuple)
        if array.shape != (num_envs, 2 * count):   # (B, 2N), documented, is the only other form accepted
            raise ValueError(team_shape_error(team, expected, tuple(array.shape), batched='num_envs x ',
                                              alternative=(num_envs, 2 * count)))
        array = array.reshape(expected)
    finite = np.isfinite(array) if isinstance(array, np.ndarray) else array.isfinite()   # (the host's hot path)
    if not bool(finite.all()):
        xp = array_namespace(array)
        rows = xp.all(xp.reshape(finite, (num_envs, -1)), axis=1)
        bad = np.flatnonzero(~np.asarray(rows if isinstance(rows, np.ndarray) else rows.cpu()))
        raise ValueError(f'{team} actions contain NaN or inf (envs {env_listing(bad)}); every entry must be '
                         f'finite (bounds {box.low.tolist()}..{box.high.tolist()}; larger values are clipped)')
    return array


def env_listing(indices: np.ndarray, limit: int = 10) -> str:
    """'[0, 3, 5]' (the first `limit` of `indices`, then '...'): the envs a refusal names."""
    shown = ', '.join(str(int(i)) for i in indices[:limit])
    return f'[{shown}{", ..." if len(indices) > limit else ""}]'


class VectorGames(GameDescription, VectorEnv):
    """The part of a vector env that does not depend on where its B games run: their description and spaces, the
    reset's mask and seeds, the infos, random joint actions and the views of the world (the CPU env and the device
    env are both one)."""

    def _describe_games(self, config: Any, num_envs: int, observation_dtype, autoreset_mode,
                        overrides: dict) -> MultiAgentTracking:
        """Check B and the observation dtype, read the game and set what both envs hold (config, params, num_envs,
        counts (Nc, Nt, No), observation_dtype, autoreset_mode, metadata, the spaces); returns the single env the
        game and its per-agent spaces were read from."""
        if not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool) or num_envs < 1:
            raise ValueError(f'num_envs must be a positive integer, got {num_envs!r}')
        dtype = np.dtype(observation_dtype)
        if dtype not in (np.float64, np.float32):
            raise ValueError(f'observation_dtype must be float64 or float32, got {dtype}')
        template = MultiAgentTracking(config, **overrides)
        self.config, self.params = template.config, template.params
        self.num_envs, self.observation_dtype = int(num_envs), dtype
        self.counts = (self.params.num_cameras, self.params.num_targets, self.params.num_obstacles)
        self.autoreset_mode = autoreset_mode_of(autoreset_mode)
        self.metadata = {'render_modes': [], 'autoreset_mode': self.autoreset_mode}
        self.render_mode = None
        for name, space in vector_spaces(template, self.num_envs, dtype).items():
            setattr(self, name, space)
        return template

    def _reset_mask(self, options: dict | None) -> np.ndarray | None:
        """`options['reset_mask']` of a reset as a private, writable, contiguous (B,) bool host array (None: every
        game); ValueError for another option or a mask of another dtype or shape."""
        options = dict(options or {})
        mask = options.pop('reset_mask', None)
        if options:
            raise ValueError(f"reset takes only the option 'reset_mask', got {sorted(options)}")
        if mask is None:
            return None
        host = np.asarray(mask.cpu() if hasattr(mask, 'cpu') else mask)
        if host.dtype != np.bool_ or host.shape != (self.num_envs,):
            raise ValueError(f"options['reset_mask'] must be a bool array of shape ({self.num_envs},), "
                             f'got {host.dtype} {host.shape}')
        return np.array(host, dtype=bool, order='C')

    def _rows_to_seed(self, seed, mask: np.ndarray, streams: np.ndarray) -> tuple[np.ndarray, list[int | None]]:
        """(the (B,) rows a reset of `mask` seeds, their seeds): the rows given a seed (`row_seeds_of`) and those
        never seeded (their random stream `streams` (B, 2) all zero: they draw fresh entropy). An int `seed` also
        seeds `np_random` (`sample_actions`' default)."""
        seeds = row_seeds_of(seed, self.num_envs)
        if isinstance(seed, (int, np.integer)):
            VectorEnv.reset(self, seed=int(seed))
        never_seeded = (streams[:, 0] == 0) & (streams[:, 1] == 0)
        to_seed = mask & (np.array([s is not None for s in seeds], dtype=bool) | never_seeded)
        return to_seed, [seeds[i] for i in np.flatnonzero(to_seed)]

    def _joint_actions(self, actions) -> tuple:
        """(camera actions, target actions) of a step's `actions` pair; ValueError (one line) for anything else."""
        try:
            camera_actions, target_actions = actions
        except (TypeError, ValueError):
            raise ValueError('actions must be a pair (camera_actions (B, Nc, 2), target_actions (B, Nt, 2)), '
                             f'got {type(actions).__name__}') from None
        return camera_actions, target_actions

    def _checked_actions(self, actions, convert) -> tuple:
        """`step`'s joint `actions` as (camera (B, Nc, 2), target (B, Nt, 2)) float64 arrays of the env's kind, each
        team's checked by `checked_team_actions` (`convert` making the env's array of it); ValueError (one line)."""
        camera_actions, target_actions = self._joint_actions(actions)
        return (checked_team_actions(camera_actions, self.counts[0], 'camera', self.camera_action_space,
                                     self.num_envs, convert),
                checked_team_actions(target_actions, self.counts[1], 'target', self.target_action_space,
                                     self.num_envs, convert))

    def _infos(self) -> dict:
        """The infos of every game now (`INFO_KEYS`): fresh (B,) arrays (tensors on a device), each with its `_key`
        mask (`self._info_mask`: every game, shared)."""
        world = self._world
        statistics = episode_statistics(self.params, world)
        infos = {}
        for key in INFO_KEYS:
            infos[key] = statistics[key] if key in statistics else copied(getattr(world, key))
            infos[f'_{key}'] = self._info_mask
        return infos

    def _final_info(self, infos: dict, done) -> dict:
        """Same-step autoreset's `final_info` of the step just played (`infos`), before the games of `done` (B,)
        restart: `infos` with masks `done`, and copies of the world arrays of `FINAL_WORLD_KEYS` (the restart
        overwrites them)."""
        final_info = dict(infos)
        for key in INFO_KEYS:
            final_info[f'_{key}'] = done
        for key in FINAL_WORLD_KEYS:         # per-agent results of the step, gone with the restart
            final_info[key] = copied(getattr(self._world, key))
        return final_info

    @property
    def world(self):
        """The batched world itself (`mate.core.world.World`'s fields with a leading batch axis, e.g. `target_bounty`
        (B, Nt): numpy arrays, or tensors viewing a device's arrays); read it, never write it (the next step
        overwrites it in place)."""
        return self._world

    @property
    def obstacle_states(self):
        """(B, No, 3) obstacle [x, y, r] per game and slot (a fresh array or tensor)."""
        return obstacle_states(self._world)

    @property
    def remaining_cargoes(self):
        """(B, 4, 4) units waiting at warehouse `src` (rows) for destination `dst` (a copy)."""
        return copied(self._world.remaining_cargoes)

    def __repr__(self) -> str:
        return (f'{type(self).__name__}({self.name}, num_envs={self.num_envs}, '
                f'observation_dtype={self.observation_dtype.name}, autoreset_mode={self.autoreset_mode.name})')

    def sample_actions(self, rng: np.random.Generator | int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Uniform random joint actions (camera (B, Nc, 2), target (B, Nt, 2)), float64, much cheaper than
        `action_space.sample()`. `rng`: a numpy Generator, an int seed, or None for `self.np_random` (seeded by
        `reset(seed=int)`)."""
        if rng is None:
            rng = self.np_random
        elif not isinstance(rng, np.random.Generator):
            rng = np.random.default_rng(rng)
        B, (nc, nt, _) = self.num_envs, self.counts
        return (uniform_actions(rng, self.camera_action_space, (B, nc, 2)),
                uniform_actions(rng, self.target_action_space, (B, nt, 2)))
