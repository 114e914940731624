"""Agent base classes: the per-agent life cycle, seeding, messages and observation decoders.

Life cycle of one agent (docs/agents.md, "Writing an agent"); `mate.group_step` drives it each env step:

    agent.reset(observation)                       # after env.reset(), once per episode
    agent.observe(observation, info)               # then two communication rounds:
    messages = agent.send_requests()               #   env.send_messages(messages)
    agent.receive_requests(messages)               #   env.receive_messages(agent=agent)
    messages = agent.send_responses()
    agent.receive_responses(messages)
    action = agent.act(observation, info, deterministic)   # then env.step(...)

`episode_step` counts env steps: it is 0 at the first decision after `reset` and equals the
number of env steps taken so far. It advances once per `observe`/`act` cycle: at the first of
the two calls after the previous `act` (an agent driven by `act` alone counts too). Subclasses
override `observe` and `act` freely; the counting wraps them automatically.

Seeding: `np_random` is the agent's own numpy Generator; `action_space` has its own generator,
seeded from the agent's at every `reset`. `seed(s)` draws nothing, so after `seed(s)` and
`reset(observation)` an agent behaves as a new agent built with seed s would: a reused agent replays
a seeded episode. `clone()` deep-copies an agent and reseeds the copy with a seed drawn from the
prototype, so `Cls(seed=s).spawn(n)` gives n reproducible teammates.
"""

from __future__ import annotations

import abc
import copy
import functools
from typing import Any, ClassVar

import numpy as np
from gymnasium.utils import seeding

from ..constants import (
    CAMERA_DEFAULT_ACTION,
    OBSTACLE_STATE_DIM,
    PRESERVED_DIM,
    TARGET_DEFAULT_ACTION,
)
from ..messages import Message, Team
from ..teams.streams import INT_MAX, UniformDraws, child_seed
from ..spaces import observation_indices_of, observation_slices_of, observation_space_of
from . import utils

__all__ = ['INT_MAX', 'AgentBase', 'CameraAgentBase', 'TargetAgentBase', 'UniformDraws', 'child_seed']

def _not_reset(*args, **kwargs):
    raise RuntimeError('this helper is bound to the team sizes at reset(): call agent.reset(observation) first')


