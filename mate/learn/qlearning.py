"""What the Q-learners share (`iql.py`, `qmix.py`): their common settings and the pure pieces of double Q-learning.

* `QLearningConfig`: the options of both (the team env's and the run's, then exploration, replay timing, target
  copies, the log period, the HRL selection form); each trainer adds its replay size, network and optimiser;
* `action_kind(config)`: the spec's action kind of a config (grid moves, or HRL selections in one of two forms);
* `allowed_choices(spec, features)`: the choices an HRL camera may take, as a tensor (None for other kinds);
* formulas: `masked_argmax`, `double_q_values`, `double_q_targets`, `epsilon_greedy`;
* `QLearner`: what both learners do on the off-policy loop (`mate.learn.offpolicy_loop`): epsilon-greedy acting
  from per-head values, the learning rate's step schedule, hard target copies every `target_update` decision
  steps, the log row (epsilon, lr, loss, q_mean, buffer).

Values are per head: (..., H, C) for H independent choices of C options each (grid moves: one head of 25; HRL
'per-target': Nt heads of keep/ignore; HRL 'joint': one head of 2^Nt subsets). The value of a joint choice is the
sum of its heads' values, so its argmax is each head's own argmax.
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar, Literal

import numpy as np
import torch

from ..cli.options import option
from .offpolicy_loop import OffPolicyConfig, OffPolicyLearner
from .run import mean_or_nan
from .schedules import check_network_options, piecewise, resolve_schedule
from ..policies.spec import PolicySpec

__all__ = ['QLearner', 'QLearningConfig', 'SELECTIONS', 'action_kind', 'allowed_choices', 'double_q_targets',
           'double_q_values', 'epsilon_greedy', 'masked_argmax']

SELECTIONS = ('joint', 'per-target')
"""How HRL cameras choose targets: one of the 2^Nt subsets (the spec's Discrete(256)) or a keep/ignore bit per slot."""


@dataclasses.dataclass
class QLearningConfig(OffPolicyConfig):
    """Settings of a Q-learning run (IQL, QMIX): the off-policy loop's options, then what both learners share."""

    selection: Literal['joint', 'per-target'] = option(
        'joint', "with --hrl: 'joint' (the spec's Discrete(256)): one choice among the 2^Nt target subsets, those "
                 "keeping an invisible target never taken; 'per-target': a keep/ignore head per target slot")
    target_update: int = option(500, 'decision steps between hard copies to the target networks', minimum=1)
    epsilon_schedule: tuple[tuple[float, float], ...] = option(
        ((0, 1.0), (50_000, 0.02)), 'exploration rate, piecewise linear in decision steps [[step, epsilon], ...] '
        '(a step "P%%": P %% of --steps)')

    SCHEDULES: ClassVar[tuple[str, ...]] = ('epsilon_schedule',)
    """The schedule options of the config (a learner adds its learning rate's): checked once, in __post_init__."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.selection not in SELECTIONS:
            raise ValueError(f'selection must be one of {", ".join(SELECTIONS)} (HRL cameras), got {self.selection!r}')
        if self.selection != 'joint' and not self.hrl:
            raise ValueError(f'--selection {self.selection} is how HRL cameras select targets; it needs --hrl')
        check_network_options(self, self.SCHEDULES, shares=True)


def action_kind(config: QLearningConfig) -> str:
    """The spec's action kind: 'grid' moves, or HRL selections ('hrl-joint': one head of 2^Nt subsets; 'hrl': a
    keep/ignore head per target slot)."""
    if not config.hrl:
        return 'grid'
    return 'hrl-joint' if config.selection == 'joint' else 'hrl'


def allowed_choices(spec: PolicySpec, features: np.ndarray, device=None) -> torch.Tensor | None:
    """(..., H, C) bool tensor of the choices an HRL camera may take from its features (..., D) (`spec.allowed`:
    only visible targets kept), on `device`; None for other action kinds (every choice allowed)."""
    allowed = spec.allowed(np.asarray(features))
    return None if allowed is None else torch.from_numpy(allowed).to(device)


# ============================================================================ the formulas

def masked_argmax(q: torch.Tensor, allowed: torch.Tensor | None = None) -> torch.Tensor:
    """Each head's best choice (..., H) of values q (..., H, C), among the `allowed` ones (..., H, C) bool if given."""
    return (q if allowed is None else q.masked_fill(~allowed, -math.inf)).argmax(-1)


