"""Trained policies as `mate` agents, and `load_agent('checkpoint:PATH' | 'pretrained:NAME', team)`.

A policy agent preprocesses its raw observation exactly as in training (relative coordinates, then
rescaling to [-1, 1]), picks one of the `levels**2` discrete actions, maps it onto the grid of
`DiscreteCamera` / `DiscreteTarget` scaled by its own step bounds, and holds the decision for
`frame_skip` env steps (the training frame skip).

Policies trained with learned messages (TarMAC, `meta['comm']`) exchange them as `mate.Message`s through
the env's channel, so the communication wrappers (RandomMessageDropout, RestrictedCommunicationRange,
ExtraCommunicationDelays, NoCommunication, ...) act on them. An agent keeps its LSTM state and its own last
message; at a decision it reads N messages (spec §2.8): its own (kept locally, never lost) and, per teammate,
the last `{'tarmac': float32 array (64,)}` message from that sender that arrived since its previous decision,
zeros when none did (dropped, out of range, not yet released by a delay, silenced), as after a reset.
After the decision it broadcasts its new message once, in the response round of the next env step (the
first round after `act`), so it is read at the teammates' next decision: the one-decision delay of
training. With a hold of `frame_skip` > 1 steps a delay of up to `frame_skip - 1` steps still arrives in
time; a later message is read at the first decision after it arrives.

I2C policies (`meta['comm'] == 'i2c'`) use the two rounds of one step, no delay (spec §2.8): at a decision,
an agent sends an empty request `{'i2c': None}` in the request round to each teammate its prior network
selects (from its current observation); a teammate answers every request it received in that step's
response round with its raw current observation `{'i2c': float64 array (D_raw,)}`; the agent preprocesses the
replies as its own observation and reads them in the teammates' slots, zeros for a reply that did not come
(dropped, out of range, delayed past the decision), which is `I2CActor.step` on its own row. Only replies
from the teammates it asked, in the response round of its decision step, are read (a late reply is ignored).

Value-based policies (IQL, QMIX) are read the same way, their Q-values taken as logits and acted on greedily
(QMIX's GRU state carried like an LSTM's). MADDPG policies (`meta['continuous']`) hold one actor per agent:
an agent feeds its own network (by its index in the team) and holds the continuous action it returns, a share
of its own step bounds, for `frame_skip` steps.

HRL camera policies (`meta['hrl']`) instead hold a target selection (one bit per target slot) for
`frame_skip` steps and let the rule executor of `mate.learn.hrl` aim at every step.

Camera policies trained with the team's sighting memory (`meta['memory']`, `mate train --memory`) keep
that memory as agents: each camera broadcasts the targets it sees in the first communication round of
every step (`{'sightings': [(slot, x, y), ...]}`) and records its teammates' sightings, so every camera
of the team holds the memory the learner had (`mate.group_step` drives the rounds; an agent whose
`observe` was skipped updates its memory from `act`'s observation, without its teammates' news).

Camera policies trained with target velocities (`meta['velocity']`, `mate train --velocity`) keep their
previous observation and compute the same displacement columns as the training env (over the training
frame skip, whatever the agent's own hold).

The network is shared, read-only, by every agent cloned from one prototype (`spawn`).
"""

from __future__ import annotations

import contextlib
import functools
from pathlib import Path

import numpy as np
import torch

from ..agents.base import CameraAgentBase, TargetAgentBase
from ..messages import Team
from .checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from .envs import action_high, as_team, discrete_to_continuous, preprocess_observation
from .hrl import executor_actions, masked_selection_logits, selection_bits
from .memory import SightingMemory, camera_sightings
from .networks import Actor, make_actor
from .velocity import target_displacements

__all__ = [
    'PRETRAINED_DIR',
    'LoadedPolicy',
    'PolicyCameraAgent',
    'PolicyTargetAgent',
    'export_policy',
    'load_agent',
    'load_policy',
    'pretrained_path',
]

