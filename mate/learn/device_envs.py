"""`DeviceTeamEnv`: `TeamVecEnv`'s training view of B games, with the games, the opponent and the learner's view on a
CUDA device, torch tensors in and out (what `mate train --game-device cuda` trains in).

It steps `mate.device_team_vector.DeviceTeamVecEnv` (the games and the greedy opponent as CUDA kernels) and does on
the device, as torch operations, what `TeamVecEnv` does in numpy on the host: the policy spec's features and the
compressed global state (`TorchPipeline`, checked against `PolicySpec.features` and `compress`), the decoding of a held
decision (grid moves, continuous shares; HRL selections through the executor kernel, re-aimed at every env step),
the cameras' sighting memory and target velocities (`--memory`, `--velocity`), full observability (the
`EnhancedObservation` arrays of `enhance_observations`), frame skip, the reward kinds ('team', cameras
'difference', targets 'own'), horizon cuts with the last observation kept for bootstrapping, and the finished
episodes' records. Only their list (`info['episodes']`) and the decision's coverage
come to the host, once per decision.

Semantics are `TeamVecEnv`'s, step for step: an env whose opponent is the device team's host twin
(`mate.teams.device.HostTeam`, seeded seed + 7919 as here: `OPPONENT_SEED_OFFSET`) plays the same games and returns the same numbers (the tests
check this under numba's CUDA simulator, and a PPO run over either env logs the same rows). What differs is the
opponent's random streams: the device teams draw from counter-based streams of their own, so a run here and a run of
`TeamVecEnv` (whose greedy team draws as the Python agents) play other games of the same distribution
(docs/performance.md, "The game on a CUDA device").

Not on the device (each refused with the option to drop): the population players' 'mixed' camera reward and
opponents other than the greedy rules. `mate train --game-device auto` (the default) plays those on the CPU.
"""

from __future__ import annotations

import functools

import numpy as np

from ..constants import PRESERVED_DIM
from ..messages import Team
from ..registration import resolve_config
from ..spaces import observation_indices_of, observation_space_of, state_space_of
from ..team_vector import EPISODE_INFO
from .memory import target_record_scale
from .spec import PolicySpec, as_team

__all__ = ['DeviceTeamEnv', 'TorchPipeline', 'device_game_available', 'device_unsupported']


def device_unsupported(spec: PolicySpec, camera_reward: str = 'coverage', opponent=None) -> list[str]:
    """The settings of a training env that `DeviceTeamEnv` cannot play, in the words of the command line (empty:
    it plays them all)."""
    found = []
    if spec.action == 'discrete':
        found.append("'discrete' actions (a toy task)")
    if camera_reward != 'coverage':
        found.append(f'the {camera_reward!r} camera reward')
    if opponent is not None:
        found.append('an opponent other than the greedy rules')
    return found


@functools.cache
def device_game_available() -> bool:
    """Whether numba sees a CUDA device (or its simulator) to play the games on."""
    try:
        from numba import cuda
    except ImportError:
        return False
    return bool(cuda.is_available())


def _tensor(array, like, dtype=None):
    import torch

    return torch.as_tensor(np.array(array), device=like.device, dtype=dtype)


