"""MAPPO and IPPO for MATE, in one file that reads top to bottom.

    config  ->  batched envs (`TeamVecEnv`: B games + batched greedy opponent)
            ->  networks (shared actor; critic on the global state (MAPPO) or the local observation (IPPO))
            ->  loop: collect T decisions x B envs x N agents, GAE, K epochs of clipped PPO on minibatches
            ->  logs (rich progress bar, CSV, TensorBoard when installed) and checkpoints

One policy is shared by every agent of the trained team (full parameter sharing, as in the paper).
Its action is one or more independent categorical choices (`action_distribution`): one of 25 grid
moves for the flat learners, or one keep/ignore bit per target slot for HRL cameras (`hrl=True`,
spec training.md §3), whose rule executor runs inside `TeamVecEnv`.
Rewards are team rewards, repeated to every agent. Values are learned on normalised returns
(running mean/std, "value normalisation"). Schedules (learning rate, entropy coefficient) are
piecewise functions of decision steps, as in spec training.md §1.6.

Deviations from the paper's RLlib runs, on purpose: a feed-forward policy (the paper's LSTM is not
implemented yet), GAE lambda 0.95 (RLlib's default 1.0 is a flag away), no adaptive KL penalty,
gradient-norm clipping at 10, horizon cuts bootstrap from the critic instead of counting as terminal.
"""

from __future__ import annotations

import csv
import dataclasses
import itertools
import math
import os
import time
from collections import deque
from pathlib import Path

import numpy as np
import torch
from torch import nn

from .checkpoint import load_checkpoint, save_checkpoint
from .envs import PAPER_SETTINGS, TeamVecEnv

__all__ = [
    'Actor',
    'Critic',
    'PPOConfig',
    'ValueNormalizer',
    'PerTargetActor',
    'RecurrentActor',
    'action_distribution',
    'compute_gae',
    'make_actor',
    'minibatch_rows',
    'piecewise',
    'ppo_policy_loss',
    'train',
]


# ============================================================================ configuration

@dataclasses.dataclass
class PPOConfig:
    algo: str = 'mappo'                  # 'mappo' (centralised critic on the state) or 'ippo' (local critic)
    team: str = 'camera'                 # trained team; the other one is the batched greedy opponent
    env_id: str | None = None            # None: the paper's preset for the team (PAPER_SETTINGS)
    config: str | None = None            # optional config (YAML/JSON path) for env_id 'MultiAgentTracking-v0'
    frame_skip: int | None = None        # None: 5 for cameras, 10 for targets
    horizon: int | None = None           # raw steps per training episode; None: 500 decisions
    levels: int = 5                      # discrete levels per action axis (25 actions)
    hrl: bool = False                    # cameras only: select targets (Nt bits), rule executor aims (§3)
    actor: str = 'mlp'                   # 'mlp', or 'per-target' (HRL: one shared scorer per target slot)
    lstm: int = 0                        # > 0: recurrent actor, MLP -> LSTM(lstm) -> head (paper: 256)
    total_steps: int = 2_000_000         # decision steps (per env, summed over envs), as RLlib counts
    num_envs: int = 64
    rollout_length: int = 25             # decisions per env per iteration (paper: 25-step fragments)
    epochs: int = 4
    minibatches: int = 4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.3
    value_coef: float = 1.0
    max_grad_norm: float | None = 10.0
    hidden: tuple = (256, 256)
    activation: str = 'tanh'
    lr_schedule: tuple = ((0, 5e-4), (4_000_000, 1e-4), (8_000_000, 5e-5))            # steps
    entropy_schedule: tuple = ((0, 0.05), (2_000_000, 0.01), (4_000_000, 0.001), (10_000_000, 0.0))  # linear
    seed: int = 0
    torch_threads: int = 1
    checkpoint_every: int = 20           # iterations
    snapshot_every: int = 0              # iterations; > 0 keeps the actor as snapshots/policy-STEPS.pt

    def resolved(self) -> PPOConfig:
        """A copy with the team's paper defaults filled in."""
        defaults = PAPER_SETTINGS[self.team]
        frame_skip = self.frame_skip or defaults['frame_skip']
        return dataclasses.replace(self, env_id=self.env_id or defaults['env_id'], frame_skip=frame_skip,
                                   horizon=self.horizon or 500 * frame_skip)

    def to_dict(self) -> dict:
        return {k: (list(map(list, v)) if k.endswith('schedule') else list(v) if isinstance(v, tuple) else v)
                for k, v in dataclasses.asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict) -> PPOConfig:
        known = {f.name for f in dataclasses.fields(cls)}
        data = {k: v for k, v in data.items() if k in known}
        for key in ('lr_schedule', 'entropy_schedule'):
            if key in data:
                data[key] = tuple(tuple(p) for p in data[key])
        if 'hidden' in data:
            data['hidden'] = tuple(data['hidden'])
        return cls(**data)