def _counting_env_steps(method, closes_step: bool):
    """Wrap `observe` (closes_step=False) or `act` (True) so that `episode_step` advances once per cycle."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        if self._step_closed:
            self.episode_step += 1
            self._step_closed = False
        result = method(self, *args, **kwargs)
        if closes_step:
            self._step_closed = True
        return result

    wrapper._counts_env_steps = True
    return wrapper


class AgentBase(abc.ABC):
    """Base of every agent. Subclasses set the team-specific class attributes and implement `act`.

    Args:
        seed: seed of the agent's generator (None: fresh entropy).
    """

    TEAM: ClassVar[Team]
    DEFAULT_ACTION: ClassVar[np.ndarray]
    STATE_CLASS: ClassVar[type]
    TEAMMATE_STATE_CLASS: ClassVar[type]
    OPPONENT_STATE_CLASS: ClassVar[type]

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        for name, closes_step in (('observe', False), ('act', True)):
            method = getattr(cls, name, None)   # may come from a mixin that is no AgentBase
            if callable(method) and not getattr(method, '_counts_env_steps', False):
                setattr(cls, name, _counting_env_steps(method, closes_step))

    def __init__(self, seed: int | None = None) -> None:
        self.num_cameras = self.num_targets = self.num_obstacles = None
        self.index = None
        self.agent_id = f'{self.TEAM.name.lower()}_0'
        self.action_space = None
        self.observation_dim = self.observation_space = None
        self.observation_indices = self.observation_slices = None
        self.convert_coordinates = self.rescale_observation = self.split_observation = _not_reset
        self._observation_shape = None
        self._state = self._state_source = None
        self.episode_step = -1
        self._step_closed = True
        self.last_observation = self.last_info = None
        self.last_requests = self.last_responses = ()
        self._np_random = None
        self._draw = self._space_draw = None
        self._action_low = self._action_high = None
        self.seed(seed)

    # ------------------------------------------------------------------ team sizes
    @property
    def num_teammates(self) -> int | None:
        return self.num_cameras if self.TEAM is Team.CAMERA else self.num_targets

    @property
    def num_opponents(self) -> int | None:
        return self.num_targets if self.TEAM is Team.CAMERA else self.num_cameras

    num_adversaries = num_opponents

    # ------------------------------------------------------------------ seeding and copies
    @property
    def np_random(self) -> np.random.Generator:
        """The agent's generator (seeded from entropy on first use if never seeded)."""
        if self._np_random is None:
            self.seed()
        return self._np_random

    def seed(self, seed: int | None = None) -> list[int]:
        """Reseed the agent's generator (and, after the first reset, its action space).

        Reseeding draws nothing from the new generator, so what an agent does after `seed(s)` and
        `reset(observation)` depends on `s` and the observations alone, not on the episodes it played
        before. An action space that already exists (a reseed between two resets or mid-episode) gets a
        seed derived from `seed` itself; the next `reset` reseeds it from the agent's generator anyway.

        Returns the seeds used: `[seed]`, plus the action space's seed when there is one.
        """
        self._np_random, used = seeding.np_random(seed)
        self._draw = UniformDraws(self._np_random)
        seeds = [used]
        if self.action_space is not None:
            derived = np.random.SeedSequence(used).generate_state(1, np.uint64)[0]
            seeds.append(self._seed_action_space(int(derived >> np.uint64(1))))
        return seeds

    def _seed_action_space(self, seed: int | None = None) -> int:
        """Seed the action space (default: a child seed drawn from the agent's generator); returns the seed."""
        seed = child_seed(self._np_random) if seed is None else seed
        self.action_space.seed(seed)
        self._space_draw = UniformDraws(self.action_space.np_random, block=64)
        return seed

    def clone(self):
        """A deep copy reseeded with a seed drawn from this agent's generator (one draw)."""
        twin = copy.deepcopy(self)
        twin.seed(child_seed(self.np_random))
        return twin

    def spawn(self, num_agents: int) -> list:
        """`num_agents` clones with seeds drawn in turn from this agent's generator."""
        return [self.clone() for _ in range(num_agents)]

    # ------------------------------------------------------------------ episode
    def reset(self, observation) -> None:
        """Start an episode from this agent's first observation (1-D): read the team sizes and own
        index from it, bind the layout helpers and draw a fresh seed for the action space."""
        observation = np.asarray(observation, dtype=np.float64)
        if observation.ndim != 1:
            raise ValueError(f'{type(self).__name__}.reset expects one agent\'s observation (1-D), '
                             f'got shape {observation.shape}')
        if observation.shape[0] < PRESERVED_DIM:
            raise ValueError(f'observation too short ({observation.shape[0]} values) to hold the preserved part')
        nc, nt, no, index = (int(round(v)) for v in observation[:4].tolist())
        team = self.TEAM
        self.num_cameras, self.num_targets, self.num_obstacles, self.index = nc, nt, no, index
        self.agent_id = f'{team.name.lower()}_{index}'
        self.observation_indices = observation_indices_of(team, nc, nt, no)
        self.observation_slices = observation_slices_of(team, nc, nt, no)
        self.observation_dim = int(self.observation_indices[-1])
        self.observation_space = observation_space_of(team, nc, nt, no)
        counts = dict(team=team, num_cameras=nc, num_targets=nt, num_obstacles=no)
        self.convert_coordinates = functools.partial(utils.convert_coordinates, **counts)
        self.rescale_observation = functools.partial(utils.rescale_observation, **counts)
        self.split_observation = functools.partial(utils.split_observation, **counts)
        self._observation_shape = (self.observation_dim,)
        if observation.shape != self._observation_shape:
            raise ValueError(f'observation has shape {observation.shape}; team {team.name} with '
                             f'({nc}, {nt}, {no}) entities needs ({self.observation_dim},)')
        self.state = self.STATE_CLASS(observation[self.observation_slices['self_state']], index)
        self.action_space = copy.deepcopy(self._state.action_space)
        self._action_low = self.action_space.low.tolist()
        self._action_high = self.action_space.high.tolist()
        self._seed_action_space()
        self.episode_step = -1
        self._step_closed = True
        self.last_observation = self.last_info = None
        self.last_requests = self.last_responses = ()

    @property
    def state(self):
        """This agent's own state view (`STATE_CLASS`) from the latest observation."""
        state = self._state
        if state is None and self._state_source is not None:
            begin = PRESERVED_DIM
            state = self._state = self.STATE_CLASS(self._state_source[begin:begin + self.STATE_CLASS.DIM],
                                                   self.index)
        return state

    @state.setter
    def state(self, value) -> None:
        self._state, self._state_source = value, None

    def _accept(self, observation) -> np.ndarray:
        """`observation` as a float64 (D,) array after a shape check; the own state is decoded lazily."""
        if type(observation) is not np.ndarray or observation.dtype != np.float64:
            observation = np.asarray(observation, dtype=np.float64)
        if observation.shape != self._observation_shape:
            self._raise_bad_observation(observation)
        self._state, self._state_source = None, observation
        return observation

    def _raise_bad_observation(self, observation: np.ndarray):
        if self._observation_shape is None:
            raise RuntimeError(f'{type(self).__name__}: call reset(observation) before observe/act')
        raise ValueError(f'{self.agent_id}: observation has shape {observation.shape}, '
                         f'expected {self._observation_shape}')

    def check_inputs(self, observation, info: dict | None = None):
        """Validate one step's inputs: returns (own state view, observation as float64 (D,), info
        (a dict, {} for None), the messages listed in info)."""
        observation = self._accept(observation)
        info = {} if info is None else info
        return self.state, observation, info, info.get('messages', [])

    # ------------------------------------------------------------------ one step
    def observe(self, observation, info: dict | None = None) -> None:
        """Take in this step's observation and info (before communication)."""
        self.state, self.last_observation, self.last_info, _ = self.check_inputs(observation, info)

    def send_requests(self):
        """Messages of the first communication round (none by default)."""
        return ()

    def receive_requests(self, messages) -> None:
        """Take the first round's messages addressed to this agent."""
        self.last_requests = tuple(messages)

    def send_responses(self):
        """Messages of the second communication round (none by default)."""
        return ()

    def receive_responses(self, messages) -> None:
        """Take the second round's messages addressed to this agent."""
        self.last_responses = tuple(messages)

    @abc.abstractmethod
    def act(self, observation, info: dict | None = None, deterministic: bool | None = None):
        """This step's action, float64 (2,)."""

    def predict(self, observation, info: dict | None = None, deterministic: bool | None = None):
        """Same as `act`."""
        return self.act(observation, info, deterministic)

    __call__ = predict

    def pack_message(self, content: Any, recipient: int | None = None) -> Message:
        """A message from this agent; `recipient=None` broadcasts to the whole team (self included)."""
        return Message(sender=self.index, recipient=recipient, content=content, team=self.TEAM,
                       broadcasting=recipient is None)

    # ------------------------------------------------------------------ random draws for subclasses
    def _sample_action(self) -> np.ndarray:
        """A uniform draw from the action box, from the action space's own generator."""
        draw, low, high = self._space_draw, self._action_low, self._action_high
        return np.array([low[0] + (high[0] - low[0]) * draw(), low[1] + (high[1] - low[1]) * draw()])

    # ------------------------------------------------------------------ observation decoders
    def _record(self, observation, part: int, state_class, count: int, index: int):
        if not 0 <= index < count:
            raise IndexError(f'index {index} out of range for {count} entities')
        observation = np.asarray(observation, dtype=np.float64)
        dim = state_class.DIM
        begin = int(self.observation_indices[part]) + (dim + 1) * index
        return state_class(observation[begin:begin + dim], index), bool(observation[begin + dim])

    def get_teammate_state(self, observation, index: int):
        """(teammate `index`'s public state view, visibility flag) from `observation`."""
        return self._record(observation, 4, self.TEAMMATE_STATE_CLASS, self.num_teammates, index)

    def get_opponent_state(self, observation, index: int):
        """(opponent `index`'s public state view, visibility flag) from `observation`."""
        return self._record(observation, 2, self.OPPONENT_STATE_CLASS, self.num_opponents, index)

    def get_obstacle_state(self, observation, index: int):
        """(obstacle `index`'s state view, visibility flag) from `observation`."""
        return self._record(observation, 3, utils.ObstacleState, self.num_obstacles, index)

    @staticmethod
    def _unzip(pairs) -> tuple[tuple, tuple]:
        pairs = list(pairs)
        return tuple(p[0] for p in pairs), tuple(p[1] for p in pairs)

    def get_teammate_states(self, observation) -> tuple[tuple, tuple]:
        """((views of every teammate), (their flags))."""
        return self._unzip(self.get_teammate_state(observation, i) for i in range(self.num_teammates))

    def get_all_opponent_states(self, observation) -> tuple[tuple, tuple]:
        """((views of every opponent), (their flags))."""
        return self._unzip(self.get_opponent_state(observation, i) for i in range(self.num_opponents))

    def get_all_obstacle_states(self, observation) -> tuple[tuple, tuple]:
        """((views of every obstacle), (their flags))."""
        return self._unzip(self.get_obstacle_state(observation, i) for i in range(self.num_obstacles))

    get_all_teammate_states = get_teammate_states

    def __repr__(self) -> str:
        return f'<{type(self).__module__}.{type(self).__qualname__} {self.agent_id}>'


AgentBase.observe = _counting_env_steps(AgentBase.observe, closes_step=False)


class CameraAgentBase(AgentBase):
    """Base of camera agents: actions are (rotation, zoom) in degrees within the camera's steps."""

    TEAM = Team.CAMERA
    DEFAULT_ACTION = CAMERA_DEFAULT_ACTION
    STATE_CLASS = utils.CameraStatePrivate
    TEAMMATE_STATE_CLASS = utils.CameraStatePublic
    OPPONENT_STATE_CLASS = utils.TargetStatePublic


class TargetAgentBase(AgentBase):
    """Base of target agents: actions are displacements (dx, dy) within +-step_size."""

    TEAM = Team.TARGET
    DEFAULT_ACTION = TARGET_DEFAULT_ACTION
    STATE_CLASS = utils.TargetStatePrivate
    TEAMMATE_STATE_CLASS = utils.TargetStatePublic
    OPPONENT_STATE_CLASS = utils.CameraStatePublic


assert OBSTACLE_STATE_DIM == utils.ObstacleState.DIM
