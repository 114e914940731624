"""`TeamVecEnv`: the training view of B batched games for one team against a batched opponent.

What a learner sees per decision step (the paper's wrapper stack, done on arrays):

* discrete actions, `levels**2` per agent (the grids of `DiscreteCamera` / `DiscreteTarget`, scaled by
  each agent's own step bounds read from its observation);
* the opponent (by default the greedy rules, `VecGreedyTarget` / `VecGreedyCamera`) acts at every raw step;
* frame skip k: a decision is held for k raw steps; rewards are summed (camera: coverage rate, the
  `AuxiliaryCameraRewards` setting of the paper; target: the raw dense team reward);
* observations with coordinates relative to the agent (`convert_coordinates`) and rescaled to
  [-1, 1] (`rescale_observation`); the global state rescaled with the state-space bounds, its
  unbounded counters log-compressed (`compress`);
* episodes cut at `horizon` raw steps (the paper: 500 decisions);
* `hrl=True` (cameras): the action is one keep/ignore bit per target slot, (B, Nc, Nt), and the rule
  executor of `mate.learn.hrl` turns it into rotation/zoom at every raw step of the held decision;
* `full_observability=True`: the trained team's raw observations go through `enhance_observations`
  (the `EnhancedObservation` wrapper's arrays: every entity seen, targets know which warehouses are
  empty), the paper's Fig. 6 ablation; the opponent keeps its partial view;
* `memory=PERIOD` (cameras): the team's shared memory of target sightings (`mate.learn.memory`), updated
  at every raw step, appended to each camera's processed observation (4 columns per target slot);
* `velocity=True` (cameras): each seen target's displacement over one held decision at its current
  velocity (`mate.learn.velocity`, from the camera's observations at the last two raw steps), appended
  after the memory columns (2 per target slot);
* `credit='difference'` (cameras): each camera is rewarded with its own marginal contribution to the
  coverage rate (`difference_rewards`) instead of the team's coverage rate; rewards are then (B, N);
* `camera_reward='mixed'` (cameras): the population players' reward (spec training.md §5.1), per raw step
  0.5 coverage rate + 0.5 real coverage rate + 0.1 x the raw camera-team reward, instead of the coverage rate;
* `opponent=factory`: the other team is `factory(num_envs, counts, seed)`, any batched team of
  `mate.learn.evaluate` (`reset(observation, rows)`, `act(observation)`), e.g. a mixture over a population
  (`mate psro`), instead of the batched greedy rules.

Episode ends inside a decision: the vector env runs in `next_step` autoreset mode, so a row that
ends at raw step j restarts at raw step j + 1 and plays the rest of the held decision in its new
episode; those raw steps' rewards are not credited to anyone. The row's last observation and state
are kept (`final_obs`, `final_state`) so that the learner can bootstrap through a truncation.
"""

from __future__ import annotations

import numpy as np

from .. import make_vec
from ..agents.utils import (
    convert_coordinates,
    normalize_observation,
    rescale_observation,
)
from ..constants import CAMERA_STATE_DIM_PRIVATE, PRESERVED_DIM, TARGET_STATE_DIM_PRIVATE
from ..messages import Team
from ..spaces import observation_indices_of
from ..wrappers.discrete_camera import square_grid
from ..wrappers.discrete_target import disk_grid
from ..wrappers.enhanced_observation import empty_warehouses, enhance_observations
from .hrl import executor_actions
from .memory import MEMORY_FEATURES, SightingMemory, camera_sightings
from .velocity import VELOCITY_FEATURES, target_displacements
from .opponents import VecGreedyCamera, VecGreedyTarget

__all__ = ['CAMERA_REWARDS', 'CREDITS', 'PAPER_SETTINGS', 'TeamVecEnv', 'action_high', 'difference_rewards',
           'discrete_to_continuous', 'mixed_camera_reward', 'preprocess_observation']

CREDITS = ('team', 'difference')
"""How a camera's reward is assigned: the team's coverage rate, or its own marginal contribution to it."""

CAMERA_REWARDS = ('coverage', 'mixed')
"""What a camera team is rewarded with per raw step: the coverage rate (the paper's cooperative runs), or
0.5 coverage + 0.5 real coverage + 0.1 raw camera-team reward (its population players, spec training.md §5.1)."""


