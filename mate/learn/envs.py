"""The training view of B games for one team: `TeamEnvConfig` (the options every trainer takes) -> `TeamVecEnv`.

A `TeamVecEnv` steps the public single-team env, `mate.SingleTeamVecEnv` (the games and the opponent, which a
researcher's own algorithm steps too), and adds what mate's learners need on top: the policy spec's features and
action decoding, frame skip, the team's reward kinds and episode sums in decisions.

What a learner sees per decision (the paper's wrapper stack, done on arrays):

* observations through its `PolicySpec`'s `features` (relative coordinates rescaled to [-1, 1], the team's
  sighting-memory and target-velocity columns when the spec has them), and the global state rescaled with the
  state-space bounds, its unbounded counters log-compressed (`compress`);
* its held decision turned into env actions by the spec's `decode`: a grid move scaled by the agent's own step
  limits, the HRL executor re-aiming at the selected targets at every env step, or continuous shares;
* the opponent (by default the greedy rules, `mate.teams.GreedyTeam`) acting at every env step;
* frame skip k: a decision is held for k env steps; rewards are summed (camera: the coverage rate, the
  `AuxiliaryCameraRewards` setting of the paper; target: the raw dense team reward);
* episodes cut at `horizon` env steps (the paper: 500 decisions);
* `full_observability`: the trained team's raw observations go through `enhance_observations` (the
  `EnhancedObservation` wrapper's arrays: every entity seen, targets know which warehouses are empty), the
  paper's Fig. 6 ablation; the opponent keeps its partial view;
* `credit='difference'` (cameras): each camera is rewarded with its own marginal contribution to the coverage
  rate (the core's `World.camera_reward_parts`) instead of the team's; rewards are then (B, N);
* `credit='own'` (targets): each target is rewarded with its own part of the team's raw reward (the core's
  `World.target_reward_parts`: its tracking penalty and its deliveries), which sum to the team reward; rewards are
  then (B, N);
* `camera_reward='mixed'` (cameras): the population players' reward (docs/population.md), per env step
  0.5 coverage rate + 0.5 real coverage rate + 0.1 x the raw camera-team reward;
* `opponent=factory`: the other team is `factory(num_envs, counts, seed)`, any batched team of `mate.teams`
  (e.g. a mixture over a population, `mate psro`).

Episode ends inside a decision: the vector env runs in `next_step` autoreset mode, so a row that ends at env
step j restarts at step j + 1 and plays the rest of the held decision in its new episode; those steps' rewards
are credited to no one. The row's last observation and state are kept (`final_obs`, `final_state`) so that the
learner can bootstrap through a truncation.

`state_dict()` / `load_state_dict()` hold everything the batch's future depends on (the games, the opponent's
state and random streams, the sighting memory, the episode sums), for exact resumes.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np

from ..agents.utils import normalize_observation
from ..constants import CAMERA_STATE_DIM_PRIVATE, PRESERVED_DIM, TARGET_STATE_DIM_PRIVATE
from ..messages import Team
from ..options import option
from ..protocol import PAPER_SETTINGS
from ..registration import resolve_config
from ..team_vector import SingleTeamVecEnv
from ..teams import GreedyTeam
from ..wrappers.enhanced_observation import empty_warehouses, enhance_observations
from .memory import SightingMemory
from .spec import PolicySpec, as_team

__all__ = ['CAMERA_REWARDS', 'CREDITS', 'OPPONENT_SEED_OFFSET', 'PAPER_SETTINGS', 'TeamEnvConfig', 'TeamVecEnv',
           'compress', 'game_of', 'mixed_camera_reward', 'team_positions']

CREDITS = ('team', 'difference', 'own')
"""How an agent's reward is assigned: the team's (both teams); a camera's own marginal contribution to the coverage
rate ('difference'); a target's own part of the team's raw reward ('own')."""
CAMERA_REWARDS = ('coverage', 'mixed')
"""What a camera team is rewarded with per env step: the coverage rate (the paper's cooperative runs), or
0.5 coverage + 0.5 real coverage + 0.1 raw camera-team reward (its population players, docs/population.md)."""
def game_of(config: str | None, team: str) -> tuple[str, str | None]:
    """(env_id, config path) of a `--config` value: a registered preset name (with or without '-v0'), a YAML/JSON
    path, or None for the paper preset of `team`. A bad name or file raises `ConfigError` listing the presets."""
    if config is None:
        return PAPER_SETTINGS[team]['env_id'], None
    from ..config import read_config
    from ..registration import registered_ids

    name = str(config).removesuffix('-v0')
    if f'{name}-v0' in registered_ids():
        return f'{name}-v0', None
    read_config(config)
    return 'MultiAgentTracking-v0', str(config)


@dataclasses.dataclass
class TeamEnvConfig:
    """The game a team trains in and what its policy sees: options every trainer takes."""

    team: Literal['camera', 'target'] = option('camera', 'the team to train; the other team plays the greedy rules')
    config: str | None = option(None, "preset name (e.g. MATE-4v8-9) or YAML/JSON path; None: the paper's preset of "
                                      'the team (cameras MATE-4v8-9, targets MATE-2v4-0)', metavar='PRESET')
    frame_skip: int | None = option(None, 'env steps a decision is held; None: 5 for cameras, 10 for targets',
                                    minimum=1)
    horizon: int | None = option(None, 'env steps per training episode; None: 500 decisions', minimum=1)
    num_envs: int = option(64, 'games played at once', minimum=1)
    hrl: bool = option(False, 'cameras: the policy selects targets (one keep/ignore bit per target slot) and a rule '
                              'executor aims at them (paper §HRL)')
    memory: int = option(0, "cameras: env steps the team's shared memory of target sightings keeps a target, "
                            "appended to each camera's observation (the greedy cameras' 25); 0: none", minimum=0)
    velocity: bool = option(False, "cameras: append each seen target's displacement over one held decision")
    full_observability: bool = option(False, "the trained team sees every entity (EnhancedObservation, the paper's "
                                              'Fig. 6); evaluate with mate evaluate --enhanced-observation TEAM')
    credit: Literal['team', 'difference', 'own'] = option(
        'team', "reward every agent with the team's reward, or each with its own part: cameras their marginal share of "
                "the coverage ('difference'), targets their own tracking penalty and deliveries ('own')")
    seed: int = option(0, 'seed of the run: networks, envs, opponents, sampling', minimum=0)

    def __post_init__(self) -> None:
        camera_only = [flag for flag, used in (('--hrl', self.hrl), ('--memory', self.memory),
                                               ('--velocity', self.velocity),
                                               ("--credit difference", self.credit == 'difference')) if used]
        if camera_only and self.team != 'camera':
            raise ValueError(f'{camera_only[0]} exists for cameras only (--team camera)')
        if self.credit == 'own' and self.team != 'target':
            raise ValueError('--credit own (each target\'s own part of the team reward) exists for targets only '
                             '(--team target)')

    @property
    def env_id(self) -> str:
        return game_of(self.config, self.team)[0]

    @property
    def resolved_frame_skip(self) -> int:
        return int(self.frame_skip or PAPER_SETTINGS[self.team]['frame_skip'])

    @property
    def resolved_horizon(self) -> int:
        return int(self.horizon or 500 * self.resolved_frame_skip)

    def policy_spec(self, *, action: str = 'grid', network: str = 'mlp', hidden=(256, 256), activation: str = 'tanh',
                    lstm: int = 0, algo: str = '', deterministic: bool = False, levels: int = 5) -> PolicySpec:
        """The spec of the policy trained in this game (the action kind, network and algorithm from the trainer)."""
        env_id, config = game_of(self.config, self.team)
        return PolicySpec.for_game(self.team, env_id, config, frame_skip=self.resolved_frame_skip, action=action,
                                   levels=levels, memory=self.memory, velocity=self.velocity,
                                   full_observability=self.full_observability, network=network, hidden=hidden,
                                   activation=activation, lstm=lstm, algo=algo, deterministic=deterministic)

    def make_env(self, spec: PolicySpec, opponent=None, camera_reward: str = 'coverage') -> TeamVecEnv:
        """The training envs of this config for a policy of `spec` (the one place a `TeamVecEnv` is made)."""
        return TeamVecEnv(spec, num_envs=self.num_envs, horizon=self.resolved_horizon, seed=self.seed,
                          credit=self.credit, camera_reward=camera_reward, opponent=opponent)


def mixed_camera_reward(coverage_rate, real_coverage_rate, camera_reward):
    """The population players' camera reward (docs/population.md) from one env step's (B,) arrays."""
    return 0.5 * np.asarray(coverage_rate) + 0.5 * np.asarray(real_coverage_rate) + 0.1 * np.asarray(camera_reward)


def compress(x: np.ndarray) -> np.ndarray:
    """float32 x, with the entries beyond [-1, 1] (unbounded counters: bounties, freights, cargo counts up
    to 200) squashed logarithmically, sign(x) (1 + log|x|), so that they do not saturate the critic."""
    magnitude = np.abs(x)
    return np.where(magnitude > 1.0, np.sign(x) * (1.0 + np.log(np.maximum(magnitude, 1.0))), x).astype(np.float32)


def team_positions(state: np.ndarray, team: Team, counts) -> np.ndarray:
    """(B, N, 2) float64 world positions of `team`'s agents, cut from the global states (B, S) of games of `counts`
    = (Nc, Nt, No) (each agent's private state block starts with its x, y)."""
    nc, nt, _ = counts
    if team is Team.CAMERA:
        begin, count, width = PRESERVED_DIM, nc, CAMERA_STATE_DIM_PRIVATE
    else:
        begin, count, width = PRESERVED_DIM + CAMERA_STATE_DIM_PRIVATE * nc, nt, TARGET_STATE_DIM_PRIVATE
    rows = np.asarray(state)[:, begin:begin + count * width].reshape(len(state), count, width)
    return rows[..., :2].astype(np.float64)


OPPONENT_SEED_OFFSET = 7919
"""A training env of seed s seeds its opponent with s + 7919 (its row b with s + 7919 + b), apart from the games'."""


def greedy_opponent(team: Team, num_envs: int, counts, seed):
    """The default opponent of a team in training: the other team's greedy agents (`mate.teams.GreedyTeam`, draw
    for draw the Python agents; row b seeded seed + b)."""
    return GreedyTeam(Team.TARGET if team is Team.CAMERA else Team.CAMERA, num_envs, counts, seed=seed)


class TeamVecEnv:
    """B games in which a policy of `spec` plays its team against a batched opponent (module docstring).

    `reset(seed)` -> (obs (B, N, D) float32, state (B, S) float32).
    `step(actions)` -> (obs, state, reward, done (B,), truncated (B,), info). Actions: what the team holds for the
    decision, (B, N, heads) int choices (or (B, N) for one head) or (B, N, 2) continuous shares in [-1, 1] (values
    outside are clipped, as the env's action box would). Reward (B,) the team's, or (B, N) per camera with
    `credit='difference'`; done covers both ends of an episode, `truncated` the horizon cuts, and info holds
    `final_obs` / `final_state` (rows valid where done), `coverage` (B,) mean env-step coverage of the decision,
    and `episodes`: a list of finished-episode dicts (`coverage`: step-mean coverage rate, `return`: the learner's
    reward summed, `raw_return`: the target team's raw reward summed and divided by the preset's maximum
    target-team episode reward (the paper's normalised reward), `length`).

    Args:
        spec: the trained policy's spec (team, game, frame skip, observation features, action kind).
        num_envs: B.
        horizon: env steps per episode (None: 500 decisions).
        seed: seed of `reset()` without a seed, and of the opponent (seed + 7919).
        credit: 'team' or 'difference' (cameras).
        camera_reward: 'coverage' or 'mixed' (cameras, credit 'team').
        opponent: a factory `f(num_envs, counts, seed)` of the other team (default: the greedy rules).
        **overrides: config keys of the game (`mate.make_vec`'s).
    """

    def __init__(self, spec: PolicySpec, num_envs: int = 64, horizon: int | None = None, seed: int | None = 0,
                 credit: str = 'team', camera_reward: str = 'coverage', opponent=None, **overrides) -> None:
        team = as_team(spec.team)
        if credit not in CREDITS:
            raise ValueError(f'credit must be one of {CREDITS}, got {credit!r}')
        if camera_reward not in CAMERA_REWARDS:
            raise ValueError(f'camera_reward must be one of {CAMERA_REWARDS}, got {camera_reward!r}')
        if camera_reward != 'coverage' and (team is not Team.CAMERA or credit != 'team'):
            raise ValueError(f"camera_reward {camera_reward!r} is a camera team reward (credit 'team' only)")
        if credit == 'difference' and team is not Team.CAMERA:
            raise ValueError("credit 'difference' (each camera's own share of the coverage) exists for cameras only")
        if credit == 'own' and team is not Team.TARGET:
            raise ValueError("credit 'own' (each target's own part of the team reward) exists for targets only")
        self.spec, self.team, self.credit, self.camera_reward = spec, team, credit, camera_reward
        self.frame_skip = spec.frame_skip
        self.horizon = int(horizon or 500 * spec.frame_skip)
        self.num_envs = int(num_envs)
        opponent_seed = None if seed is None else seed + OPPONENT_SEED_OFFSET
        factory = opponent or (lambda n, counts, s: greedy_opponent(team, n, counts, s))
        self.envs = SingleTeamVecEnv(resolve_config(spec.env_id, spec.config), team, self.num_envs,
                                     opponent=lambda n, counts, _: factory(n, counts, opponent_seed),
                                     reward='team' if credit == 'team' else credit, max_episode_steps=self.horizon,
                                     observation_dtype=np.float32, autoreset_mode='next_step', **overrides)
        self.vec = self.envs.vec
        self.counts = (self.vec.num_cameras, self.vec.num_targets, self.vec.num_obstacles)
        spec.check_game(team, self.counts, 'the policy spec')
        self.num_agents = spec.num_agents
        self.obs_dim, self.state_dim = spec.obs_dim, self.vec.single_state_space.shape[0]
        self.action_heads, self.action_choices, self.num_actions = spec.heads, spec.choices, spec.num_actions
        self.memory = SightingMemory(self.num_envs, self.counts, spec.memory) if spec.memory else None
        self._seed = seed
        self._agent_rewards = None   # credit 'own' / 'difference': the last env step's per-agent rewards
        self._raw = self._own_raw = self._before = None
        self._return = np.zeros(self.num_envs)   # the learner's reward summed (the game's statistics: the core's)
        self._max_reward = float(self.vec.params.max_target_team_episode_reward)

    # ------------------------------------------------------------------ helpers
    def _own(self, observations):
        return observations[0] if self.team is Team.CAMERA else observations[1]

    def _enhanced(self, observations):
        """`observations` as the trained team sees them: unchanged, or (full observability) with every
        record of its team filled in place (the vector env's buffers; the opponent's are untouched)."""
        if self.spec.full_observability:
            camera = self.team is Team.CAMERA
            enhance_observations(*observations, self.vec.obstacle_states, empty_warehouses(self.vec.remaining_cargoes),
                                 *self.counts, camera=camera, target=not camera)
        return observations

    def _features(self, raw, rows=None):
        """The spec's features of raw own observations (R, N, D_raw) of the rows `rows` (all if None)."""
        memory = None if self.memory is None else self.memory.features(raw, rows)
        before = self._before if rows is None else self._before[rows]
        return self.spec.features(raw, memory, before)

    def _step_vec(self, own_actions, restarting):
        """One env step of the single-team env (the opponent acts inside it, and restarts with its rows); returns
        (both teams' observations, (camera reward, target reward), terminated, truncated, infos). Keeps the trained
        team's previous raw observations (velocity), which for rows starting an episode at this step are their first
        ones (no motion yet)."""
        before = self._own_raw.copy() if self.spec.velocity else None
        _, reward, terminated, truncated, infos = self.envs.step(own_actions)
        target_reward = self.vec.world.target_reward.copy()
        rewards = (-target_reward, target_reward)           # the game is zero-sum
        observations = self.vec.observations
        if self.credit != 'team':         # the single-team env's per-agent rewards: each target's own part of the
            self._agent_rewards = reward  # team reward (B, Nt), or each camera's difference credit (B, Nc)
        observations = self._enhanced(observations)
        if self.spec.velocity:
            own = self._own(observations)
            before[restarting] = own[restarting]
            self._before = before
        return observations, rewards, terminated, truncated, infos

    def _remember(self, observations, restarting=None) -> None:
        """One env step of the sighting memory: rows that start an episode forget, then every camera's
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
    def opponent(self):
        """The other team's batched team (played inside `self.envs`, the public `mate.SingleTeamVecEnv`)."""
        return self.envs.opponent

    @property
    def raw_observations(self) -> np.ndarray:
        """(B, N, D) unprocessed observations of the trained team at the current decision (do not modify)."""
        return self._raw

    def positions(self) -> np.ndarray:
        """(B, N, 2) float64 world positions of the trained team's agents at the current decision, cut from the
        global state as `RestrictedCommunicationRange` reads them (the training channel's range test)."""
        return team_positions(self.vec.state(), self.team, self.counts)

    def allowed_actions(self, features: np.ndarray) -> np.ndarray | None:
        """The spec's allowed choices (..., N, heads, choices) of features (..., N, D); None when all are."""
        return self.spec.allowed(features)

    def reset(self, seed: int | None = None):
        self.envs.reset(seed=self._seed if seed is None else seed)
        observations = self._enhanced(self.vec.observations)
        self._raw = self._own(observations).copy()
        self._before = self._raw.copy()
        self._own_raw = self._own(observations)
        if self.memory is not None:
            self.memory.forget()
        self._remember(observations)
        self._return[:] = 0.0
        return self._features(self._raw), self._state()

    def _held(self, actions) -> np.ndarray:
        """The decision's actions as (B, N, heads) choices or (B, N, 2) continuous shares."""
        B, N = self.num_envs, self.num_agents
        actions = np.asarray(actions)
        if self.spec.continuous:
            return np.clip(actions.reshape(B, N, 2), -1.0, 1.0)
        return actions.reshape(B, N, self.action_heads)

    def step(self, actions):
        B = self.num_envs
        held = self._held(actions)
        if not self.spec.closed_loop:   # open loop: decoded once, at the decision (the limits are fixed in an episode)
            own_actions = self.spec.decode(held, self._raw)
        reward = np.zeros(B if self.credit == 'team' else (B, self.num_agents))
        coverage = np.zeros(B)
        counted = np.zeros(B)
        done = np.zeros(B, dtype=bool)
        truncated = np.zeros(B, dtype=bool)
        final_obs = np.zeros((B, self.num_agents, self.obs_dim), dtype=np.float32)
        final_state = np.zeros((B, self.state_dim), dtype=np.float32)
        episodes = []
        restarting = np.zeros(B, dtype=bool)     # rows whose episode ended at the previous env step
        for _ in range(self.frame_skip):
            if self.spec.closed_loop:   # the executor re-aims at every env step from the fresh observation
                own_actions = self.spec.decode(held, self._own_raw)
            observations, rewards, terminated, truncated_now, infos = self._step_vec(own_actions, restarting)
            self._remember(observations, restarting)
            live = ~done & ~restarting
            r = rewards[0] if self.team is Team.CAMERA else rewards[1]
            if self.team is Team.CAMERA:
                r = infos['coverage_rate'] if self.camera_reward == 'coverage' else \
                    mixed_camera_reward(infos['coverage_rate'], infos['real_coverage_rate'], rewards[0])
            if self.credit != 'team':
                reward += np.where(live[:, None], self._agent_rewards, 0.0)
            else:
                reward += np.where(live, r, 0.0)
            coverage += np.where(live, infos['coverage_rate'], 0.0)
            counted += live
            self._return += np.where(live, r, 0.0)
            ended = live & (terminated | truncated_now)
            restarting = ended.copy()
            if ended.any():
                rows = np.flatnonzero(ended)
                final_obs[rows] = self._features(self._own(observations)[rows], rows)
                final_state[rows] = self._state()[rows]
                truncated[rows] = truncated_now[rows] & ~terminated[rows]
                done |= ended
                game = infos.get('final_info', infos)     # the episode's statistics, as the core counted them
                for i in rows:
                    episodes.append(dict(coverage=float(game['episode_coverage_rate'][i]),
                                         length=int(game['episode_step'][i]), **{'return': float(self._return[i])},
                                         raw_return=float(game['episode_target_return'][i]) / self._max_reward))
                self._return[rows] = 0.0
            self._own_raw = self._own(observations)
        if restarting.any():   # ended at the last env step: restart now so the next decision is clean
            observations = self._step_vec(own_actions, restarting)[0]
            self._remember(observations, restarting)
        self._own_raw = self._own(observations)
        self._raw = self._own(observations).copy()
        info = dict(final_obs=final_obs, final_state=final_state, coverage=coverage / np.maximum(counted, 1),
                    episodes=episodes)
        return self._features(self._raw), self._state(), reward, done, truncated, info

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict:
        """Everything the batch's future depends on, as plain data (see the module docstring)."""
        memory = None if self.memory is None else dict(location=self.memory.location.copy(), age=self.memory.age.copy())
        games = self.envs.state_dict()
        return dict(vec=games['vec'], opponent=games['opponent'], pending=games['pending'], memory=memory,
                    before=None if self._before is None else self._before.copy(),
                    sums=dict(returns=self._return.copy()))

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (taken from envs of the same spec, size and opponent kind)."""
        if 'device' in state:
            raise ValueError('this checkpoint holds the state of games played on a GPU; resume it with '
                             '--game-device cuda')
        self.envs.load_state_dict(dict(vec=state['vec'], opponent=state['opponent'],
                                       pending=state.get('pending', False)))   # (older checkpoints: none pending)
        if self.memory is not None:
            self.memory.location[...] = state['memory']['location']
            self.memory.age[...] = state['memory']['age']
        observations = self._enhanced(self.vec.observations)
        self._own_raw = self._own(observations)
        self._raw = self._own(observations).copy()
        self._before = None if state['before'] is None else np.array(state['before'])
        sums = state['sums']
        self._return[...] = sums['returns']
        if 'coverage_rate_sum' not in state['vec']['world'] and 'coverage' in sums:   # an earlier version's state
            self.vec.world.coverage_rate_sum[...] = sums['coverage']

    def observations(self):
        """(features (B, N, D), state (B, S)) of the current decision (as `reset` and `step` return them)."""
        return self._features(self._raw), self._state()

