"""Trained policies: the network of a `PolicySpec`, and policies acting as batched teams and as agents.

* `make_actor(spec)`: the policy network a spec names (the one builder, for trainers and loaders);
* `load_policy(path)` -> `LoadedPolicy` (the actor and its spec), `export_policy(checkpoint, out)`, the shipped
  policies (`pretrained_path`), `load_agent('checkpoint:PATH' | 'pretrained:NAME', team)`;
* `PolicyTeam`: a policy playing every agent of a team in B games at once (a batched team of `mate.teams`);
* `PolicyCameraAgent` / `PolicyTargetAgent`: a policy as one `mate` agent in a single env.

Both apply the spec's pipeline as training did (`PolicySpec.features`, `choose`, `decode`): the same
preprocessing, the team's sighting memory (`spec.memory`) and the target-velocity columns (`spec.velocity`), a
decision every `frame_skip` env steps, held, and decoded once (grid moves, continuous shares) or at every step
(the HRL executor). Sampling (the default of a training checkpoint; exported policies store how they were scored,
`deterministic`) uses the team's or agent's own generator, so batched teams match the agents in distribution,
not draw by draw. Value-based policies (IQL, QMIX) act greedily on their Q-values; MA-TD3 policies hold one
actor per agent.

Agents of one team talk through the env's channel (`mate.Message`s, so that the communication wrappers act on
them), as their policy's training read:

* sighting memory (`spec.memory`): each camera broadcasts the targets it sees in the first round of every step
  (`{'sightings': [(slot, x, y), ...]}`) and records its teammates' sightings, so every camera holds the memory the
  learner had (an agent whose `observe` was skipped updates its memory from `act`'s observation, without news);
* TarMAC (`spec.comm == 'tarmac'`): an agent keeps its LSTM state and its own last message; at a decision it
  reads N messages: its own (kept locally, never lost) and, per teammate, the last `{'tarmac': float32 array}`
  message from that sender since its previous decision, zeros when none came (dropped, out of range, delayed,
  silenced). After the decision it broadcasts its new message once, in the response round of the next env step,
  so it is read at the teammates' next decision: the one-decision delay of training;
* I2C (`spec.comm == 'i2c'`): at a decision an agent sends an empty request `{'i2c': None}` in the request round
  to each teammate its prior network selects; a teammate answers every request of that step in its response round
  with its raw observation `{'i2c': float64 array}`; the agent reads the replies in the teammates' slots, zeros
  for a reply that did not come; only replies from the teammates it asked, in its decision step, count.

The network is shared, read-only, by every agent cloned from one prototype (`spawn`).
"""

from __future__ import annotations

import contextlib
import copy
import functools
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..agents.base import CameraAgentBase, TargetAgentBase
from ..messages import Team
from ..teams.interface import as_team
from .checkpoint import CheckpointError, load_checkpoint, read_spec, save_checkpoint
from .actors import network_kind
from .memory import SightingMemory, camera_sightings
from .spec import PolicySpec, SpecError

__all__ = ['AGENT_CLASSES', 'BATCHED_AGENTS', 'PRETRAINED_DIR', 'LoadedPolicy', 'PolicyCameraAgent',
           'PolicyTargetAgent', 'PolicyTeam', 'export_policy', 'load_agent', 'load_policy', 'make_actor', 'make_team',
           'pretrained_path']

PRETRAINED_DIR = Path(__file__).resolve().parent.parent / 'pretrained'
BATCHED_AGENTS = ('random', 'greedy', 'upper-bound', 'checkpoint:PATH', 'pretrained:NAME')
"""Agent names of `mate evaluate` that have a batched team (upper-bound: cameras only)."""
_NEVER = np.iinfo(np.int64).max // 2
"""A decision countdown that does not run out within any episode."""


def make_actor(spec: PolicySpec) -> nn.Module:
    """The policy network of `spec`: the builder registered for `spec.network` (`mate.policies.actors`); its outputs
    are `spec.num_actions` logits per agent (Q-values for 'dueling' and 'recurrent-q', actions in [-1, 1] for
    'independent')."""
    return network_kind(spec.network).builder()(spec)