def mixed_camera_reward(coverage_rate, real_coverage_rate, camera_reward):
    """The population players' camera reward (spec training.md §5.1) from one raw step's (B,) arrays."""
    return 0.5 * np.asarray(coverage_rate) + 0.5 * np.asarray(real_coverage_rate) + 0.1 * np.asarray(camera_reward)


PAPER_SETTINGS = {
    'camera': dict(env_id='MATE-4v8-9-v0', frame_skip=5, horizon=2500),
    'target': dict(env_id='MATE-2v4-0-v0', frame_skip=10, horizon=5000),
}
"""Paper defaults per trained team (spec training.md §0): preset, frame skip, raw-step episode cut."""


def as_team(team) -> Team:
    """Team from a Team, its value, or a name ('camera' / 'target', any case)."""
    return Team[team.upper()] if isinstance(team, str) else Team(team)


def preprocess_observation(observation, team, num_cameras, num_targets, num_obstacles) -> np.ndarray:
    """Raw observations (..., D) -> float32 relative coordinates rescaled to [-1, 1]."""
    team = as_team(team)
    relative = convert_coordinates(observation, team, num_cameras, num_targets, num_obstacles)
    return rescale_observation(relative, team, num_cameras, num_targets, num_obstacles).astype(np.float32)


def action_high(observation, team) -> np.ndarray:
    """Each agent's action bound (..., 2), float64, from its raw observation (..., D): cameras
    (rotation step, zooming step) in degrees, targets (step size, step size)."""
    own = np.asarray(observation)[..., PRESERVED_DIM:]
    if as_team(team) is Team.CAMERA:
        return own[..., 7:9].astype(np.float64)
    return np.repeat(own[..., 4:5].astype(np.float64), 2, axis=-1)


def discrete_to_continuous(indices, observation, team, levels: int = 5) -> np.ndarray:
    """Action indices (..., N) -> continuous actions (..., N, 2) scaled by each agent's own bounds,
    read from its raw observation (..., N, D) (`action_high`)."""
    indices = np.asarray(indices, dtype=np.int64)
    grid = square_grid(levels) if as_team(team) is Team.CAMERA else disk_grid(levels)
    return grid[indices] * action_high(observation, team)


def difference_rewards(sees: np.ndarray) -> np.ndarray:
    """Each camera's marginal contribution to the coverage rate (the *difference reward*).

    `sees` (..., Nc, Nt) bool: camera c tracks target t (the flags of the cameras' raw observations).
    Returns (..., Nc) float64: the coverage rate minus the coverage rate the other cameras would give
    without camera c, i.e. the share of the Nt targets that camera c alone tracks. A camera changes
    its own difference reward exactly as much as it changes the team's coverage rate, while the other
    cameras' sightings, which it does not control, no longer enter its reward.
    """
    sees = np.asarray(sees, dtype=bool)
    watchers = sees.sum(axis=-2, keepdims=True)                       # (..., 1, Nt) cameras tracking each target
    return (sees & (watchers == 1)).sum(axis=-1) / sees.shape[-1]


def compress(x: np.ndarray) -> np.ndarray:
    """float32 x, with the entries beyond [-1, 1] (unbounded counters: bounties, freights, cargo counts up
    to 200) squashed logarithmically, sign(x) (1 + log|x|), so that they do not saturate the critic."""
    magnitude = np.abs(x)
    return np.where(magnitude > 1.0, np.sign(x) * (1.0 + np.log(np.maximum(magnitude, 1.0))), x).astype(np.float32)


