"""MATE as a Ray RLlib `MultiAgentEnv` (new API stack), a PPO setup, and RLlib's PPO as a `mate.learn` run.

    from mate.integrations import rllib as mate_rllib
    mate_rllib.register()                                   # RLlib env name 'mate'
    config = mate_rllib.ppo_config({'config': 'MATE-4v4-9', 'opponent': 'greedy'})
    algo = config.build_algo()
    print(algo.train()['env_runners']['episode_return_mean'])

The class docstring of `MateMultiAgentEnv` describes the env: its env_config keys, agents, spaces,
rewards, episode end and infos (`help(MateMultiAgentEnv)`, or the API page of the docs). With a
`PolicySpec` in its env_config (`'spec'`), the env shows RLlib exactly what a `mate.learn` policy of
that spec sees and does (features, grid moves, frame skip), so that the RLlib policy exports to a
`mate` policy file (`mate.integrations.rllib_export`). `train_run(config)` is `mate rllib-train`: RLlib's
PPO trained and logged as a `mate.learn.Run`, scored with the evaluation protocol of `mate train`
(docs/rllib.md, "The witness").
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from gymnasium import spaces
from ray.rllib.callbacks.callbacks import RLlibCallback
from ray.rllib.env.multi_agent_env import MultiAgentEnv

from ..envs.multi_agent_tracking import MultiAgentTracking, agent_action
from ..policies.spec import PolicySpec, SpecError

__all__ = ['ENV_NAME', 'MateMultiAgentEnv', 'MateMetricsCallback', 'register', 'ppo_config', 'policy_mapping_fn',
           'train']

ENV_NAME = 'mate'
"""The name `register()` gives the env in Ray's registry."""

ENV_CONFIG_KEYS = ('config', 'overrides', 'team', 'opponent', 'rescale_observations', 'spec', 'reward', 'seed',
                   'envs_per_runner')
TEAMS = ('camera', 'target', 'both')
REWARDS = ('team', 'coverage')
RULE_BASED = {'greedy': 'Greedy', 'naive': 'Naive', 'random': 'Random'}
BATCHED = {'batched-greedy': 'greedy', 'batched-random': 'random'}
"""Opponents played by a batched team of `mate.teams` with one row (the opponent of `mate train`'s envs)."""


# --------------------------------------------------------------------------- opponents
class _CallableTeam:
    """A stateless team policy: actions (N, 2) = fn(joint_obs (N, D))."""

    def __init__(self, fn: Callable) -> None:
        self.fn = fn

    def reset(self, env, joint_obs, seed) -> None:
        pass

    def act(self, env, joint_obs, infos) -> np.ndarray:
        return np.asarray(self.fn(joint_obs), dtype=np.float64)


class _UniformTeam:
    """Built-in opponent: i.i.d. uniform actions over the action box (no mate.agents needed)."""

    def __init__(self, box: spaces.Box, count: int) -> None:
        self.low, self.high, self.count = box.low, box.high, count
        self.rng = np.random.default_rng()

    def reset(self, env, joint_obs, seed) -> None:
        if seed is not None:
            self.rng = np.random.default_rng(seed)

    def act(self, env, joint_obs, infos) -> np.ndarray:
        return self.rng.uniform(self.low, self.high, (self.count, 2))


class _AgentTeam:
    """A team of mate.agents agents spawned from a prototype; observe, communicate, act each step."""

    def __init__(self, prototype, count: int) -> None:
        self.prototype, self.count, self.agents = prototype, count, None

    def reset(self, env, joint_obs, seed) -> None:
        from ..agents import group_reset

        if seed is not None:
            self.prototype.seed(seed)
            self.agents = None
        if self.agents is None:
            self.agents = self.prototype.spawn(self.count)
        group_reset(self.agents, joint_obs)

    def act(self, env, joint_obs, infos) -> np.ndarray:
        from ..agents import group_step

        return np.asarray(group_step(env, self.agents, joint_obs, infos), dtype=np.float64)


class _BatchedTeam:
    """A batched team of `mate.teams` (`make_team(name, ...)`) playing the one game of the env as its only row: the
    opponent `mate train`'s envs and the evaluation protocol use. A seeded reset builds it anew with that seed (row 0
    plays draw for draw as the Python agents seeded so); an unseeded one continues its random streams."""

    def __init__(self, name: str, team: str, counts) -> None:
        self.name, self.team_name, self.counts = name, team, counts
        self.team = None

    def reset(self, env, joint_obs, seed) -> None:
        from ..teams import make_team

        if seed is not None or self.team is None:
            self.team = make_team(self.name, self.team_name, 1, self.counts, seed=seed)
        self.team.reset(np.asarray(joint_obs, dtype=np.float64)[None], np.ones(1, dtype=bool))

    def act(self, env, joint_obs, infos) -> np.ndarray:
        return self.team.act(np.asarray(joint_obs, dtype=np.float64)[None])[0]


