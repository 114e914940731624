"""Single-team machinery: play one team against built-in (or any) opponent agents.

`SingleTeamHelper` turns the two-team env into a one-team view; `SingleTeamMultiAgent` (behind MultiCamera
and MultiTarget) exposes the whole own team; `SingleTeamSingleAgent` (behind SingleCamera and
SingleTarget) exposes one agent and drives its teammates with agents as well. Opponents and teammates
are `mate.agents` objects: they observe, talk through the wrapped env (`group_step`), and act inside
`step`.

Randomness: a seeded reset `reset(seed=s)` seeds the opponents' prototype with s and makes the opponents its
fresh copies (`prototype.spawn(N)`), in slot order, as `mate evaluate` seeds the agents of its episode with seed s:
the same seed gives the same game here, in `mate.SingleTeamVecEnv`, the PettingZoo adapters with an opponent and
`mate evaluate` (with the greedy agents: the greedy batched teams play the same draws). A reset without a seed lets
the opponents go on with their streams. The teammates of `SingleCamera`/`SingleTarget` (and the controlled slot,
when the env shuffles its entities) are drawn from the unwrapped env's `np_random`. The env's own episode stream is
never touched, so the same seed gives the same episode with or without these wrappers.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from mate.agents.base import CameraAgentBase, TargetAgentBase, child_seed
from mate.agents.group import group_reset, group_step
from mate.messages import Message, Team

from .base import MateWrapper, assert_base_environment, has_wrapper

__all__ = ['MultiCamera', 'MultiTarget', 'SingleCamera', 'SingleTarget', 'SingleTeamHelper', 'SingleTeamMultiAgent',
           'SingleTeamSingleAgent', 'TeamInfos']

_AGENT_BASES = {Team.CAMERA: CameraAgentBase, Team.TARGET: TargetAgentBase}


class TeamInfos(dict):
    """The info dicts of a team's N agents, returned by MultiCamera and MultiTarget.

    A `dict` keyed by agent index 0..N-1, so that Gymnasium (which wants one dict of infos) accepts
    the env, that also reads as the list of per-agent dicts of the two-team env: iterating, unpacking
    and `zip` give the dicts in index order (not the keys), `infos[-1]` is the last agent's, a slice
    gives a list, and it equals the list of the same dicts. `keys()`, `items()` and `values()` are
    those of the dict.
    """

    def __init__(self, infos: Iterable[dict] = ()) -> None:
        super().__init__(enumerate(infos))

    def __iter__(self):
        return iter(self.values())

    def __reversed__(self):
        return reversed(list(self.values()))

    def __getitem__(self, key):
        if isinstance(key, slice):
            return list(self.values())[key]
        if isinstance(key, int) and not isinstance(key, bool) and -len(self) <= key < 0:
            key += len(self)
        return super().__getitem__(key)

    def __eq__(self, other) -> bool:
        if isinstance(other, list):
            return list(self.values()) == other
        return super().__eq__(other)

    def __ne__(self, other) -> bool:
        return not self == other

    __hash__ = None

    def __repr__(self) -> str:
        return f'{type(self).__name__}({list(self.values())!r})'


def _agent_name(agent: Any) -> str:
    return f'{type(agent).__module__}.{type(agent).__qualname__}'


class SingleTeamHelper(MateWrapper):
    """A one-team view of the env: `team`, `opponent_team`, `num_teammates`, `num_opponents`, and the
    `teammate_*` / `opponent_*` aliases of the inner action and observation spaces (a discrete camera
    space shows here when DiscreteCamera sits inside).

    Order: directly over the two-team env stack (no other single-team wrapper inside); the own team must
    have at least one agent.
    """

    ROLES = frozenset({'single-team'})

    def __init__(self, env, team: Team) -> None:
        assert_base_environment(env, type(self).__name__)
        team = Team(team)
        base = env.unwrapped
        sizes = {Team.CAMERA: base.num_cameras, Team.TARGET: base.num_targets}
        if sizes[team] < 1:
            raise ValueError(f'{type(self).__name__} needs at least one agent in team {team.name}; '
                             f'the environment has none')
        super().__init__(env)
        self.team, self.opponent_team = team, Team(1 - team)
        self.num_teammates, self.num_opponents = sizes[team], sizes[self.opponent_team]
        for role, side in (('teammate', team), ('opponent', self.opponent_team)):
            prefix = side.name.lower()
            for kind in ('action_space', 'joint_action_space', 'observation_space', 'joint_observation_space'):
                setattr(self, f'{role}_{kind}', getattr(env, f'{prefix}_{kind}'))
        self.repeated_reward_individual_done = has_wrapper(env, 'repeated-reward')

    # ------------------------------------------------------------------ team pairs
    def own(self, pair):
        """The own team's item of a (camera, target) pair."""
        return pair[self.team]

    def opponent(self, pair):
        """The opponent team's item of a (camera, target) pair."""
        return pair[self.opponent_team]

    def joint(self, own, opponent) -> tuple:
        """(own, opponent) back in (camera, target) order."""
        return (own, opponent) if self.team is Team.CAMERA else (opponent, own)

    def _own_flag(self, flag):
        """terminated/truncated of the own team: a list per team when RepeatedRewardIndividualDone is inside."""
        return self.own(flag) if self.repeated_reward_individual_done else flag

    def _shuffled(self, agents: list) -> list:
        """A copy of `agents`, permuted with the env's `np_random` when the env shuffles its entities."""
        agents = list(agents)
        if self.env.unwrapped.shuffle_entities and len(agents) > 1:
            order = self.env.unwrapped.np_random.permutation(len(agents))
            agents = [agents[i] for i in order]
        return agents

    @staticmethod
    def _check_agent(agent: Any, team: Team, argument: str, wrapper: str) -> None:
        if not isinstance(agent, _AGENT_BASES[team]):
            raise TypeError(f'{wrapper}: {argument} must be a {_AGENT_BASES[team].__name__} instance '
                            f'(an agent of team {team.name}), got {agent!r}')

    def _seed_opponents(self, seed: int | None) -> None:
        """On a seeded reset: the opponents' prototype seeded with `seed`, the opponents its fresh copies."""
        if seed is not None:
            self.opponent_agent.seed(seed)
            self.opponent_agents = self.opponent_agent.spawn(self.num_opponents)

    def _seed_agents(self, *agents) -> list[int]:
        """Reseed `agents` in turn with child seeds drawn from the env's `np_random`; returns the seeds."""
        rng = self.env.unwrapped.np_random
        seeds = []
        for agent in agents:
            seed = child_seed(rng)
            agent.seed(seed)
            seeds.append(seed)
        return seeds

    @staticmethod
    def _as_messages(messages: Message | Iterable[Message]) -> list[Message]:
        return [messages] if isinstance(messages, Message) else list(messages)

    def _check_team(self, messages: list[Message]) -> None:
        for message in messages:
            if Team(message.team) is not self.team:
                raise ValueError(f'{type(self).__name__} only sends messages of team {self.team.name} '
                                 f'(the opponents talk inside the wrapper); got {message!r}')


