"""What the PPO trainers share (`mappo`, `mappo_lstm`, `tarmac`, `i2c`): their settings and the pure pieces.

* `PPOConfig`: the options of every PPO trainer (the team env's and the run's, then PPO's hyper-parameters);
  `PAPER_HYPERPARAMETERS` (`--paper`) the paper's values where ours differ;
* formulas: `compute_gae`, `ppo_policy_loss`, `sampled_kl`, `adapt_kl_coeff`, `action_distribution`;
* `ValueNormalizer` (value targets on a running scale), `minibatch_rows`, `Schedules` (learning rate and entropy
  coefficient at a step count), `bootstrapped` (horizon cuts), `UpdateStats` (the iteration's loss means);
* `warm_start` (`--init-from`).

Deviations from the paper's RLlib runs, on purpose (docs/training.md): GAE lambda 0.95 (RLlib's default 1.0 is a
flag away), no adaptive KL penalty unless `kl_coeff` > 0 (`--paper` turns on RLlib's 0.2 / target 0.01), gradient
norm clipping at 10, horizon cuts bootstrap from the critic instead of counting as terminal.
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import torch
from torch import nn

from ..cli.options import option
from ..policies.checkpoint import CheckpointError, load_checkpoint, read_spec
from .envs import GameDeviceConfig, TeamEnvConfig
from .run import RunConfig
from .schedules import check_network_options, piecewise, resolve_schedule

__all__ = ['PAPER_HYPERPARAMETERS', 'PPOConfig', 'Schedules', 'UpdateStats', 'ValueNormalizer', 'action_distribution',
           'adapt_kl_coeff', 'bootstrapped', 'compute_gae', 'learning_targets', 'minibatch_rows', 'ppo_policy_loss',
           'ppo_update', 'sampled_kl', 'warm_start']


PAPER_HYPERPARAMETERS = dict(
    mask_invisible=False,
    lr_schedule=((0, 5e-4), (4_000_000, 1e-4), (8_000_000, 5e-5)),
    entropy_schedule=((0, 0.05), (2_000_000, 0.01), (4_000_000, 0.001), (10_000_000, 0.0)),
    kl_coeff=0.2,
)
"""The paper's settings where `PPOConfig`'s defaults differ (the paper's appendix; `--paper`, which also
selects the MLP actor of `mappo`). Our defaults are tuned for budgets of a few million decision steps
(docs/training.md has the measurements): the paper's schedules are stretched over 10 M steps and its entropy bonus
of 0.05 keeps the policies nearly uniform for the first million steps; the per-target camera actor learns faster
than the MLP. `mask_invisible` (HRL): the executor ignores selected targets that the camera does not see, so
masking them changes no behaviour; it removes their random bits from the log-probabilities and the entropy, which
otherwise add noise to every gradient (the paper's code had the mask, unused)."""
PAPER_HELP = ("the paper's settings where ours differ: the adaptive KL penalty (0.2, target 0.01), schedules stretched "
              'over 10M steps (lr 5e-4 -> 1e-4 @4M -> 5e-5 @8M; entropy 0.05 -> 0.01 @2M -> 0.001 @4M -> 0 @10M), no '
              'HRL masking; options given explicitly still win')

@dataclasses.dataclass
class PPOConfig(GameDeviceConfig, RunConfig, TeamEnvConfig):
    """Settings of a PPO trainer: the team env's and the run's options, then PPO's hyper-parameters."""

    PRESETS: ClassVar[dict] = {'paper': (PAPER_HELP, PAPER_HYPERPARAMETERS)}

    rollout_length: int = option(25, 'decisions per env per iteration (the paper: 25-step fragments)', minimum=1)
    epochs: int = option(4, 'passes over each rollout', minimum=1)
    minibatches: int = option(4, 'minibatches per pass', minimum=1)
    gamma: float = option(0.99, 'discount per decision', minimum=0, maximum=1)
    gae_lambda: float = option(0.95, 'GAE lambda (RLlib and the paper: 1.0)', minimum=0, maximum=1)
    clip: float = option(0.3, 'PPO clip range of the probability ratio', above=0)
    value_coef: float = option(1.0, 'weight of the value loss', minimum=0)
    kl_coeff: float = option(0.0, 'initial coefficient of the adaptive KL penalty (RLlib and the paper: 0.2); 0: off',
                             minimum=0)
    kl_target: float = option(0.01, 'KL per iteration the penalty adapts towards (x1.5 above twice, x0.5 below half)',
                              above=0)
    max_grad_norm: float = option(10.0, 'gradient norm clipping; 0: none', minimum=0)
    hidden: tuple[int, ...] = option((256, 256), 'hidden layer widths of the actor and the critic', minimum=1)
    activation: str = option('tanh', "hidden activation: 'tanh' or 'relu'")
    lr_schedule: tuple[tuple[float, float], ...] = option(
        ((0, 5e-4), (1_500_000, 2e-4), (3_000_000, 1e-4)), 'learning rate, a step function of decision steps '
        '[[step, lr], ...] (a step "P%%": P %% of --steps)')
    entropy_schedule: tuple[tuple[float, float], ...] = option(
        ((0, 0.01), (1_000_000, 0.001), (3_000_000, 0.0)), 'entropy coefficient, piecewise linear in decision steps '
        '[[step, coefficient], ...] (a step "P%%": P %% of --steps, for a schedule that scales with the budget)')
    mask_invisible: bool = option(True, 'HRL: never select a target the camera cannot see (the executor would ignore '
                                        'it; masking removes its random bits from the gradient)')
    init_from: str | None = option(None, 'warm start from the networks of a checkpoint or policy file of the same '
                                         'setting (steps and schedules start from 0)', metavar='PATH')
    def __post_init__(self) -> None:
        TeamEnvConfig.__post_init__(self)
        RunConfig.__post_init__(self)
        check_network_options(self, ('lr_schedule', 'entropy_schedule'), shares=True)
        self.hidden = tuple(self.hidden)
        GameDeviceConfig.__post_init__(self)


# ============================================================================ the formulas

def action_distribution(logits: torch.Tensor, heads: int, choices: int, allowed: torch.Tensor | None = None):
    """Independent categoricals: logits (..., heads x choices) -> batch shape (..., heads). Flat discrete
    actions are one head of levels**2 choices; HRL selections are Nt heads of 2 (keep/ignore). The
    joint log-probability and entropy are sums over the heads. `allowed` (..., heads, choices) bool
    masks choices out (probability 0); a head with a single allowed choice adds nothing to either."""
    logits = logits.reshape(*logits.shape[:-1], heads, choices)
    if allowed is not None:
        logits = logits.masked_fill(~allowed, torch.finfo(logits.dtype).min)
    return torch.distributions.Categorical(logits=logits)


def compute_gae(rewards, values, dones, last_values, gamma: float, lam: float):
    """Generalised advantage estimation over a rollout.

    rewards, values, dones: (T, ...) with dones[t] = the episode ended after step t (no bootstrap
    across it); last_values (...): values of the observations after step T-1.
    Returns (advantages, returns = advantages + values), both (T, ...).
    """
    advantages = torch.zeros_like(values)
    running = torch.zeros_like(last_values)
    for t in reversed(range(values.shape[0])):
        next_values = last_values if t == values.shape[0] - 1 else values[t + 1]
        alive = 1.0 - dones[t].to(values.dtype)
        delta = rewards[t] + gamma * next_values * alive - values[t]
        running = delta + gamma * lam * alive * running
        advantages[t] = running
    return advantages, advantages + values


def learning_targets(rewards, values, episode_ends, last_values, value_norm: ValueNormalizer, gamma: float,
                     lam: float) -> tuple[torch.Tensor, torch.Tensor]:
    """What the PPO update regresses on, for a rollout of T decisions x B envs x N agents, one row per (decision,
    env): `(advantages (T * B, N), standardised over the rollout; returns (T * B, N) in the units of `value_norm`,
    updated with them first)`.

    rewards, values: (T, B, N) (a team reward repeated per agent, or each agent's own); episode_ends: (T, B), the
    env's episode ended after decision t; last_values: (B, N), the values after the last decision (`compute_gae`).
    """
    T, B, N = values.shape
    advantages, returns = compute_gae(rewards, values, episode_ends.unsqueeze(-1).expand(T, B, N), last_values, gamma,
                                      lam)
    value_norm.update(returns)
    advantages, returns = advantages.reshape(T * B, N), value_norm.normalize(returns.reshape(T * B, N))
    return (advantages - advantages.mean()) / (advantages.std() + 1e-8), returns


def minibatch_rows(T: int, B: int, minibatches: int, sequences: bool, generator) -> list[torch.Tensor]:
    """Shuffled minibatches of row indices t * B + b into a (T, B) rollout flattened t-major.

    Feed-forward: independent (t, b) rows. `sequences` (recurrent actor): whole env sequences, each
    minibatch the T steps of a group of envs, ordered t-major (its first len/T rows are the envs at t = 0).
    """
    device = generator.device                # (a CUDA generator draws on its GPU only)
    if not sequences:
        return list(torch.randperm(T * B, generator=generator, device=device).split(math.ceil(T * B / minibatches)))
    groups = torch.randperm(B, generator=generator, device=device).split(math.ceil(B / minibatches))
    return [(torch.arange(T, device=device)[:, None] * B + group[None, :]).reshape(-1) for group in groups]


def sampled_kl(new_logp, old_logp) -> torch.Tensor:
    """KL(old || new) estimated on actions drawn from the old policy: E[(r - 1) - log r], r = new/old
    probability. Non-negative per sample, unbiased (E_old[r] = 1), and differentiable in `new_logp`."""
    log_ratio = new_logp - old_logp
    return (torch.exp(log_ratio) - 1.0 - log_ratio).mean()


def adapt_kl_coeff(coeff: float, kl: float, target: float) -> float:
    """RLlib's adaptive KL rule, applied once per iteration to the iteration's mean KL: x1.5 above twice
    the target, x0.5 below half of it, unchanged in between."""
    if kl > 2.0 * target:
        return coeff * 1.5
    if kl < 0.5 * target:
        return coeff * 0.5
    return coeff


def ppo_policy_loss(new_logp, old_logp, advantages, clip: float) -> torch.Tensor:
    """Clipped surrogate objective, as a loss to minimise: -E[min(r A, clip(r, 1-e, 1+e) A)]."""
    ratio = torch.exp(new_logp - old_logp)
    return -torch.min(ratio * advantages, ratio.clamp(1.0 - clip, 1.0 + clip) * advantages).mean()


def bootstrapped(reward: torch.Tensor, truncated, final_values: torch.Tensor, gamma: float) -> torch.Tensor:
    """Rewards (B, N) with a horizon cut's bootstrap added: + gamma x the critic's value (B, N) or (B, 1) of the
    episode's last observation, in the rows cut by the horizon (`truncated` (B,) bool, a numpy array or a tensor)."""
    cut = torch.as_tensor(truncated).to(reward.device, reward.dtype)[:, None]
    return reward + gamma * cut * final_values


class ValueNormalizer(nn.Module):
    """Running mean/variance of the value targets; the critic predicts normalised values."""

    def __init__(self, epsilon: float = 1e-4) -> None:
        super().__init__()
        self.register_buffer('mean', torch.zeros((), dtype=torch.float64))
        self.register_buffer('var', torch.ones((), dtype=torch.float64))
        self.register_buffer('count', torch.tensor(epsilon, dtype=torch.float64))

    def update(self, x: torch.Tensor) -> None:
        x = x.detach().double().reshape(-1)
        batch_mean, batch_var, n = x.mean(), x.var(unbiased=False), x.numel()
        delta, total = batch_mean - self.mean, self.count + n
        self.mean += delta * n / total
        self.var.copy_((self.var * self.count + batch_var * n + delta ** 2 * self.count * n / total) / total)
        self.count.copy_(total)

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        return ((x - self.mean) / self.var.clamp_min(1e-8).sqrt()).to(x.dtype)

    def denormalize(self, x: torch.Tensor) -> torch.Tensor:
        return (x * self.var.clamp_min(1e-8).sqrt() + self.mean).to(x.dtype)


class Schedules:
    """The learning rate (a step function) and entropy coefficient (piecewise linear) of `config` at a step count,
    their shares of the budget ('40%') read against `config.steps`; `apply(optimizer, steps)` sets the learning rate
    and returns (lr, entropy coefficient)."""

    def __init__(self, config: PPOConfig) -> None:
        self.lr, self.entropy = (resolve_schedule(points, config.steps)
                                 for points in (config.lr_schedule, config.entropy_schedule))

    def apply(self, optimizer: torch.optim.Optimizer, steps: int) -> tuple[float, float]:
        lr = piecewise(self.lr, steps, interpolate=False)
        for group in optimizer.param_groups:
            group['lr'] = lr
        return lr, piecewise(self.entropy, steps, interpolate=True)


class UpdateStats:
    """Sums of an iteration's loss terms over its minibatch updates; `means()` divides by the updates."""

    def __init__(self, *names: str) -> None:
        self.sums = dict.fromkeys(names, 0.0)
        self.updates = 0

    def add(self, **values: float) -> None:
        for name, value in values.items():
            self.sums[name] = self.sums.get(name, 0.0) + float(value)

    def means(self) -> dict:
        return {name: total / max(self.updates, 1) for name, total in self.sums.items()}


def clipped_step(optimizer: torch.optim.Optimizer, loss: torch.Tensor, parameters, max_grad_norm: float) -> None:
    """One optimiser step on `loss`, the gradient's norm clipped at `max_grad_norm` (0: no clipping)."""
    optimizer.zero_grad()
    loss.backward()
    if max_grad_norm:
        nn.utils.clip_grad_norm_(parameters, max_grad_norm)
    optimizer.step()


def ppo_update(optimizer: torch.optim.Optimizer, parameters, config: PPOConfig, dist, actions: torch.Tensor,
               old_logp: torch.Tensor, advantages: torch.Tensor, predicted: torch.Tensor, returns: torch.Tensor,
               entropy_coef: float, kl_coeff: float, stats: UpdateStats, extra=()) -> None:
    """One clipped-PPO step on a minibatch: loss = the clipped surrogate (`ppo_policy_loss`) + `value_coef` x half
    the squared error of the critic's `predicted` (normalised) values to `returns` - `entropy_coef` x the entropy
    of `dist` (+ `kl_coeff` x the sampled KL when it is > 0, + each term of `extra`: an algorithm's own losses, e.g.
    I2C's); the optimiser's step with the gradient norm clipped; the minibatch's terms added to `stats`.
    `actions` (..., heads) were drawn from the old policy with log-probabilities `old_logp` (...)."""
    new_logp = dist.log_prob(actions).sum(-1)
    policy_loss = ppo_policy_loss(new_logp, old_logp, advantages, config.clip)
    value_loss = 0.5 * (predicted - returns).pow(2).mean()
    entropy = dist.entropy().sum(-1).mean()
    kl = sampled_kl(new_logp, old_logp)
    loss = policy_loss + config.value_coef * value_loss - entropy_coef * entropy
    if kl_coeff > 0:
        loss = loss + kl_coeff * kl
    for term in extra:
        loss = loss + term
    clipped_step(optimizer, loss, parameters, config.max_grad_norm)
    with torch.no_grad():
        clipped = ((new_logp - old_logp).exp() - 1).abs() > config.clip
    stats.add(approx_kl=kl.item(), clip_fraction=float(clipped.float().mean()), policy_loss=policy_loss.item(),
              value_loss=value_loss.item(), entropy=entropy.item())
    stats.updates += 1


def warm_start(path, spec, actor: nn.Module, critics: dict[str, nn.Module], algo: str, credit: str) -> None:
    """`--init-from`: load the actor of `path` (a checkpoint or a policy file of a policy with the same spec) and,
    from a run checkpoint of the same algorithm and credit, the `critics` (name -> module, e.g. the critic and the
    value normaliser) too. CheckpointError naming the setting that differs, or when the weights do not fit."""
    data = load_checkpoint(path)
    saved = read_spec(data, path)
    differences = saved.differences(spec, ignore=('algo', 'deterministic', 'frame_skip', 'state_dim'))
    if differences:
        raise CheckpointError(f'warm start {str(path)!r}: {differences[0]}')
    networks = data['state']['networks'] if 'state' in data else data       # a run checkpoint, or a policy file
    try:
        actor.load_state_dict(networks['actor'])
    except RuntimeError as exc:
        raise CheckpointError(f'warm start {str(path)!r}: actor weights do not fit: '
                              f'{str(exc).splitlines()[0]}') from None
    saved_algo = data.get('algo')
    if saved_algo == algo and data['config'].get('credit', 'team') == credit:   # the critic's inputs and outputs
        for name, module in critics.items():
            if name in networks:
                module.load_state_dict(networks[name])