# ============================================================================ policy files

@contextlib.contextmanager
def torch_threads(count: int):
    """Run the block with `count` torch intra-op threads, restored after (a sub-microsecond switch)."""
    previous = torch.get_num_threads()
    if previous != count:
        torch.set_num_threads(count)
    try:
        yield
    finally:
        if previous != count:
            torch.set_num_threads(previous)


class LoadedPolicy:
    """An actor network and its spec; deep copies return the same object (shared by an agent's clones).

    `threads`: torch threads of its forward passes (1). A decision is a small matrix product: on our 2-core
    machines two threads played `mate evaluate` 5-10x slower than one when the other core was busy (29 against
    155-316 env-steps/s for the shipped HRL cameras), and no faster when it was idle.
    """

    threads = 1

    def __init__(self, actor: nn.Module, spec: PolicySpec, source: str = '', device='cpu') -> None:
        self.device = torch.device(device)
        self.actor = actor.eval().to(self.device)
        self.spec = spec
        self.source = source

    def __deepcopy__(self, memo):
        return self

    def on(self, device) -> LoadedPolicy:
        """This policy with its network on `device` (a torch device or name; itself when it is there already):
        batched teams of many games run their forward passes there, one transfer in and out per decision."""
        device = torch.device(device)
        if device == self.device:
            return self
        return LoadedPolicy(copy.deepcopy(self.actor), self.spec, self.source, device)

    @property
    def recurrent(self) -> bool:
        return bool(getattr(self.actor, 'recurrent', False))

    @property
    def comm(self) -> str:
        """The communication scheme of its actor: 'none', 'tarmac' or 'i2c'."""
        return self.spec.comm

    @property
    def communicates(self) -> bool:
        """Its agents exchange learned messages (TarMAC or I2C)."""
        return self.spec.comm != 'none'

    def initial_memory(self, *shape: int):
        """The recurrent actor's zero state for `shape` agents, on its device (None for a feed-forward actor)."""
        return tuple(part.to(self.device) for part in self.actor.initial_state(*shape)) if self.recurrent else None

    def features(self, raw: np.ndarray, memory: np.ndarray | None = None, previous: np.ndarray | None = None):
        """The spec's features (the network's input) of raw observations (`PolicySpec.features`)."""
        return self.spec.features(raw, memory, previous)

    @torch.no_grad()
    def outputs(self, features: np.ndarray, memory=None, **inputs):
        """Outputs (..., A) of features (..., D): logits, Q-values or actions; with a recurrent actor also the next
        memory. `inputs`: more arguments of the recurrent actor's `step` (I2C: `teammates`, `agents`)."""
        obs = torch.as_tensor(features, dtype=torch.float32, device=self.device)
        inputs = {k: v.to(self.device) if isinstance(v, torch.Tensor) else v for k, v in inputs.items()}
        with torch_threads(self.threads):
            if not self.recurrent:
                return self.actor(obs).cpu().numpy()
            outputs, memory = self.actor.step(obs, memory, **inputs)
        return outputs.cpu().numpy(), memory

    def requests(self, features: np.ndarray, agent: int) -> np.ndarray:
        """The teammates (indices in the team) agent `agent` asks before acting, from its features (D,): the actor's
        own `requested` (an actor whose agents ask their teammates: I2C's)."""
        with torch_threads(self.threads):
            return self.actor.requested(torch.as_tensor(features[None], dtype=torch.float32, device=self.device),
                                        agent)


def _actor_weights(data: dict) -> dict:
    """The actor's state dict of a loaded file: a policy file's or a run checkpoint's."""
    if 'actor' in data:
        return data['actor']
    if isinstance(data.get('state'), dict) and 'networks' in data['state']:
        return data['state']['networks']['actor']
    raise KeyError('actor')