class SingleTeamMultiAgent(SingleTeamHelper):
    """The whole own team against `opponent_agent` copies (`opponent_agent.spawn(num_opponents)`).

    `reset(seed=None, options=None) -> (own_joint_observation, own_infos)`;
    `step(own_joint_action) -> (own_joint_observation, own_reward, terminated, truncated, own_infos)`, where
    reward/terminated/truncated are the own team's lists when RepeatedRewardIndividualDone is inside. The own
    agents should communicate (through this wrapper's `send_messages`/`receive_messages`) before `step`;
    the opponents observe, communicate through the inner env, and act inside `step`.
    """

    def __init__(self, env, team: Team, opponent_agent) -> None:
        super().__init__(env, team)
        self._check_agent(opponent_agent, self.opponent_team, f'{self.opponent_team.name.lower()}_agent',
                          type(self).__name__)
        self.opponent_agent = opponent_agent
        self.opponent_agents = opponent_agent.spawn(self.num_opponents)
        self.action_space = self.teammate_joint_action_space
        self.observation_space = self.teammate_joint_observation_space
        self.opponent_observation = None
        self.opponent_infos = None

    def _arguments(self) -> str:
        return f'opponent={_agent_name(self.opponent_agent)}'

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        observation, infos = self.env.reset(seed=seed, options=options)
        self._seed_opponents(seed)
        self.opponent_observation, self.opponent_infos = self.opponent(observation), None
        group_reset(self.opponent_agents, self.opponent_observation)
        return self.own(observation), TeamInfos(self.own(infos))

    def step(self, action):
        opponent_action = group_step(self.env, self.opponent_agents, self.opponent_observation, self.opponent_infos)
        observation, reward, terminated, truncated, infos = self.env.step(self.joint(action, opponent_action))
        self.opponent_observation, self.opponent_infos = self.opponent(observation), self.opponent(infos)
        return (self.own(observation), self.own(reward), self._own_flag(terminated), self._own_flag(truncated),
                TeamInfos(self.own(infos)))

    def send_messages(self, messages) -> None:
        """Send own-team messages through the inner env (ValueError for another team's message)."""
        messages = self._as_messages(messages)
        self._check_team(messages)
        self.env.send_messages(messages)

    def receive_messages(self, agent_id=None, agent=None):
        """With no argument: copies of the own team's per-step message buffers (queues are not drained).
        With `agent_id=(team, index)` or `agent=`: that agent's queued messages (drained)."""
        if agent_id is None and agent is None:
            return self.own(self.env.unwrapped.message_buffers)
        return self.env.receive_messages(agent_id=agent_id, agent=agent)


