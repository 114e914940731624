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

Autoreset, as the CPU vector env's (`autoreset_mode`): 'next_step' (the default) -- the step after a game ended
ignores its actions, starts its next episode and returns its first observations with reward 0 and no end flags --
or 'same_step' -- a game that ends starts its next episode in the same step (without the final observation): the
step returns that step's rewards and end flags and the new episode's first observations. Either way `info` holds
the step's coverage rate (in same_step that of the step played, also in the games that ended: the CPU env's `info`
shows their new episode's there and keeps the step played in `final_info`) and, where `terminated | truncated`, the
ended episodes' length and mean coverage rate. A
game's random stream goes on into its next episode, as on the CPU, so with the caller's actions the games are the
CPU env's with the same autoreset mode, game for game (to the rounding of the device's math library).

The returned tensors are the env's buffers: the next call overwrites them (clone what you keep), as the CPU vector
env's buffers are. Actions are (B, Nc, 2) / (B, Nt, 2) tensors or arrays (float64 on the device; others are
converted) and must be finite (the kernels do not check). Without a GPU, numba's CUDA simulator
(`NUMBA_ENABLE_CUDASIM=1`) runs the same kernels slowly, with CPU tensors: what the tests use.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import registration
from .core.device import BLOCK, DeviceCore, from_torch, to_torch
from .env import MultiAgentTracking
from .messages import Team

__all__ = ['DeviceVecEnv', 'INFO_KEYS']

INFO_KEYS = ('coverage_rate', 'episode_length', 'episode_coverage_rate', 'episode_real_coverage_rate',
             'episode_target_return', 'transport_rate', 'delivered_cargoes')
"""The (B,) tensors of a step's `info`: the step's coverage rate, and where `terminated | truncated` the ended
episodes' statistics (`mate.core.device.Outputs`)."""