def _opponent(spec, team: str, env: MultiAgentTracking):
    """The opponent team policy for `team` ('camera' or 'target', the opponent's own team)."""
    count = env.num_cameras if team == 'camera' else env.num_targets
    box = env.camera_action_space if team == 'camera' else env.target_action_space
    if isinstance(spec, str):
        if spec == 'uniform':
            return _UniformTeam(box, count)
        if spec in BATCHED:
            return _BatchedTeam(BATCHED[spec], team, (env.num_cameras, env.num_targets, env.num_obstacles))
        if spec in RULE_BASED:
            try:
                agents = importlib.import_module('mate.agents')
            except ImportError as exc:
                raise ValueError(f'opponent {spec!r} needs mate.agents ({exc}); use "uniform" or a callable') from None
            spec = getattr(agents, f'{RULE_BASED[spec]}{team.capitalize()}Agent')
        elif ':' in spec:
            module, _, name = spec.partition(':')
            spec = getattr(importlib.import_module(module), name)
        else:
            raise ValueError(f'unknown opponent {spec!r}: use one of {", ".join([*RULE_BASED, *BATCHED, "uniform"])}, '
                             "'package.module:name', an agent or a callable")
    if isinstance(spec, type) and hasattr(spec, 'spawn'):
        spec = spec()
    if hasattr(spec, 'spawn') and hasattr(spec, 'act'):
        return _AgentTeam(spec, count)
    if callable(spec):
        return _CallableTeam(spec)
    raise TypeError(f'opponent must be a name, an agent, an agent class or a callable; got {spec!r}')