def load_policy(path, team=None) -> LoadedPolicy:
    """The actor of a checkpoint or policy file (either format). CheckpointError if unreadable, without a valid
    spec, trained for the other team, or if the weights do not fit the spec."""
    data = load_checkpoint(path)
    spec = read_spec(data, path)
    if team is not None and spec.team != as_team(team).name.lower():
        raise CheckpointError(f'checkpoint {str(path)!r} holds a policy for the {spec.team} team, not the '
                              f'{as_team(team).name.lower()} team')
    try:
        actor = make_actor(spec)
        actor.load_state_dict(_actor_weights(data))
    except (KeyError, RuntimeError, ValueError) as exc:
        raise CheckpointError(f'checkpoint {str(path)!r}: the actor weights do not fit its spec: '
                              f'{str(exc).splitlines()[0]}') from None
    return LoadedPolicy(actor, spec, str(path))


def export_policy(checkpoint, out, note: str = '', deterministic: bool = False) -> Path:
    """Write the acting part of a checkpoint (its spec and actor weights, the config, step count and `note`) to
    `out`: a small policy file (`mate/pretrained/`, `pretrained:NAME`). `deterministic` is stored as the agents'
    default way of acting (argmax instead of sampling), the way the policy was scored."""
    data = load_checkpoint(checkpoint)
    spec = read_spec(data, checkpoint).replace(deterministic=bool(deterministic))
    counters = data.get('run', data)
    return save_checkpoint(out, dict(spec=spec.to_dict(), algo=spec.algo, actor=_actor_weights(data),
                                     config=data['config'], env_steps=int(counters.get('env_steps', 0)), note=note))


def pretrained_path(name: str) -> Path:
    """Path of a shipped policy `mate/pretrained/NAME.pt`; ValueError listing the available ones."""
    path = PRETRAINED_DIR / f'{name}.pt'
    if not path.is_file():
        names = sorted(p.stem for p in PRETRAINED_DIR.glob('*.pt'))
        raise ValueError(f'no pretrained policy {name!r}; available: {", ".join(names) or "none"}')
    return path


# ============================================================================ batched: a team of B games