def piecewise(schedule, step: float, interpolate: bool) -> float:
    """Value of a ((step, value), ...) schedule: a step function, or linear between breakpoints."""
    points = sorted(schedule)
    if step <= points[0][0]:
        return float(points[0][1])
    for (s0, v0), (s1, v1) in itertools.pairwise(points):
        if step < s1:
            return float(v0 + (v1 - v0) * (step - s0) / (s1 - s0)) if interpolate else float(v0)
    return float(points[-1][1])


# ============================================================================ networks

ACTIVATIONS = {'tanh': (nn.Tanh, 5.0 / 3.0), 'relu': (nn.ReLU, math.sqrt(2.0))}


def linear(inputs: int, outputs: int, scale: float, gain: float) -> nn.Linear:
    """Orthogonal weights with every output row rescaled to L2 norm `scale * gain`; zero bias (§1.5)."""
    layer = nn.Linear(inputs, outputs)
    with torch.no_grad():
        nn.init.orthogonal_(layer.weight)
        layer.weight.mul_(scale * gain / layer.weight.norm(dim=1, keepdim=True).clamp_min(1e-8))
        layer.bias.zero_()
    return layer


def mlp(inputs: int, hidden, activation: str) -> tuple[nn.Sequential, int]:
    act, gain = ACTIVATIONS[activation]
    layers = []
    for width in hidden:
        layers += [linear(inputs, width, 1.0, gain), act()]
        inputs = width
    return nn.Sequential(*layers), inputs


class Actor(nn.Module):
    """Shared policy: preprocessed local observation -> logits over the discrete actions."""

    def __init__(self, obs_dim: int, num_actions: int, hidden=(256, 256), activation: str = 'tanh') -> None:
        super().__init__()
        self.body, width = mlp(obs_dim, hidden, activation)
        self.head = linear(width, num_actions, 0.01, 1.0)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.head(self.body(obs))


class PerTargetActor(nn.Module):
    """HRL selection policy that scores every target slot with the same small network.

    context = MLP(observation); logits of slot i = head([record_i, context]) where record_i is the
    slot's 5 observed values (location, radius, ..., visibility flag). Slots carry no identity
    (`shuffle_entities`), so sharing the scorer across them lets one sample teach all eight.
    Output: (..., Nt x 2) keep/ignore logits, the layout of `Actor` with `action_distribution`.
    """

    def __init__(self, obs_dim: int, records: tuple[int, int], hidden=(256, 256), activation: str = 'tanh',
                 head_width: int = 128) -> None:
        super().__init__()
        self.begin, self.num_targets = int(records[0]), int(records[1])
        self.body, width = mlp(obs_dim, hidden, activation)
        act, gain = ACTIVATIONS[activation]
        self.head = nn.Sequential(linear(width + 5, head_width, 1.0, gain), act(), linear(head_width, 2, 0.01, 1.0))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        context = self.body(obs)
        records = obs[..., self.begin:self.begin + 5 * self.num_targets].reshape(
            *obs.shape[:-1], self.num_targets, 5)
        joint = torch.cat([records, context.unsqueeze(-2).expand(*records.shape[:-1], context.shape[-1])], dim=-1)
        return self.head(joint).reshape(*obs.shape[:-1], 2 * self.num_targets)