# --------------------------------------------------------------------------- env
class MateMultiAgentEnv(MultiAgentEnv):
    """One `MultiAgentTracking` env as an RLlib `MultiAgentEnv` (new API stack).

    RLlib controls one team (or both); the other team is played by an opponent inside the env.
    `register()` makes it RLlib's env `'mate'`, built from the algorithm's `env_config`.

    **env_config keys.**

    - `config`: a preset name, a YAML/JSON path or a dict (default `'MATE-4v8-9'`; with `spec`, the spec's game).
    - `overrides`: a dict deep-merged into the configuration (e.g. `{'max_episode_steps': 500}`).
    - `team`: `'camera'` (default), `'target'` or `'both'`: the agents RLlib controls.
    - `opponent`: the other team (ignored for `'both'`). `'greedy'` (default), `'naive'`, `'random'`:
      the rule-based agents of `mate.agents`, spawned one per slot and driven with `group_reset` /
      `group_step`, messages included; `'batched-greedy'`, `'batched-random'`: the same rules as a
      batched team of `mate.teams` with one row (what `mate train` and its evaluations play against;
      about 5x faster); `'uniform'`: i.i.d. uniform actions (built in);
      `'package.module:name'`: imported, then as below; an agent instance or class of `mate.agents`;
      or any callable `f(joint_obs (N, D)) -> actions (N, 2)`. `reset(seed=s)` reseeds the opponent.
    - `rescale_observations`: divide every observation entry by its finite space bound (default
      True): coordinates / 2000, angles / 180, flags and counts unchanged. Not with `spec`.
    - `spec`: a `mate.learn.PolicySpec` (or its `to_dict()`) of a policy with grid actions: the env then
      shows RLlib what a `mate.learn` policy of that spec sees and does. Its team is the team RLlib
      controls; observations are `spec.features(raw)` (relative coordinates rescaled to [-1, 1]); each
      agent's action is one of the `spec.choices` grid moves (`Discrete`), decoded as `spec.decode` does
      (scaled by the agent's own step limits) and held for `spec.frame_skip` env steps (the opponent acts
      at every one); one RLlib step is one decision.
    - `reward`: `'team'` (default): the env's team reward; `'coverage'` (cameras): the coverage rate of
      each env step (the paper's cooperative camera runs). Summed over the env steps of a decision.
    - `seed`, `envs_per_runner`: the run's seed S and RLlib's `num_envs_per_env_runner` E. RLlib resets
      sub-env i of env runner w first with seed `S + w + i`, which repeats seeds across runners; with
      these keys the env plays that first episode with seed `S + row` instead, row = (w - 1) E + i on a
      remote runner (w >= 1) and i on the local one, so that the games of a run are seeded S, S + 1, ...
      as `mate train`'s rows are.

    **Agents.** `camera_0 .. camera_{Nc-1}`, `target_0 .. target_{Nt-1}`: those of the controlled
    team(s), in `possible_agents`.

    **Action space.** Without `spec`, `action_spaces[agent]` is a float32 `Box(2)`: `[rotate, zoom]` in
    degrees for a camera, a displacement `[dx, dy]` for a target. An agent's action must have that shape
    `(2,)` (any real dtype); another shape raises a `ValueError` naming the agent and the expected shape
    (nothing is reshaped). Out-of-bounds values are clipped by the core. With `spec`, it is
    `Discrete(spec.choices)` and an action must be an integer in that range. An agent missing from the
    action dict stays still.

    **Observation space.** Without `spec`, `observation_spaces[agent]` is a float32 `Box` of the team's
    observation layout (`mate.spaces`), rescaled as `rescale_observations` says; with `spec`, a float32
    `Box(spec.obs_dim)` (unbounded: the preserved block's counters are not rescaled).

    **Rewards.** The team reward (or the coverage rate, `reward='coverage'`) summed over the decision's env
    steps, repeated for each agent of the team (zero-sum between the teams with `'team'`).

    **Episode end.** The whole team ends together: `terminateds` / `truncateds` hold every agent and
    `'__all__'`; terminated once every cargo unit is delivered, truncated at `max_episode_steps` env steps
    (a decision ending the episode stops there).

    **infos.** Per agent: `coverage_rate`, `real_coverage_rate`, `mean_transport_rate` and
    `num_delivered_cargoes` of the last env step; `decision_coverage_rate`, the mean coverage rate over the
    decision's env steps; and the episode so far: `episode_coverage_rate` (mean over its env steps),
    `episode_length` (env steps), `episode_return` (the controlled team's reward summed; for `'both'`, the
    cameras') and `episode_normalized_target_return` (the target team's env reward summed, divided by the
    preset's maximum target-team episode reward). `reset` returns empty infos.

    Args:
        config: the env_config dict (keys above); None or `{}` for every default. Unknown keys
            raise `ValueError`.
        worker_index: the RLlib env runner that owns the env (0: the local one); `register()` passes it.
    """

    def __init__(self, config: dict | None = None, *, worker_index: int = 0) -> None:
        super().__init__()
        config = dict(config or {})
        unknown = set(config) - set(ENV_CONFIG_KEYS)
        if unknown:
            raise ValueError(f'unknown env_config keys {sorted(unknown)}; known keys: {", ".join(ENV_CONFIG_KEYS)}')
        self.policy_spec = _env_spec(config)
        self.team = self.policy_spec.team if self.policy_spec is not None else config.get('team', 'camera')
        if self.team not in TEAMS:
            raise ValueError(f'team must be one of {TEAMS}, got {self.team!r}')
        self.reward = config.get('reward', 'team')
        if self.reward not in REWARDS:
            raise ValueError(f'reward must be one of {REWARDS}, got {self.reward!r}')
        if self.reward == 'coverage' and self.team != 'camera':
            raise ValueError(f"reward 'coverage' (the coverage rate) is a camera team reward; team is {self.team!r}")
        default_game = self.policy_spec.game if self.policy_spec is not None else 'MATE-4v8-9'
        self.env = env = MultiAgentTracking(config.get('config', default_game), **config.get('overrides', {}))
        counts = (env.num_cameras, env.num_targets, env.num_obstacles)
        if self.policy_spec is not None:
            self.policy_spec.check_game(self.policy_spec.team, counts, 'the env_config spec')
        self.frame_skip = self.policy_spec.frame_skip if self.policy_spec is not None else 1
        self.camera_agents = [f'camera_{i}' for i in range(env.num_cameras)]
        self.target_agents = [f'target_{i}' for i in range(env.num_targets)]
        controls = {'camera': (True, False), 'target': (False, True), 'both': (True, True)}[self.team]
        self._controls = controls
        self.possible_agents = (self.camera_agents if controls[0] else []) + (self.target_agents if controls[1] else [])
        self.agents = []
        self._opponent_team = None
        if self.team != 'both':
            opponent_team = 'target' if self.team == 'camera' else 'camera'
            self._opponent_team = _opponent(config.get('opponent', 'greedy'), opponent_team, env)
        rescale = config.get('rescale_observations', True)
        self._scales = [self._scale(env.camera_observation_space, rescale),
                        self._scale(env.target_observation_space, rescale)]
        self.observation_spaces, self.action_spaces = {}, {}
        for team, agents, obs_space, act_space, scale in (
                (0, self.camera_agents, env.camera_observation_space, env.camera_action_space, self._scales[0]),
                (1, self.target_agents, env.target_observation_space, env.target_action_space, self._scales[1])):
            if not controls[team]:
                continue
            if self.policy_spec is not None:
                obs_box = spaces.Box(-np.inf, np.inf, (self.policy_spec.obs_dim,), dtype=np.float32)
                act_box = spaces.Discrete(self.policy_spec.choices)
            else:
                obs_box = spaces.Box((obs_space.low / scale).astype(np.float32),
                                     (obs_space.high / scale).astype(np.float32), dtype=np.float32)
                act_box = spaces.Box(act_space.low.astype(np.float32), act_space.high.astype(np.float32),
                                     dtype=np.float32)
            for agent in agents:
                self.observation_spaces[agent], self.action_spaces[agent] = obs_box, act_box
        self._row_seeding = None
        if 'seed' in config:
            self._row_seeding = (int(config['seed']), int(worker_index), int(config.get('envs_per_runner', 1)))
        self._joint_obs = None
        self._joint_infos = (None, None)
        self._episode = _EpisodeSums()

    @staticmethod
    def _scale(box: spaces.Box, rescale: bool) -> np.ndarray:
        bound = np.maximum(np.abs(box.low), np.abs(box.high))
        if not rescale:
            return np.ones_like(bound)
        return np.where(np.isfinite(bound) & (bound > 0), bound, 1.0)

    def _row_seed(self, seed: int | None) -> int | None:
        """The seed of the env's first episode in a run seeded by rows (env_config `seed`; class docstring)."""
        if seed is None or self._row_seeding is None:
            return seed
        base, worker, per_runner = self._row_seeding
        index = int(seed) - base - worker
        if not 0 <= index < per_runner:
            return seed             # not RLlib's seed of a sub-env: taken as it is
        return base + (worker - 1) * per_runner + index if worker >= 1 else base + index

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        seed = self._row_seed(seed)
        super().reset(seed=seed, options=options)
        self._joint_obs, infos = self.env.reset(seed=seed, options=options)
        self._joint_infos = (None, None)  # agents see no infos before their first step
        if self._opponent_team is not None:
            other = 1 if self.team == 'camera' else 0
            self._opponent_team.reset(self.env, self._joint_obs[other], seed)
        self.agents = list(self.possible_agents)
        self._episode = _EpisodeSums()
        return self._observations(), {agent: {} for agent in self.agents}

    def _own_actions(self, action_dict: dict) -> list[np.ndarray]:
        """The controlled teams' env actions (Nc, 2), (Nt, 2) of RLlib's actions (validated, before any env step)."""
        joint_actions = [np.zeros((self.env.num_cameras, 2)), np.zeros((self.env.num_targets, 2))]
        chosen = {}
        for agent, action in action_dict.items():
            if agent not in self.action_spaces:
                raise ValueError(f'unknown agent {agent!r}; the agents are {", ".join(self.possible_agents)}')
            team, index = agent.rsplit('_', 1)
            if self.policy_spec is None:
                joint_actions[team == 'target'][int(index)] = agent_action(agent, action,
                                                                           self.action_spaces[agent].shape)
            else:
                chosen[int(index)] = _grid_choice(agent, action, self.policy_spec.choices)
        if chosen:      # grid moves scaled by each agent's own step limits, as mate.learn decodes them
            team = 0 if self.policy_spec.team == 'camera' else 1
            raw = np.asarray(self._joint_obs[team], dtype=np.float64)
            held = np.zeros((len(raw), 1), dtype=np.int64)
            for index, choice in chosen.items():
                held[index, 0] = choice
            decoded = self.policy_spec.decode(held[None], raw[None])[0]
            for index in chosen:
                joint_actions[team][index] = decoded[index]
        return joint_actions

    def step(self, action_dict: dict):
        own = self._own_actions(action_dict)
        other = None if self._opponent_team is None else (1 if self.team == 'camera' else 0)
        rewards_sum = [0.0, 0.0]           # what each team learns from, summed over the decision's env steps
        coverage_sum, steps = 0.0, 0
        terminated = truncated = False
        for _ in range(self.frame_skip):
            joint_actions = list(own)
            if other is not None:
                joint_actions[other] = self._opponent_team.act(self.env, self._joint_obs[other],
                                                               self._joint_infos[other])
            self._joint_obs, (camera_reward, target_reward), terminated, truncated, self._joint_infos = \
                self.env.step(tuple(joint_actions))
            info = self._joint_infos[0][0] if self.env.num_cameras else self._joint_infos[1][0]
            steps += 1
            coverage_sum += info['coverage_rate']
            rewards_sum[0] += info['coverage_rate'] if self.reward == 'coverage' else float(camera_reward)
            rewards_sum[1] += float(target_reward)
            if terminated or truncated:
                break
        learner = 1 if self.team == 'target' else 0
        self._episode.learner_return += rewards_sum[learner]
        shared = {key: info[key] for key in ('coverage_rate', 'real_coverage_rate', 'mean_transport_rate',
                                             'num_delivered_cargoes')}
        shared['decision_coverage_rate'] = coverage_sum / steps
        shared.update(self._episode.summary(info, int(self.env.episode_step), self.env.max_target_team_episode_reward))
        rewards = {agent: rewards_sum[0] for agent in self.possible_agents if agent.startswith('camera_')}
        rewards.update({agent: rewards_sum[1] for agent in self.possible_agents if agent.startswith('target_')})
        terminateds = dict.fromkeys(self.possible_agents, bool(terminated))
        truncateds = dict.fromkeys(self.possible_agents, bool(truncated))
        terminateds['__all__'], truncateds['__all__'] = bool(terminated), bool(truncated)
        if terminated or truncated:
            self.agents = []
        infos = {agent: dict(shared) for agent in self.possible_agents}
        return self._observations(), rewards, terminateds, truncateds, infos

    def _observations(self) -> dict[str, np.ndarray]:
        out = {}
        for team, agents in ((0, self.camera_agents), (1, self.target_agents)):
            if self._controls[team]:
                if self.policy_spec is not None:
                    features = self.policy_spec.features(np.asarray(self._joint_obs[team], dtype=np.float64))
                else:
                    features = self._joint_obs[team] / self._scales[team]
                out.update(zip(agents, np.asarray(features, dtype=np.float32), strict=True))
        return out

    @property
    def raw_observations(self) -> tuple[np.ndarray, np.ndarray]:
        """Both teams' raw joint observations (Nc, D_c), (Nt, D_t) of the current step, before any rescaling or
        features (do not modify)."""
        return self._joint_obs

    def render(self):
        return self.env.render()

    def close(self) -> None:
        self.env.close()