class TorchPipeline:
    """`PolicySpec`'s pipeline and `TeamVecEnv`'s state as torch operations, on the device of the tensors given.

    The arithmetic is numpy's, in the same order and in float64 before the cast to float32, so that on a CPU the
    features equal `spec.features` bit for bit (tested); on a GPU the one transcendental, the log of `compress`, is
    the device's and may round the last bit of a float64 otherwise.

    Args:
        spec: the policy's spec.
        device: where the constants live (that of the observations).
    """

    def __init__(self, spec: PolicySpec, device) -> None:
        import torch

        from ..agents.utils import relative_layout
        from ..wrappers.discrete_camera import square_grid
        from ..wrappers.discrete_target import disk_grid
        from .hrl import selection_bits

        self.spec, self.team = spec, as_team(spec.team)
        counts = spec.counts
        like = torch.empty(0, device=device)
        xs, flags = relative_layout(self.team, *counts)
        self._xs, self._ys = _tensor(xs, like), _tensor(xs + 1, like)
        self._flags, self._gated = _tensor(np.maximum(flags, 0), like), _tensor(flags >= 0, like)
        self._observation = self._scaling(observation_space_of(self.team, *counts), like)
        self._state = self._scaling(state_space_of(*counts), like)
        self._grid = None
        if spec.action == 'grid':
            grid = square_grid(spec.levels) if self.team is Team.CAMERA else disk_grid(spec.levels)
            self._grid = _tensor(grid, like, torch.float64)
        self._bits = _tensor(selection_bits(counts[1]).astype(bool), like) if spec.hrl else None
        self.begin = int(observation_indices_of(Team.CAMERA, *counts)[2]) if self.team is Team.CAMERA else 0
        self.scale = target_record_scale(*counts) if self.team is Team.CAMERA else 1.0

    @staticmethod
    def _scaling(space, like):
        """(shift, span, scaled) of `normalize_observation` for `space`, as float64/bool tensors (D,)."""
        low, high = space.low.astype(np.float64), space.high.astype(np.float64)
        below, above = space.bounded_below, space.bounded_above
        scaled = below & above & (high > low)
        return (_tensor(np.where(below, low, 0.0), like), _tensor(np.where(scaled, high - low, 1.0), like),
                _tensor(scaled, like))

    @staticmethod
    def _normalized(values, scaling):
        """`normalize_observation`: float64 values (..., D) mapped onto [-1, 1] where the box bounds them."""
        import torch

        shift, span, scaled = scaling
        core = values - shift
        return torch.where(scaled, 2.0 * core / span - 1.0, core)

    def features(self, raw, memory=None, previous=None):
        """`spec.features(raw, memory, previous)`: (..., N, D) float32 from raw observations (..., N, D_raw) of the
        team, the sighting memory `memory` = (age (..., Nt), location (..., Nt, 2)) of a spec with `memory`, and the
        raw observations `previous` of the env step before of a spec with `velocity`."""
        import torch

        columns = [self._preprocessed(raw)]
        if self.spec.memory:
            columns.append(self.memory_columns(raw, *memory))
        if self.spec.velocity:
            columns.append(self.displacements(raw, previous))
        return torch.cat(columns, dim=-1) if len(columns) > 1 else columns[0]

    def _preprocessed(self, raw):
        """`preprocess_observation`: relative coordinates rescaled to [-1, 1], float32."""
        import torch

        out = raw.to(torch.float64, copy=True)
        origin_x = out[..., PRESERVED_DIM:PRESERVED_DIM + 1].clone()
        origin_y = out[..., PRESERVED_DIM + 1:PRESERVED_DIM + 2].clone()
        gate = self._gated.logical_not() | (out[..., self._flags] == 1.0)
        out[..., self._xs] -= gate * origin_x
        out[..., self._ys] -= gate * origin_y
        return self._normalized(out, self._observation).float()

    def sightings(self, raw):
        """`mate.learn.memory.camera_sightings`: (own location (..., N, 2), seen (..., N, Nt) bool, target
        locations (..., N, Nt, 2)) float64 from raw camera observations (..., N, D)."""
        nt = self.spec.counts[1]
        records = raw[..., self.begin:self.begin + 5 * nt].double().reshape(*raw.shape[:-1], nt, 5)
        own = raw[..., PRESERVED_DIM:PRESERVED_DIM + 2].double()
        return own, records[..., 4] > 0.5, records[..., :2]

    def memory_columns(self, raw, age, location):
        """`SightingMemory.features`: (B, N, 4 Nt) float32 of raw camera observations (B, N, D) and the team's
        memory, `age` (B, Nt) int64 and `location` (B, Nt, 2) float64."""
        import torch

        period = self.spec.memory
        own, visible, _ = self.sightings(raw)
        known = age < period
        freshness = torch.where(known, 1.0 - age.double() / period, 0.0)
        offset = (location[:, None] - own[..., None, :]) / self.scale * known[:, None, :, None]
        teammate = (age == 0)[:, None] & ~visible
        nb, n, nt = visible.shape
        columns = torch.cat([offset, freshness[:, None, :, None].expand(nb, n, nt, 1),
                             teammate[..., None].double()], dim=-1)
        return columns.reshape(nb, n, nt * 4).float()

    def displacements(self, raw, previous):
        """`mate.learn.velocity.target_displacements` over one held decision: (..., N, 2 Nt) float32."""
        import torch

        _, seen_now, where_now = self.sightings(raw)
        _, seen_before, where_before = self.sightings(previous)
        both = (seen_now & seen_before)[..., None]
        moved = torch.where(both, (where_now - where_before) * (self.spec.frame_skip / self.scale), 0.0)
        return moved.reshape(*moved.shape[:-2], -1).float()

    def state(self, state):
        """`compress(normalize_observation(state, state space))`: (B, S) float32 from the games' state (B, S)."""
        import torch

        x = self._normalized(state.double(), self._state)
        magnitude = x.abs()
        squashed = torch.sign(x) * (1.0 + torch.log(torch.clamp(magnitude, min=1.0)))
        return torch.where(magnitude > 1.0, squashed, x).float()

    def action_high(self, raw):
        """`mate.teams.protocol.action_high`: each agent's action bound (..., N, 2) float64."""
        own = raw[..., PRESERVED_DIM:].double()
        return own[..., 7:9] if self.team is Team.CAMERA else own[..., 4:5].expand(*own.shape[:-1], 2)

    def keep_bits(self, held):
        """HRL: the keep bits (..., N, Nt) bool of held choices (..., N, heads)."""
        return held.bool() if self.spec.action == 'hrl' else self._bits[held[..., 0]]

    def decode(self, held, raw):
        """Open-loop `spec.decode`: env actions (..., N, 2) float64 of grid choices (..., N, 1) or continuous shares
        (..., N, 2) and the raw observations (..., N, D)."""
        if self.spec.action == 'grid':
            return self._grid[held[..., 0]] * self.action_high(raw)
        return held.double().clamp(-1.0, 1.0) * self.action_high(raw)

    def allowed(self, features):
        """`spec.allowed`: (..., N, heads, choices) bool of HRL features (..., N, D), None for the other kinds."""
        import torch

        if not self.spec.hrl:
            return None
        nt = self.spec.counts[1]
        visible = features[..., self.begin + 4:self.begin + 5 * nt:5] > 0.5
        if self.spec.action == 'hrl':
            return torch.stack([torch.ones_like(visible), visible], dim=-1)
        return ~(self._bits & ~visible[..., None, :]).any(-1)[..., None, :]