class RecurrentActor(nn.Module):
    """The paper's recurrent policy: MLP -> LSTM -> head on [MLP features, LSTM output] (skip-concat).

    `step(obs (..., D), state)` -> (logits (..., A), state); `state` is a pair (h, c) of (..., L).
    `forward(obs (T, ..., D), state, starts (T, ...))` runs a sequence, zeroing the state of the rows
    where `starts[t]` (an episode begins at t) before step t; returns logits (T, ..., A).
    """

    recurrent = True

    def __init__(self, obs_dim: int, num_actions: int, hidden=(256, 256), activation: str = 'tanh',
                 lstm: int = 256) -> None:
        super().__init__()
        self.body, width = mlp(obs_dim, hidden, activation)
        self.cell = nn.LSTMCell(width, lstm)
        self.head = linear(width + lstm, num_actions, 0.01, 1.0)
        self.lstm_size = lstm

    def initial_state(self, *shape: int) -> tuple[torch.Tensor, torch.Tensor]:
        return torch.zeros(*shape, self.lstm_size), torch.zeros(*shape, self.lstm_size)

    def step(self, obs: torch.Tensor, state):
        features = self.body(obs)
        lead = features.shape[:-1]
        h, c = self.cell(features.reshape(-1, features.shape[-1]),
                         (state[0].reshape(-1, self.lstm_size), state[1].reshape(-1, self.lstm_size)))
        h, c = h.reshape(*lead, self.lstm_size), c.reshape(*lead, self.lstm_size)
        return self.head(torch.cat([features, h], dim=-1)), (h, c)

    def forward(self, obs: torch.Tensor, state, starts: torch.Tensor) -> torch.Tensor:
        logits = []
        for t in range(obs.shape[0]):
            keep = (~starts[t]).to(obs.dtype).reshape(*starts.shape[1:], *([1] * (state[0].dim() - starts.dim() + 1)))
            state = (state[0] * keep, state[1] * keep)
            out, state = self.step(obs[t], state)
            logits.append(out)
        return torch.stack(logits)


def make_actor(kind: str, obs_dim: int, num_actions: int, hidden, activation: str, meta: dict,
               lstm: int = 0) -> nn.Module:
    """The actor named by `PPOConfig.actor` ('mlp' or 'per-target'; the latter for HRL cameras only),
    recurrent when `lstm` > 0 (MLP actors only)."""
    if kind == 'mlp':
        return RecurrentActor(obs_dim, num_actions, hidden, activation, lstm) if lstm else \
            Actor(obs_dim, num_actions, hidden, activation)
    if lstm:
        raise ValueError(f"actor {kind!r} has no recurrent version; use actor 'mlp' with lstm > 0")
    if kind == 'per-target':
        if not meta.get('hrl'):
            raise ValueError("actor 'per-target' scores target slots: it needs HRL cameras (hrl=True)")
        return PerTargetActor(obs_dim, (meta['target_records'], meta['counts'][1]), hidden, activation)
    raise ValueError(f"unknown actor {kind!r}; valid: 'mlp', 'per-target'")


class Critic(nn.Module):
    """Value in normalised units; input = state + agent one-hot (MAPPO) or local observation (IPPO)."""

    def __init__(self, input_dim: int, hidden=(256, 256), activation: str = 'tanh') -> None:
        super().__init__()
        self.body, width = mlp(input_dim, hidden, activation)
        self.head = linear(width, 1, 1.0, 1.0)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.body(x)).squeeze(-1)


def action_distribution(logits: torch.Tensor, heads: int, choices: int):
    """Independent categoricals: logits (..., heads x choices) -> batch shape (..., heads). Flat discrete
    actions are one head of levels**2 choices; HRL selections are Nt heads of 2 (keep/ignore). The
    joint log-probability and entropy are sums over the heads."""
    return torch.distributions.Categorical(logits=logits.reshape(*logits.shape[:-1], heads, choices))