class TeamVecEnv:
    """B games, one trained team (`'camera'` or `'target'`), the other team a batched opponent (greedy by default).

    `reset(seed)` -> (obs (B, N, D) float32, state (B, S) float32).
    `step(actions)` -> (obs, state, reward, done (B,), truncated (B,), info). Actions: (B, N) int indices of
    the `levels` x `levels` grid of moves; (B, N, Nt) keep/ignore bits with `hrl`; or, with `levels=0`
    (continuous, MADDPG), (B, N, 2) floats in [-1, 1], each agent's share of its own action bounds (values
    outside are clipped to the bounds, as the env's action box would). Reward (B,) the
    team's, or (B, N) per camera with `credit='difference'`; done
    covers both ends of an episode, `truncated` the horizon/time-limit ones, and info holds
    `final_obs` / `final_state` (rows valid where done), `coverage` (B,) mean raw-step coverage of the
    decision, and `episodes`: a list of finished-episode dicts (`coverage`: step-mean coverage rate,
    `return`: the learner's reward summed, `raw_return`: the target team's raw reward summed and divided
    by the preset's maximum target-team episode reward (the paper's normalised reward), `length`).
    """

    def __init__(self, team: str = 'camera', num_envs: int = 64, env_id: str | None = None,
                 frame_skip: int | None = None, horizon: int | None = None, levels: int = 5,
                 seed: int | None = 0, config=None, hrl: bool = False, full_observability: bool = False,
                 memory: int = 0, velocity: bool = False, credit: str = 'team', camera_reward: str = 'coverage',
                 opponent=None, **overrides) -> None:
        team = as_team(team)
        if credit not in CREDITS:
            raise ValueError(f'credit must be one of {CREDITS}, got {credit!r}')
        if camera_reward not in CAMERA_REWARDS:
            raise ValueError(f'camera_reward must be one of {CAMERA_REWARDS}, got {camera_reward!r}')
        if camera_reward != 'coverage' and (team is not Team.CAMERA or credit != 'team'):
            raise ValueError(f"camera_reward {camera_reward!r} is a camera team reward (credit 'team' only)")
        self.camera_reward = camera_reward
        if credit == 'difference' and team is not Team.CAMERA:
            raise ValueError("credit 'difference' (each camera's own share of the coverage) exists for cameras only")
        self.credit = credit
        if hrl and team is not Team.CAMERA:
            raise ValueError('HRL (target selection + rule executor) exists for cameras only')
        if not (isinstance(levels, (int, np.integer)) and (levels == 0 or levels >= 2)):
            raise ValueError(f'levels must be an integer >= 2 (discrete moves), or 0 for continuous actions; got {levels!r}')
        if hrl and levels == 0:
            raise ValueError('HRL selects targets (discrete); it has no continuous form (levels=0)')
        self.continuous = levels == 0
        if memory and team is not Team.CAMERA:
            raise ValueError('the sighting memory exists for cameras only')
        if velocity and team is not Team.CAMERA:
            raise ValueError('the target velocity features exist for cameras only')
        if memory < 0:
            raise ValueError(f'memory must be a period of at least 1 step, or 0 for none; got {memory}')
        self.hrl = bool(hrl)
        self.full_observability = bool(full_observability)
        defaults = PAPER_SETTINGS[team.name.lower()]
        self.team = team
        self.env_id = env_id or defaults['env_id']
        self.frame_skip = int(frame_skip or defaults['frame_skip'])
        self.horizon = int(horizon or defaults['horizon'])
        self.levels = levels
        self.num_envs = num_envs
        kwargs = dict(overrides)
        kwargs['max_episode_steps'] = self.horizon
        self.vec = make_vec(self.env_id, num_envs=num_envs, config=config, observation_dtype=np.float32,
                            autoreset_mode='next_step', **kwargs)
        nc, nt, no = self.vec.num_cameras, self.vec.num_targets, self.vec.num_obstacles
        self.counts = (nc, nt, no)
        self.num_agents = nc if team is Team.CAMERA else nt
        # the policy's action: `action_heads` independent choices among `action_choices` per agent
        # (continuous: `num_actions` = 2 action dimensions per agent)
        self.action_heads, self.action_choices = (nt, 2) if self.hrl else (1, 2 if self.continuous else levels ** 2)
        self.num_actions = self.action_heads * self.action_choices     # logits (or action dimensions) per agent
        self.obs_dim = self.vec.single_observation_space[0 if team is Team.CAMERA else 1].shape[-1]
        self.memory = SightingMemory(num_envs, self.counts, memory) if memory else None
        if self.memory is not None:
            self.obs_dim += MEMORY_FEATURES * nt
        self.velocity = bool(velocity)
        if self.velocity:
            self.obs_dim += VELOCITY_FEATURES * nt
        self._before = None    # velocity: the trained team's raw observations one raw step earlier
        self._target_records = int(observation_indices_of(team, nc, nt, no)[2])   # camera obs: target slots
        self.state_dim = self.vec.single_state_space.shape[0]
        opponent_seed = None if seed is None else seed + 7919
        if opponent is not None:
            self.opponent = opponent(num_envs, self.counts, opponent_seed)
        elif team is Team.CAMERA:
            self.opponent = VecGreedyTarget(num_envs, nt, seed=opponent_seed)
        else:
            self.opponent = VecGreedyCamera(num_envs, nc, nt, no, seed=opponent_seed)
        self._seed = seed
        self._raw = None
        self._return = np.zeros(num_envs)
        self._raw_return = np.zeros(num_envs)
        self._max_reward = float(self.vec.params.max_target_team_episode_reward)
        self._coverage_sum = np.zeros(num_envs)
        self._length = np.zeros(num_envs, dtype=np.int64)

    # ------------------------------------------------------------------ helpers
    def _own(self, observations):
        return observations[0] if self.team is Team.CAMERA else observations[1]

    def _enhanced(self, observations):
        """`observations` as the trained team sees them: unchanged, or (full observability) with every
        record of its team filled in place (the vector env's buffers; the opponent's are untouched)."""
        if self.full_observability:
            camera = self.team is Team.CAMERA
            enhance_observations(*observations, self.vec.obstacle_states, empty_warehouses(self.vec.remaining_cargoes),
                                 *self.counts, camera=camera, target=not camera)
        return observations

    def _other(self, observations):
        return observations[1] if self.team is Team.CAMERA else observations[0]

    def _process(self, raw, rows=None):
        processed = preprocess_observation(raw, self.team, *self.counts)
        columns = [processed]
        if self.memory is not None:
            columns.append(self.memory.features(raw, rows))
        if self.velocity:
            before = self._before if rows is None else self._before[rows]
            columns.append(target_displacements(raw, before, self.counts, self.frame_skip))
        return columns[0] if len(columns) == 1 else np.concatenate(columns, axis=-1)

    def _step_vec(self, joint, restarting):
        """One raw step of the vector env; keeps (velocity) the trained team's previous raw observations,
        which for rows starting an episode at this step are their first ones (no motion yet)."""
        before = self._own_raw.copy() if self.velocity else None
        result = self.vec.step(joint)
        if self.credit == 'difference':   # before full observability fills in every flag
            self._sees = camera_sightings(result[0][0], *self.counts)[1]
        observations = self._enhanced(result[0])
        if self.velocity:
            own = self._own(observations)
            before[restarting] = own[restarting]
            self._before = before
        return (observations, *result[1:])

    def _remember(self, observations, restarting=None) -> None:
        """One raw step of the sighting memory: rows that start an episode forget, then every camera's
        sightings enter the team's memory."""
        if self.memory is None:
            return
        if restarting is not None and restarting.any():
            self.memory.forget(restarting)
        self.memory.tick()
        self.memory.observe_team(self._own(observations))

    def _state(self):
        return compress(normalize_observation(self.vec.state(), self.vec.single_state_space))

    # ------------------------------------------------------------------ API
    @property
    def raw_observations(self) -> np.ndarray:
        """(B, N, D) unprocessed observations of the trained team at the current decision (do not modify)."""
        return self._raw

    def positions(self) -> np.ndarray:
        """(B, N, 2) float64 world positions of the trained team's agents at the current decision, cut from the
        global state as `RestrictedCommunicationRange` reads them (the training channel's range test)."""
        state = self.vec.state()
        nc, nt, _ = self.counts
        if self.team is Team.CAMERA:
            begin, count, width = PRESERVED_DIM, nc, CAMERA_STATE_DIM_PRIVATE
        else:
            begin, count, width = PRESERVED_DIM + CAMERA_STATE_DIM_PRIVATE * nc, nt, TARGET_STATE_DIM_PRIVATE
        rows = state[:, begin:begin + count * width].reshape(self.num_envs, count, width)
        return rows[..., :2].astype(np.float64)

    def allowed_actions(self, processed: np.ndarray) -> np.ndarray:
        """HRL: (..., N, Nt, 2) bool from processed observations (..., N, D): 'ignore' is always allowed,
        'keep' only for the targets the camera sees (the executor ignores the others anyway)."""
        begin = self._target_records
        visible = processed[..., begin + 4:begin + 5 * self.counts[1]:5] > 0.5
        return np.stack([np.ones_like(visible), visible], axis=-1)

    def reset(self, seed: int | None = None):
        observations, _ = self.vec.reset(seed=self._seed if seed is None else seed)
        observations = self._enhanced(observations)
        self.opponent.reset(self._other(observations), np.ones(self.num_envs, dtype=bool))
        self._raw = self._own(observations).copy()
        self._before = self._raw.copy()
        self._other_raw = self._other(observations)
        self._own_raw = self._own(observations)
        if self.memory is not None:
            self.memory.forget()
        self._remember(observations)
        self._return[:] = 0.0
        self._raw_return[:] = 0.0
        self._coverage_sum[:] = 0.0
        self._length[:] = 0
        return self._process(self._raw), self._state()

    def step(self, actions):
        B = self.num_envs
        actions = np.asarray(actions)
        if self.hrl:
            selection = actions.reshape(B, self.num_agents, self.action_heads)
        elif self.continuous:
            own_actions = np.clip(actions.reshape(B, self.num_agents, 2), -1.0, 1.0) * action_high(self._raw, self.team)
        else:
            own_actions = discrete_to_continuous(actions.reshape(B, self.num_agents), self._raw, self.team,
                                                 self.levels)
        reward = np.zeros((B, self.num_agents) if self.credit == 'difference' else B)
        coverage = np.zeros(B)
        counted = np.zeros(B)
        done = np.zeros(B, dtype=bool)
        truncated = np.zeros(B, dtype=bool)
        final_obs = np.zeros((B, self.num_agents, self.obs_dim), dtype=np.float32)
        final_state = np.zeros((B, self.state_dim), dtype=np.float32)
        episodes = []
        restarting = np.zeros(B, dtype=bool)     # rows whose episode ended at the previous raw step
        for _ in range(self.frame_skip):
            if self.hrl:   # closed loop: the executor re-aims at every raw step from the fresh observation
                own_actions = executor_actions(self._own_raw, selection, *self.counts)
            other = self.opponent.act(self._other_raw)
            joint = (own_actions, other) if self.team is Team.CAMERA else (other, own_actions)
            observations, rewards, terminated, truncated_now, infos = self._step_vec(joint, restarting)
            if restarting.any():
                self.opponent.reset(self._other(observations), restarting)
            self._remember(observations, restarting)
            live = ~done & ~restarting
            r = rewards[0] if self.team is Team.CAMERA else rewards[1]
            if self.team is Team.CAMERA:
                r = infos['coverage_rate'] if self.camera_reward == 'coverage' else \
                    mixed_camera_reward(infos['coverage_rate'], infos['real_coverage_rate'], rewards[0])
            if self.credit == 'difference':
                reward += np.where(live[:, None], difference_rewards(self._sees), 0.0)
            else:
                reward += np.where(live, r, 0.0)
            coverage += np.where(live, infos['coverage_rate'], 0.0)
            counted += live
            self._return += np.where(live, r, 0.0)
            self._raw_return += np.where(live, rewards[1], 0.0)    # target-team raw reward (zero-sum game)
            self._coverage_sum += np.where(live, infos['coverage_rate'], 0.0)
            self._length += live
            ended = live & (terminated | truncated_now)
            restarting = ended.copy()
            if ended.any():
                rows = np.flatnonzero(ended)
                final_obs[rows] = self._process(self._own(observations)[rows], rows)
                final_state[rows] = self._state()[rows]
                truncated[rows] = truncated_now[rows] & ~terminated[rows]
                done |= ended
                for i in rows:
                    episodes.append(dict(coverage=self._coverage_sum[i] / max(self._length[i], 1),
                                         length=int(self._length[i]), **{'return': float(self._return[i])},
                                         raw_return=float(self._raw_return[i]) / self._max_reward))
                self._return[rows] = 0.0
                self._raw_return[rows] = 0.0
                self._coverage_sum[rows] = 0.0
                self._length[rows] = 0
            self._other_raw = self._other(observations)
            self._own_raw = self._own(observations)
        if restarting.any():   # ended at the last raw step: restart now so the next decision is clean
            other = self.opponent.act(self._other(observations))
            joint = (own_actions, other) if self.team is Team.CAMERA else (other, own_actions)
            observations = self._step_vec(joint, restarting)[0]
            self.opponent.reset(self._other(observations), restarting)
            self._remember(observations, restarting)
        self._other_raw = self._other(observations)
        self._own_raw = self._own(observations)
        self._raw = self._own(observations).copy()
        info = dict(final_obs=final_obs, final_state=final_state, coverage=coverage / np.maximum(counted, 1),
                    episodes=episodes)
        return self._process(self._raw), self._state(), reward, done, truncated, info
