"""MATE as a PettingZoo environment: `parallel_env()` (Parallel API) and `env()` (AEC API).

    from mate.integrations import pettingzoo as mate_pz
    env = mate_pz.parallel_env(config='MATE-4v8-9', max_cycles=500)
    observations, infos = env.reset(seed=0)
    while env.agents:
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)

Agents: `camera_0 .. camera_{Nc-1}` then `target_0 .. target_{Nt-1}` (slot order of the single
env's joint observations and actions). Every agent acts every step (simultaneous moves); in
the AEC version (`parallel_to_aec`) agents take turns in that order and the world advances
once all of them have acted (an action of the wrong shape is refused at its agent's turn).

Spaces: each agent has its own space objects, built once (`observation_space(agent)` returns
the same object every call; seeding one agent's space leaves the others alone). Observations
are float64 vectors of the layouts in `mate.spaces`; a camera acts with (rotation, zoom) in
degrees, a target with a displacement (dx, dy): one agent's action is an array (or sequence) of
the shape of its action space, (2,), in any real dtype; any other shape raises a ValueError naming
the agent and the expected shape (nothing is reshaped). An agent missing from the actions dict
stays still (a zero action). `state()` is the global state vector, `state_space` its Box.

Rewards: team rewards, repeated for every agent of the team (camera reward == -target reward).
infos: the single env's per-agent info dicts (coverage_rate, raw_reward, messages, ...).

Episode end: every agent terminates when all cargo is delivered and is truncated at the
configuration's `max_episode_steps` or after `max_cycles` steps, whichever comes first; then
`agents` is empty until the next reset.

Rendering: `render_mode` is passed to the single env and `render()` delegates to it.

One team against a built-in opponent: `parallel_env(..., opponent='greedy', team='camera')` makes only that team's
agents (`camera_0 ..`), and plays the other team inside with a batched team of `mate.teams` (an agent name with a
batched form, or a factory `f(num_envs, counts, seed)` as `mate.SingleTeamVecEnv` takes). `reset(seed=s)` seeds the
opponent with s too, so the game is the one `mate.SingleTeamVecEnv`, `mate evaluate --seed s` and the `MultiCamera`
wrapper play for that seed. `reward` chooses the agents' rewards as `mate.SingleTeamVecEnv` does: 'team' (the team
reward, repeated), 'coverage' (cameras), or per agent, 'own' (targets: each target's own part of the team reward)
and 'difference' (cameras: each camera's marginal share of the coverage rate).
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec_wrapper
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from ..envs.multi_agent_tracking import MultiAgentTracking, agent_action
from ..messages import Team

__all__ = ['MateParallelEnv', 'parallel_env', 'env', 'raw_env']


class MateParallelEnv(ParallelEnv):
    """The Parallel API over one `MultiAgentTracking` env (`self.env`)."""

    metadata = {
        'name': 'mate_v0',
        'render_modes': list(MultiAgentTracking.metadata.get('render_modes', [])),
        'render_fps': MultiAgentTracking.metadata.get('render_fps', 60),
        'is_parallelizable': True,
    }

    def __init__(self, config: Any = 'MATE-4v8-9', render_mode: str | None = None, max_cycles: int | None = None,
                 opponent=None, team: str | None = None, reward: str = 'team', **overrides: Any) -> None:
        if max_cycles is not None and (not isinstance(max_cycles, (int, np.integer)) or max_cycles < 1):
            raise ValueError(f'max_cycles must be a positive integer or None, got {max_cycles!r}')
        if opponent is None and (team is not None or reward != 'team'):
            raise ValueError('team and reward choose the side played against an opponent: give opponent too '
                             "(e.g. opponent='greedy')")
        self.env = MultiAgentTracking(config, render_mode=render_mode, **overrides)
        self.render_mode = render_mode
        self.max_cycles = max_cycles
        nc, nt = self.env.num_cameras, self.env.num_targets
        self.camera_agents = [f'camera_{i}' for i in range(nc)]
        self.target_agents = [f'target_{i}' for i in range(nt)]
        self.opponent = None if opponent is None else _Opponent(self.env, opponent, team or 'camera', reward)
        if self.opponent is not None:
            self.camera_agents, self.target_agents = ((self.camera_agents, []) if self.opponent.team is Team.CAMERA
                                                      else ([], self.target_agents))
        self.possible_agents = self.camera_agents + self.target_agents
        self.agents: list[str] = []
        self._index = {agent: i for i, agent in enumerate(self.camera_agents)}
        self._index.update({agent: i for i, agent in enumerate(self.target_agents)})
        team_spaces = [(self.camera_agents, self.env.camera_observation_space, self.env.camera_action_space),
                       (self.target_agents, self.env.target_observation_space, self.env.target_action_space)]
        self.observation_spaces = {a: copy.deepcopy(obs) for agents, obs, _ in team_spaces for a in agents}
        self.action_spaces = {a: copy.deepcopy(act) for agents, _, act in team_spaces for a in agents}
        self.state_space = copy.deepcopy(self.env.state_space)
        self._camera_actions = np.zeros((nc, 2))
        self._target_actions = np.zeros((nt, 2))
        self.num_cycles = 0

    def observation_space(self, agent: str):
        return self.observation_spaces[agent]

    def action_space(self, agent: str):
        return self.action_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None):
        (camera_obs, target_obs), (camera_infos, target_infos) = self.env.reset(seed=seed, options=options)
        self.agents = list(self.possible_agents)
        self.num_cycles = 0
        if self.opponent is not None:
            self.opponent.reset(seed, camera_obs, target_obs)
        return self._per_agent(camera_obs, target_obs), self._per_agent(camera_infos, target_infos)

    def step(self, actions: dict[str, Any]):
        if not self.agents:
            raise RuntimeError('every agent is done: call reset() before step()')
        self._camera_actions[:] = 0.0
        self._target_actions[:] = 0.0
        for agent, action in actions.items():
            if action is None:  # a done agent's turn in the AEC conversion
                continue
            if agent not in self.action_spaces:
                raise ValueError(f'unknown agent {agent!r}; the agents are {", ".join(self.possible_agents)}')
            team = self._camera_actions if agent.startswith('camera_') else self._target_actions
            team[self._index[agent]] = self._agent_action(agent, action)
        if self.opponent is not None:
            self.opponent.act(self._camera_actions, self._target_actions)
        (camera_obs, target_obs), (camera_reward, target_reward), terminated, truncated, infos = self.env.step(
            (self._camera_actions, self._target_actions))
        self.num_cycles += 1
        truncated = truncated or (self.max_cycles is not None and self.num_cycles >= self.max_cycles)
        observations = self._per_agent(camera_obs, target_obs)
        rewards = {**dict.fromkeys(self.camera_agents, float(camera_reward)),
                   **dict.fromkeys(self.target_agents, float(target_reward))}
        if self.opponent is not None:
            rewards = dict(zip(self.possible_agents, self.opponent.observed(
                camera_obs, target_obs, camera_reward if self.camera_agents else target_reward, infos).tolist(),
                               strict=True))
        terminations = dict.fromkeys(self.possible_agents, bool(terminated))
        truncations = dict.fromkeys(self.possible_agents, bool(truncated) and not terminated)
        infos = self._per_agent(*infos)
        if terminated or truncated:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def _agent_action(self, agent: str, action) -> np.ndarray:
        """One agent's action as a float64 array of its action space's shape; ValueError for another shape."""
        return agent_action(agent, action, self.action_spaces[agent].shape)

    def _per_agent(self, camera_values, target_values) -> dict[str, Any]:
        out = dict(zip(self.camera_agents, camera_values, strict=len(self.camera_agents) > 0))
        out.update(zip(self.target_agents, target_values, strict=len(self.target_agents) > 0))
        return out

    def state(self) -> np.ndarray:
        return self.env.state()

    def render(self):
        return self.env.render()

    def close(self) -> None:
        self.env.close()

    def __str__(self) -> str:
        return 'mate_v0'


class _Opponent:
    """The other team of a one-team PettingZoo env: a batched team of one row that acts inside `step`, and the
    own agents' rewards of the chosen kind."""

    def __init__(self, env: MultiAgentTracking, opponent, team, reward: str) -> None:
        from ..evaluation.protocol import checked_reward
        from ..envs.single_team_vector import opponent_factory
        from ..teams.interface import as_team

        self.env, self.team, self.reward = env, as_team(team), checked_reward(team, reward)
        self.counts = (env.num_cameras, env.num_targets, env.num_obstacles)
        self.factory = opponent_factory(opponent, self.team)
        self.players = self.factory(1, self.counts, None)
        self._other_obs = None

    def _other(self, camera_obs, target_obs) -> np.ndarray:
        return (target_obs if self.team is Team.CAMERA else camera_obs)[None]

    def reset(self, seed, camera_obs, target_obs) -> None:
        if seed is not None:
            self.players = self.factory(1, self.counts, int(seed))
        self._other_obs = self._other(camera_obs, target_obs)
        self.players.reset(self._other_obs, np.ones(1, dtype=bool))

    def act(self, camera_actions: np.ndarray, target_actions: np.ndarray) -> None:
        """Write the opponents' actions into their team's row of the joint action."""
        other = self.players.act(self._other_obs)[0]
        (target_actions if self.team is Team.CAMERA else camera_actions)[:] = other

    def observed(self, camera_obs, target_obs, team_reward: float, infos) -> np.ndarray:
        """The own agents' rewards (N,) of the step just played (`team_reward`: the own team's), as
        `mate.SingleTeamVecEnv` gives them; keeps the opponents' observations."""
        from ..envs.single_team_vector import step_rewards

        self._other_obs = self._other(camera_obs, target_obs)
        own_infos = infos[0] if self.team is Team.CAMERA else infos[1]
        rewards = step_rewards(self.reward, self.env._world, [team_reward], [own_infos[0]['coverage_rate']])[0]
        return np.full(len(own_infos), float(rewards)) if rewards.ndim == 0 else rewards


