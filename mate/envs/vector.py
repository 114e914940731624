"""`MultiAgentTrackingVectorEnv`: B MATE games stepped together by the batched core (`make_vec`).

The class docstring of `MultiAgentTrackingVectorEnv` describes the spaces, the accepted action
forms, autoreset, seeding, buffers and arguments (`help(mate.MultiAgentTrackingVectorEnv)`, or
the API page and the vector env page of the docs).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import VectorEnv, VectorRewardWrapper

from . import registration
from ..core import engine
from ..core.snapshot import get_snapshot
from ..core.world import empty_world
from ..messages import Team, as_team
from .vector_contract import ADDED_FIELDS, AutoresetMode, VectorGames, env_listing

__all__ = ['MultiAgentTrackingVectorEnv', 'TeamReward', 'make_vec', 'AutoresetMode']


def _float64_array(value) -> np.ndarray:
    return np.asarray(value, dtype=np.float64)


class MultiAgentTrackingVectorEnv(VectorGames):
    """`num_envs` worlds stepped together by the batched core, as a Gymnasium `VectorEnv`.

    One world of B rows is advanced by a single call into `mate.core.engine` per step: there is no
    loop over single environments. Row i behaves exactly like a `MultiAgentTracking` env reset with
    seed `s + i` (see Seeding). `mate.make_vec(id, num_envs=B)` builds one from a registered ID.

    **Action space** (Gymnasium vector conventions). `single_action_space` is
    `Tuple(Box(Nc, 2), Box(Nt, 2))`, float64, and `action_space` the batched
    `Tuple(Box(B, Nc, 2), Box(B, Nt, 2))`. A camera acts with `[rotate, zoom]` in degrees within
    +-`rotation_step` / +-`zooming_step`; a target with a displacement `[dx, dy]` whose length the
    core shortens to its speed. `step` takes each team's actions as a `(B, N, 2)` array of any real
    dtype, or `(B, 2N)` (each env's row holding the agents' pairs in slot order). Any other shape
    raises a `ValueError` naming the team, the expected shape and the shape given: nothing else is
    reshaped. Out-of-bounds values are clipped by the core; NaN and inf are refused, naming the envs.

    **Observation space.** `single_observation_space` is `Tuple(Box(Nc, D_c), Box(Nt, D_t))` in
    `observation_dtype`, `observation_space` the batched `Tuple(Box(B, Nc, D_c), Box(B, Nt, D_t))`,
    with the layouts of `mate.spaces` (one row per agent, as the single env returns them).
    `single_state_space` / `state_space` are `Box(S)` / `Box(B, S)`, S = 29 + 9 Nc + 16 Nt + 3 No.

    **Step.** `envs.step((camera_actions, target_actions))` returns
    `((camera_obs (B, Nc, D_c), target_obs (B, Nt, D_t)), (camera_rewards (B,), target_rewards (B,)),
    terminations (B,), truncations (B,), infos)`. The game is zero-sum:
    `camera_rewards == -target_rewards`; Gymnasium's vector reward wrappers, which expect one
    (B,) reward, apply to `TeamReward(envs, team)` (one team's). `infos` is a dict of `(B,)` arrays (`coverage_rate`,
    `real_coverage_rate`, `mean_transport_rate`, `num_delivered_cargoes`, `episode_step`), each with
    Gymnasium's `_<key>` mask (all true). There is no per-agent info and no message channel: use the
    single env (`mate.make`) for communication. `step` before `reset` raises `RuntimeError`.

    **Autoreset** (`autoreset_mode`, also in `metadata['autoreset_mode']`).

    - `NEXT_STEP` (default, Gymnasium 1.x): the step after env i finished ignores env i's actions,
      starts its next episode and returns that episode's first observation with reward 0 and
      terminated = truncated = False. The finished episode's last observation is the one returned by
      the step that finished it.
    - `SAME_STEP`: the step that finishes env i also resets it; it returns the new episode's first
      observation, the final step's reward and flags, and the finished episode's last observation in
      `infos['final_obs']` (an object array (B,): a `(camera_obs (Nc, D_c), target_obs (Nt, D_t))`
      pair of copies for finished envs, None elsewhere; mask `infos['_final_obs']`) and its infos in
      `infos['final_info']` (dict of (B,) arrays with masks; mask `infos['_final_info']`).
    - `DISABLED`: no autoreset; stepping a finished env raises; reset some envs with
      `reset(options={'reset_mask': mask (B,) bool})`.

    **Seeding.** `reset(seed=s)` seeds env i with s + i (a list of B ints/None seeds env i with
    `seed[i]`), so env i replays `mate.make(same id and config).reset(seed=s + i)` step for step,
    autoresets included (an autoreset continues env i's random stream, as the single env's `reset()`
    without a seed does). `reset()` without a seed continues each env's stream; a never-seeded env
    draws OS entropy.

    **Buffers** (zero-copy). Observations, rewards, terminations and truncations are preallocated
    arrays that the next `step()` or `reset()` overwrites in place; pass `copy=True` to get fresh
    arrays instead. `infos` arrays are fresh each call. Observations are written by the core directly
    in `observation_dtype` (float64 default; float32 for learners, no extra cast).

    Args:
        config: a preset name, a YAML/JSON path or a dict (see `mate.read_config`), as for the
            single env.
        num_envs: B, the number of games.
        observation_dtype: `np.float64` or `np.float32`.
        autoreset_mode: a `gymnasium.vector.AutoresetMode` or its name (`'next_step'`,
            `'same_step'`, `'disabled'`).
        copy: return copies instead of the reused buffers.
        **overrides: keys deep-merged into the configuration.
    """

    def __init__(self, config: Any = None, num_envs: int = 1, *, observation_dtype=np.float64,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, copy: bool = False,
                 **overrides: Any) -> None:
        self._describe_games(config, num_envs, observation_dtype, autoreset_mode, overrides)
        self.copy = bool(copy)
        B, dtype, p = self.num_envs, self.observation_dtype, self.params
        nc, nt = p.num_cameras, p.num_targets

        # ---- world and buffers
        self._world = empty_world(p, B)
        self._camera_obs = np.zeros((B, nc, self.camera_observation_space.shape[0]), dtype=dtype)
        self._target_obs = np.zeros((B, nt, self.target_observation_space.shape[0]), dtype=dtype)
        self._camera_actions = np.zeros((B, nc, 2))  # actions are copied in: the compiled step is bound to these
        self._target_actions = np.zeros((B, nt, 2))
        self._step_world = None  # `engine.bind_step` on these arrays, made by the first step (and after a copy)
        self._camera_reward = np.zeros(B)
        self._target_reward = np.zeros(B)
        self._terminated = np.zeros(B, dtype=bool)
        self._truncated = np.zeros(B, dtype=bool)
        self._autoreset = np.zeros(B, dtype=bool)  # finished at the last step (kept apart from returned arrays)
        self._everyone = np.ones(B, dtype=bool)  # the reset mask of all rows (writable: one numba type)
        self._info_mask = np.ones(B, dtype=bool)  # the `_key` masks of infos, shared and read-only
        self._info_mask.flags.writeable = False
        self._needs_reset = True

    def __getstate__(self) -> dict:
        return {**self.__dict__, '_step_world': None}  # a copy binds the step to its own arrays

    # ------------------------------------------------------------------ episodes
    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """Start new episodes in every env (or in options['reset_mask'] (B,) bool only).

        Returns ((camera_obs (B, Nc, D_c), target_obs (B, Nt, D_t)), infos). `seed`: None
        (continue each env's stream; never-seeded envs draw OS entropy), an int s (env i gets
        s + i) or a list of B ints/None. With a mask, only the masked envs are seeded and reset;
        the others keep their episode and observation.
        """
        mask = self._reset_mask(options)
        mask = self._everyone if mask is None else mask
        world = self._world
        to_seed, seeds = self._rows_to_seed(seed, mask, world.rng)
        if to_seed.any():
            engine.seed_rows(world, to_seed, seeds)
        engine.reset(self.params, world, mask, self._camera_obs, self._target_obs)
        self._autoreset[mask] = False
        self._terminated[mask] = False
        self._truncated[mask] = False
        self._camera_reward[mask] = 0.0
        self._target_reward[mask] = 0.0
        self._needs_reset = False
        return self._observations(), self._infos()

    def step(self, actions):
        """Advance every env by one step (see the class docstring for the accepted action forms and the
        autoreset semantics)."""
        if self._needs_reset:
            raise RuntimeError('MultiAgentTrackingVectorEnv: call reset() before step()')
        camera_actions, target_actions = self._checked_actions(actions, _float64_array)
        p, world, mode = self.params, self._world, self.autoreset_mode
        if mode is AutoresetMode.DISABLED and self._autoreset.any():
            finished = np.flatnonzero(self._autoreset)
            raise RuntimeError(f'envs {env_listing(finished)} finished their episodes and autoreset_mode is DISABLED: '
                               "reset them with reset(options={'reset_mask': mask}) before step()")
        pending = self._autoreset if mode is AutoresetMode.NEXT_STEP and self._autoreset.any() else None
        if pending is not None:
            pending = pending.copy()
            streams = world.rng[pending]  # the finished rows' streams as their episodes ended
        np.copyto(self._camera_actions, camera_actions)
        np.copyto(self._target_actions, target_actions)
        if self._step_world is None:
            self._step_world = engine.bind_step(p, world, self._camera_actions, self._target_actions,
                                                self._camera_obs, self._target_obs)
        self._step_world()
        if pending is not None:
            # The finished rows were stepped with the rest (the core steps whole batches); put their
            # streams back so that their new episodes draw exactly what a single env's reset() draws.
            world.rng[pending] = streams
            engine.reset(p, world, pending, self._camera_obs, self._target_obs)  # zeroes reward and flags
        np.copyto(self._target_reward, world.target_reward)
        np.negative(self._target_reward, out=self._camera_reward)
        np.copyto(self._terminated, world.terminated)
        np.copyto(self._truncated, world.truncated)
        np.logical_or(self._terminated, self._truncated, out=self._autoreset)
        infos = self._infos()
        if mode is AutoresetMode.SAME_STEP and self._autoreset.any():
            done = self._autoreset.copy()
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(done):
                final_obs[i] = (self._camera_obs[i].copy(), self._target_obs[i].copy())
            final_info = self._final_info(infos, done)
            engine.reset(p, world, done, self._camera_obs, self._target_obs)
            self._autoreset[:] = False
            infos = self._infos()
            infos.update(final_obs=final_obs, _final_obs=done, final_info=final_info, _final_info=done)
        rewards = (self._camera_reward, self._target_reward)
        if self.copy:
            rewards = (rewards[0].copy(), rewards[1].copy())
            return self._observations(), rewards, self._terminated.copy(), self._truncated.copy(), infos
        return self._observations(), rewards, self._terminated, self._truncated, infos

    def step_games(self, actions):
        """`step(actions)`: the device env's `step_games` leaves out a check that reads the device back; on the host
        there is nothing to leave out (one loop steps either env)."""
        return self.step(actions)

    def _observations(self) -> tuple[np.ndarray, np.ndarray]:
        if self.copy:
            return self._camera_obs.copy(), self._target_obs.copy()
        return self._camera_obs, self._target_obs

    def get_world(self, index: int = 0) -> dict:
        """A snapshot of env `index`'s world as a dict of fresh arrays, as the single env's `get_world()` gives
        (for rendering a row: `mate.envs.render.Renderer.frame(vec.get_world(i), ...)`, or `set_world` of a single
        env)."""
        if not 0 <= int(index) < self.num_envs:
            raise IndexError(f'env index {index} out of range 0..{self.num_envs - 1}')
        return get_snapshot(self.params, self._world, int(index))

    @property
    def observations(self) -> tuple[np.ndarray, np.ndarray]:
        """The observations of the last `reset` or `step` (camera (B, Nc, D_c), target (B, Nt, D_t)): the buffers
        themselves (copies with `copy=True`)."""
        return self._observations()

    # ------------------------------------------------------------------ checkpoints
    _BUFFERS = ('_camera_obs', '_target_obs', '_camera_reward', '_target_reward', '_terminated', '_truncated',
                '_autoreset')

    def state_dict(self) -> dict:
        """Everything the batch's future depends on, as plain data (copies): every world array (the random
        streams included), the returned buffers and the episode flags. `load_state_dict` on an env made with
        the same config and `num_envs` continues exactly where this one stands (a training run's exact resume)."""
        return dict(world={name: getattr(self._world, name).copy() for name in self._world._fields},
                    buffers={name: getattr(self, name).copy() for name in self._BUFFERS},
                    needs_reset=self._needs_reset, np_random=None if self._np_random is None else
                    self._np_random.bit_generator.state)

    def load_state_dict(self, state: dict) -> None:
        """Restore `state_dict()`'s output in place (ValueError if it was taken from another game or batch)."""
        world = state['world']
        if set(world) | ADDED_FIELDS != set(self._world._fields) | ADDED_FIELDS:
            raise ValueError('state_dict: the world fields differ from this env\'s (another version of mate?)')
        for name in self._world._fields:
            if name not in world:          # a field an earlier version did not have (ADDED_FIELDS): zero
                getattr(self._world, name).fill(0)
                continue
            target, value = getattr(self._world, name), np.asarray(world[name])
            if value.shape != target.shape:
                raise ValueError(f'state_dict: world field {name} has shape {value.shape}, this env {target.shape} '
                                 '(another game or num_envs)')
            np.copyto(target, value)
        for name in self._BUFFERS:
            np.copyto(getattr(self, name), np.asarray(state['buffers'][name]))
        self._needs_reset = bool(state['needs_reset'])
        if state.get('np_random') is not None:
            self.np_random.bit_generator.state = state['np_random']

    # ------------------------------------------------------------------ helpers
    def state(self) -> np.ndarray:
        """Every env's global state vector: a fresh (B, S) array in `observation_dtype`."""
        out = np.empty(self.state_space.shape, dtype=self.observation_dtype)
        engine.global_states(self.params, self._world, out)
        return out


class TeamReward(VectorRewardWrapper):
    """The two-team vector env with one team's rewards: `step` returns that team's (B,) float64 array in place of the
    (camera, target) pair, so that Gymnasium's reward wrappers apply (`RecordEpisodeStatistics`, `NormalizeReward`,
    `TransformReward`, `ClipReward`: they expect one reward per env and fail on the pair).

    The game is zero-sum: the other team's rewards are the negatives of the ones returned, and so is its episode
    return (`RecordEpisodeStatistics`' `r`); `NormalizeReward` only divides by a running scale, so the other team's
    normalised rewards are the negatives too. Observations, actions, autoreset and infos are the wrapped env's
    (the pair of teams). The rewards returned are a fresh array (a wrapper above may write into it).

    Args:
        env: `mate.make_vec(...)` (a `MultiAgentTrackingVectorEnv`, or a wrapper of one).
        team: 'camera' (default) or 'target', the team whose rewards are returned.
    """

    def __init__(self, env: VectorEnv, team='camera') -> None:

        super().__init__(env)
        self.team = as_team(team)
        self._index = 0 if self.team is Team.CAMERA else 1

    def rewards(self, rewards):
        """The chosen team's (B,) rewards, copied, of the (camera, target) pair."""
        return np.array(rewards[self._index], dtype=np.float64)


def make_vec(env_id: str = 'MultiAgentTracking-v0', num_envs: int = 1, config: Any = None, *,
             observation_dtype=np.float64, autoreset_mode: AutoresetMode | str | None = None,
             copy: bool = False, device: str | None = None, **overrides: Any):
    """A vector env of `num_envs` games for an ID of `mate.make`; `config=` replaces the ID's
    preset and keyword overrides are deep-merged, exactly as in `mate.make`.

    `device='cuda'` (or 'cuda:N' where numba-cuda sees it as the current device) gives the games on the GPU:
    `mate.envs.device_vector.DeviceVecEnv` (the gpu extra), the same Gymnasium `VectorEnv` API (spaces, `reset`,
    `step`, infos, autoreset NEXT_STEP or SAME_STEP, seeding) with torch tensors on the device for arrays (the rule
    teams there: `mate.teams.device.DeviceRuleTeam`). None or 'cpu': this module's env. Autoreset NEXT_STEP unless
    `autoreset_mode` says otherwise, on either."""
    if device is not None and str(device) != 'cpu':
        if not str(device).startswith('cuda'):
            raise ValueError(f"device must be 'cpu' or 'cuda' (or 'cuda:N'), got {device!r}")
        if copy:
            raise ValueError('copy=True is not available on a device: clone the tensors you keep')
        from .device_vector import make_device_vec

        return make_device_vec(env_id, num_envs, config, observation_dtype=observation_dtype,
                               autoreset_mode=AutoresetMode.NEXT_STEP if autoreset_mode is None else autoreset_mode,
                               **overrides)
    return MultiAgentTrackingVectorEnv(registration.resolve_config(env_id, config), num_envs,
                                       observation_dtype=observation_dtype,
                                       autoreset_mode=AutoresetMode.NEXT_STEP if autoreset_mode is None
                                       else autoreset_mode, copy=copy, **overrides)


def make_vector_from_gymnasium(num_envs: int = 1, config: Any = None, **kwargs: Any) -> MultiAgentTrackingVectorEnv:
    """Entry point of `gymnasium.make_vec(id, num_envs, vectorization_mode='vector_entry_point')`."""
    return MultiAgentTrackingVectorEnv(config, num_envs, **kwargs)