PRETRAINED_DIR = Path(__file__).resolve().parent.parent / 'pretrained'


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
    """An actor network plus what is needed to feed it; deep copies return the same object (shared).

    `threads`: torch threads of its forward passes (1). A decision is a small matrix product: on our
    2-core machines two threads played `mate evaluate` 5-10x slower than one when the other core was busy
    (29 against 155-316 env-steps/s for the shipped HRL cameras), and no faster when it was idle.
    """

    threads = 1

    def __init__(self, actor: Actor, meta: dict, source: str = '') -> None:
        self.actor = actor.eval()
        self.meta = dict(meta)
        self.source = source

    def __deepcopy__(self, memo):
        return self

    @property
    def recurrent(self) -> bool:
        return bool(getattr(self.actor, 'recurrent', False))

    @property
    def communicates(self) -> bool:
        """Its agents exchange messages (TarMAC or I2C, `comm`)."""
        return bool(getattr(self.actor, 'communicates', False))

    @property
    def comm(self) -> str:
        """The communication scheme of its actor: 'none', 'tarmac' or 'i2c'."""
        return getattr(self.actor, 'scheme', 'none')

    def initial_memory(self, *shape: int):
        """The recurrent actor's zero state for `shape` agents (None for a feed-forward actor)."""
        return self.actor.initial_state(*shape) if self.recurrent else None

    def inputs(self, raw: np.ndarray, memory: np.ndarray | None = None, previous: np.ndarray | None = None):
        """The network's input (..., D) from raw observations (..., D_raw) of its team, as in training:
        preprocessed (relative coordinates rescaled to [-1, 1]), then the sighting-memory columns `memory`
        (..., 4 Nt) of a policy trained with them, then (velocity policies) each seen target's displacement
        since the observations `previous` (..., D_raw) of the last env step."""
        meta = self.meta
        counts = tuple(meta['counts'])
        columns = [preprocess_observation(raw, meta['team'], *counts)]
        if memory is not None:
            columns.append(memory)
        if meta.get('velocity'):
            columns.append(target_displacements(raw, previous, counts, meta['frame_skip']))
        return np.concatenate(columns, axis=-1) if len(columns) > 1 else columns[0]

    @torch.no_grad()
    def logits(self, processed: np.ndarray, memory=None, **inputs):
        """Logits (..., A) of processed observations (..., D); with a recurrent actor also the next memory.
        `inputs`: more arguments of the recurrent actor's `step` (I2C: `teammates`, `agents`)."""
        obs = torch.as_tensor(processed, dtype=torch.float32)
        with torch_threads(self.threads):
            if not self.recurrent:
                return self.actor(obs).numpy()
            logits, memory = self.actor.step(obs, memory, **inputs)
        return logits.numpy(), memory

    @torch.no_grad()
    def requests(self, processed: np.ndarray, agent: int) -> np.ndarray:
        """I2C: the teammates (indices in the team) that agent `agent` asks, from its processed observation (D,)."""
        with torch_threads(self.threads):
            logits = self.actor.request_logits(torch.as_tensor(processed[None], dtype=torch.float32),
                                               torch.tensor([agent]))[0]
        return (agent + 1 + np.flatnonzero(logits.numpy() >= 0)) % self.actor.num_agents


def choose(logits: np.ndarray, deterministic: bool, rng: np.random.Generator) -> np.ndarray:
    """Choices (...,) from logits (..., A): the argmax, or one draw from softmax(logits) per row (one
    uniform number each from `rng`, in row order)."""
    if deterministic:
        return logits.argmax(axis=-1)
    p = np.exp(logits - logits.max(axis=-1, keepdims=True))
    p /= p.sum(axis=-1, keepdims=True)
    u = rng.random(p.shape[:-1] + (1,))
    return np.minimum((p.cumsum(axis=-1) < u).sum(axis=-1), p.shape[-1] - 1)


def load_policy(path, team=None) -> LoadedPolicy:
    """The actor of a checkpoint. CheckpointError if unreadable or trained for the other team."""
    expect = None if team is None else dict(team=as_team(team).name.lower())
    data = load_checkpoint(path, expect=expect)
    meta, config = data['meta'], data['config']
    try:
        actor = make_actor(meta.get('actor', 'mlp'), meta['obs_dim'], meta['num_actions'], tuple(config['hidden']),
                           config['activation'], meta, int(config.get('lstm', 0)))
    except (KeyError, TypeError, ValueError) as exc:
        raise CheckpointError(f'checkpoint {str(path)!r}: cannot build its actor from the metadata: {exc}') from None
    try:
        actor.load_state_dict(data['actor'])
    except RuntimeError as exc:
        raise CheckpointError(f'checkpoint {str(path)!r}: actor weights do not fit its own metadata: '
                              f'{str(exc).splitlines()[0]}') from None
    return LoadedPolicy(actor, meta, str(path))