class PolicyTeam:
    """A trained policy playing every agent of a team in B games (a batched team of `mate.teams`).

    The whole team of a row decides together (features (R, N, D)), so the agents of a TarMAC policy read each
    other's last messages, and those of an I2C policy the current observations of the teammates their priors
    ask, as in training.

    Args:
        policy: a `LoadedPolicy` (`load_policy(path)`), or a checkpoint path.
        team: Team.CAMERA / Team.TARGET (or 'camera' / 'target').
        num_envs: B.
        counts: (Nc, Nt, No) of the game; must be the policy's.
        seed: seed of the sampling generator.
        deterministic: argmax instead of sampling (None: the policy file's default).
        frame_skip: env steps a decision is held (None: the training frame skip).
        device: where the forward passes run ('cpu', 'cuda', a `torch.device`): the features go there once per
            decision, the outputs come back.
    """

    def __init__(self, policy, team, num_envs: int, counts, seed: int | None = None,
                 deterministic: bool | None = None, frame_skip: int | None = None, device='cpu') -> None:
        self.team = as_team(team)
        self.policy = (policy if isinstance(policy, LoadedPolicy) else load_policy(policy, self.team)).on(device)
        spec = self.spec = self.policy.spec
        spec.check_game(self.team, counts, f'policy {self.policy.source!r}')
        self.full_observability = spec.full_observability   # `play_batch` fills its observations in (every entity)
        self.counts = spec.counts
        self.num_envs, self.num_agents = int(num_envs), spec.num_agents
        self.deterministic = bool(spec.deterministic if deterministic is None else deterministic)
        self.frame_skip = int(frame_skip or spec.frame_skip)
        self.rng = np.random.default_rng(seed)
        shape = (self.num_envs, self.num_agents)
        self.held = np.zeros(shape + (2,)) if spec.continuous else np.zeros(shape + (spec.heads,), dtype=np.int64)
        self.actions = np.zeros(shape + (2,))                        # the held decision decoded (open loop)
        self.countdown = np.zeros(self.num_envs, dtype=np.int64)
        self.sightings = SightingMemory(self.num_envs, self.counts, spec.memory) if spec.memory else None
        self.previous = None                                        # velocity: last step's observations
        self.memory = self.policy.initial_memory(*shape)   # recurrent state: (h, c), (h,), (h, c, messages) or None

    def reset(self, observation: np.ndarray, rows: np.ndarray) -> None:
        rows = np.asarray(rows, dtype=bool)
        self.countdown[rows] = 0
        if self.sightings is not None:
            self.sightings.forget(rows)
        if self.previous is None:
            self.previous = np.array(observation, dtype=np.float64)
        self.previous[rows] = observation[rows]
        if self.memory is not None:
            index = torch.as_tensor(rows, device=self.policy.device)
            for part in self.memory:
                part[index] = 0.0

    def idle(self, rows: np.ndarray) -> None:
        """Make no more decisions in the rows `rows` (until their next reset): their games are over."""
        self.countdown[np.asarray(rows, dtype=bool)] = _NEVER

    def _decide(self, observation: np.ndarray, rows: np.ndarray) -> None:
        """New decisions for the rows `rows` (indices): one forward pass for all their agents."""
        raw = observation[rows]
        memory = None if self.sightings is None else self.sightings.features(raw, rows)
        features = self.spec.features(raw, memory, self.previous[rows])
        if self.memory is not None:
            index = torch.as_tensor(rows, device=self.policy.device)
            outputs, memory = self.policy.outputs(features, tuple(part[index] for part in self.memory))
            for part, value in zip(self.memory, memory):
                part[index] = value
        else:
            outputs = self.policy.outputs(features)
        self.held[rows] = self.spec.choose(outputs.reshape(len(rows), self.num_agents, -1), features,
                                           self.deterministic, self.rng)
        if not self.spec.closed_loop:
            self.actions[rows] = self.spec.decode(self.held[rows], raw)

    def act(self, observation: np.ndarray) -> np.ndarray:
        observation = np.asarray(observation, dtype=np.float64)
        if self.sightings is not None:   # every step: the team's sightings enter its memory
            self.sightings.tick()
            self.sightings.observe_team(observation)
        deciding = np.flatnonzero(self.countdown <= 0)
        if deciding.size:
            self._decide(observation, deciding)
            self.countdown[deciding] = self.frame_skip
        self.countdown -= 1
        self.previous = observation.copy()
        if self.spec.closed_loop:         # HRL: the executor re-aims at every step
            return self.spec.decode(self.held, observation)
        return self.actions.copy()

    def state_dict(self) -> dict:
        """Everything its future depends on (a training run's opponent: exact resumes)."""
        memory = None if self.memory is None else [part.clone() for part in self.memory]
        sightings = None if self.sightings is None else dict(location=self.sightings.location.copy(),
                                                             age=self.sightings.age.copy())
        return dict(rng=self.rng.bit_generator.state, held=self.held.copy(), actions=self.actions.copy(),
                    countdown=self.countdown.copy(), previous=None if self.previous is None else self.previous.copy(),
                    memory=memory, sightings=sightings)

    def load_state_dict(self, state: dict) -> None:
        self.rng.bit_generator.state = state['rng']
        self.held[...], self.actions[...], self.countdown[...] = state['held'], state['actions'], state['countdown']
        self.previous = None if state['previous'] is None else np.array(state['previous'])
        if self.memory is not None:
            for part, value in zip(self.memory, state['memory']):
                part.copy_(value)
        if self.sightings is not None:
            self.sightings.location[...] = state['sightings']['location']
            self.sightings.age[...] = state['sightings']['age']