class DeviceVecEnv:
    """B games of one configuration on a CUDA device (see the module docstring).

    Args:
        config: a preset name, a path or a dict, as `mate.make`'s; `overrides` are deep-merged into it.
        num_envs: B.
        observation_dtype: float64 or float32 (the world is float64 either way).
        camera_agent: None (the caller acts for the cameras) or a built-in agent played on the device, 'greedy' or
            'random'; `camera_options` are its options.
        target_agent: the same for the targets (`target_options`).
        seed: the teams' seeds (row b: seed + b; their random streams, not the games').
        autoreset_mode: 'next_step' (default) or 'same_step' (module docstring).
        block: threads per CUDA block.
    """

    def __init__(self, config: Any = None, num_envs: int = 1, *, observation_dtype=np.float64,
                 camera_agent: str | None = None, target_agent: str | None = None,
                 camera_options: dict | None = None, target_options: dict | None = None, seed: int = 0,
                 autoreset_mode: str = 'next_step', block: int = BLOCK, **overrides: Any) -> None:
        if not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool) or num_envs < 1:
            raise ValueError(f'num_envs must be a positive integer, got {num_envs!r}')
        dtype = np.dtype(observation_dtype)
        if dtype not in (np.float64, np.float32):
            raise ValueError(f'observation_dtype must be float64 or float32, got {dtype}')
        mode = str(getattr(autoreset_mode, 'value', autoreset_mode)).replace('-', '').replace('_', '').lower()
        if mode not in ('nextstep', 'samestep'):
            raise ValueError(f"on a device autoreset_mode is 'next_step' or 'same_step', got {autoreset_mode!r}")
        self.autoreset_mode = 'next_step' if mode == 'nextstep' else 'same_step'
        self.next_step = mode == 'nextstep'
        template = MultiAgentTracking(config, **overrides)
        self.config, self.params = template.config, template.params
        self.num_envs = B = int(num_envs)
        p = self.params
        self.counts = (p.num_cameras, p.num_targets, p.num_obstacles)
        dims = (template.camera_observation_space.shape[0], template.target_observation_space.shape[0])
        self.camera_observation_space, self.target_observation_space = (template.camera_observation_space,
                                                                        template.target_observation_space)
        self.camera_action_space, self.target_action_space = (template.camera_action_space,
                                                              template.target_action_space)
        self.core = DeviceCore(p, B, dims, dtype, block=block)
        self.every = self.core.cuda.to_device(np.ones(B, bool))
        rows = self.core.rows
        self._agents = {team: (agent, dict(options or {})) for team, agent, options in (
            (Team.CAMERA, camera_agent, camera_options), (Team.TARGET, target_agent, target_options))
            if agent is not None}
        self.teams = self._make_teams(seed)
        self._observations = (to_torch(rows.camera_obs), to_torch(rows.target_obs))
        out = self.core.out
        self._rewards = (to_torch(out.camera_reward), to_torch(out.target_reward))
        self._flags = (to_torch(out.terminated), to_torch(out.truncated))
        self._info = {name: to_torch(getattr(out, name)) for name in INFO_KEYS}
        self._world_views = {}                    # world_tensor's views, by name
        self._started = self._seeded = False

    def _make_teams(self, seed: int) -> dict:
        """The device teams, row b seeded with seed + b, writing their actions into the core's action buffers."""
        from .teams.device import device_team

        buffers = {Team.CAMERA: self.core.rows.camera_actions, Team.TARGET: self.core.rows.target_actions}
        teams = {}
        for team, (agent, options) in self._agents.items():
            device = device_team(agent, team, self.num_envs, self.counts, seed=seed, **options).to_device()
            teams[team] = device._replace(state=device.state._replace(action=buffers[team]))
        return teams

    def _reset_teams(self, mask) -> None:
        """The device teams start an episode in the games of `mask` (B,) bool (device array), from their first
        observations."""
        for team, observation in ((Team.CAMERA, self.core.rows.camera_obs), (Team.TARGET, self.core.rows.target_obs)):
            if team in self.teams:
                self.teams[team].reset(observation, mask, self.core.block)

    def reset(self, seed: int | None = None, options: dict | None = None, *, team_seed: int | None = None):
        """Start every game; returns ((camera_obs, target_obs), {}). `seed` s: game b and the device teams' row b
        are seeded with s + b (the teams made anew); None: every stream goes on (the first reset draws fresh
        entropy), as the CPU vector env's. `team_seed` t (with a seed): the teams' row b is seeded t + b instead
        (`TeamVecEnv`'s opponent keeps the seed it was made with)."""
        if options:
            raise ValueError(f'DeviceVecEnv.reset takes no options, got {sorted(options)}')
        for name, value in (('seed', seed), ('team_seed', team_seed)):
            if value is not None and (not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < 0):
                raise ValueError(f'{name} must be a non-negative integer or None, got {value!r}')
        if team_seed is not None and seed is None:
            raise ValueError('team_seed needs a seed (an unseeded reset goes on with every stream)')
        if seed is not None:
            self.teams = self._make_teams(int(seed if team_seed is None else team_seed))
            seeds = [int(seed) + b for b in range(self.num_envs)]
        else:                                     # streams go on; never-seeded games draw fresh entropy
            seeds = None if self._seeded else [None] * self.num_envs
        self.core.reset(seeds=seeds)
        self._seeded = True
        self._reset_teams(self.every)
        self.core.rows.mask.copy_to_device(np.zeros(self.num_envs, bool))       # no game waits for a restart
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
        if hasattr(actions, 'to') and hasattr(actions, 'detach'):        # a torch tensor, float64 on its device
            import torch

            actions = actions.to(dtype=torch.float64)
        array = from_torch(actions)
        if not hasattr(array, 'copy_to_host'):
            array = np.ascontiguousarray(array, dtype=np.float64)
        return array

    def step(self, camera_actions=None, target_actions=None, restart_ended: bool = True):
        """One step of every game: the device teams act, the world advances, the games that ended restart.
        Returns ((camera_obs, target_obs), (camera_reward, target_reward), terminated, truncated, info).
        `restart_ended=False` (same_step): the ended games restart only at `restart_ended()`, so that the world
        arrays of their ended step can be read first (`world_tensor`)."""
        if not self._started:
            raise RuntimeError('DeviceVecEnv: call reset() before step()')
        camera_actions = self._actions(camera_actions, Team.CAMERA)
        target_actions = self._actions(target_actions, Team.TARGET)
        rows = self.core.rows
        for team, observation in ((Team.CAMERA, rows.camera_obs), (Team.TARGET, rows.target_obs)):
            if team in self.teams:
                self.teams[team].act(observation, self.every, self.core.block)
        self.core.step(camera_actions, target_actions, restart_masked=self.next_step)
        if self.next_step:               # the games that ended last step restarted instead of stepping
            self._reset_teams(rows.mask)
            self.core.finish(restart=False)
        elif restart_ended:
            self.core.finish(restart=True)
            self._reset_teams(rows.mask)
        else:
            self.core.finish(restart=False)
        return self._observations, self._rewards, self._flags[0], self._flags[1], self._info

    def restart_ended(self) -> None:
        """After `step(..., restart_ended=False)`: the games that ended in it start their next episode."""
        self.core.reset_masked()
        self._reset_teams(self.core.rows.mask)

    def restart(self, mask) -> None:
        """The games of `mask` (B,) bool (host) start their next episode now, their streams going on (what a
        partial reset of TorchRL asks for); no game waits for a restart after it."""
        mask = np.asarray(mask, bool)
        self.core.reset(mask)
        self._reset_teams(self.core.rows.mask)
        self.core.rows.mask.copy_to_device(np.zeros(self.num_envs, bool))

    def state(self):
        """(B, S) tensor: every game's global state (`mate.make_vec(...).state()`'s values, in the observations'
        dtype), e.g. for a centralised critic; one buffer on the device, overwritten by the next call."""
        return to_torch(self.core.state())

    def state_dict(self) -> dict:
        """Everything the games' future depends on, as host numpy arrays: the world, the observations, the actions
        held, the games waiting for a next_step restart and the device teams' states (their random streams
        included). `load_state_dict` on an env made alike continues exactly."""
        core = self.core
        host = lambda group: {name: array.copy_to_host() for name, array in zip(group._fields, group)}  # noqa: E731
        return dict(world=host(core.world), rows=host(core.rows),
                    teams={team.name.lower(): host(device.state) for team, device in self.teams.items()},
                    started=self._started, seeded=self._seeded)

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (taken from an env of the same game, size and device teams)."""
        core = self.core
        for group, arrays in ((core.world, state['world']), (core.rows, state['rows'])):
            for name, array in zip(group._fields, group):
                array.copy_to_device(np.ascontiguousarray(arrays[name]))
        if sorted(state['teams']) != sorted(team.name.lower() for team in self.teams):
            raise ValueError(f"the state's device teams ({', '.join(sorted(state['teams'])) or 'none'}) are not this "
                             f"env's ({', '.join(sorted(team.name.lower() for team in self.teams)) or 'none'})")
        for team, device in self.teams.items():
            arrays = state['teams'][team.name.lower()]
            for name, array in zip(device.state._fields, device.state):
                if name != 'action':          # the core's action buffer, loaded with the rows
                    array.copy_to_device(np.ascontiguousarray(arrays[name]))
        self._started, self._seeded = bool(state['started']), bool(state.get('seeded', True))

    @property
    def observations(self):
        """(camera_obs (B, Nc, D_c), target_obs (B, Nt, D_t)) tensors: both teams' current observations (the env's
        buffers, overwritten by the next step)."""
        return self._observations

    def world_tensor(self, name: str):
        """A torch tensor viewing the world array `name` on the device (`mate.core.world.World`'s fields, e.g.
        'target_reward_parts' (B, Nt), 'camera_target_view_mask' (B, Nc, Nt)): one view per name, made at its first
        call and kept (the world's arrays stay in place: steps and `load_state_dict` write into them)."""
        view = self._world_views.get(name)
        if view is None:
            view = self._world_views[name] = to_torch(getattr(self.core.world, name))
        return view

    def close(self) -> None:
        """Nothing to release (the device arrays go with the object)."""


def make_device_vec(env_id: str = 'MultiAgentTracking-v0', num_envs: int = 1, config: Any = None,
                    **kwargs: Any) -> DeviceVecEnv:
    """`DeviceVecEnv` for an ID of `mate.make` (`mate.make_vec(..., device='cuda')` calls this)."""
    return DeviceVecEnv(registration.resolve_config(env_id, config), num_envs, **kwargs)
