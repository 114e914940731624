"""`PolicySpec`: what a trained policy is, and the one pipeline from observations to actions.

A spec is saved in every checkpoint and policy file. It says which game and team the policy plays, how a
raw observation becomes the network's input (`features`), what the network's outputs mean and how they
become env actions (`choose`, `decode`), and which network reads them. Training envs (`TrainingEnv`),
batched evaluation (`PolicyTeam`) and the deployment agents all go through these methods, so the three
cannot drift apart.

    raw observations (..., N, D_raw) float64
      -> features(raw, memory, previous)   relative coordinates rescaled to [-1, 1] (float32), then the
                                           team's sighting-memory columns (4 per target slot) and each
                                           seen target's displacement over one held decision (2 per slot)
      -> network                           logits (..., N, heads x choices), or actions in [-1, 1]^2
      -> choose(logits, features, ...)     one choice per head (..., N, heads); HRL-joint policies never
                                           pick a selection that keeps an invisible target
      -> decode(held, raw)                 env actions (..., N, 2) float64: a grid move scaled by the agent's
                                           own step limits, the HRL executor aiming at the selected targets,
                                           or the continuous share of the step limits

Action kinds (`action`):

* `'grid'`: one of `levels`^2 moves (one head);
* `'hrl'`: cameras; one keep/ignore head (2 choices) per target slot, the rule executor of `mate.policies.hrl`
  aims at the kept visible targets at every env step (closed loop);
* `'hrl-joint'`: cameras; one head of 2^Nt choices, a subset of target slots (the spec's Discrete(256));
* `'continuous'`: each agent's share of its step limits, in [-1, 1]^2 (MA-TD3);
* `'discrete'`: `levels` abstract choices (one head) that no game decodes: the toy tasks of the tests.

Open-loop actions (grid, continuous) are decoded once per decision and held; HRL selections are held and
decoded at every env step (`closed_loop`). The limits an agent's actions are scaled by are constant within
an episode, so both readings agree for open-loop actions.

A mismatch between a spec and a game, or between two specs (resuming, warm starts), is reported by the
setting that differs, in the words of the command line (`differences`): 'trained with --hrl; this run is
without it', 'trained for MATE-4v8-9-v0; this run plays MATE-8v8-9-v0 (--config)'.
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np

from ..agents.utils import observation_scaling, relative_in_place, scale_in_place
from ..core.arrays import array_namespace, float64_copy, on_device_of
from ..messages import Team
from ..spaces import observation_indices_of
from ..teams.interface import action_high, as_team
from ..wrappers.discrete_action_spaces import disk_grid, square_grid
from .actors import network_kind
from .hrl import executor_actions, joint_allowed, selection_bits
from .memory import MEMORY_FEATURES
from .velocity import VELOCITY_FEATURES, target_displacements

__all__ = ['ACTIONS', 'SPEC_VERSION', 'PolicySpec', 'SpecError', 'action_high', 'as_team',
           'discrete_to_continuous', 'preprocess_observation']

SPEC_VERSION = 2
"""Version of the saved form (`to_dict`)."""
ACTIONS = ('grid', 'hrl', 'hrl-joint', 'continuous', 'discrete')
"""Action kinds (module docstring)."""


class SpecError(ValueError):
    """A spec that is invalid, or that does not fit a game or another spec (one line, naming the setting)."""


def preprocess_observation(observation, team, num_cameras, num_targets, num_obstacles):
    """Raw observations (..., D) -> float32 relative coordinates rescaled to [-1, 1] (numpy arrays, or tensors on
    their device: one body, `mate.core.arrays`)."""
    team = as_team(team)
    out = relative_in_place(float64_copy(observation), team, num_cameras, num_targets, num_obstacles)
    out = scale_in_place(out, observation_scaling(team, num_cameras, num_targets, num_obstacles))
    return array_namespace(out).astype(out, array_namespace(out).float32)


def discrete_to_continuous(indices, observation, team, levels: int = 5):
    """Action indices (..., N) -> continuous actions (..., N, 2) scaled by each agent's own bounds,
    read from its raw observation (..., N, D) (`action_high`); numpy, or tensors on their device."""
    if not hasattr(indices, 'shape'):
        indices = np.asarray(indices, dtype=np.int64)
    grid = square_grid(levels) if as_team(team) is Team.CAMERA else disk_grid(levels)
    return on_device_of(grid, observation)[indices] * action_high(observation, team)


# flags of the command line that set each field, for `differences`
_FLAGS = {'team': '--team', 'env_id': '--config', 'config': '--config', 'frame_skip': '--frame-skip',
          'levels': '--levels', 'memory': '--memory', 'velocity': '--velocity',
          'full_observability': '--full-observability', 'hidden': '--hidden', 'activation': '--activation',
          'lstm': '--lstm'}


@dataclasses.dataclass(frozen=True)
class PolicySpec:
    """A policy's contract (module docstring). Build one with `PolicySpec.for_game(...)`, which reads the
    entity counts and sizes from the game; `to_dict` / `from_dict` save and load it.

    Args:
        team: 'camera' or 'target'.
        env_id: registered env ID of the game ('MATE-4v8-9-v0'), or 'MultiAgentTracking-v0' with `config`.
        config: a YAML/JSON config path for 'MultiAgentTracking-v0' (None for a registered preset).
        counts: (cameras, targets, obstacles) of the game.
        frame_skip: env steps a decision is held.
        action: the action kind, one of `ACTIONS`.
        levels: grid levels per axis ('grid' only; 0 otherwise).
        memory: env steps the team's shared sighting memory keeps a target (cameras; 0: no memory columns).
        velocity: the target displacement columns (cameras).
        full_observability: the policy saw every entity (the `EnhancedObservation` wrapper; deploy it with
            `mate evaluate --enhanced-observation TEAM`).
        network: a registered network (`mate.policies.actors.NETWORK_KINDS`).
        hidden: widths of the network's hidden layers.
        activation: 'tanh' or 'relu'.
        lstm: LSTM cells of a recurrent actor (0: feed-forward; TarMAC and I2C always have one).
        obs_dim: width of `features` (checked against the game).
        state_dim: width of the global state the critic read in training.
        num_agents: agents of the team.
        algo: the algorithm that trained it (for information).
        deterministic: the default way its agents act: argmax (True) or sampling.
    """

    team: str
    env_id: str
    config: str | None
    counts: tuple[int, int, int]
    frame_skip: int
    action: str
    levels: int
    memory: int
    velocity: bool
    full_observability: bool
    network: str
    hidden: tuple[int, ...]
    activation: str
    lstm: int
    obs_dim: int
    state_dim: int
    num_agents: int
    algo: str = ''
    deterministic: bool = False

    def __post_init__(self) -> None:
        if self.team not in ('camera', 'target'):
            raise SpecError(f"team must be 'camera' or 'target', got {self.team!r}")
        if self.action not in ACTIONS:
            raise SpecError(f'action must be one of {", ".join(ACTIONS)}, got {self.action!r}')
        try:
            kind = network_kind(self.network)
        except ValueError as exc:
            raise SpecError(str(exc)) from None
        if self.action.startswith('hrl') and self.team != 'camera':
            raise SpecError('HRL (target selection + rule executor) exists for cameras only (--hrl)')
        if self.action == 'grid' and not self.levels >= 2:
            raise SpecError(f'a grid of moves needs levels >= 2, got {self.levels}')
        if self.action == 'discrete' and not self.levels >= 1:
            raise SpecError(f'discrete actions need levels >= 1 choices, got {self.levels}')
        if (self.memory or self.velocity) and self.team != 'camera':
            raise SpecError('the sighting memory and the target velocity columns exist for cameras only '
                            '(--memory, --velocity)')
        if self.memory < 0:
            raise SpecError(f'memory must be a period of at least 1 env step, or 0 for none; got {self.memory}')
        if kind.team is not None and self.team != kind.team:
            raise SpecError(f"network {self.network!r} plays the {kind.team}s only: it needs --team {kind.team}")
        if kind.needs_lstm and self.lstm <= 0:
            raise SpecError(f'network {self.network!r} needs an LSTM (lstm > 0), got {self.lstm}')
        if kind.action is not None and self.action != kind.action:
            raise SpecError(f'network {self.network!r} acts with {kind.action} actions, got {self.action!r}')
        object.__setattr__(self, 'counts', tuple(int(n) for n in self.counts))
        object.__setattr__(self, 'hidden', tuple(int(n) for n in self.hidden))

    # ------------------------------------------------------------------ construction and saved form
    @classmethod
    def for_game(cls, team: str, env_id: str, config: str | None = None, *, frame_skip: int, action: str = 'grid',
                 levels: int = 5, memory: int = 0, velocity: bool = False, full_observability: bool = False,
                 network: str = 'mlp', hidden=(256, 256), activation: str = 'tanh', lstm: int = 0, algo: str = '',
                 deterministic: bool = False) -> PolicySpec:
        """A spec for the game `env_id` (+ `config`), its counts and sizes read from the game's spaces."""
        from ..envs.vector import make_vec

        vec = make_vec(env_id, num_envs=1, config=config)
        counts = (vec.num_cameras, vec.num_targets, vec.num_obstacles)
        raw_dim = vec.single_observation_space[0 if team == 'camera' else 1].shape[-1]
        obs_dim = (raw_dim + (MEMORY_FEATURES * counts[1] if memory else 0)
                   + (VELOCITY_FEATURES * counts[1] if velocity else 0))
        return cls(team=team, env_id=env_id, config=config, counts=counts, frame_skip=int(frame_skip), action=action,
                   levels=int(levels) if action in ('grid', 'discrete') else 0, memory=int(memory),
                   velocity=bool(velocity),
                   full_observability=bool(full_observability), network=network, hidden=tuple(hidden),
                   activation=activation, lstm=int(lstm), obs_dim=obs_dim, state_dim=vec.single_state_space.shape[0],
                   num_agents=counts[0] if team == 'camera' else counts[1], algo=algo, deterministic=deterministic)

    def replace(self, **changes) -> PolicySpec:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """The saved form: plain data (JSON-able), with the spec version."""
        data = dataclasses.asdict(self)
        data.update(counts=list(self.counts), hidden=list(self.hidden), version=SPEC_VERSION)
        return data

    @classmethod
    def from_dict(cls, data: dict) -> PolicySpec:
        """A spec from `to_dict`'s form; SpecError for another version or missing/unknown fields."""
        if not isinstance(data, dict):
            raise SpecError(f'a policy spec is a dict, got {type(data).__name__}')
        data = dict(data)
        version = data.pop('version', None)
        if version != SPEC_VERSION:
            raise SpecError(f'policy spec version {version!r}; this mate reads version {SPEC_VERSION}')
        fields = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - fields)
        missing = sorted(f.name for f in dataclasses.fields(cls)
                         if f.name not in data and f.default is dataclasses.MISSING)
        if unknown or missing:
            raise SpecError(f'policy spec: unknown fields {unknown}, missing fields {missing}')
        return cls(**data)

    def __str__(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    # ------------------------------------------------------------------ derived sizes
    @property
    def team_enum(self) -> Team:
        return as_team(self.team)

    @property
    def hrl(self) -> bool:
        return self.action.startswith('hrl')

    @property
    def continuous(self) -> bool:
        return self.action == 'continuous'

    @property
    def closed_loop(self) -> bool:
        """Whether a held decision is decoded again at every env step (HRL) rather than once per decision."""
        return self.hrl

    @property
    def heads(self) -> int:
        """Independent choices per agent (Nt for 'hrl', 1 otherwise; continuous: 1)."""
        return self.counts[1] if self.action == 'hrl' else 1

    @property
    def choices(self) -> int:
        """Options of each head (continuous: the 2 action dimensions)."""
        return {'grid': self.levels ** 2, 'hrl': 2, 'hrl-joint': 2 ** self.counts[1], 'continuous': 2,
                'discrete': self.levels}[self.action]

    @property
    def num_actions(self) -> int:
        """Network outputs per agent: heads x choices (logits), or the 2 action dimensions."""
        return self.heads * self.choices

    @property
    def comm(self) -> str:
        """The communication scheme: 'tarmac', 'i2c' or 'none'."""
        return network_kind(self.network).comm

    @property
    def recurrent(self) -> bool:
        return self.lstm > 0 or network_kind(self.network).recurrent

    @property
    def value_based(self) -> bool:
        """The outputs are Q-values, acted on greedily (IQL, QMIX)."""
        return network_kind(self.network).value_based

    @property
    def game(self) -> str:
        """The game's name as the command line takes it (preset or config path)."""
        return self.config or self.env_id.removesuffix('-v0')

    # ------------------------------------------------------------------ the pipeline
    def features(self, raw: np.ndarray, memory: np.ndarray | None = None,
                 previous: np.ndarray | None = None) -> np.ndarray:
        """The network input (..., D) float32 from raw observations (..., D_raw) of the team: preprocessed, then
        the sighting-memory columns `memory` (..., 4 Nt) of a policy with `memory`, then (velocity) each seen
        target's displacement since the raw observations `previous` (..., D_raw) of the env step before."""
        columns = [preprocess_observation(raw, self.team, *self.counts)]
        if self.memory:
            if memory is None:
                raise SpecError('this policy reads the team\'s sighting memory (--memory): pass its columns')
            columns.append(memory)
        if self.velocity:
            if previous is None:
                raise SpecError('this policy reads target velocities (--velocity): pass the previous observations')
            columns.append(target_displacements(raw, previous, self.counts, self.frame_skip))
        return array_namespace(columns[0]).concat(columns, axis=-1) if len(columns) > 1 else columns[0]

    def visible(self, features: np.ndarray) -> np.ndarray:
        """(..., Nt) bool: the target slots a camera sees, from its features (..., D) (the rescaled flags)."""
        begin = int(observation_indices_of(Team.CAMERA, *self.counts)[2])
        return features[..., begin + 4:begin + 5 * self.counts[1]:5] > 0.5

    def allowed(self, features: np.ndarray) -> np.ndarray | None:
        """HRL: (..., heads, choices) bool, the choices that keep only visible targets ('hrl': 'ignore' always,
        'keep' for the visible slots; 'hrl-joint': the subsets of visible slots), from features (..., D);
        None (every choice allowed) for the other kinds."""
        if not self.hrl:
            return None
        visible = self.visible(features)
        if self.action == 'hrl':
            xp = array_namespace(visible)
            return xp.stack([xp.ones_like(visible), visible], axis=-1)
        return joint_allowed(visible)[..., None, :]

    def choose(self, outputs: np.ndarray, features: np.ndarray, deterministic: bool,
               rng: np.random.Generator) -> np.ndarray:
        """What to hold from network outputs (..., A) and the features they came from (..., D): continuous
        actions (..., 2) as they are; else a choice per head (..., heads) int64, the argmax or one draw from
        the softmax (one uniform number per head from `rng`, in row order), never a masked-out HRL-joint choice
        (such selections were never taken in training, so their values are untrained)."""
        if self.continuous:
            return np.asarray(outputs, dtype=np.float64)
        logits = np.asarray(outputs).reshape(*outputs.shape[:-1], self.heads, self.choices)
        if self.action == 'hrl-joint':
            logits = np.where(self.allowed(features), logits, -np.inf)
        if deterministic:
            return logits.argmax(axis=-1)
        p = np.exp(logits - logits.max(axis=-1, keepdims=True))
        p /= p.sum(axis=-1, keepdims=True)
        u = rng.random(p.shape[:-1] + (1,))
        return np.minimum((p.cumsum(axis=-1) < u).sum(axis=-1), p.shape[-1] - 1)

    def decode(self, held, raw):
        """Env actions (..., N, 2) float64 from what a team holds, (..., N, heads) int choices or (..., N, 2)
        continuous shares, and its raw observations (..., N, D_raw) at this env step (numpy arrays, or tensors on
        their device)."""
        if not hasattr(held, 'shape'):
            held = np.asarray(held)
        if self.action == 'grid':
            return discrete_to_continuous(held[..., 0], raw, self.team, self.levels)
        if self.action == 'continuous':
            xp = array_namespace(held)        # (minimum/maximum: numpy's own functions; the namespace's clip is not)
            return xp.minimum(xp.maximum(held, -1.0), 1.0) * action_high(raw, self.team)
        if self.action == 'discrete':
            raise SpecError("'discrete' actions are decoded by their own env (a toy task), not by a game")
        bits = held if self.action == 'hrl' else on_device_of(selection_bits(self.counts[1]), held)[held[..., 0]]
        return executor_actions(raw, bits, *self.counts)

    # ------------------------------------------------------------------ fitting games and other specs
    def check_game(self, team, counts, source: str = 'the policy') -> None:
        """SpecError unless this policy plays `team` in a game of `counts` (cameras, targets, obstacles)."""
        team = as_team(team).name.lower()
        if team != self.team:
            raise SpecError(f'{source} was trained for the {self.team} team, not the {team} team')
        counts = tuple(int(n) for n in counts)
        if counts != self.counts:
            raise SpecError(f'{source} was trained with (cameras, targets, obstacles) = {self.counts} '
                            f'({self.game}); this game has {counts}')

    def differences(self, other: PolicySpec, ignore=('algo', 'deterministic')) -> list[str]:
        """How `other` (this run's spec) differs from this one (a checkpoint's), one phrase per setting in the
        words of the command line, the cause first (the action kind before the sizes it implies)."""
        order = ('team', 'env_id', 'config', 'action', 'network', 'lstm', 'hidden', 'activation', 'memory', 'velocity',
                 'full_observability', 'frame_skip', 'levels', 'counts', 'obs_dim', 'state_dim', 'num_agents')
        phrases = []
        for name in order:
            saved, wanted = getattr(self, name), getattr(other, name)
            if name in ignore or saved == wanted:
                continue
            phrases.append(_difference(name, saved, wanted))
            if name in ('team', 'env_id', 'config', 'action'):
                break     # what follows from these (sizes) would only repeat them
        return phrases


def _difference(name: str, saved: Any, wanted: Any) -> str:
    if name == 'team':
        return f'trained for the {saved} team; this run is for the {wanted} team (--team)'
    if name in ('env_id', 'config'):
        return f'trained for {saved}; this run plays {wanted} (--config)'
    if name == 'action':
        def flags(action: str) -> str:
            return {'grid': 'grid moves (no --hrl)', 'hrl': 'per-target HRL selections (--hrl)',
                    'hrl-joint': 'joint HRL selections (--hrl --selection joint)',
                    'continuous': 'continuous actions (matd3)',
                    'discrete': 'abstract discrete choices (a toy task)'}[action]
        return f'trained with {flags(saved)}; this run has {flags(wanted)}'
    if name == 'network':
        return f'trained with the {saved} network; this run builds the {wanted} network'
    flag = _FLAGS.get(name)
    if flag is None:
        return f'{name} is {saved!r} in the checkpoint, {wanted!r} here'
    if isinstance(saved, bool) or isinstance(wanted, bool):
        return f'trained with {flag}; this run is without it' if saved else f'trained without {flag}; this run has it'
    if name == 'memory' and not (saved and wanted):
        return f'trained with {flag} {saved}; this run is without it' if saved else \
            f'trained without {flag}; this run has {flag} {wanted}'
    show = (lambda v: ' '.join(map(str, v))) if isinstance(saved, tuple) else str
    return f'trained with {flag} {show(saved)}; this run has {flag} {show(wanted)}'