def double_q_values(next_online, next_target, allowed=None) -> torch.Tensor:
    """sum_h Q'_h(s', argmax_c Q_h(s', c)) (...,): the online network's per-head values `next_online`
    (..., H, C) choose, the target network's `next_target` (..., H, C) evaluate; `allowed` (..., H, C) bool
    restricts the choice."""
    choice = masked_argmax(next_online, allowed).unsqueeze(-1)
    return next_target.gather(-1, choice).squeeze(-1).sum(-1)


def double_q_targets(reward, terminal, next_online, next_target, gamma: float, allowed=None) -> torch.Tensor:
    """1-step double-Q targets (M,): r + gamma (1 - terminal) `double_q_values(...)` for per-head values
    (M, H, C) of the next observations."""
    return reward + gamma * (1.0 - terminal) * double_q_values(next_online, next_target, allowed)


def epsilon_greedy(q: torch.Tensor, epsilon: float, rng: np.random.Generator, allowed=None) -> np.ndarray:
    """Actions (..., H) from per-head values q (..., H, C) on the CPU: each agent (leading index) explores with
    probability `epsilon`, then every head takes a uniform allowed choice, else the greedy one. Draws from `rng`
    one uniform number per agent, and when any explores one per head of every agent."""
    greedy = masked_argmax(q, allowed).numpy()
    explore = rng.random(q.shape[:-2]) < epsilon
    if explore.any():
        weights = np.ones(q.shape) if allowed is None else allowed.numpy().astype(np.float64)
        u = rng.random(q.shape[:-1] + (1,)) * weights.sum(-1, keepdims=True)
        uniform = np.minimum((weights.cumsum(-1) <= u).sum(-1), q.shape[-1] - 1)
        greedy = np.where(explore[..., None], uniform, greedy)
    return greedy


# ============================================================================ on the off-policy loop

class QLearner(OffPolicyLearner):
    """What IQL and QMIX share on the off-policy loop (their files add the networks, the replay, `act`, `store`,
    `update` and `copy_targets`): epsilon-greedy acting, the learning rate's steps, the target copies' schedule
    (`next_copy`), the checkpoint's optimiser and the log row."""

    schedule_keys = ('next_copy',)

    def __init__(self, config: QLearningConfig, spec: PolicySpec, device) -> None:
        self.config, self.spec, self.device = config, spec, device
        self.heads, self.choices = spec.heads, spec.choices                 # values per agent: H heads of C choices
        self.epsilon_schedule, self.lr_schedule = (resolve_schedule(points, config.steps)   # shares of the budget
                                                   for points in (config.epsilon_schedule, config.lr_schedule))
        self.epsilon = float(self.epsilon_schedule[0][1])
        self.losses, self.q_means = [], []

    def state_dict(self) -> dict:
        return dict(optimizer=self.optimizer.state_dict())

    def load_state_dict(self, saved: dict) -> None:
        super().load_state_dict(saved)
        self.optimizer.load_state_dict(saved['optimizer'])

    def own_schedule(self, steps: int) -> dict:
        return dict(next_copy=(steps // self.config.target_update + 1) * self.config.target_update)

    def explore(self, q: torch.Tensor, features: np.ndarray, steps: int, rng: np.random.Generator):
        """(the choices (B, N, H), what the envs take: (B, N) for one head) epsilon-greedy from the values q
        (B, N, H x C) on the CPU of the features (B, N, D), at the schedule's epsilon of `steps`."""
        self.epsilon = piecewise(self.epsilon_schedule, steps, interpolate=True)
        action = epsilon_greedy(q.unflatten(-1, (self.heads, self.choices)), self.epsilon, rng,
                                allowed_choices(self.spec, features))
        return action, action[..., 0] if self.heads == 1 else action

    def set_learning_rate(self, steps: int) -> None:
        lr = piecewise(self.lr_schedule, steps, interpolate=False)
        for group in self.optimizer.param_groups:
            group['lr'] = lr

    def copy_targets(self) -> None:
        raise NotImplementedError

    def after_step(self, steps: int, schedule: dict) -> None:
        if steps >= schedule['next_copy']:
            self.copy_targets()
            schedule['next_copy'] += self.config.target_update

    def row(self, steps: int) -> dict:
        row = dict(epsilon=self.epsilon, lr=piecewise(self.lr_schedule, steps, interpolate=False),
                   loss=mean_or_nan(self.losses), q_mean=mean_or_nan(self.q_means), buffer=self.replay.size)
        self.losses, self.q_means = [], []
        return row

    def status(self) -> str:
        return f'epsilon {self.epsilon:.2f}'