def export_policy(checkpoint, out, note: str = '', deterministic: bool = False) -> Path:
    """Write the acting part of a checkpoint (actor weights, meta, config, step count, `note`) to `out`:
    a small file for `mate/pretrained/` that `load_policy` / `pretrained:NAME` read. `deterministic`
    is stored as the agents' default way of acting (argmax instead of sampling), the way it was scored."""
    data = load_checkpoint(checkpoint)
    actor = {k: v.clone() for k, v in data['actor'].items()}
    meta = dict(data['meta'], deterministic=bool(deterministic))
    return save_checkpoint(out, dict(actor=actor, meta=meta, config=data['config'],
                                     env_steps=data.get('env_steps', 0), note=note))


MESSAGE_KEY = 'tarmac'
"""Content key of a TarMAC agent's broadcast: `{'tarmac': float32 array (key + value,)}` (a copy, compared by
value as every message content is: `mate.messages.values_equal`)."""
I2C_KEY = 'i2c'
"""Content key of I2C messages: a request `{'i2c': None}`, a reply `{'i2c': float64 array (D_raw,)}` (a copy)."""


class _PolicyAgentMixin:
    """Shared logic of the camera and target policy agents."""

    def __init__(self, policy: LoadedPolicy, seed: int | None = None, deterministic: bool | None = None,
                 frame_skip: int | None = None) -> None:
        if policy.meta['team'] != self.TEAM.name.lower():
            raise CheckpointError(f'policy {policy.source!r} was trained for the {policy.meta["team"]} team; '
                                  f'{type(self).__name__} needs a {self.TEAM.name.lower()} policy')
        self.policy = policy
        # None: the policy file's default (exported policies: the way they were scored), else sampling
        self.deterministic = bool(policy.meta.get('deterministic', False) if deterministic is None else deterministic)
        self.frame_skip = int(frame_skip or policy.meta.get('frame_skip', 1))
        self._held = None
        self._countdown = 0
        super().__init__(seed=seed)

    @classmethod
    def from_checkpoint(cls, path, seed: int | None = None, deterministic: bool | None = None,
                        frame_skip: int | None = None):
        return cls(load_policy(path, cls.TEAM), seed=seed, deterministic=deterministic, frame_skip=frame_skip)

    def reset(self, observation) -> None:
        super().reset(observation)
        counts = (self.num_cameras, self.num_targets, self.num_obstacles)
        if list(counts) != list(self.policy.meta['counts']):
            raise ValueError(f'policy {self.policy.source!r} was trained with (cameras, targets, obstacles) = '
                             f'{tuple(self.policy.meta["counts"])}; this environment has {counts}')
        self._held, self._countdown = None, 0
        self._memory = self.policy.initial_memory(1)     # TarMAC: (h, c, own last message), each (1, size)
        self._heard = {}                                 # TarMAC: sender -> its message since my last decision
        self._outbox = None                              # TarMAC: my new message, until the next response round
        self._current = None                             # I2C: this step's observation (observe), until act
        self._askers = []                                # I2C: teammates that asked for it in this step
        self._asked = ()                                 # I2C: teammates I asked at this step's decision
        self._replies = {}                               # I2C: sender -> its raw observation, for my decision
        period = int(self.policy.meta.get('memory', 0))
        self._sightings = SightingMemory(1, counts, period) if period else None
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
        if self.policy.comm == 'i2c':
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
        self._asked = tuple(int(j) for j in self.policy.requests(self.policy.inputs(self._current), self.index))
        return [self.pack_message({I2C_KEY: None}, recipient=j) for j in self._asked]

    def receive_requests(self, messages) -> None:
        super().receive_requests(messages)
        self._hear(messages)              # a delayed TarMAC message may be released in the requests round
        if self.policy.comm == 'i2c':
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
        if self.policy.comm == 'i2c':
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
        if self.policy.comm == 'i2c':
            for message in messages:
                content = message.content
                if (isinstance(content, dict) and isinstance(content.get(I2C_KEY), np.ndarray)
                        and content[I2C_KEY].shape == self._observation_shape and message.sender in self._asked):
                    self._replies[message.sender] = content[I2C_KEY]

    def _hear(self, messages) -> None:
        """Keep each teammate's latest TarMAC message (a malformed one, or one of mine, is ignored)."""
        if self.policy.comm != 'tarmac':
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

    def _teammates(self, processed: np.ndarray) -> torch.Tensor:
        """I2C: (N - 1, D) the processed replies in my cyclic teammate slots (zeros where none came); forgets them."""
        n = self.num_teammates
        slots = torch.zeros(n - 1, processed.shape[-1])
        for k in range(n - 1):
            reply = self._replies.get((self.index + 1 + k) % n)
            if reply is not None:
                slots[k] = torch.as_tensor(self.policy.inputs(reply), dtype=torch.float32)
        self._replies, self._asked = {}, ()
        return slots

    def act(self, observation, info=None, deterministic=None):
        self._current = None
        observation = self._accept(observation)
        if self._sightings is not None and not self._observed:
            self._remember(observation)
        self._observed = False
        if self._countdown <= 0 or self._held is None:
            memory = None if self._sightings is None else self._sightings.features(observation[None, None])[0, 0]
            processed = self.policy.inputs(observation, memory, self._previous)
            if self.policy.meta.get('continuous'):   # per-agent actors (MADDPG): this agent's row of the team input
                team_input = np.zeros((self.policy.meta['num_agents'], processed.shape[-1]), dtype=np.float32)
                team_input[self.index] = processed
                self._held = self.policy.logits(team_input)[self.index]
            else:
                if self.policy.comm == 'tarmac':   # one receiver (1, ...) reading N senders (N, 64)
                    logits, self._memory = self.policy.logits(processed[None], self._team_memory())
                    self._outbox = self._memory[2][0].numpy().copy()
                elif self.policy.comm == 'i2c':     # my row, reading the replies in my teammates' slots
                    logits, self._memory = self.policy.logits(processed[None], self._memory,
                                                              teammates=self._teammates(processed)[None],
                                                              agents=torch.tensor([self.index]))
                elif self.policy.recurrent:
                    logits, self._memory = self.policy.logits(processed[None], self._memory)
                else:
                    logits = self.policy.logits(processed[None])
                logits = logits[0].reshape(self.policy.meta.get('action_heads', 1), -1)
                if self.policy.meta.get('joint_selection'):   # only selections of visible targets, as in training
                    logits = masked_selection_logits(logits, observation, self.num_cameras, self.num_targets,
                                                     self.num_obstacles)
                greedy = self.deterministic if deterministic is None else deterministic
                self._held = choose(logits, greedy, self.np_random)
            self._countdown = self.frame_skip
        self._countdown -= 1
        self._previous = np.array(observation, dtype=np.float64)
        if self.policy.meta.get('hrl'):   # target selection held; the executor re-aims every step
            selection = self._held
            if self.policy.meta.get('joint_selection'):   # one index among 2^Nt selections
                selection = selection_bits(self.num_targets)[self._held[0]]
            return executor_actions(observation, selection, self.num_cameras, self.num_targets, self.num_obstacles)
        if self.policy.meta.get('continuous'):
            return self._held * action_high(observation, self.TEAM)
        return discrete_to_continuous(self._held[:1], observation[None], self.TEAM, self.policy.meta['levels'])[0]