class _EpisodeSums:
    """The learner's return summed over an episode; the game's own statistics are the core's (the env's infos)."""

    def __init__(self) -> None:
        self.learner_return = 0.0

    def summary(self, info: dict, length: int, max_target_reward: float) -> dict:
        """The episode so far: the core's statistics from the env's last `info` and its `length` in env steps."""
        return dict(episode_coverage_rate=info['episode_coverage_rate'], episode_length=length,
                    episode_return=self.learner_return,
                    episode_normalized_target_return=info['episode_target_return'] / max_target_reward)


SPEC_SUPPORTED = "grid actions, an MLP network, no --memory, --velocity or --full-observability"


def _env_spec(config: dict) -> PolicySpec | None:
    """The PolicySpec of an env_config (None without 'spec'); ValueError for a spec this env cannot play."""
    if 'spec' not in config:
        return None
    spec = config['spec']
    if isinstance(spec, dict):
        spec = PolicySpec.from_dict(spec)
    if not isinstance(spec, PolicySpec):
        raise ValueError(f"env_config 'spec' must be a PolicySpec or its to_dict(), got {type(spec).__name__}")
    if 'rescale_observations' in config:
        raise ValueError("env_config 'rescale_observations' does not go with 'spec' (the observations are the "
                         "spec's features)")
    if 'team' in config and config['team'] != spec.team:
        raise ValueError(f"env_config team {config['team']!r} differs from the spec's team {spec.team!r}")
    unsupported = [name for name, bad in (('action ' + repr(spec.action), spec.action != 'grid'),
                                          ('memory', bool(spec.memory)), ('velocity', spec.velocity),
                                          ('full_observability', spec.full_observability),
                                          ('lstm', spec.lstm > 0)) if bad]
    if unsupported:
        raise SpecError(f'the RLlib env plays specs with {SPEC_SUPPORTED}; this one has {unsupported[0]}')
    return spec


