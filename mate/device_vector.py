"""B games on a CUDA device, rule opponents included, handing torch tensors over without a copy.

`DeviceVecEnv` is the vector env of the device core (`mate.core.device.DeviceCore`): the world, the observations,
the rewards and the flags stay on the GPU; `reset` and `step` launch kernels (one thread a game) and return torch
tensors that view the device buffers (`__cuda_array_interface__`: no host round trip, no copy). A team can be played
on the device too (`camera_agent='greedy'`, `target_agent='random'`, ...: `mate.teams.device`), so that a learner
drives one team and the rules the other without the CPU in the loop.

    env = mate.make_vec('MultiAgentTracking-v0', num_envs=65536, config='MATE-4v8-9', device='cuda',
                        target_agent='greedy')
    (camera_obs, target_obs), info = env.reset(seed=0)           # (B, Nc, D_c) torch tensors on the GPU
    (camera_obs, target_obs), (camera_reward, target_reward), terminated, truncated, info = env.step(camera_actions)

Autoreset: a game that ends in a step starts its next episode in the same step (gymnasium's SAME_STEP without the
final observation): the step returns that step's rewards and end flags, the new episode's first observations, and
in `info` the ended episodes' length and mean coverage rate (where `terminated | truncated`). A game's random
stream goes on into its next episode, as in the CPU vector env's autoreset, so with no device team the games are
the CPU env's (`autoreset_mode='same-step'`) game for game (to the rounding of the device's math library).

The returned tensors are the env's buffers: the next call overwrites them (clone what you keep), as the CPU vector
env's buffers are. Actions are (B, Nc, 2) / (B, Nt, 2) tensors or arrays (float64 on the device; others are
converted) and must be finite (the kernels do not check). Without a GPU, numba's CUDA simulator
(`NUMBA_ENABLE_CUDASIM=1`) runs the same kernels slowly, with CPU tensors: what the tests use.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import registration
from .core.device import DeviceCore, from_torch, to_torch
from .env import MultiAgentTracking
from .messages import Team

__all__ = ['DeviceVecEnv']


class DeviceVecEnv:
    """B games of one configuration on a CUDA device (see the module docstring).

    Args:
        config: a preset name, a path or a dict, as `mate.make`'s; `overrides` are deep-merged into it.
        num_envs: B.
        observation_dtype: float64 or float32 (the world is float64 either way).
        camera_agent, target_agent: None (the caller acts for that team) or a built-in agent played on the device,
            'greedy' or 'random'; `camera_options` / `target_options` are its options.
        seed: the teams' seeds (row b: seed + b; their random streams, not the games').
        block: threads per CUDA block.
    """

    def __init__(self, config: Any = None, num_envs: int = 1, *, observation_dtype=np.float64,
                 camera_agent: str | None = None, target_agent: str | None = None,
                 camera_options: dict | None = None, target_options: dict | None = None, seed: int = 0,
                 block: int = 128, **overrides: Any) -> None:
        from .core.device import BLOCK
        from .teams.device import device_team

        if not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool) or num_envs < 1:
            raise ValueError(f'num_envs must be a positive integer, got {num_envs!r}')
        dtype = np.dtype(observation_dtype)
        if dtype not in (np.float64, np.float32):
            raise ValueError(f'observation_dtype must be float64 or float32, got {dtype}')
        template = MultiAgentTracking(config, **overrides)
        self.config, self.params = template.config, template.params
        self.num_envs = B = int(num_envs)
        p = self.params
        self.counts = (p.num_cameras, p.num_targets, p.num_obstacles)
        dims = (template.camera_observation_space.shape[0], template.target_observation_space.shape[0])
        self.core = DeviceCore(p, B, dims, dtype, block=block or BLOCK)
        self.every = self.core.cuda.to_device(np.ones(B, bool))
        rows = self.core.rows
        self.teams = {}
        for team, agent, options, buffer in ((Team.CAMERA, camera_agent, camera_options, rows.camera_actions),
                                             (Team.TARGET, target_agent, target_options, rows.target_actions)):
            if agent is None:
                continue
            host = device_team(agent, team, B, self.counts, seed=seed, **(options or {}))
            device = host.to_device()                     # the team writes its actions into the core's buffer
            self.teams[team] = device._replace(state=device.state._replace(action=buffer))
        self._observations = (to_torch(rows.camera_obs), to_torch(rows.target_obs))
        out = self.core.out
        self._rewards = (to_torch(out.camera_reward), to_torch(out.target_reward))
        self._flags = (to_torch(out.terminated), to_torch(out.truncated))
        self._info = dict(coverage_rate=to_torch(out.coverage_rate), episode_length=to_torch(out.episode_length),
                          episode_coverage_rate=to_torch(out.episode_coverage_rate))
        self._started = False

    def _observe_teams(self, mask) -> None:
        for team, observation in ((Team.CAMERA, self.core.rows.camera_obs), (Team.TARGET, self.core.rows.target_obs)):
            if team in self.teams:
                self.teams[team].reset(observation, mask, self.core.block)

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start every game (game b with seed + b; None: fresh entropy); returns ((camera_obs, target_obs), {})."""
        if options:
            raise ValueError(f'DeviceVecEnv.reset takes no options, got {sorted(options)}')
        seeds = [None] * self.num_envs if seed is None else [int(seed) + b for b in range(self.num_envs)]
        self.core.reset(seeds=seeds)
        self._observe_teams(self.every)
        self._started = True
        return self._observations, {}

    def _actions(self, actions, team: Team):
        if team in self.teams:
            if actions is not None:
                raise ValueError(f'the {team.name.lower()}s are played on the device: pass no actions for them')
            return None
        if actions is None:
            raise ValueError(f'{team.name.lower()} actions are missing (no device team plays the '
                             f'{team.name.lower()}s)')
        if hasattr(actions, 'dtype') and hasattr(actions, 'to') and str(actions.dtype) != 'torch.float64':
            actions = actions.to(dtype=__import__('torch').float64)
        array = from_torch(actions)
        if not hasattr(array, 'copy_to_host'):
            array = np.ascontiguousarray(array, dtype=np.float64)
        return array

    def step(self, camera_actions=None, target_actions=None):
        """One step of every game: the device teams act, the world advances, the games that ended restart.
        Returns ((camera_obs, target_obs), (camera_reward, target_reward), terminated, truncated, info)."""
        if not self._started:
            raise RuntimeError('DeviceVecEnv: call reset() before step()')
        camera_actions = self._actions(camera_actions, Team.CAMERA)
        target_actions = self._actions(target_actions, Team.TARGET)
        rows = self.core.rows
        for team, observation in ((Team.CAMERA, rows.camera_obs), (Team.TARGET, rows.target_obs)):
            if team in self.teams:
                self.teams[team].act(observation, self.every, self.core.block)
        self.core.step(camera_actions, target_actions)
        self.core.finish()
        self._observe_teams(rows.mask)
        return self._observations, self._rewards, self._flags[0], self._flags[1], self._info

    def close(self) -> None:
        """Nothing to release (the device arrays go with the object)."""


def make_device_vec(env_id: str = 'MultiAgentTracking-v0', num_envs: int = 1, config: Any = None,
                    **kwargs: Any) -> DeviceVecEnv:
    """`DeviceVecEnv` for an ID of `mate.make` (`mate.make_vec(..., device='cuda')` calls this)."""
    return DeviceVecEnv(registration.resolve_config(env_id, config), num_envs, **kwargs)