class DeviceTeamEnv:
    """B games in which a policy of `spec` plays its team against the greedy rules, on a CUDA device (module
    docstring). `TeamVecEnv`'s interface with torch tensors: `reset(seed)` -> (features (B, N, D) float32, state
    (B, S) float32); `step(actions)` with (B, N, heads) int choices (or (B, N) for one head) or (B, N, 2) shares ->
    (features, state, reward (B,) or (B, N) float64, done (B,) bool, truncated (B,) bool, info) with info's
    `final_obs`, `final_state` and `coverage` tensors and `episodes` a host list of dicts.

    Args:
        spec: the trained policy's spec.
        num_envs: B.
        horizon: env steps per episode (None: 500 decisions).
        seed: seed of `reset()` without a seed; the opponent's rows are seeded seed + 7919 + b (as `TeamVecEnv`'s).
        credit: 'team', 'difference' (cameras) or 'own' (targets).
        block: threads per CUDA block.
        **overrides: config keys of the game.
    """

    tensors = True
    """The trainer passes actions as tensors and takes tensors back (`TeamVecEnv`: numpy)."""

    def __init__(self, spec: PolicySpec, num_envs: int = 64, horizon: int | None = None, seed: int | None = 0,
                 credit: str = 'team', block: int | None = None, **overrides) -> None:
        import torch

        from ..core.device import BLOCK
        from ..device_team_vector import DeviceTeamVecEnv
        from .envs import CREDITS, OPPONENT_SEED_OFFSET

        team = as_team(spec.team)
        if credit not in CREDITS:
            raise ValueError(f'credit must be one of {CREDITS}, got {credit!r}')
        unsupported = device_unsupported(spec)
        if unsupported:
            raise ValueError(f'{unsupported[0]} is not played on the device yet; use --game-device cpu')
        reward = {'team': 'coverage' if team is Team.CAMERA else 'team', 'difference': 'difference',
                  'own': 'own'}[credit]
        self.spec, self.team, self.credit = spec, team, credit
        self.frame_skip = spec.frame_skip
        self.horizon = int(horizon or 500 * spec.frame_skip)
        self.num_envs = int(num_envs)
        self.envs = DeviceTeamVecEnv(resolve_config(spec.env_id, spec.config), team, self.num_envs, reward=reward,
                                     max_episode_steps=self.horizon, observation_dtype=np.float32,
                                     autoreset_mode='next_step', block=block or BLOCK, **overrides)
        self.vec = self.envs.vec
        self.counts = self.vec.counts
        spec.check_game(team, self.counts, 'the policy spec')
        self.num_agents = spec.num_agents
        self.obs_dim, self.state_dim = spec.obs_dim, spec.state_dim
        self.action_heads, self.action_choices, self.num_actions = spec.heads, spec.choices, spec.num_actions
        self._seed = seed
        self._opponent_seed = None if seed is None else seed + OPPONENT_SEED_OFFSET
        like = self.envs.vec.world_tensor('target_reward')
        self.device = like.device
        self.pipeline = TorchPipeline(spec, self.device)
        self._return = like.new_zeros(self.num_envs)          # the learner's team reward summed over the episode
        self._max_reward = float(self.vec.params.max_target_team_episode_reward)
        self._raw = None
        self._before = None            # velocity: the team's raw observations of the env step before
        self._age = self._location = None
        if spec.memory:                # the team's sighting memory (`mate.learn.memory.SightingMemory`'s arrays)
            nt = self.counts[1]
            self._age = torch.full((self.num_envs, nt), spec.memory, dtype=torch.long, device=self.device)
            self._location = torch.zeros((self.num_envs, nt, 2), dtype=torch.float64, device=self.device)
        self._observation_slices = None
        if spec.full_observability:
            from ..spaces import camera_observation_slices_of, target_observation_slices_of

            slices_of = camera_observation_slices_of if team is Team.CAMERA else target_observation_slices_of
            self._observation_slices = slices_of(*self.counts)
        self._hrl = None
        if spec.hrl:
            B, N = self.num_envs, self.num_agents
            self._hrl = (like.new_zeros(B * N, 2), like.new_zeros((B * N, self.counts[1]), dtype=bool))

    # ------------------------------------------------------------------ helpers
    def _decode(self, held, raw):
        """Env actions (B, N, 2) float64 of the held decision at this env step (HRL: the executor kernel)."""
        if not self.spec.hrl:
            return self.pipeline.decode(held, raw)
        from ..core.device import from_torch
        from ..teams.device import hrl_actions

        out, keep = self._hrl
        keep.copy_(self.pipeline.keep_bits(held).reshape(keep.shape))
        observation = raw.reshape(out.shape[0], raw.shape[-1]).contiguous()
        hrl_actions(from_torch(observation), from_torch(keep), self.pipeline.begin, from_torch(out))
        return out.reshape(self.num_envs, self.num_agents, 2).clone()

    def _enhanced(self, raw):
        """The team's raw observations (B, N, D) as it sees them: unchanged, or (full observability) a copy with every
        record filled as `mate.wrappers.enhanced_observation.enhance_observations` fills it (every entity's public
        state and flag 1; targets: the true empty warehouses). The opponent keeps its partial view."""
        import torch

        if not self.spec.full_observability:
            return raw
        from ..constants import CAMERA_STATE_DIM_PUBLIC, TARGET_STATE_DIM_PUBLIC
        from ..wrappers.enhanced_observation import TARGET_EMPTY_BITS

        def flagged(records):      # (B, n, d) -> (B, 1, n (d + 1)): each record and a flag 1, one row block
            ones = torch.ones(*records.shape[:-1], 1, dtype=torch.float64, device=records.device)
            return torch.cat([records.double(), ones], dim=-1).reshape(records.shape[0], 1, -1)

        camera_obs, target_obs = self.vec.observations
        cameras = flagged(camera_obs[..., PRESERVED_DIM:PRESERVED_DIM + CAMERA_STATE_DIM_PUBLIC])   # public states
        targets = flagged(target_obs[..., PRESERVED_DIM:PRESERVED_DIM + TARGET_STATE_DIM_PUBLIC])
        obstacles = flagged(torch.cat([self.vec.world_tensor('obstacle_pos'),
                                       self.vec.world_tensor('obstacle_radius')[..., None]], dim=-1))
        out = raw.clone()
        slices = self._observation_slices
        if self.team is Team.CAMERA:
            records = (targets, obstacles, cameras)
        else:
            records = (cameras, obstacles, targets)
            stock = self.vec.world_tensor('remaining_cargoes').any(dim=-1)           # (B, W): cargo left to send
            out[..., TARGET_EMPTY_BITS] = (~stock).to(out.dtype)[:, None, :]
        for name, values in zip(('opponent_states_with_mask', 'obstacle_states_with_mask', 'teammate_states_with_mask'),
                                records):
            out[..., slices[name]] = values.to(out.dtype)
        return out

    def _remember(self, raw, restarting=None) -> None:
        """One env step of the sighting memory (`TeamVecEnv._remember`): the rows of `restarting` forget, a step
        passes, and what every camera sees in `raw` (B, N, D) enters its team's memory."""
        import torch

        if not self.spec.memory:
            return
        period = self.spec.memory
        if restarting is not None:
            self._age.masked_fill_(restarting[:, None], period)
        torch.clamp(self._age + 1, max=period, out=self._age)
        _, seen, location = self.pipeline.sightings(raw)
        first = seen.to(torch.uint8).argmax(dim=-2)                           # a camera that sees it (the first)
        picked = torch.take_along_dim(location, first[:, None, :, None], dim=-3)[:, 0]
        sighted = seen.any(dim=-2)
        self._age.masked_fill_(sighted, 0)
        self._location = torch.where(sighted[..., None], picked, self._location)

    def _features(self, raw, memory=None, before=None):
        """The spec's features of raw observations (B, N, D) with the current memory and previous observations (or
        those given)."""
        memory = memory or (self._age, self._location)
        return self.pipeline.features(raw, memory, self._before if before is None else before)

    def _team_reward(self, info):
        """(B,) the learner's team reward of the env step just played: the coverage rate (cameras) or the targets'
        raw team reward."""
        if self.team is Team.CAMERA:
            return info['coverage_rate']
        return self.vec.world_tensor('target_reward')

    # ------------------------------------------------------------------ TeamVecEnv's interface
    def positions(self) -> np.ndarray:
        """(B, N, 2) float64 host array: the team's agents' world positions, cut from the global state as
        `TeamVecEnv.positions` does (for a channel's range limit)."""
        from .envs import team_positions

        return team_positions(self.vec.state().cpu().numpy(), self.team, self.counts)

    def allowed_actions(self, features):
        """The spec's allowed choices (B, N, heads, choices) bool tensor of features (B, N, D); None when all are."""
        return self.pipeline.allowed(features)

    @property
    def raw_observations(self):
        """(B, N, D) raw observations of the trained team at the current decision (do not modify)."""
        return self._raw

    def observations(self):
        """(features (B, N, D), state (B, S)) of the current decision."""
        return self._features(self._raw), self.pipeline.state(self.vec.state())

    def reset(self, seed: int | None = None):
        raw, _ = self.envs.reset(seed=self._seed if seed is None else seed, opponent_seed=self._opponent_seed)
        self._raw = self._enhanced(raw).clone()
        self._before = self._raw.clone() if self.spec.velocity else None
        if self.spec.memory:
            self._age.fill_(self.spec.memory)
        self._remember(self._raw)
        self._return.zero_()
        return self.observations()

    def _held(self, actions):
        """The decision's actions on the device: (B, N, 2) float64 shares clipped to [-1, 1] (as the env's action
        box would), or (B, N, heads) int64 choices."""
        import torch

        B, N = self.num_envs, self.num_agents
        actions = torch.as_tensor(actions, device=self.device)
        if self.spec.continuous:
            return actions.reshape(B, N, 2).to(torch.float64).clamp(-1.0, 1.0)
        return actions.reshape(B, N, self.action_heads).to(torch.long)

    def step(self, actions):
        import torch

        B, N, device = self.num_envs, self.num_agents, self.device
        held = self._held(actions)
        own_actions = None if self.spec.closed_loop else self._decode(held, self._raw)
        zero = torch.zeros((), dtype=torch.float64, device=device)
        reward = torch.zeros(B if self.credit == 'team' else (B, N), dtype=torch.float64, device=device)
        coverage = torch.zeros(B, dtype=torch.float64, device=device)
        counted = torch.zeros(B, dtype=torch.float64, device=device)
        done = torch.zeros(B, dtype=torch.bool, device=device)
        truncated = torch.zeros(B, dtype=torch.bool, device=device)
        final_raw = torch.zeros_like(self._raw)
        final_before = torch.zeros_like(self._raw) if self.spec.velocity else None
        final_memory = (self._age.clone(), self._location.clone()) if self.spec.memory else None
        final_state = torch.zeros(B, self.state_dim, dtype=self._raw.dtype, device=device)
        ended_at = torch.zeros(B, dtype=torch.long, device=device)            # the env step a record ended at
        record = {name: torch.zeros(B, dtype=torch.float64, device=device)
                  for name in ('coverage', 'length', 'return', 'raw_return')}
        restarting = torch.zeros(B, dtype=torch.bool, device=device)      # rows whose episode ended at the last step
        own_raw = self._raw
        for k in range(self.frame_skip):
            if self.spec.closed_loop:      # the executor re-aims at every env step from the fresh observation
                own_actions = self._decode(held, own_raw)
            raw, rewards, terminated, truncated_now, info = self._step(own_actions, own_raw, restarting)
            live = ~done & ~restarting
            team_reward = self._team_reward(info)
            reward += torch.where(live if rewards.dim() == 1 else live[:, None], rewards, zero)   # (B,) or (B, N)
            coverage += torch.where(live, info['coverage_rate'], zero)
            counted += live
            self._return += torch.where(live, team_reward, zero)
            ended = live & (terminated | truncated_now)
            final_raw = torch.where(ended[:, None, None], raw, final_raw)
            if final_before is not None:
                final_before = torch.where(ended[:, None, None], self._before, final_before)
            if final_memory is not None:
                final_memory = (torch.where(ended[:, None], self._age, final_memory[0]),
                                torch.where(ended[:, None, None], self._location, final_memory[1]))
            final_state = torch.where(ended[:, None], self.vec.state(), final_state)
            truncated |= ended & truncated_now & ~terminated
            done |= ended
            episode = info[EPISODE_INFO]
            for name, value in (('coverage', episode['coverage_rate']), ('length', episode['l']),
                                ('return', self._return),
                                ('raw_return', episode['target_return'] / self._max_reward)):
                record[name] = torch.where(ended, value.to(torch.float64), record[name])
            ended_at.masked_fill_(ended, k)
            self._return.masked_fill_(ended, 0.0)
            restarting = ended
            own_raw = raw
        if bool(restarting.any()):   # ended at the last env step: restart now so that the next decision is clean
            raw = self._step(own_actions, own_raw, restarting)[0]
        self._raw = raw.clone()
        info = dict(final_obs=self._features(final_raw, final_memory, final_before),
                    final_state=self.pipeline.state(final_state),
                    coverage=coverage / counted.clamp(min=1.0), episodes=self._episodes(done, ended_at, record))
        features, state = self.observations()
        return features, state, reward, done, truncated, info

    def _step(self, own_actions, previous, restarting):
        """One env step of the games (`TeamVecEnv._step_vec` and `_remember`): keeps the team's raw observations of
        the step before (`previous`; the first ones for the rows of `restarting`, which start an episode now) and
        updates the sighting memory."""
        import torch

        previous = previous.clone() if self.spec.velocity else None
        raw, rewards, terminated, truncated, info = self.envs.step_games(own_actions)
        raw = self._enhanced(raw)
        if previous is not None:
            self._before = torch.where(restarting[:, None, None], raw, previous)
        self._remember(raw, restarting)
        return raw, rewards, terminated, truncated, info

    @staticmethod
    def _episodes(done, ended_at, record) -> list[dict]:
        """The finished episodes' records (host dicts), in the order `TeamVecEnv` lists them (env step, then row)."""
        rows = done.nonzero().flatten()
        if rows.numel() == 0:
            return []
        order = rows[(ended_at[rows] * done.shape[0] + rows).argsort()]
        values = {name: value[order].cpu().tolist() for name, value in record.items()}
        return [dict(coverage=values['coverage'][i], length=int(values['length'][i]),
                     **{'return': values['return'][i]}, raw_return=values['raw_return'][i])
                for i in range(len(order))]

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict:
        """Everything the batch's future depends on, as host arrays: the device games and opponent
        (`DeviceTeamVecEnv.state_dict`), the held raw observations and the episodes' sums."""
        host = lambda x: None if x is None else x.cpu().numpy().copy()   # noqa: E731
        return dict(device=self.envs.state_dict(), raw=host(self._raw), returns=host(self._return),
                    before=host(self._before), age=host(self._age), location=host(self._location))

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (taken from an env of the same spec and size)."""
        import torch

        if 'device' not in state:
            raise ValueError('this checkpoint holds the state of games played on the CPU; resume it with '
                             '--game-device cpu')
        self.envs.load_state_dict(state['device'])
        self._raw = torch.as_tensor(state['raw']).to(self.device)
        self._return.copy_(torch.as_tensor(state['returns']))
        self._before = None if state['before'] is None else torch.as_tensor(state['before']).to(self.device)
        if self.spec.memory:
            self._age.copy_(torch.as_tensor(state['age']))
            self._location.copy_(torch.as_tensor(state['location']))
