"""What the Q-learners share (`iql.py`, `qmix.py`): their common settings and the pure pieces of double Q-learning.

* `QLearningConfig`: the options of both (the team env's and the run's, then exploration, replay timing, target
  copies, the log period, the HRL selection form); each trainer adds its replay size, network and optimiser;
* `action_kind(config)`: the spec's action kind of a config (grid moves, or HRL selections in one of two forms);
* `allowed_choices(spec, features)`: the choices an HRL camera may take, as a tensor (None for other kinds);
* formulas: `masked_argmax`, `double_q_values`, `double_q_targets`, `epsilon_greedy`.

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

from ..options import option
from .envs import TeamEnvConfig
from .run import RunConfig
from .schedules import check_network_options
from .spec import PolicySpec

__all__ = ['QLearningConfig', 'SELECTIONS', 'action_kind', 'allowed_choices', 'double_q_targets', 'double_q_values',
           'epsilon_greedy', 'masked_argmax']

SELECTIONS = ('joint', 'per-target')
"""How HRL cameras choose targets: one of the 2^Nt subsets (the spec's Discrete(256)) or a keep/ignore bit per slot."""


@dataclasses.dataclass
class QLearningConfig(RunConfig, TeamEnvConfig):
    """Settings of a Q-learning run (IQL, QMIX): the team env's and the run's options, then what both learners share."""

    num_envs: int = option(16, 'games played at once', minimum=1)
    threads: int = option(1, 'torch threads of the updates; 0: every core (acting always uses 1; the updates are small '
                             'and come between decisions, so more threads rarely pay for switching)', minimum=0)
    selection: Literal['joint', 'per-target'] = option(
        'joint', "with --hrl: 'joint' (the spec's Discrete(256)): one choice among the 2^Nt target subsets, those "
                 "keeping an invisible target never taken; 'per-target': a keep/ignore head per target slot")
    learning_starts: int = option(5_000, 'decision steps stored before the first update (a run resumed without its '
                                         'replay stores as many again)', minimum=0)
    update_every: int = option(128, "decision steps between updates (the spec's sampling round of 16 x 8)", minimum=1)
    target_update: int = option(500, 'decision steps between hard copies to the target networks', minimum=1)
    gamma: float = option(0.99, 'discount per decision', minimum=0, maximum=1)
    epsilon_schedule: tuple[tuple[float, float], ...] = option(
        ((0, 1.0), (50_000, 0.02)), 'exploration rate, piecewise linear in decision steps [[step, epsilon], ...] '
        '(a step "P%%": P %% of --steps)')
    report_every: int = option(5_120, 'decision steps per log row (an iteration; and one at the end)', minimum=1)

    SCHEDULES: ClassVar[tuple[str, ...]] = ('epsilon_schedule',)
    """The schedule options of the config (a learner adds its learning rate's): checked once, in __post_init__."""

    def cuts_its_last_iteration(self) -> bool:
        """A row every `report_every` decision steps and one at the budget: early unless `steps` is a multiple."""
        return self.steps % self.report_every != 0

    def __post_init__(self) -> None:
        TeamEnvConfig.__post_init__(self)
        RunConfig.__post_init__(self)
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