def _grid_choice(agent: str, action, choices: int) -> int:
    """An agent's grid move index in [0, choices); ValueError naming the agent and the range otherwise."""
    array = np.asarray(action)
    if array.shape not in ((), (1,)) or not np.issubdtype(array.dtype, np.integer) and not (
            np.issubdtype(array.dtype, np.floating) and float(array.reshape(-1)[0]).is_integer()):
        raise ValueError(f'action of {agent} must be an integer in [0, {choices - 1}] (a grid move); got {action!r}')
    value = int(array.reshape(-1)[0])
    if not 0 <= value < choices:
        raise ValueError(f'action of {agent} must be an integer in [0, {choices - 1}] (a grid move); got {value}')
    return value


class MateMetricsCallback(RLlibCallback):
    """Logs, on the env runners, what `mate rllib-train` reads back from each iteration's results:

    * at each episode's end: `mate/coverage_rate` (episode mean) and `mate/delivered_cargoes` (means over the
      recent episodes), and `mate/episodes`, the list of the iteration's finished episodes (`coverage`, `return`,
      `raw_return`: the normalised target return, `length` in env steps), the episodes `mate.learn.Run` logs;
    * at each step: `mate/decision_coverage_sum` and `mate/decisions` (sums over the iteration), whose ratio is
      the iteration's mean coverage per decision (`rollout_coverage` of `progress.csv`).
    """

    @staticmethod
    def _last_info(episode) -> dict | None:
        last = episode.get_infos(-1)
        return next((value for value in last.values() if value), None) if isinstance(last, dict) else None

    def on_episode_step(self, *, episode, metrics_logger=None, **kwargs) -> None:
        info = self._last_info(episode) if metrics_logger is not None else None
        if info and 'decision_coverage_rate' in info:
            metrics_logger.log_value('mate/decision_coverage_sum', info['decision_coverage_rate'], reduce='sum')
            metrics_logger.log_value('mate/decisions', 1, reduce='sum')

    def on_episode_end(self, *, episode, metrics_logger=None, **kwargs) -> None:
        info = self._last_info(episode) if metrics_logger is not None else None
        if info:
            metrics_logger.log_value('mate/coverage_rate', info['episode_coverage_rate'], reduce='mean')
            metrics_logger.log_value('mate/delivered_cargoes', info['num_delivered_cargoes'], reduce='mean')
            if 'episode_length' in info:
                metrics_logger.log_value('mate/episodes', {
                    'coverage': float(info['episode_coverage_rate']), 'return': float(info['episode_return']),
                    'raw_return': float(info['episode_normalized_target_return']),
                    'length': int(info['episode_length'])}, reduce='item_series')


