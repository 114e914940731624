"""What the vector envs of both devices share: the autoreset modes, the info keys, the spaces, the action draws and
the refusals' listings (`mate.vector`'s CPU env and `mate.device_vector`'s device env have one API)."""

from __future__ import annotations

from enum import Enum

import numpy as np
from gymnasium import spaces
from gymnasium.vector.utils import batch_space

from .core.world import EPISODE_STATISTICS
from .env import MultiAgentTracking

__all__ = ['ADDED_FIELDS', 'AutoresetMode', 'FINAL_WORLD_KEYS', 'INFO_KEYS', 'autoreset_mode_of', 'env_listing',
           'uniform_actions', 'vector_spaces']

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
episode sums of coverage then count from the resume, unless the caller has them: `TeamVecEnv` restores its own)."""
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


def env_listing(indices: np.ndarray, limit: int = 10) -> str:
    """'[0, 3, 5]' (the first `limit` of `indices`, then '...'): the envs a refusal names."""
    shown = ', '.join(str(int(i)) for i in indices[:limit])
    return f'[{shown}{", ..." if len(indices) > limit else ""}]'
