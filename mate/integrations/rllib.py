"""MATE as a Ray RLlib `MultiAgentEnv` (new API stack), and a PPO setup for the camera team.

    from mate.integrations import rllib as mate_rllib
    mate_rllib.register()                                   # RLlib env name 'mate'
    config = mate_rllib.ppo_config({'config': 'MATE-4v4-9', 'opponent': 'greedy'})
    algo = config.build_algo()
    print(algo.train()['env_runners']['episode_return_mean'])

The class docstring of `MateMultiAgentEnv` describes the env: its env_config keys, agents, spaces,
rewards, episode end and infos (`help(MateMultiAgentEnv)`, or the API page of the docs).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

import numpy as np
from gymnasium import spaces
from ray.rllib.callbacks.callbacks import RLlibCallback
from ray.rllib.env.multi_agent_env import MultiAgentEnv

from ..env import MultiAgentTracking, agent_action

__all__ = ['ENV_NAME', 'MateMultiAgentEnv', 'MateMetricsCallback', 'register', 'ppo_config', 'policy_mapping_fn',
           'train']

ENV_NAME = 'mate'
"""The name `register()` gives the env in Ray's registry."""

ENV_CONFIG_KEYS = ('config', 'overrides', 'team', 'opponent', 'rescale_observations')
TEAMS = ('camera', 'target', 'both')
RULE_BASED = {'greedy': 'Greedy', 'naive': 'Naive', 'random': 'Random'}


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