# --------------------------------------------------------------------------- training setup
def register(name: str = ENV_NAME) -> str:
    """Register `MateMultiAgentEnv` in Ray Tune's registry under `name` (returned); each env learns the index of
    the env runner that builds it (`worker_index`, for `seed`-by-rows seeding)."""
    from ray.tune.registry import register_env

    def make(env_config):
        return MateMultiAgentEnv(dict(env_config), worker_index=int(getattr(env_config, 'worker_index', 0) or 0))

    register_env(name, make)
    return name


def policy_mapping_fn(agent_id: str, episode=None, **kwargs) -> str:
    """One shared policy per team: 'camera' or 'target'."""
    return agent_id.split('_', 1)[0]


def _per_agent_mapping_fn(agent_id: str, episode=None, **kwargs) -> str:
    return agent_id


def _schedule(value):
    """An RLlib value or schedule: a number, or [[step, value], ...] (a single point is its value)."""
    if isinstance(value, (int, float)):
        return float(value)
    points = [[int(step), float(v)] for step, v in value]
    if points[0][0] != 0:
        raise ValueError(f'an RLlib schedule must start at step 0, got {points[0][0]} ({points})')
    return points[0][1] if len(points) == 1 else points


def ppo_config(env_config: dict | None = None, *, policy_per_agent: bool = False, num_env_runners: int = 0,
               train_batch_size: int = 4000, minibatch_size: int = 500, num_epochs: int = 5, lr=3e-4,
               gamma: float = 0.99, hidden: tuple[int, ...] = (256, 256), seed: int | None = None,
               num_envs_per_env_runner: int = 1, rollout_fragment_length: int | str = 'auto',
               activation: str = 'tanh', vf_share_layers: bool | None = None, **training: Any):
    """A PPO `AlgorithmConfig` (new API stack) for the teams RLlib controls in `env_config`.

    Policies: one shared policy per controlled team ('camera', 'target'), or one per agent
    (`policy_per_agent`). Rollouts run on `num_env_runners` remote workers (0: on the driver), each
    with `num_envs_per_env_runner` envs. `lr` is a number or a schedule `[[step, lr], ...]` (RLlib
    interpolates linearly between the points, in env steps sampled). The MLP of the module has the
    widths `hidden` and the `activation`; `vf_share_layers` (None: RLlib's default, shared) gives the
    value function the policy's layers or its own. `training`: more keywords of `PPOConfig.training`
    (`lambda_`, `clip_param`, `kl_coeff`, `entropy_coeff` (a number or a schedule), ...).
    """
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    env_config = dict(env_config or {})
    probe = MateMultiAgentEnv(env_config)
    if policy_per_agent:
        policies, mapping = set(probe.possible_agents), _per_agent_mapping_fn
    else:
        policies, mapping = {policy_mapping_fn(agent) for agent in probe.possible_agents}, policy_mapping_fn
    probe.close()
    if 'entropy_coeff' in training:
        training['entropy_coeff'] = _schedule(training['entropy_coeff'])
    model = dict(fcnet_hiddens=list(hidden), fcnet_activation=activation)
    if vf_share_layers is not None:
        model['vf_share_layers'] = bool(vf_share_layers)
    config = (
        PPOConfig()
        .environment(register(), env_config=env_config)
        .env_runners(num_env_runners=num_env_runners, num_envs_per_env_runner=num_envs_per_env_runner,
                     rollout_fragment_length=rollout_fragment_length)
        .multi_agent(policies=policies, policy_mapping_fn=mapping, policies_to_train=sorted(policies))
        .training(train_batch_size_per_learner=train_batch_size, minibatch_size=minibatch_size,
                  num_epochs=num_epochs, lr=_schedule(lr), gamma=gamma, **training)
        .rl_module(model_config=DefaultModelConfig(**model))
        .callbacks(MateMetricsCallback)
    )
    if seed is not None:
        config = config.debugging(seed=seed)
    return config