def make_team(name: str, team, num_envs: int, counts, seed: int | None = None, device='cpu', **kwargs):
    """A batched team from an agent name of `mate evaluate`: 'random', 'greedy' (the `mate.teams` rule teams, with
    their options), 'checkpoint:PATH' or 'pretrained:NAME' (kwargs: deterministic, frame_skip; their forward passes
    on `device`). ValueError naming the batched agents otherwise."""
    from .. import teams

    team = as_team(team)
    kind, _, value = name.partition(':')
    if name in teams.RULE_TEAMS:
        return teams.make_team(name, team, num_envs, counts, seed=seed, **kwargs)
    if kind in ('checkpoint', 'pretrained') and value:
        path = Path(value).expanduser() if kind == 'checkpoint' else pretrained_path(value)   # as `load_agent`
        return PolicyTeam(load_policy(path, team), team, num_envs, counts, seed=seed, device=device, **kwargs)
    raise ValueError(f'agent {name!r} has no batched version; batched agents: {", ".join(BATCHED_AGENTS)}')


# ============================================================================ one agent in a single env

MESSAGE_KEY = 'tarmac'
"""Content key of a TarMAC agent's broadcast: `{'tarmac': float32 array (key + value,)}` (a copy, compared by
value as every message content is: `mate.messages.values_equal`)."""
I2C_KEY = 'i2c'
"""Content key of I2C messages: a request `{'i2c': None}`, a reply `{'i2c': float64 array (D_raw,)}` (a copy)."""