def _opponent(spec, team: str, env: MultiAgentTracking):
    """The opponent team policy for `team` ('camera' or 'target', the opponent's own team)."""
    count = env.num_cameras if team == 'camera' else env.num_targets
    box = env.camera_action_space if team == 'camera' else env.target_action_space
    if isinstance(spec, str):
        if spec == 'uniform':
            return _UniformTeam(box, count)
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
            raise ValueError(f'unknown opponent {spec!r}: use one of {", ".join([*RULE_BASED, "uniform"])}, '
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

    - `config`: a preset name, a YAML/JSON path or a dict (default `'MATE-4v8-9'`).
    - `overrides`: a dict deep-merged into the configuration (e.g. `{'max_episode_steps': 500}`).
    - `team`: `'camera'` (default), `'target'` or `'both'`: the agents RLlib controls.
    - `opponent`: the other team (ignored for `'both'`). `'greedy'` (default), `'naive'`, `'random'`:
      the rule-based agents of `mate.agents`, spawned one per slot and driven with `group_reset` /
      `group_step`, messages included; `'uniform'`: i.i.d. uniform actions (built in);
      `'package.module:name'`: imported, then as below; an agent instance or class of `mate.agents`;
      or any callable `f(joint_obs (N, D)) -> actions (N, 2)`. `reset(seed=s)` reseeds the opponent.
    - `rescale_observations`: divide every observation entry by its finite space bound (default
      True): coordinates / 2000, angles / 180, flags and counts unchanged.

    **Agents.** `camera_0 .. camera_{Nc-1}`, `target_0 .. target_{Nt-1}`: those of the controlled
    team(s), in `possible_agents`.

    **Action space.** `action_spaces[agent]` is a float32 `Box(2)`: `[rotate, zoom]` in degrees for a
    camera, a displacement `[dx, dy]` for a target. An agent's action must have that shape `(2,)`
    (any real dtype); another shape raises a `ValueError` naming the agent and the expected shape
    (nothing is reshaped). Out-of-bounds values are clipped by the core; an agent missing from the
    action dict stays still.

    **Observation space.** `observation_spaces[agent]` is a float32 `Box` of the team's observation
    layout (`mate.spaces`), rescaled as `rescale_observations` says.

    **Rewards.** The team reward, repeated for each agent of the team (zero-sum between the teams).

    **Episode end.** The whole team ends together: `terminateds` / `truncateds` hold every agent and
    `'__all__'`; terminated once every cargo unit is delivered, truncated at `max_episode_steps`.

    **infos.** Per agent: `coverage_rate`, `real_coverage_rate`, `mean_transport_rate` and
    `num_delivered_cargoes` of the step, and `episode_coverage_rate` (the mean over the episode so
    far). `reset` returns empty infos.

    Args:
        config: the env_config dict (keys above); None or `{}` for every default. Unknown keys
            raise `ValueError`.
    """

    def __init__(self, config: dict | None = None) -> None:
        super().__init__()
        config = dict(config or {})
        unknown = set(config) - set(ENV_CONFIG_KEYS)
        if unknown:
            raise ValueError(f'unknown env_config keys {sorted(unknown)}; known keys: {", ".join(ENV_CONFIG_KEYS)}')
        self.team = config.get('team', 'camera')
        if self.team not in TEAMS:
            raise ValueError(f'team must be one of {TEAMS}, got {self.team!r}')
        self.env = env = MultiAgentTracking(config.get('config', 'MATE-4v8-9'), **config.get('overrides', {}))
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
            obs_box = spaces.Box((obs_space.low / scale).astype(np.float32),
                                 (obs_space.high / scale).astype(np.float32), dtype=np.float32)
            act_box = spaces.Box(act_space.low.astype(np.float32), act_space.high.astype(np.float32), dtype=np.float32)
            for agent in agents:
                self.observation_spaces[agent], self.action_spaces[agent] = obs_box, act_box
        self._joint_obs = None
        self._joint_infos = (None, None)
        self._coverage_sum = 0.0
        self._steps = 0

    @staticmethod
    def _scale(box: spaces.Box, rescale: bool) -> np.ndarray:
        bound = np.maximum(np.abs(box.low), np.abs(box.high))
        if not rescale:
            return np.ones_like(bound)
        return np.where(np.isfinite(bound) & (bound > 0), bound, 1.0)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed, options=options)
        self._joint_obs, infos = self.env.reset(seed=seed, options=options)
        self._joint_infos = (None, None)  # agents see no infos before their first step
        if self._opponent_team is not None:
            other = 1 if self.team == 'camera' else 0
            self._opponent_team.reset(self.env, self._joint_obs[other], seed)
        self.agents = list(self.possible_agents)
        self._coverage_sum, self._steps = 0.0, 0
        return self._observations(), {agent: {} for agent in self.agents}

    def step(self, action_dict: dict):
        joint_actions = [np.zeros((self.env.num_cameras, 2)), np.zeros((self.env.num_targets, 2))]
        for agent, action in action_dict.items():
            if agent not in self.action_spaces:
                raise ValueError(f'unknown agent {agent!r}; the agents are {", ".join(self.possible_agents)}')
            team, index = agent.rsplit('_', 1)
            joint_actions[team == 'target'][int(index)] = agent_action(agent, action, self.action_spaces[agent].shape)
        if self._opponent_team is not None:
            other = 1 if self.team == 'camera' else 0
            joint_actions[other] = self._opponent_team.act(self.env, self._joint_obs[other], self._joint_infos[other])
        self._joint_obs, (camera_reward, target_reward), terminated, truncated, self._joint_infos = self.env.step(
            tuple(joint_actions))
        info = self._joint_infos[0][0] if self.env.num_cameras else self._joint_infos[1][0]
        self._steps += 1
        self._coverage_sum += info['coverage_rate']
        shared = {key: info[key] for key in ('coverage_rate', 'real_coverage_rate', 'mean_transport_rate',
                                             'num_delivered_cargoes')}
        shared['episode_coverage_rate'] = self._coverage_sum / self._steps
        rewards = {agent: float(camera_reward) for agent in self.possible_agents if agent.startswith('camera_')}
        rewards.update({agent: float(target_reward) for agent in self.possible_agents if agent.startswith('target_')})
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
                scaled = (self._joint_obs[team] / self._scales[team]).astype(np.float32)
                out.update(zip(agents, scaled, strict=True))
        return out

    def render(self):
        return self.env.render()

    def close(self) -> None:
        self.env.close()


class MateMetricsCallback(RLlibCallback):
    """Logs `mate/coverage_rate` (episode mean) and `mate/delivered_cargoes` at each episode's end."""

    def on_episode_end(self, *, episode, metrics_logger=None, **kwargs) -> None:
        if metrics_logger is None:
            return
        last = episode.get_infos(-1)
        info = next((value for value in last.values() if value), None) if isinstance(last, dict) else None
        if info:
            metrics_logger.log_value('mate/coverage_rate', info['episode_coverage_rate'], reduce='mean')
            metrics_logger.log_value('mate/delivered_cargoes', info['num_delivered_cargoes'], reduce='mean')


# --------------------------------------------------------------------------- training setup
def register(name: str = ENV_NAME) -> str:
    """Register `MateMultiAgentEnv` in Ray Tune's registry under `name` (returned)."""
    from ray.tune.registry import register_env

    register_env(name, lambda env_config: MateMultiAgentEnv(dict(env_config)))
    return name


def policy_mapping_fn(agent_id: str, episode=None, **kwargs) -> str:
    """One shared policy per team: 'camera' or 'target'."""
    return agent_id.split('_', 1)[0]


def _per_agent_mapping_fn(agent_id: str, episode=None, **kwargs) -> str:
    return agent_id


def ppo_config(env_config: dict | None = None, *, policy_per_agent: bool = False, num_env_runners: int = 0,
               train_batch_size: int = 4000, minibatch_size: int = 500, num_epochs: int = 5, lr: float = 3e-4,
               gamma: float = 0.99, hidden: tuple[int, ...] = (256, 256), seed: int | None = None):
    """A PPO `AlgorithmConfig` (new API stack) for the teams RLlib controls in `env_config`.

    Policies: one shared policy per controlled team ('camera', 'target'), or one per agent
    (`policy_per_agent`). Rollouts run on `num_env_runners` remote workers (0: on the driver).
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
    config = (
        PPOConfig()
        .environment(register(), env_config=env_config)
        .env_runners(num_env_runners=num_env_runners, num_envs_per_env_runner=1)
        .multi_agent(policies=policies, policy_mapping_fn=mapping, policies_to_train=sorted(policies))
        .training(train_batch_size_per_learner=train_batch_size, minibatch_size=minibatch_size,
                  num_epochs=num_epochs, lr=lr, gamma=gamma)
        .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=list(hidden), fcnet_activation='tanh'))
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
        ray.init(address=address, num_cpus=None if address else num_cpus, include_dashboard=False,
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