def parallel_env(config: Any = 'MATE-4v8-9', render_mode: str | None = None, max_cycles: int | None = None,
                 opponent=None, team: str | None = None, reward: str = 'team', **overrides: Any) -> MateParallelEnv:
    """MATE under PettingZoo's Parallel API (see the module docstring); with `opponent`, one team's agents only."""
    return MateParallelEnv(config, render_mode=render_mode, max_cycles=max_cycles, opponent=opponent, team=team,
                           reward=reward, **overrides)


class _CheckedParallelToAEC(parallel_to_aec_wrapper):
    """PettingZoo's Parallel-to-AEC conversion, refusing an action of the wrong shape at its agent's own
    turn (the turn does not pass), rather than when the last agent's turn advances the world."""

    def step(self, action) -> None:
        agent = self.agent_selection
        if action is not None and not (self.terminations[agent] or self.truncations[agent]):
            self.env._agent_action(agent, action)
        super().step(action)


def env(config: Any = 'MATE-4v8-9', render_mode: str | None = None, max_cycles: int | None = None,
        **overrides: Any):
    """MATE under PettingZoo's AEC API: `parallel_to_aec(parallel_env(...))` (order-enforced); an action
    of the wrong shape is refused at its agent's turn, which then does not pass."""
    return OrderEnforcingWrapper(_CheckedParallelToAEC(
        parallel_env(config, render_mode=render_mode, max_cycles=max_cycles, **overrides)))


raw_env = env
"""The same function as `env` (PettingZoo's conventional name for the unwrapped AEC constructor)."""