class _PolicyAgentMixin:
    """Shared logic of the camera and target policy agents (module docstring)."""

    def __init__(self, policy: LoadedPolicy, seed: int | None = None, deterministic: bool | None = None,
                 frame_skip: int | None = None) -> None:
        if policy.spec.team != self.TEAM.name.lower():
            raise CheckpointError(f'policy {policy.source!r} was trained for the {policy.spec.team} team; '
                                  f'{type(self).__name__} needs a {self.TEAM.name.lower()} policy')
        self.policy, self.spec = policy, policy.spec
        # None: the policy file's default (exported policies: the way they were scored), else sampling
        self.deterministic = bool(policy.spec.deterministic if deterministic is None else deterministic)
        self.frame_skip = int(frame_skip or policy.spec.frame_skip)
        self._held = self._action = None
        self._countdown = 0
        super().__init__(seed=seed)

    @classmethod
    def from_checkpoint(cls, path, seed: int | None = None, deterministic: bool | None = None,
                        frame_skip: int | None = None):
        return cls(load_policy(path, cls.TEAM), seed=seed, deterministic=deterministic, frame_skip=frame_skip)

    def reset(self, observation) -> None:
        super().reset(observation)
        counts = (self.num_cameras, self.num_targets, self.num_obstacles)
        try:
            self.spec.check_game(self.TEAM, counts, f'policy {self.policy.source!r}')
        except SpecError as exc:
            raise ValueError(str(exc)) from None
        self._held, self._action, self._countdown = None, None, 0
        self._memory = self.policy.initial_memory(1)     # TarMAC: (h, c, own last message), each (1, size)
        self._heard = {}                                 # TarMAC: sender -> its message since my last decision
        self._outbox = None                              # TarMAC: my new message, until the next response round
        self._current = None                             # I2C: this step's observation (observe), until act
        self._askers = []                                # I2C: teammates that asked for it in this step
        self._asked = ()                                 # I2C: teammates I asked at this step's decision
        self._replies = {}                               # I2C: sender -> its raw observation, for my decision
        self._sightings = SightingMemory(1, counts, self.spec.memory) if self.spec.memory else None
        self._seen_now = []
        self._previous = np.array(observation, dtype=np.float64)     # velocity: the last step's observation
        if self._sightings is not None:
            self._remember(np.asarray(observation, dtype=np.float64), tick=False)

    def _remember(self, observation, tick: bool = True) -> None:
        """Own sightings of this step into the team memory (after one step of forgetting); kept for broadcast."""
        if tick:
            self._sightings.tick()
        _, seen, location = camera_sightings(observation[None, None], *self._sightings.counts)
        self._sightings.see(seen[:, 0], location[:, 0])
        self._seen_now = [(int(t), float(location[0, 0, t, 0]), float(location[0, 0, t, 1]))
                          for t in np.flatnonzero(seen[0, 0])]
        self._observed = True

    def observe(self, observation, info=None) -> None:
        super().observe(observation, info)
        self._current = self.last_observation
        if self._sightings is not None:
            self._remember(self._accept(observation))

    def send_requests(self):
        if self.spec.comm == 'i2c':
            return self._i2c_requests()
        if self._sightings is None or not self._seen_now:
            return ()
        return [self.pack_message({'sightings': list(self._seen_now)})]

    def _deciding(self) -> bool:
        """Whether this step's `act` makes a new decision (else it holds the last one)."""
        return self._countdown <= 0 or self._held is None

    def _i2c_requests(self):
        """I2C: at a decision, an empty request to each teammate my prior selects from my current observation."""
        if not self._deciding() or self._current is None:
            return ()
        self._replies = {}
        self._asked = tuple(int(j) for j in self.policy.requests(self.policy.features(self._current), self.index))
        return [self.pack_message({I2C_KEY: None}, recipient=j) for j in self._asked]

    def receive_requests(self, messages) -> None:
        super().receive_requests(messages)
        self._hear(messages)              # a delayed TarMAC message may be released in the requests round
        if self.spec.comm == 'i2c':
            self._askers += [m.sender for m in messages if isinstance(m.content, dict)
                             and I2C_KEY in m.content and m.content[I2C_KEY] is None and m.sender != self.index]
        if self._sightings is None:
            return
        seen = np.zeros((1, self.num_targets), dtype=bool)
        location = np.zeros((1, self.num_targets, 2))
        for message in messages:
            for t, x, y in message.content.get('sightings', ()) if isinstance(message.content, dict) else ():
                if 0 <= t < self.num_targets:
                    seen[0, t], location[0, t] = True, (x, y)
        self._sightings.see(seen, location)

    def send_responses(self):
        """TarMAC: the message of my last decision, once, to the whole team (my own copy is ignored).
        I2C: my raw current observation to each teammate that asked in this step."""
        if self.spec.comm == 'i2c':
            askers, self._askers = self._askers, []
            if self._current is None:
                return ()
            return [self.pack_message({I2C_KEY: self._current.copy()}, recipient=int(j)) for j in askers]
        if self._outbox is None:
            return ()
        message, self._outbox = self.pack_message({MESSAGE_KEY: self._outbox}), None
        return [message]

    def receive_responses(self, messages) -> None:
        super().receive_responses(messages)
        self._hear(messages)
        if self.spec.comm == 'i2c':
            for message in messages:
                content = message.content
                if (isinstance(content, dict) and isinstance(content.get(I2C_KEY), np.ndarray)
                        and content[I2C_KEY].shape == self._observation_shape and message.sender in self._asked):
                    self._replies[message.sender] = content[I2C_KEY]

    def _hear(self, messages) -> None:
        """Keep each teammate's latest TarMAC message (a malformed one, or one of mine, is ignored)."""
        if self.spec.comm != 'tarmac':
            return
        size = self._memory[2].shape[-1]
        for message in messages:
            content, sender = message.content, message.sender
            if not isinstance(content, dict) or MESSAGE_KEY not in content or sender == self.index:
                continue
            vector = np.asarray(content[MESSAGE_KEY], dtype=np.float32)
            if vector.shape == (size,) and 0 <= sender < self.num_teammates:
                self._heard[sender] = vector

    def _team_memory(self):
        """TarMAC: the actor's state for this agent's decision: (h, c) (1, lstm) and the N messages it reads
        (N, key + value), its own last one in its row, zeros for teammates not heard from; forgets them."""
        h, c, own = self._memory
        messages = torch.zeros(self.num_teammates, own.shape[-1])
        for sender, vector in self._heard.items():
            messages[sender] = torch.from_numpy(vector)
        messages[self.index] = own[0]
        self._heard = {}
        return h, c, messages

    def _teammates(self, features: np.ndarray) -> torch.Tensor:
        """I2C: (N - 1, D) the replies' features in my cyclic teammate slots (zeros where none came); forgets them."""
        n = self.num_teammates
        slots = torch.zeros(n - 1, features.shape[-1])
        for k in range(n - 1):
            reply = self._replies.get((self.index + 1 + k) % n)
            if reply is not None:
                slots[k] = torch.as_tensor(self.policy.features(reply), dtype=torch.float32)
        self._replies, self._asked = {}, ()
        return slots

    def _outputs(self, features: np.ndarray) -> np.ndarray:
        """This agent's network outputs (A,) for its features (D,), its recurrent state and messages updated."""
        spec = self.spec
        if network_kind(spec.network).team_input:   # MA-TD3: one actor per agent; my row of the team input
            team_input = np.zeros((spec.num_agents, features.shape[-1]), dtype=np.float32)
            team_input[self.index] = features
            return self.policy.outputs(team_input)[self.index]
        if spec.comm == 'tarmac':            # one receiver (1, ...) reading N senders (N, 64)
            outputs, self._memory = self.policy.outputs(features[None], self._team_memory())
            self._outbox = self._memory[2][0].numpy().copy()
        elif spec.comm == 'i2c':             # my row, reading the replies in my teammates' slots
            outputs, self._memory = self.policy.outputs(features[None], self._memory,
                                                        teammates=self._teammates(features)[None],
                                                        agents=torch.tensor([self.index]))
        elif self.policy.recurrent:
            outputs, self._memory = self.policy.outputs(features[None], self._memory)
        else:
            outputs = self.policy.outputs(features[None])
        return outputs[0]

    def act(self, observation, info=None, deterministic=None):
        self._current = None
        observation = self._accept(observation)
        if self._sightings is not None and not self._observed:
            self._remember(observation)
        self._observed = False
        if self._deciding():
            memory = None if self._sightings is None else self._sightings.features(observation[None, None])[0, 0]
            features = self.policy.features(observation, memory, self._previous)
            greedy = self.deterministic if deterministic is None else deterministic
            self._held = self.spec.choose(self._outputs(features), features, greedy, self.np_random)
            if not self.spec.closed_loop:
                self._action = self.spec.decode(self._held[None], observation[None])[0]
            self._countdown = self.frame_skip
        self._countdown -= 1
        self._previous = np.array(observation, dtype=np.float64)
        if self.spec.closed_loop:             # HRL: the selection is held; the executor re-aims every step
            return self.spec.decode(self._held[None], observation[None])[0]
        return self._action.copy()


class PolicyCameraAgent(_PolicyAgentMixin, CameraAgentBase):
    """A camera driven by a trained `mate.learn` policy (`PolicyCameraAgent.from_checkpoint(path)`)."""


class PolicyTargetAgent(_PolicyAgentMixin, TargetAgentBase):
    """A target driven by a trained `mate.learn` policy (`PolicyTargetAgent.from_checkpoint(path)`)."""


AGENT_CLASSES = {Team.CAMERA: PolicyCameraAgent, Team.TARGET: PolicyTargetAgent}


def load_agent(spec: str, team):
    """An agent factory for `checkpoint:PATH` or `pretrained:NAME`, called as `factory(seed=..., **kwargs)`
    (kwargs: deterministic, frame_skip). The checkpoint is read once, here, so errors surface early."""
    team = as_team(team)
    kind, sep, value = spec.partition(':')
    if not sep or kind not in ('checkpoint', 'pretrained') or not value:
        raise ValueError(f"agent spec {spec!r}: expected 'checkpoint:PATH' or 'pretrained:NAME'")
    path = Path(value).expanduser() if kind == 'checkpoint' else pretrained_path(value)
    return functools.partial(AGENT_CLASSES[team], load_policy(path, team))