def train(env_config: dict | None = None, iterations: int = 10, *, address: str | None = None,
          num_cpus: int | None = None, checkpoint_dir: str | None = None, progress: Callable | None = None,
          **ppo_kwargs: Any) -> list[dict]:
    """Train PPO for `iterations` iterations; returns one summary dict per iteration.

    Ray: connects to the cluster at `address` ('auto', 'ray://host:10001', ...) or starts a local
    instance with `num_cpus` CPUs (default: all); an already initialised Ray is used as it is.
    `progress(summary)` is called after each iteration; `checkpoint_dir` receives the final
    algorithm checkpoint. `ppo_kwargs` go to `ppo_config`.
    """
    import logging

    import ray

    started = not ray.is_initialized()
    if started:
        ray.init(address=address or 'local', num_cpus=None if address else num_cpus, include_dashboard=False,
                 logging_level=logging.WARNING)
    try:
        algo = ppo_config(env_config, **ppo_kwargs).build_algo()
        summaries = []
        for _ in range(iterations):
            result = algo.train()
            runners = result.get('env_runners', {})
            summary = {
                'iteration': result['training_iteration'],
                'env_steps': int(runners.get('num_env_steps_sampled_lifetime', 0)),
                'episodes': int(runners.get('num_episodes_lifetime', 0)),
                'returns': {policy: float(value) for policy, value in
                            runners.get('module_episode_returns_mean', {}).items()},
                'coverage_rate': float(runners.get('mate/coverage_rate', np.nan)),
                'delivered_cargoes': float(runners.get('mate/delivered_cargoes', np.nan)),
                'seconds': float(result.get('time_this_iter_s', np.nan)),
            }
            summaries.append(summary)
            if progress is not None:
                progress(summary)
        if checkpoint_dir is not None:
            summaries[-1]['checkpoint'] = str(algo.save_to_path(checkpoint_dir)) if summaries else None
        algo.stop()
        return summaries
    finally:
        if started:
            ray.shutdown()


# --------------------------------------------------------------------------- the witness: a mate.learn run
LEARNER_COLUMNS = {'default_optimizer_learning_rate': 'lr', 'curr_entropy_coeff': 'entropy_coef',
                   'policy_loss': 'policy_loss', 'vf_loss': 'value_loss', 'entropy': 'entropy',
                   'mean_kl_loss': 'approx_kl', 'curr_kl_coeff': 'kl_coeff', 'vf_explained_var': 'explained_variance'}
"""RLlib's learner results -> the `progress.csv` columns (named as `mate train`'s where both have them)."""


def witness_env_config(config, spec: PolicySpec) -> dict:
    """The env_config of a `mate rllib-train` run (`config`: `mate.integrations.rllib_train.RLlibPPOConfig`): the
    spec's observations, grid moves and frame skip; the training horizon; the batched greedy opponent (the one
    `mate train` and the evaluations play); cameras learn the coverage rate, targets the team reward; the games
    seeded by rows."""
    return {'spec': spec.to_dict(), 'overrides': {'max_episode_steps': config.resolved_horizon},
            'opponent': 'batched-greedy', 'reward': 'coverage' if spec.team == 'camera' else 'team',
            'seed': config.seed, 'envs_per_runner': config.envs_per_runner}


def witness_ppo_config(config, spec: PolicySpec):
    """RLlib's `PPOConfig` of a `mate rllib-train` run: one policy shared by the team (policy id = the team), a
    batch of num_envs x rollout_length decisions per iteration (sampled as rollout_length decisions of every env),
    minibatches of `minibatch_size` agent steps, the hyper-parameters of `config`."""
    kl = dict(use_kl_loss=config.kl_coeff > 0, kl_coeff=config.kl_coeff, kl_target=config.kl_target)
    return ppo_config(
        witness_env_config(config, spec), num_env_runners=config.num_env_runners,
        num_envs_per_env_runner=config.envs_per_runner, rollout_fragment_length=config.rollout_length,
        train_batch_size=config.num_envs * config.rollout_length, minibatch_size=config.minibatch_size,
        num_epochs=config.epochs, lr=config.lr_schedule, gamma=config.gamma, hidden=config.hidden,
        activation=config.activation, vf_share_layers=config.vf_share_layers, seed=config.seed,
        lambda_=config.gae_lambda, clip_param=config.clip, vf_clip_param=config.vf_clip,
        vf_loss_coeff=config.value_coef, entropy_coeff=config.entropy_schedule,
        grad_clip=config.max_grad_norm or None, **kl)