class SingleTeamSingleAgent(SingleTeamHelper):
    """One agent of the own team; its `num_teammates - 1` teammates are `teammate_agent` copies and the
    opponents `opponent_agent` copies.

    The controlled agent's slot `index` is the last one (`num_teammates - 1`), or a uniformly random slot
    each episode when the env shuffles entities. `reset -> (observation (D,), info)`;
    `step(action (2,) or index) -> (observation, reward, terminated, truncated, info)` (this agent's entries
    when RepeatedRewardIndividualDone is inside). Inside `step` the teammates act first, then the
    opponents; both talk through the inner env.
    """

    ROLES = frozenset({'single-team', 'single-agent'})

    def __init__(self, env, team: Team, teammate_agent, opponent_agent) -> None:
        super().__init__(env, team)
        wrapper = type(self).__name__
        self._check_agent(teammate_agent, self.team, f'other_{self.team.name.lower()}_agent', wrapper)
        self._check_agent(opponent_agent, self.opponent_team, f'{self.opponent_team.name.lower()}_agent', wrapper)
        self.teammate_agent, self.opponent_agent = teammate_agent, opponent_agent
        self.teammate_agents_ordered = teammate_agent.spawn(self.num_teammates - 1)
        self.teammate_agents = list(self.teammate_agents_ordered)
        self.opponent_agents = opponent_agent.spawn(self.num_opponents)
        self.action_space = self.teammate_action_space
        self.observation_space = self.teammate_observation_space
        self.index = self.num_teammates - 1
        self.teammate_observation = self.teammate_infos = None
        self.opponent_observation = self.opponent_infos = None

    def _arguments(self) -> str:
        return f'teammate={_agent_name(self.teammate_agent)}, opponent={_agent_name(self.opponent_agent)}'

    def _others(self, rows):
        """Rows of the teammates (all own-team rows except `index`)."""
        return [row for i, row in enumerate(rows) if i != self.index]

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        observation, infos = self.env.reset(seed=seed, options=options)
        if seed is not None:
            self._seed_agents(self.teammate_agent, *self.teammate_agents_ordered)
        self._seed_opponents(seed)
        self.opponent_observation, self.opponent_infos = self.opponent(observation), None
        group_reset(self.opponent_agents, self.opponent_observation)

        self.index = self.num_teammates - 1
        self.teammate_agents = list(self.teammate_agents_ordered)
        if self.env.unwrapped.shuffle_entities:
            self.index = int(self.env.unwrapped.np_random.integers(self.num_teammates))
            self.teammate_agents = self._shuffled(self.teammate_agents_ordered)
        own_observation = self.own(observation)
        self.teammate_observation, self.teammate_infos = np.asarray(self._others(own_observation)), None
        group_reset(self.teammate_agents, self.teammate_observation)
        return own_observation[self.index], self.own(infos)[self.index]

    def step(self, action):
        teammate_action = group_step(self.env, self.teammate_agents, self.teammate_observation, self.teammate_infos)
        own_action = list(teammate_action)
        own_action.insert(self.index, action)
        opponent_action = group_step(self.env, self.opponent_agents, self.opponent_observation, self.opponent_infos)
        observation, reward, terminated, truncated, infos = self.env.step(self.joint(own_action, opponent_action))
        own_observation, own_infos = self.own(observation), self.own(infos)
        self.opponent_observation, self.opponent_infos = self.opponent(observation), self.opponent(infos)
        self.teammate_observation = np.asarray(self._others(own_observation))
        self.teammate_infos = self._others(own_infos)
        reward, terminated, truncated = self.own(reward), self._own_flag(terminated), self._own_flag(truncated)
        if self.repeated_reward_individual_done:
            reward, terminated, truncated = reward[self.index], terminated[self.index], truncated[self.index]
        return own_observation[self.index], reward, terminated, truncated, own_infos[self.index]

    def send_messages(self, messages) -> None:
        """Send this agent's messages (team and `sender == index` are checked) through the inner env."""
        messages = self._as_messages(messages)
        self._check_team(messages)
        for message in messages:
            if message.sender != self.index:
                raise ValueError(f'{type(self).__name__} controls agent {self.index} this episode; '
                                 f'got a message from sender {message.sender}: {message!r}')
        self.env.send_messages(messages)

    def receive_messages(self, agent_id=None, agent=None):
        """With no argument: this agent's queued messages (drained). Otherwise forwarded to the inner env."""
        if agent_id is None and agent is None:
            return self.env.receive_messages(agent_id=(self.team, self.index))
        return self.env.receive_messages(agent_id=agent_id, agent=agent)