def critic_inputs(algo: str, obs: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
    """(..., N, D) observations and (..., S) states -> (..., N, input) critic inputs."""
    if algo == 'ippo':
        return obs
    n = obs.shape[-2]
    eye = torch.eye(n, dtype=obs.dtype).expand(*obs.shape[:-1], n)
    return torch.cat([state.unsqueeze(-2).expand(*obs.shape[:-1], state.shape[-1]), eye], dim=-1)


def critic_input_dim(algo: str, obs_dim: int, state_dim: int, num_agents: int) -> int:
    return obs_dim if algo == 'ippo' else state_dim + num_agents


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


# ============================================================================ the two formulas

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


def minibatch_rows(T: int, B: int, minibatches: int, sequences: bool, generator) -> list[torch.Tensor]:
    """Shuffled minibatches of row indices t * B + b into a (T, B) rollout flattened t-major.

    Feed-forward: independent (t, b) rows. `sequences` (recurrent actor): whole env sequences, each
    minibatch the T steps of a group of envs, ordered t-major (its first len/T rows are the envs at t = 0).
    """
    if not sequences:
        return list(torch.randperm(T * B, generator=generator).split(math.ceil(T * B / minibatches)))
    groups = torch.randperm(B, generator=generator).split(math.ceil(B / minibatches))
    return [(torch.arange(T)[:, None] * B + group[None, :]).reshape(-1) for group in groups]


def ppo_policy_loss(new_logp, old_logp, advantages, clip: float) -> torch.Tensor:
    """Clipped surrogate objective, as a loss to minimise: -E[min(r A, clip(r, 1-e, 1+e) A)]."""
    ratio = torch.exp(new_logp - old_logp)
    return -torch.min(ratio * advantages, ratio.clamp(1.0 - clip, 1.0 + clip) * advantages).mean()


# ============================================================================ training

class Logger:
    """CSV rows (+ TensorBoard scalars when `torch.utils.tensorboard` imports)."""

    def __init__(self, run_dir: Path, resume: bool) -> None:
        self.path = run_dir / 'progress.csv'
        self.fields = None
        self.append = resume and self.path.exists()
        try:
            from torch.utils.tensorboard import SummaryWriter
            self.tb = SummaryWriter(str(run_dir / 'tensorboard'))
        except Exception:  # noqa: BLE001  (tensorboard missing or broken: CSV only)
            self.tb = None

    def write(self, row: dict) -> None:
        if self.fields is None:
            self.fields = list(row)
            mode = 'a' if self.append else 'w'
            with open(self.path, mode, newline='') as f:
                if mode == 'w':
                    csv.DictWriter(f, self.fields).writeheader()
        with open(self.path, 'a', newline='') as f:
            csv.DictWriter(f, self.fields, extrasaction='ignore').writerow(row)
        if self.tb is not None:
            for key, value in row.items():
                if key != 'env_steps' and isinstance(value, (int, float)) and not math.isnan(value):
                    self.tb.add_scalar(key, value, row['env_steps'])
            self.tb.flush()

    def close(self) -> None:
        if self.tb is not None:
            self.tb.close()


def train(config: PPOConfig, run_dir: str | os.PathLike, resume: bool = True, progress: bool = True,
          callback=None, envs=None) -> dict:
    """Train; write progress.csv, tensorboard/ and checkpoint.pt (+ final.pt) under `run_dir`.

    Resumes from `run_dir/checkpoint.pt` when it exists and `resume` is true (the config stored in the
    checkpoint must describe the same experiment, else `CheckpointError`). `callback(row)` sees every
    log row. `envs` replaces the `TeamVecEnv` (anything with its attributes and reset/step; tests use
    toy tasks). Returns the last log row.
    """
    config = config.resolved()
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(config.torch_threads)

    # ---- environments
    envs = envs or TeamVecEnv(config.team, num_envs=config.num_envs, env_id=config.env_id, frame_skip=config.frame_skip,
                      horizon=config.horizon, levels=config.levels, seed=config.seed, config=config.config,
                      hrl=config.hrl)
    B, N, D, S, A = envs.num_envs, envs.num_agents, envs.obs_dim, envs.state_dim, envs.num_actions
    H, C = getattr(envs, 'action_heads', 1), getattr(envs, 'action_choices', A)   # A = H x C logits per agent

    # ---- networks and optimiser
    torch.manual_seed(config.seed)
    meta = dict(team=config.team, env_id=config.env_id, frame_skip=config.frame_skip, levels=config.levels,
                obs_dim=D, state_dim=S, num_agents=N, num_actions=A, action_heads=H, action_choices=C,
                hrl=bool(getattr(envs, 'hrl', False)), counts=list(getattr(envs, 'counts', ())),
                actor=config.actor, lstm=config.lstm, target_records=getattr(envs, 'target_records', None))
    actor = make_actor(config.actor, D, A, config.hidden, config.activation, meta, config.lstm)
    recurrent = getattr(actor, 'recurrent', False)
    critic = Critic(critic_input_dim(config.algo, D, S, N), config.hidden, config.activation)
    value_norm = ValueNormalizer()
    optimizer = torch.optim.Adam([*actor.parameters(), *critic.parameters()], lr=config.lr_schedule[0][1], eps=1e-5)
    env_steps, iteration = 0, 0
    checkpoint_path = run_dir / 'checkpoint.pt'
    if resume and checkpoint_path.exists():
        saved = load_checkpoint(checkpoint_path, expect=dict(meta, algo=config.algo))
        actor.load_state_dict(saved['actor'])
        critic.load_state_dict(saved['critic'])
        value_norm.load_state_dict(saved['value_norm'])
        optimizer.load_state_dict(saved['optimizer'])
        env_steps, iteration = saved['env_steps'], saved['iteration']
    generator = torch.Generator().manual_seed(config.seed * 1_000_003 + iteration)

    def checkpoint(path: Path) -> None:
        save_checkpoint(path, dict(actor=actor.state_dict(), critic=critic.state_dict(),
                                   value_norm=value_norm.state_dict(), optimizer=optimizer.state_dict(),
                                   env_steps=env_steps, iteration=iteration, config=config.to_dict(),
                                   meta=dict(meta, algo=config.algo)))

    def snapshot(path: Path) -> None:   # the acting part only (the format of `export_policy`): small files
        save_checkpoint(path, dict(actor=actor.state_dict(), meta=dict(meta, algo=config.algo),
                                   config=config.to_dict(), env_steps=env_steps, note=f'iteration {iteration}'))

    def values_of(obs_t, state_t):
        return value_norm.denormalize(critic(critic_inputs(config.algo, obs_t, state_t)))

    # ---- rollout storage: T decisions x B envs x N agents
    T = config.rollout_length
    obs_buf = torch.zeros(T, B, N, D)
    state_buf = torch.zeros(T, B, S)
    action_buf = torch.zeros(T, B, N, H, dtype=torch.long)
    logp_buf = torch.zeros(T, B, N)
    value_buf = torch.zeros(T, B, N)
    reward_buf = torch.zeros(T, B)
    done_buf = torch.zeros(T, B)
    start_buf = torch.zeros(T, B, dtype=torch.bool)      # an episode begins at this decision (recurrent actor)
    memory = actor.initial_state(B, N) if recurrent else None
    starting = torch.ones(B, dtype=torch.bool)

    obs, state = envs.reset(seed=config.seed + 10_007 * iteration)
    obs, state = torch.from_numpy(obs), torch.from_numpy(state)
    episodes = deque(maxlen=25)   # RLlib smooths episode metrics over the last 25 episodes
    logger = Logger(run_dir, resume=env_steps > 0)
    start, start_steps, row = time.perf_counter(), env_steps, {}
    bar = _progress_bar(config.total_steps, env_steps) if progress else None
    try:
        while env_steps < config.total_steps:
            lr = piecewise(config.lr_schedule, env_steps, interpolate=False)
            entropy_coef = piecewise(config.entropy_schedule, env_steps, interpolate=True)
            for group in optimizer.param_groups:
                group['lr'] = lr

            # ---- collect
            coverage = []
            t_collect = time.perf_counter()
            memory_at_start = memory
            for t in range(T):
                with torch.no_grad():
                    if recurrent:
                        keep = (~starting).float()[:, None, None]
                        logits, memory = actor.step(obs, (memory[0] * keep, memory[1] * keep))
                    else:
                        logits = actor(obs)
                    dist = action_distribution(logits, H, C)
                    action = torch.multinomial(dist.probs.reshape(-1, C), 1, generator=generator).reshape(B, N, H)
                    value = values_of(obs, state)
                next_obs, next_state, reward, done, truncated, info = envs.step(action.numpy()[..., 0] if H == 1 else action.numpy())
                reward = torch.from_numpy(reward).float()
                if truncated.any():   # horizon cut: bootstrap from the critic's value of the last observation
                    with torch.no_grad():
                        final = values_of(torch.from_numpy(info['final_obs']), torch.from_numpy(info['final_state']))
                    reward = reward + config.gamma * torch.from_numpy(truncated).float() * final.mean(-1)
                obs_buf[t], state_buf[t], action_buf[t] = obs, state, action
                logp_buf[t], value_buf[t] = dist.log_prob(action).sum(-1), value
                reward_buf[t], done_buf[t] = reward, torch.from_numpy(done).float()
                start_buf[t], starting = starting, torch.from_numpy(done).clone()
                obs, state = torch.from_numpy(next_obs), torch.from_numpy(next_state)
                coverage.append(float(info['coverage'].mean()))
                episodes.extend(info['episodes'])
            env_steps += T * B
            collect_seconds = time.perf_counter() - t_collect

            # ---- advantages (team reward repeated to every agent)
            with torch.no_grad():
                last_values = values_of(obs, state)
            rewards = reward_buf.unsqueeze(-1).expand(T, B, N)
            dones = done_buf.unsqueeze(-1).expand(T, B, N)
            advantages, returns = compute_gae(rewards, value_buf, dones, last_values, config.gamma,
                                              config.gae_lambda)
            value_norm.update(returns)

            # ---- learn: K epochs over shuffled minibatches of (decision, env) rows, all agents of a row together
            # (recurrent actor: minibatches of whole env sequences, replayed from the rollout's first memory)
            def logits_of(rows):
                if not recurrent:
                    return actor(b_obs[rows])
                envs_ = rows[:len(rows) // T]          # rows are t-major: the first T-th are t = 0, i.e. the envs
                first = (memory_at_start[0][envs_], memory_at_start[1][envs_])
                seq = actor(obs_buf[:, envs_], first, start_buf[:, envs_])
                return seq.reshape(-1, *seq.shape[2:])

            flat = lambda x: x.reshape(T * B, *x.shape[2:])
            b_obs, b_state, b_action, b_logp = flat(obs_buf), flat(state_buf), flat(action_buf), flat(logp_buf)
            b_adv, b_ret = flat(advantages), value_norm.normalize(flat(returns))
            b_adv = (b_adv - b_adv.mean()) / (b_adv.std() + 1e-8)
            stats = dict(policy_loss=0.0, value_loss=0.0, entropy=0.0, approx_kl=0.0, clip_fraction=0.0)
            updates = 0
            for _ in range(config.epochs):
                for idx in minibatch_rows(T, B, config.minibatches, recurrent, generator):
                    dist = action_distribution(logits_of(idx), H, C)
                    new_logp = dist.log_prob(b_action[idx]).sum(-1)
                    policy_loss = ppo_policy_loss(new_logp, b_logp[idx], b_adv[idx], config.clip)
                    value_loss = 0.5 * (critic(critic_inputs(config.algo, b_obs[idx], b_state[idx]))
                                        - b_ret[idx]).pow(2).mean()
                    entropy = dist.entropy().sum(-1).mean()
                    loss = policy_loss + config.value_coef * value_loss - entropy_coef * entropy
                    optimizer.zero_grad()
                    loss.backward()
                    if config.max_grad_norm:
                        nn.utils.clip_grad_norm_([*actor.parameters(), *critic.parameters()], config.max_grad_norm)
                    optimizer.step()
                    with torch.no_grad():
                        log_ratio = new_logp - b_logp[idx]
                        stats['approx_kl'] += float(((log_ratio.exp() - 1) - log_ratio).mean())
                        stats['clip_fraction'] += float(((log_ratio.exp() - 1).abs() > config.clip).float().mean())
                    stats['policy_loss'] += policy_loss.item()
                    stats['value_loss'] += value_loss.item()
                    stats['entropy'] += entropy.item()
                    updates += 1
            iteration += 1

            # ---- log
            elapsed = time.perf_counter() - start
            recent = list(episodes)
            row = dict(iteration=iteration, env_steps=env_steps, raw_steps=env_steps * config.frame_skip,
                       wall_seconds=round(elapsed, 2), steps_per_second=(env_steps - start_steps) / max(elapsed, 1e-9),
                       collect_share=collect_seconds / max(time.perf_counter() - t_collect, 1e-9),
                       rollout_coverage=float(np.mean(coverage)),
                       episode_coverage=float(np.mean([e['coverage'] for e in recent])) if recent else float('nan'),
                       episode_return=float(np.mean([e['return'] for e in recent])) if recent else float('nan'),
                       episode_normalized_target_return=float(np.mean([e.get('raw_return', np.nan) for e in recent]))
                       if recent else float('nan'),
                       episodes=len(recent), lr=lr, entropy_coef=entropy_coef,
                       **{k: v / updates for k, v in stats.items()})
            logger.write(row)
            if callback is not None:
                callback(row)
            if bar is not None:
                bar[0].update(bar[1], completed=env_steps, status=(
                    f"{row['steps_per_second']:,.0f} steps/s  coverage {row['rollout_coverage']:.3f}  "
                    f"episode return {row['episode_return']:.1f}  entropy {row['entropy']:.2f}"))
            if iteration % config.checkpoint_every == 0:
                checkpoint(checkpoint_path)
            if config.snapshot_every and iteration % config.snapshot_every == 0:
                snapshot(run_dir / 'snapshots' / f'policy-{env_steps:010d}.pt')
        checkpoint(checkpoint_path)
        checkpoint(run_dir / 'final.pt')
    finally:
        logger.close()
        if bar is not None:
            bar[0].stop()
    return row


def _progress_bar(total: int, done: int):
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    progress = Progress(TextColumn('training'), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                        TextColumn('{task.fields[status]}'))
    task = progress.add_task('train', total=total, completed=done, status='')
    progress.start()
    return progress, task
