"""B games on a CUDA device as a Gymnasium `VectorEnv`: the CPU vector env's API, torch tensors on the device.

`DeviceVecEnv` (`mate.make_vec(..., device='cuda')`) is the vector env of the device core
(`mate.core.device.DeviceCore`): the world, the observations, the rewards and the flags stay on the GPU; `reset`
and `step` launch kernels (one thread a game) and return torch tensors that view the device buffers
(`__cuda_array_interface__`: no host round trip, no copy). Its API is the CPU env's
(`mate.envs.vector.MultiAgentTrackingVectorEnv`), so that a loop written on the CPU runs on the GPU by changing
`device`:

    envs = mate.make_vec('MultiAgentTracking-v0', num_envs=65536, config='MATE-4v8-9', device='cuda')
    (camera_obs, target_obs), infos = envs.reset(seed=0)                # (B, Nc, D_c) torch tensors on the GPU
    for _ in range(100):
        (camera_obs, target_obs), (camera_rewards, target_rewards), terminated, truncated, infos = envs.step(
            envs.sample_actions())

The same: the spaces (numpy `Box`es: Gymnasium's spaces describe the values, whatever array holds them); `reset(*,
seed, options)` and `step((camera_actions, target_actions))` with the same action forms ((B, N, 2) or (B, 2N), of
any real dtype, tensors or arrays) and the same refusals (a wrong shape, NaN or inf, naming the envs); the info keys
(`coverage_rate`, `real_coverage_rate`, `mean_transport_rate`, `num_delivered_cargoes`, `episode_step`,
`episode_coverage_rate`, `episode_real_coverage_rate`, `episode_target_return`, each with its `_key` mask); the
autoreset modes NEXT_STEP (default) and SAME_STEP (then `final_obs`, `final_info` and their masks, on the steps
where a game ended); seeding (`reset(seed=s)`: game i with s + i, a list of B seeds, or None to go on with every
stream); `sample_actions(rng)` (the CPU env's numbers, as tensors on the device). With the same seeds and actions
the games are the CPU env's, game for game (to the rounding of the device's math library: numba's CUDA simulator,
which the tests use, gives the CPU's numbers exactly).

What differs, and why:

- The arrays are torch tensors on the device (under the simulator, CPU tensors). `final_obs` is one pair
  `(camera_obs (B, Nc, D_c), target_obs (B, Nt, D_t))` of batched tensors, valid in the games of its mask
  `_final_obs`, where the CPU env has an object array of per-game pairs (no tensor holds Python objects).
- The returned observations, rewards and flags are the env's buffers: the next call overwrites them (clone what
  you keep); there is no `copy=True`. The infos are fresh tensors.
- No DISABLED autoreset (a game that ended restarts, at the next step or in the same one).
- The rule teams on the device are `mate.teams.device.DeviceRuleTeam`s ('greedy', 'random'), played by the
  caller's loop as a `mate.teams` team is on the CPU (`team.act(observations)`, `team.reset(observations, rows)`);
  `mate.make_team_vec(..., device='cuda')` plays one against the caller's team.
- Gymnasium's vector wrappers that only pass the arrays on (`RecordVideo` aside, which needs frames) work; those
  that compute on them in numpy (`RecordEpisodeStatistics`, `NormalizeObservation`, `NormalizeReward`, ...) need
  host arrays: on a device, read the episode statistics from `infos` (`episode_*`, `_key` masks) or from
  `mate.make_team_vec(..., device='cuda')`'s `mate_episode`.

SAME_STEP checks on the host whether a game ended (one scalar read per step), to put `final_obs`/`final_info` in
exactly the steps where the CPU env does; the refusal of NaN and inf reads one more. `step_games(actions)` is `step`
without that refusal (the actions' shapes are still checked): under NEXT_STEP it reads nothing back, what the
training env of `mate.learn` steps.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import registration
from ..core.device import BLOCK, DeviceCore, from_torch, to_torch
from ..core.world import World
from ..messages import Team
from .vector_contract import ADDED_FIELDS, AutoresetMode, VectorGames

__all__ = ['DeviceVecEnv']


class DeviceVecEnv(VectorGames):
    """B games of one configuration on a CUDA device (see the module docstring).

    Args:
        config: a preset name, a path or a dict, as `mate.make`'s; `overrides` are deep-merged into it.
        num_envs: B.
        observation_dtype: float64 or float32 (the world is float64 either way).
        autoreset_mode: `AutoresetMode.NEXT_STEP` (default) or `SAME_STEP`, or its name (module docstring).
        block: threads per CUDA block.
        **overrides: keys deep-merged into the configuration.
    """

    def __init__(self, config: Any = None, num_envs: int = 1, *, observation_dtype=np.float64,
                 autoreset_mode: str = 'next_step', block: int = BLOCK, **overrides: Any) -> None:
        inside = sorted(set(overrides) & {'camera_agent', 'target_agent', 'camera_options', 'target_options'})
        if inside:
            raise TypeError(f'{inside[0]}: the device env plays no team inside; play a '
                            'mate.teams.device.DeviceRuleTeam in your loop, or use mate.make_team_vec(..., '
                            "device='cuda') for one team against the rules")
        self._describe_games(config, num_envs, observation_dtype, autoreset_mode, overrides)
        if self.autoreset_mode is AutoresetMode.DISABLED:
            raise ValueError("on a device autoreset_mode is 'next_step' or 'same_step', got "
                             f'{autoreset_mode!r} (a game that ended restarts)')
        self.next_step = self.autoreset_mode is AutoresetMode.NEXT_STEP
        B, dtype, p = self.num_envs, self.observation_dtype, self.params
        dims = (self.camera_observation_space.shape[0], self.target_observation_space.shape[0])
        self.core = DeviceCore(p, B, dims, dtype, block=block)
        rows = self.core.rows
        self._observations = (to_torch(rows.camera_obs), to_torch(rows.target_obs))
        out = self.core.out
        self._rewards = (to_torch(out.camera_reward), to_torch(out.target_reward))
        self._flags = (to_torch(out.terminated), to_torch(out.truncated))
        self._world = World(*(to_torch(field) for field in self.core.world))     # views, kept: the world stays put
        self._info_mask = self._world.episode_step.new_ones(B, dtype=bool)      # the `_key` masks: every game
        self._started = False

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """Start every game (or those of `options['reset_mask']`, a (B,) bool array or tensor); returns
        ((camera_obs, target_obs), infos). `seed` s: game b is seeded with s + b; a list of B ints or None: game b
        with `seed[b]`; None: every stream goes on (the first reset draws fresh entropy), as the CPU vector env's.
        With a mask only its games are seeded and reset."""
        mask = self._reset_mask(options)
        mask = np.ones(self.num_envs, bool) if mask is None else mask
        to_seed, seeds = self._rows_to_seed(seed, mask, self.core.world.rng.copy_to_host())
        if to_seed.any():
            self.core.seed(to_seed, seeds)
        self.core.reset(mask)
        self.core.rows.mask.copy_to_device(np.zeros(self.num_envs, bool))     # no game waits for a restart
        self._started = True
        return self._observations, self._infos()

    def _actions(self, actions, team: Team):
        """`step_games`' check: the shape (B, N, 2); the actions as a device array (or a host array under the
        simulator), float64."""
        count = self.counts[0 if team is Team.CAMERA else 1]
        expected = (self.num_envs, count, 2)
        if tuple(getattr(actions, 'shape', ())) != expected:
            raise ValueError(f'{team.name.lower()} actions must have shape {expected} (games, agents, 2), got '
                             f'{tuple(getattr(actions, "shape", ()))}')
        if hasattr(actions, 'to') and hasattr(actions, 'detach'):        # a torch tensor, float64 on its device
            import torch

            actions = actions.to(dtype=torch.float64).contiguous()
        array = from_torch(actions)
        if not hasattr(array, 'copy_to_host'):
            array = np.ascontiguousarray(array, dtype=np.float64)
        return array

    def _tensor(self, value):
        """`value` (actions: a tensor or anything numpy reads) as a float64 tensor on the env's device."""
        import torch

        return torch.as_tensor(value if isinstance(value, torch.Tensor) else np.asarray(value, np.float64),
                               dtype=torch.float64, device=self._info_mask.device)

    def step(self, actions):
        """Advance every game by one step with `actions` = (camera_actions, target_actions); returns ((camera_obs,
        target_obs), (camera_rewards, target_rewards), terminations, truncations, infos), as the CPU vector env's
        `step` (module docstring)."""
        return self._step(actions, checked=True)

    def step_games(self, actions):
        """`step` without the refusal of NaN and inf, which reads the actions back (module docstring): under
        NEXT_STEP autoreset nothing is read back. The actions are (B, N, 2) float64 tensors or arrays."""
        return self._step(actions, checked=False)

    def _step(self, actions, checked: bool):
        camera_actions, target_actions = self._joint_actions(actions)
        if not self._started:
            raise RuntimeError('DeviceVecEnv: call reset() before step()')
        if checked:                       # the CPU env's checks and conversions (a read back: NaN and inf)
            camera_actions, target_actions = self._checked_actions(actions, self._tensor)
        camera_actions = self._actions(camera_actions, Team.CAMERA)
        target_actions = self._actions(target_actions, Team.TARGET)
        self.core.step(camera_actions, target_actions, restart_masked=self.next_step)
        self.core.finish(restart=False)      # (same_step: the ended games restart below, after their last step)
        observations, rewards, (terminated, truncated) = self._observations, self._rewards, self._flags
        infos = self._infos()
        if not self.next_step:
            done = terminated | truncated
            if bool(done.any()):
                final_obs = (observations[0].clone(), observations[1].clone())
                final_info = self._final_info(infos, done)
                self.core.reset_masked()
                infos = self._infos()
                infos.update(final_obs=final_obs, _final_obs=done, final_info=final_info, _final_info=done)
        return observations, rewards, terminated, truncated, infos

    def sample_actions(self, rng: np.random.Generator | int | None = None):
        """Uniform random joint actions (camera (B, Nc, 2), target (B, Nt, 2)), float64 tensors on the env's
        device: the CPU env's `sample_actions` numbers for the same `rng` (`VectorGames.sample_actions`)."""
        import torch

        return tuple(torch.as_tensor(actions, device=self._info_mask.device) for actions in super().sample_actions(rng))

    def state(self):
        """(B, S) tensor: every game's global state (`mate.make_vec(...).state()`'s values, in the observations'
        dtype), e.g. for a centralised critic; one buffer on the device, overwritten by the next call."""
        return to_torch(self.core.state())

    def state_dict(self) -> dict:
        """Everything the games' future depends on, as host numpy arrays: the world, the observations, the actions
        held and the games waiting for a next_step restart. `load_state_dict` on an env made alike continues
        exactly."""
        core = self.core
        host = lambda group: {name: array.copy_to_host() for name, array in zip(group._fields, group)}  # noqa: E731
        return dict(world=host(core.world), rows=host(core.rows), started=self._started)

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (taken from an env of the same game and size)."""
        if state.get('teams'):
            raise ValueError('this state holds device teams played inside the env (an earlier version); the env '
                             'plays none now: their state belongs to the team that plays them')
        core = self.core
        for group, arrays in ((core.world, state['world']), (core.rows, state['rows'])):
            for name, array in zip(group._fields, group):
                if name in ADDED_FIELDS and name not in arrays:   # a state of an earlier version: recomputed
                    continue                                     # by the next step, as on the CPU
                array.copy_to_device(np.ascontiguousarray(arrays[name]))
        self._started = bool(state['started'])      # (a state's 'seeded' of earlier versions: the streams tell)

    @property
    def observations(self):
        """(camera_obs (B, Nc, D_c), target_obs (B, Nt, D_t)) tensors: both teams' current observations (the env's
        buffers, overwritten by the next step)."""
        return self._observations


def make_device_vec(env_id: str = 'MultiAgentTracking-v0', num_envs: int = 1, config: Any = None,
                    **kwargs: Any) -> DeviceVecEnv:
    """`DeviceVecEnv` for an ID of `mate.make` (`mate.make_vec(..., device='cuda')` calls this)."""
    return DeviceVecEnv(registration.resolve_config(env_id, config), num_envs, **kwargs)