class MultiCamera(SingleTeamMultiAgent):
    """All cameras are yours; the targets are copies of `target_agent` (a `TargetAgentBase`).

        env = mate.make('MultiAgentTracking-v0', wrappers=[
            mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyTargetAgent(seed=0))])
        camera_obs, camera_infos = env.reset(seed=0)                 # (Nc, D_c), Nc dicts
        camera_obs, reward, terminated, truncated, camera_infos = env.step(env.action_space.sample())

    Spaces: `action_space` / `observation_space` are the camera joint spaces of the inner env.
    Order: before it: observation-mask wrappers, DiscreteCamera/DiscreteTarget, MoreTrainingInformation;
    RepeatedRewardIndividualDone may sit inside or outside.
    """

    def __init__(self, env, target_agent) -> None:
        super().__init__(env, Team.CAMERA, opponent_agent=target_agent)

    @property
    def target_agent(self):
        """The prototype of the opponents (seeded, never acts itself)."""
        return self.opponent_agent


class MultiTarget(SingleTeamMultiAgent):
    """All targets are yours; the cameras are copies of `camera_agent` (a `CameraAgentBase`).

        env = mate.make('MultiAgentTracking-v0', wrappers=[
            mate.WrapperSpec(mate.MultiTarget, camera_agent=mate.GreedyCameraAgent(seed=0))])
        target_obs, target_infos = env.reset(seed=0)                 # (Nt, D_t), Nt dicts
        target_obs, reward, terminated, truncated, target_infos = env.step(env.action_space.sample())

    Spaces: `action_space` / `observation_space` are the target joint spaces of the inner env.
    Order: as for MultiCamera.
    """

    def __init__(self, env, camera_agent) -> None:
        super().__init__(env, Team.TARGET, opponent_agent=camera_agent)

    @property
    def camera_agent(self):
        """The prototype of the opponents (seeded, never acts itself)."""
        return self.opponent_agent


class SingleCamera(SingleTeamSingleAgent):
    """You control one camera (slot `env.index`); the other cameras are copies of `other_camera_agent`, the
    targets copies of `target_agent`.

        env = mate.make('MultiAgentTracking-v0', wrappers=[mate.WrapperSpec(
            mate.SingleCamera, other_camera_agent=mate.GreedyCameraAgent(seed=0),
            target_agent=mate.GreedyTargetAgent(seed=0))])
        observation, info = env.reset(seed=0)                        # (D_c,), one dict
        observation, reward, terminated, truncated, info = env.step(env.action_space.sample())

    Spaces: one camera's action and observation spaces. Order: as for MultiCamera, and nothing that needs
    every agent's reward (RepeatedRewardIndividualDone, Auxiliary*Rewards) may follow it.
    """

    def __init__(self, env, other_camera_agent, target_agent) -> None:
        super().__init__(env, Team.CAMERA, teammate_agent=other_camera_agent, opponent_agent=target_agent)

    @property
    def other_camera_agent(self):
        return self.teammate_agent

    @property
    def target_agent(self):
        return self.opponent_agent


class SingleTarget(SingleTeamSingleAgent):
    """You control one target (slot `env.index`); the other targets are copies of `other_target_agent`, the
    cameras copies of `camera_agent`.

        env = mate.make('MultiAgentTracking-v0', wrappers=[mate.WrapperSpec(
            mate.SingleTarget, other_target_agent=mate.GreedyTargetAgent(seed=0),
            camera_agent=mate.GreedyCameraAgent(seed=0))])
        observation, info = env.reset(seed=0)                        # (D_t,), one dict
        observation, reward, terminated, truncated, info = env.step(env.action_space.sample())

    Spaces: one target's action and observation spaces. Order: as for SingleCamera.
    """

    def __init__(self, env, other_target_agent, camera_agent) -> None:
        super().__init__(env, Team.TARGET, teammate_agent=other_target_agent, opponent_agent=camera_agent)

    @property
    def other_target_agent(self):
        return self.teammate_agent

    @property
    def camera_agent(self):
        return self.opponent_agent