class PolicyCameraAgent(_PolicyAgentMixin, CameraAgentBase):
    """A camera driven by a trained `mate.learn` policy (`PolicyCameraAgent.from_checkpoint(path)`)."""


class PolicyTargetAgent(_PolicyAgentMixin, TargetAgentBase):
    """A target driven by a trained `mate.learn` policy (`PolicyTargetAgent.from_checkpoint(path)`)."""


AGENT_CLASSES = {Team.CAMERA: PolicyCameraAgent, Team.TARGET: PolicyTargetAgent}


def pretrained_path(name: str) -> Path:
    """Path of a shipped policy `mate/pretrained/NAME.pt`; ValueError listing the available ones."""
    path = PRETRAINED_DIR / f'{name}.pt'
    if not path.is_file():
        names = sorted(p.stem for p in PRETRAINED_DIR.glob('*.pt'))
        raise ValueError(f'no pretrained policy {name!r}; available: {", ".join(names) or "none"}')
    return path


def load_agent(spec: str, team):
    """An agent factory for `checkpoint:PATH` or `pretrained:NAME`, called as `factory(seed=..., **kwargs)`
    (kwargs: deterministic, frame_skip). The checkpoint is read once, here, so errors surface early."""
    team = as_team(team)
    kind, sep, value = spec.partition(':')
    if not sep or kind not in ('checkpoint', 'pretrained') or not value:
        raise ValueError(f"agent spec {spec!r}: expected 'checkpoint:PATH' or 'pretrained:NAME'")
    path = Path(value).expanduser() if kind == 'checkpoint' else pretrained_path(value)
    policy = load_policy(path, team)
    return functools.partial(AGENT_CLASSES[team], policy)