def _iteration_summary(result: dict, module_id: str) -> tuple[int, list, list[dict], dict]:
    """(decisions sampled, rollout coverage, finished episodes, learner columns) of one `algo.train()` result."""
    runners = result.get('env_runners', {})
    steps = int(runners.get('num_env_steps_sampled', 0))
    decisions = float(runners.get('mate/decisions', 0) or 0)
    coverage = [float(runners.get('mate/decision_coverage_sum', 0.0)) / decisions] if decisions else [math.nan]
    episodes = runners.get('mate/episodes', [])
    if isinstance(episodes, dict):     # RLlib's results give a series of one item as the item itself
        episodes = [episodes]
    if not isinstance(episodes, list):
        episodes = []
    episodes = [dict(episode) for episode in episodes if isinstance(episode, dict)]
    learner = result.get('learners', {}).get(module_id, {})
    columns = {name: float(learner[key]) for key, name in LEARNER_COLUMNS.items() if key in learner}
    return steps, coverage, episodes, columns


def train_run(config, console=None, callback=None):
    """Train RLlib's PPO as `config` (`mate.integrations.rllib_train.RLlibPPOConfig`) says, as a `mate.learn.Run`:
    `progress.csv`, `best.pt`, `final.pt` and, with `eval_every`, the evaluation protocol of `mate train`
    (`evaluations.jsonl`, `best-eval.pt`, `absolute.json`), every policy exported from the RLlib module
    (`mate.integrations.rllib_export`). `checkpoint.pt` holds the RLlib algorithm's state (`algo.get_state()`, as
    plain data) beside the run's; the same call continues from it. Ray: an initialised Ray is used as it is,
    else one is started (`config.address`, `config.num_cpus`). Returns the `Run`."""
    import logging

    import ray
    import torch

    from ..policies.checkpoint import CheckpointError
    from ..learn.run import Run
    from .rllib_export import actor_state_of_module

    spec = config.witness_spec()
    run = Run.of(config, spec.algo, spec, callback=callback, console=console)
    state = run.resume()
    if state is not None and 'rllib_state' not in state:
        raise CheckpointError(f'checkpoint {str(run.checkpoint_path)!r} holds no RLlib state (written by another '
                              'version of mate rllib-train): start over with --fresh')
    if config.threads:
        torch.set_num_threads(config.threads)
    started = not ray.is_initialized()
    if started:
        ray.init(address=config.address or 'local', num_cpus=None if config.address else config.num_cpus,
                 include_dashboard=False, logging_level=logging.WARNING, log_to_driver=False)
    algo = None
    try:
        algo = witness_ppo_config(config, spec).build_algo()
        if state is not None:
            algo.set_state(state['rllib_state'])
            if state.get('kl_coeff') is not None:     # RLlib's state leaves it out
                _set_kl_coefficient(algo, spec.team, state['kl_coeff'])

        def actor() -> dict:
            return actor_state_of_module(algo.get_module(spec.team), spec)

        def save() -> dict:
            # RLlib's whole state (modules, optimizers, counters, connectors) as plain data in checkpoint.pt, read
            # back with torch's weights-only loader: RLlib's own checkpoint directories are pickles
            return {'rllib_state': algo.get_state(), 'kl_coeff': _kl_coefficient(algo, spec.team)}

        with run:
            while run.running() and (config.iterations is None or run.iteration < config.iterations):
                result = algo.train()
                steps, coverage, episodes, columns = _iteration_summary(result, spec.team)
                status = f"entropy {columns['entropy']:.2f}" if 'entropy' in columns else ''
                run.end_iteration(steps, coverage, episodes, columns, status=status, actor=actor, save=save)
        run.finish(save(), actor())
    finally:
        if algo is not None:
            algo.stop()
        if started:
            ray.shutdown()
    return run


def _kl_coefficient(algo, module_id: str) -> float | None:
    """The current coefficient of the adaptive KL penalty of `module_id` (the learners agree; None without one)."""
    results = algo.learner_group.foreach_learner(
        lambda learner: float(learner.curr_kl_coeffs_per_module[module_id]) if learner.config.use_kl_loss else None)
    values = [result.get() for result in results]
    return values[0] if values else None


def _set_kl_coefficient(algo, module_id: str, value: float) -> None:
    """Set the adaptive KL coefficient of `module_id` on every learner (after a restore: RLlib does not save it)."""
    def fill(learner) -> None:
        learner.curr_kl_coeffs_per_module[module_id].data.fill_(float(value))

    for result in algo.learner_group.foreach_learner(fill):
        result.get()
