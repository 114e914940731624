"""IQL and QMIX (deep Q-learning with a network shared by the team's agents) for MATE, in one file that reads
top to bottom.

    config  ->  batched envs (`TeamVecEnv`: B games + batched greedy opponent)
            ->  the agents' Q-network and its target copy (IQL: dueling MLP; QMIX: GRU agent network plus a
                monotonic mixer of the agents' values on the global state, and the mixer's target copy)
            ->  loop: every env step, each agent acts epsilon-greedily (one forward pass for B x N agents) and
                the step enters the replay (IQL: a ring of agent transitions; QMIX: a ring of fixed-length
                chunks of team decisions); once `learning_starts` decision steps are stored, one double-Q
                update of `batch_size` samples every `update_every` decision steps; a hard copy to the target
                networks every `target_update` decision steps
            ->  logs (progress bar, CSV, TensorBoard) and checkpoints (`checkpoint.pt`, `final.pt`, `best.pt`)

IQL, spec training.md §2.3: dueling head, double-Q, 1-step targets, Huber loss, Adam (eps 1e-8), no gradient
clipping, epsilon 1.0 -> 0.02 over the first 50,000 decision steps, replay of 500,000 agent transitions,
learning from 5,000 steps on, target copy every 500 steps.
QMIX, §2.4: agent network Linear(256) + ReLU -> GRU(256) -> Q-values; mixer with embedding 128 (hyper-network
weights made non-negative by an absolute value, ELU hidden layer, a state-value MLP); double-Q 1-step targets
of the mixed value, masked MSE, RMSprop (lr 1e-4, alpha 0.99, eps 1e-5), gradient norm clipped at 1000.

Counting as the PPO trainer does: a *decision step* is one env's decision (B per env step). IQL samples agent
transitions (B x N per env step; each agent's own sample, with the team reward repeated or each camera's own
with `credit='difference'`); QMIX samples decision steps (all N agents and the team reward). Horizon cuts are
truncations: their targets bootstrap from the last observation.

QMIX's replay holds chunks of `sequence_length` decision steps that never cross an episode start (an episode
that ends early leaves the rest of its chunk masked), each with the GRU state the acting network had at its
first step; the original stored whole episodes of up to 500 decisions. At the spec's 2,000 episodes
(1,000,000 decision steps) the HRL MATE-4v8-9 camera buffer takes 3.25 GB, filled as it is used.

HRL cameras (`hrl=True`) choose a subset of the target slots. `selection='joint'` (the spec's Discrete(2^Nt),
the default): one choice among the 2^Nt subsets, those keeping an invisible target never taken (the executor
would ignore such a target; at deployment too, since their values are untrained). `selection='per-target'`: a
keep/ignore head per slot, the value of a subset being the sum of its slots' values (the argmax of the sum is
each slot's own argmax). The spec's form is the default (docs/training.md compares the two).

Resuming: the replay is not saved (at the spec's sizes it is 1-3 GB); a resumed run refills it with
`learning_starts` decision steps before it updates again, with the exploration rate of its step count.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import os
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

from .checkpoint import save_checkpoint, load_checkpoint
from .envs import PAPER_SETTINGS, TeamVecEnv
from .hrl import joint_allowed, selection_bits
from .logging import RunReport, mean_or_nan, out_of_time
from .networks import make_actor
from .replay import TransitionRing
from .schedules import piecewise

__all__ = ['DQNConfig', 'QMixer', 'ReplayBuffer', 'SequenceReplay', 'double_q_targets', 'double_q_values',
           'epsilon_greedy', 'iql_loss', 'qmix_loss', 'train_dqn']

ALGORITHMS = ('iql', 'qmix')
SELECTIONS = ('joint', 'per-target')


# ============================================================================ configuration

@dataclasses.dataclass
class DQNConfig:
    algo: str = 'iql'                    # 'iql' or 'qmix'
    team: str = 'camera'                 # trained team; the other one is the batched greedy opponent
    env_id: str | None = None            # None: the paper's preset for the team
    config: str | None = None            # optional config for env_id 'MultiAgentTracking-v0'
    frame_skip: int | None = None        # None: 5 for cameras, 10 for targets
    horizon: int | None = None           # raw steps per training episode; None: 500 decisions
    levels: int = 5                      # discrete levels per action axis (25 actions)
    hrl: bool = False                    # cameras only: keep/ignore per target slot, rule executor aims
    selection: str = 'joint'             # HRL: 'joint', one of 2^Nt selections (spec: Discrete(256)), or 'per-target'
    credit: str = 'team'                 # cameras: 'team' or 'difference' rewards (IQL only)
    total_steps: int = 1_000_000         # decision steps (per env, summed over envs)
    time_limit: float = 0.0              # seconds of training wall time (resumed sessions included); 0: none
    num_envs: int = 16
    buffer_size: int | None = None       # IQL: agent transitions (500,000); QMIX: decision steps (1,000,000)
    batch_size: int = 1024               # IQL: agent transitions per update; QMIX: decision steps (whole chunks)
    update_every: int = 128              # decision steps per update (the spec's sampling round of 16 x 8)
    sequence_length: int = 25            # QMIX: decision steps per replay chunk
    mixer_embed: int = 128               # QMIX: mixer width
    learning_starts: int = 5_000         # decision steps stored before the first update
    target_update: int = 500             # decision steps between hard target-network copies
    gamma: float = 0.99
    hidden: tuple | None = None          # None: IQL (512, 512, 256); QMIX (256,), the GRU width
    activation: str = 'tanh'             # IQL's trunk
    lr_schedule: tuple | None = None     # step function of steps; None: IQL 5e-4 -> 1e-4 (4M) -> 5e-5 (8M); QMIX 1e-4
    epsilon_schedule: tuple = ((0, 1.0), (50_000, 0.02))                     # piecewise linear
    report_every: int = 5_120            # decision steps per log row (an "iteration")
    checkpoint_every: int = 20           # iterations
    seed: int = 0
    torch_threads: int = 1

    def resolved(self) -> DQNConfig:
        """A copy with the team's and the algorithm's defaults filled in (paper preset, frame skip, horizon,
        network widths, learning rates and buffer size)."""
        if self.algo not in ALGORITHMS:
            raise ValueError(f'unknown value-based algorithm {self.algo!r}; valid: {", ".join(ALGORITHMS)}')
        if self.selection not in SELECTIONS:
            raise ValueError(f'selection must be one of {", ".join(SELECTIONS)} (HRL cameras), got {self.selection!r}')
        if self.algo == 'qmix' and self.credit != 'team':
            raise ValueError(f"QMIX learns from the team reward: credit must be 'team', not {self.credit!r}")
        for name in ('sequence_length', 'update_every', 'batch_size', 'num_envs'):
            if getattr(self, name) < 1:
                raise ValueError(f'{name} must be >= 1, got {getattr(self, name)}')
        defaults = PAPER_SETTINGS[self.team]
        frame_skip = self.frame_skip or defaults['frame_skip']
        qmix = self.algo == 'qmix'
        return dataclasses.replace(
            self, env_id=self.env_id or defaults['env_id'], frame_skip=frame_skip,
            horizon=self.horizon or 500 * frame_skip,
            buffer_size=self.buffer_size or (1_000_000 if qmix else 500_000),
            hidden=tuple(self.hidden or ((256,) if qmix else (512, 512, 256))),
            lr_schedule=tuple(map(tuple, self.lr_schedule or (
                ((0, 1e-4),) if qmix else ((0, 5e-4), (4_000_000, 1e-4), (8_000_000, 5e-5))))))

    def to_dict(self) -> dict:
        return {k: (list(map(list, v)) if k.endswith('schedule') else list(v) if isinstance(v, tuple) else v)
                for k, v in dataclasses.asdict(self).items()}


# ============================================================================ replay and the two formulas

class ReplayBuffer(TransitionRing):
    """IQL's ring of agent transitions: obs and next_obs (C, D) float32, action (C, H) int64, reward and
    terminal (C,) float32; `add(obs, action, reward, next_obs, terminal)` takes M transitions at once.
    Memory: C x (2 D x 4 + H x 8 + 8) bytes."""

    def __init__(self, capacity: int, obs_dim: int, heads: int) -> None:
        super().__init__(capacity, obs=((obs_dim,), np.float32), action=((heads,), np.int64),
                         reward=((), np.float32), next_obs=((obs_dim,), np.float32), terminal=((), np.float32))

    def add(self, obs, action, reward, next_obs, terminal) -> None:
        super().add(obs=obs, action=action, reward=reward, next_obs=next_obs, terminal=terminal)


class SequenceReplay:
    """A ring of chunks of up to L consecutive team decisions (QMIX), filled from B envs at once.

    Stored per chunk: obs (L + 1, N, D) and state (L + 1, S) float32 (the chunk's decisions and the
    observation after its last one), action (L, N, H) int16, reward, terminal and mask (L,) float32 (mask 0
    after an episode that ended inside the chunk), h0 (N, G) float32: the acting GRU state at its first step.
    `record` appends one env step of every row to the row's open chunk and closes (stores) the chunks that
    are full or whose episode ended; `sample(K)` draws K stored chunks as tensors with a leading K axis.
    Memory: C x ((L + 1)(N D + S) x 4 + L (2 N H + 12) + 4 N G) bytes for C = capacity // L chunks.
    """

    FIELDS = ('obs', 'state', 'action', 'reward', 'terminal', 'mask', 'h0')

    def __init__(self, capacity: int, length: int, rows: int, agents: int, obs_dim: int, state_dim: int,
                 heads: int, hidden: int) -> None:
        self.length, self.chunks, self.size, self.cursor = int(length), max(int(capacity) // int(length), 1), 0, 0
        L, N = self.length, agents

        def arrays(count: int) -> dict[str, np.ndarray]:
            return dict(obs=np.zeros((count, L + 1, N, obs_dim), np.float32),
                        state=np.zeros((count, L + 1, state_dim), np.float32),
                        action=np.zeros((count, L, N, heads), np.int16), reward=np.zeros((count, L), np.float32),
                        terminal=np.zeros((count, L), np.float32), mask=np.zeros((count, L), np.float32),
                        h0=np.zeros((count, N, hidden), np.float32))

        self.stored, self.open = arrays(self.chunks), arrays(rows)
        self.position = np.zeros(rows, dtype=np.int64)             # decisions in each row's open chunk

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.stored.values())

    def record(self, obs, state, action, reward, terminal, ended, next_obs, next_state, next_h) -> None:
        """One env step of the B rows: obs (B, N, D), state (B, S), action (B, N, H), reward and terminal (B,),
        `ended` (B,) bool: the episode is over (its next observation `next_obs` (B, N, D) / `next_state` is its
        last one); `next_h` (B, N, G): the GRU state for the next decision (zero where an episode restarts)."""
        rows = np.arange(len(obs))
        at = self.position
        chunk = self.open
        chunk['obs'][rows, at], chunk['state'][rows, at], chunk['action'][rows, at] = obs, state, action
        chunk['reward'][rows, at], chunk['terminal'][rows, at], chunk['mask'][rows, at] = reward, terminal, 1.0
        self.position = at = at + 1
        closing = np.flatnonzero(ended | (at == self.length))
        if len(closing) == 0:
            return
        chunk['obs'][closing, at[closing]] = next_obs[closing]
        chunk['state'][closing, at[closing]] = next_state[closing]
        slots = (self.cursor + np.arange(len(closing))) % self.chunks
        for name in self.FIELDS:
            self.stored[name][slots] = chunk[name][closing]
        self.cursor = int((self.cursor + len(closing)) % self.chunks)
        self.size = min(self.size + len(closing), self.chunks)
        # the closed rows open new chunks at their next decision
        chunk['mask'][closing] = 0.0
        chunk['obs'][closing, 0], chunk['state'][closing, 0] = next_obs[closing], next_state[closing]
        chunk['h0'][closing] = next_h[closing]
        self.position[closing] = 0

    def sample(self, count: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
        rows = rng.integers(self.size, size=count)
        return {name: torch.from_numpy(self.stored[name][rows]) for name in self.FIELDS}


def _masked(q: torch.Tensor, allowed: torch.Tensor | None) -> torch.Tensor:
    return q if allowed is None else q.masked_fill(~allowed, -math.inf)


def double_q_values(next_online, next_target, allowed=None) -> torch.Tensor:
    """sum_h Q'_h(s', argmax_c Q_h(s', c)) (...,): the online network's per-head values `next_online`
    (..., H, C) choose, the target network's `next_target` (..., H, C) evaluate; `allowed` (..., H, C) bool
    restricts the choice."""
    choice = _masked(next_online, allowed).argmax(-1, keepdim=True)
    return next_target.gather(-1, choice).squeeze(-1).sum(-1)


def double_q_targets(reward, terminal, next_online, next_target, gamma: float, allowed=None) -> torch.Tensor:
    """1-step double-Q targets (M,): r + gamma (1 - terminal) `double_q_values(...)` for per-head values
    (M, H, C) of the next observations."""
    return reward + gamma * (1.0 - terminal) * double_q_values(next_online, next_target, allowed)


class QMixer(nn.Module):
    """QMIX's mixing network (spec training.md §2.4): the agents' chosen values q (..., N) and the global
    state (..., S) -> Q_tot (...,) = ELU(q W1(s) + b1(s)) . W2(s) + V(s), with W1 = |Linear(s)| (N x E) and
    W2 = |Linear(s)| (E): non-negative weights, so dQ_tot/dq_i >= 0 (monotonic in every agent's value)."""

    def __init__(self, state_dim: int, agents: int, embed: int = 128) -> None:
        super().__init__()
        self.agents, self.embed = int(agents), int(embed)
        self.w1 = nn.Linear(state_dim, self.agents * self.embed)
        self.b1 = nn.Linear(state_dim, self.embed)
        self.w2 = nn.Linear(state_dim, self.embed)
        self.value = nn.Sequential(nn.Linear(state_dim, self.embed), nn.ReLU(), nn.Linear(self.embed, 1))

    def forward(self, q: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        w1 = self.w1(state).abs().unflatten(-1, (self.agents, self.embed))          # (..., N, E)
        hidden = nn.functional.elu((q.unsqueeze(-2) @ w1).squeeze(-2) + self.b1(state))
        return (hidden * self.w2(state).abs()).sum(-1) + self.value(state).squeeze(-1)


def iql_loss(q_net, target_net, batch: dict, gamma: float, heads: int, allowed_of) -> tuple[torch.Tensor, float]:
    """Huber loss of the double-Q targets on a batch of agent transitions (`ReplayBuffer.sample`), and the
    mean value of the taken actions. `allowed_of(obs)` gives the allowed choices (..., H, C) or None."""
    q_taken = q_net(batch['obs']).unflatten(-1, (heads, -1)).gather(-1, batch['action'][..., None]).squeeze(-1).sum(-1)
    with torch.no_grad():
        next_q = torch.cat([q_net(batch['next_obs']), target_net(batch['next_obs'])]).unflatten(-1, (heads, -1))
        online, evaluated = next_q.chunk(2)
        targets = double_q_targets(batch['reward'], batch['terminal'], online, evaluated, gamma,
                                   allowed_of(batch['next_obs']))
    return nn.functional.smooth_l1_loss(q_taken, targets), q_taken.detach().mean().item()


def qmix_loss(q_net, target_net, mixer, target_mixer, batch: dict, gamma: float, heads: int,
              allowed_of) -> tuple[torch.Tensor, float]:
    """Masked MSE between the mixed value of the taken joint actions and its double-Q target, on a batch of
    chunks (`SequenceReplay.sample`), and the mean mixed value. Both networks unroll every chunk from its
    stored GRU state; the online network picks each agent's next action, the target networks evaluate."""
    obs = batch['obs'].transpose(0, 1)                                     # (L + 1, K, N, D)
    state = batch['state'].transpose(0, 1)                                 # (L + 1, K, S)
    action = batch['action'].transpose(0, 1).long()                        # (L, K, N, H)
    reward, terminal, mask = (batch[k].transpose(0, 1) for k in ('reward', 'terminal', 'mask'))    # (L, K)
    q = q_net(obs, batch['h0']).unflatten(-1, (heads, -1))                 # (L + 1, K, N, H, C)
    taken = q[:-1].gather(-1, action[..., None]).squeeze(-1).sum(-1)       # (L, K, N)
    q_tot = mixer(taken, state[:-1])                                       # (L, K)
    with torch.no_grad():
        evaluated = target_net(obs, batch['h0']).unflatten(-1, (heads, -1))[1:]
        next_values = double_q_values(q[1:].detach(), evaluated, allowed_of(obs[1:]))         # (L, K, N)
        targets = reward + gamma * (1.0 - terminal) * target_mixer(next_values, state[1:])
    loss = ((q_tot - targets) ** 2 * mask).sum() / mask.sum().clamp_min(1.0)
    return loss, ((q_tot.detach() * mask).sum() / mask.sum().clamp_min(1.0)).item()


def epsilon_greedy(q: torch.Tensor, epsilon: float, rng: np.random.Generator, allowed=None) -> np.ndarray:
    """Actions (..., H) from per-head values q (..., H, C): each agent (leading index) explores with
    probability `epsilon`, then every head takes a uniform allowed choice, else the greedy one."""
    greedy = _masked(q, allowed).argmax(-1).numpy()
    explore = rng.random(q.shape[:-2]) < epsilon
    if explore.any():
        weights = np.ones(q.shape) if allowed is None else allowed.numpy().astype(np.float64)
        u = rng.random(q.shape[:-1] + (1,)) * weights.sum(-1, keepdims=True)
        uniform = np.minimum((weights.cumsum(-1) <= u).sum(-1), q.shape[-1] - 1)
        greedy = np.where(explore[..., None], uniform, greedy)
    return greedy


# ============================================================================ training

def train_dqn(config: DQNConfig, run_dir: str | os.PathLike, resume: bool = True, progress: bool = True,
              callback=None, envs=None) -> dict:
    """Train; write progress.csv, tensorboard/, checkpoint.pt, final.pt and best.pt (the agent network at the
    best mean return over the last 25 training episodes) under `run_dir`. Resumes from `run_dir/checkpoint.pt`
    (CheckpointError if it belongs to another experiment). `envs` replaces the `TeamVecEnv` (tests use toy
    tasks). Returns the last log row."""
    config = config.resolved()
    qmix = config.algo == 'qmix'
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(config.torch_threads)

    # ---- environments
    envs = envs or TeamVecEnv(config.team, num_envs=config.num_envs, env_id=config.env_id, frame_skip=config.frame_skip,
                              horizon=config.horizon, levels=config.levels, seed=config.seed, config=config.config,
                              hrl=config.hrl, credit=config.credit)
    B, N, D, S = envs.num_envs, envs.num_agents, envs.obs_dim, envs.state_dim
    H = getattr(envs, 'action_heads', 1)
    C = getattr(envs, 'action_choices', envs.num_actions)
    hrl = bool(getattr(envs, 'hrl', False))
    bits = None
    if hrl and config.selection == 'joint':   # one choice among 2^Nt selections, not Nt keep/ignore heads
        bits, H, C = selection_bits(H), 1, 2 ** H

    # ---- networks, optimiser, replay
    torch.manual_seed(config.seed)
    meta = dict(team=config.team, env_id=config.env_id, frame_skip=config.frame_skip, levels=config.levels,
                obs_dim=D, state_dim=S, num_agents=N, num_actions=H * C, action_heads=H,
                action_choices=C, hrl=hrl, counts=list(getattr(envs, 'counts', ())),
                credit=getattr(envs, 'credit', 'team'), actor='recurrent-q' if qmix else 'dueling', lstm=0,
                algo=config.algo, joint_selection=bits is not None, deterministic=True)
    q_net = make_actor(meta['actor'], D, H * C, config.hidden, config.activation, meta)
    target_net = copy.deepcopy(q_net).requires_grad_(False)
    mixer = QMixer(S, N, config.mixer_embed) if qmix else None
    target_mixer = copy.deepcopy(mixer).requires_grad_(False) if qmix else None
    learned = [*q_net.parameters(), *(mixer.parameters() if qmix else ())]
    lr = config.lr_schedule[0][1]
    optimizer = (torch.optim.RMSprop(learned, lr=lr, alpha=0.99, eps=1e-5) if qmix
                 else torch.optim.Adam(learned, lr=lr, eps=1e-8))
    env_steps, iteration, wall_before, best_return = 0, 0, 0.0, -math.inf
    checkpoint_path = run_dir / 'checkpoint.pt'
    if resume and checkpoint_path.exists():
        saved = load_checkpoint(checkpoint_path, expect=meta)
        q_net.load_state_dict(saved['actor'])
        target_net.load_state_dict(saved['target'])
        if qmix:
            mixer.load_state_dict(saved['mixer'])
            target_mixer.load_state_dict(saved['target_mixer'])
        optimizer.load_state_dict(saved['optimizer'])
        env_steps, iteration = saved['env_steps'], saved['iteration']
        wall_before, best_return = float(saved['wall_seconds']), float(saved['best_return'])
    learning_from = env_steps + config.learning_starts     # a fresh or resumed buffer fills first
    if qmix:
        replay = SequenceReplay(config.buffer_size, config.sequence_length, B, N, D, S, H, q_net.width)
        hidden = q_net.initial_state(B, N)[0]                                   # (B, N, G) acting GRU state
    else:
        replay = ReplayBuffer(config.buffer_size, D, H)
    rng = np.random.default_rng([config.seed, iteration])
    masking = hrl and hasattr(envs, 'allowed_actions')

    def allowed_of(obs):   # (..., N, D) array or tensor -> (..., N, H, C) bool tensor, or None
        if not masking:
            return None
        allowed = envs.allowed_actions(np.asarray(obs))
        return torch.from_numpy(allowed if bits is None else joint_allowed(allowed[..., 1])[..., None, :])

    def checkpoint(path: Path) -> None:
        mixers = dict(mixer=mixer.state_dict(), target_mixer=target_mixer.state_dict()) if qmix else {}
        save_checkpoint(path, dict(actor=q_net.state_dict(), target=target_net.state_dict(), **mixers,
                                   optimizer=optimizer.state_dict(), env_steps=env_steps, iteration=iteration,
                                   config=config.to_dict(), wall_seconds=wall_before + time.perf_counter() - start,
                                   best_return=report.best_return, meta=meta))

    obs, state = envs.reset(seed=config.seed + 10_007 * iteration)
    report = RunReport(run_dir, config.total_steps, env_steps, progress, callback, best_return, save_best=lambda: (
        save_checkpoint(run_dir / 'best.pt', dict(actor=q_net.state_dict(), meta=meta, config=config.to_dict(),
                                                  env_steps=env_steps))))
    start, start_steps, row = time.perf_counter(), env_steps, {}
    coverage, losses, q_means = [], [], []
    next_report = (env_steps // config.report_every + 1) * config.report_every
    next_copy = (env_steps // config.target_update + 1) * config.target_update
    next_update = max(learning_from, env_steps + config.update_every)

    try:
        while env_steps < config.total_steps and not out_of_time(config.time_limit,
                                                                    wall_before + time.perf_counter() - start):
            # ---- act: epsilon-greedy for every agent of every env, one forward pass
            epsilon = piecewise(config.epsilon_schedule, env_steps, interpolate=True)
            with torch.no_grad():
                if qmix:
                    q, (next_hidden,) = q_net.step(torch.from_numpy(obs), (hidden,))
                else:
                    q = q_net(torch.from_numpy(obs))
            action = epsilon_greedy(q.unflatten(-1, (H, C)), epsilon, rng, allowed_of(obs))      # (B, N, H)
            env_action = action[..., 0] if not hrl else action if bits is None else bits[action[..., 0]]
            next_obs, next_state, reward, done, truncated, info = envs.step(env_action)

            # ---- store the step; an ended episode's own last observation is its next one
            landing = np.where(done[:, None, None], info['final_obs'], next_obs)
            terminal = (done & ~truncated).astype(np.float32)
            if qmix:
                next_hidden[torch.from_numpy(done)] = 0.0
                replay.record(obs, state, action, np.asarray(reward, dtype=np.float32), terminal, done, landing,
                              np.where(done[:, None], info['final_state'], next_state), next_hidden.numpy())
                hidden = next_hidden
            else:
                reward = np.broadcast_to(np.asarray(reward, dtype=np.float32).reshape(B, -1), (B, N))
                replay.add(obs.reshape(B * N, D), action.reshape(B * N, H), reward.reshape(-1),
                           landing.reshape(B * N, D), np.repeat(terminal, N))
            obs, state = next_obs, next_state
            env_steps += B
            coverage.append(float(np.mean(info['coverage'])))
            report.add_episodes(info['episodes'])

            # ---- learn: one double-Q update every `update_every` decision steps, once `learning_starts` are stored
            while env_steps >= next_update and replay.size:
                next_update += config.update_every
                lr = piecewise(config.lr_schedule, env_steps, interpolate=False)
                for group in optimizer.param_groups:
                    group['lr'] = lr
                if qmix:
                    batch = replay.sample(math.ceil(config.batch_size / config.sequence_length), rng)
                    loss, q_mean = qmix_loss(q_net, target_net, mixer, target_mixer, batch, config.gamma, H, allowed_of)
                else:
                    loss, q_mean = iql_loss(q_net, target_net, replay.sample(config.batch_size, rng), config.gamma,
                                            H, allowed_of)
                optimizer.zero_grad()
                loss.backward()
                if qmix:
                    nn.utils.clip_grad_norm_(learned, 1000.0)
                optimizer.step()
                losses.append(loss.item())
                q_means.append(q_mean)
            if env_steps >= next_copy:
                target_net.load_state_dict(q_net.state_dict())
                if qmix:
                    target_mixer.load_state_dict(mixer.state_dict())
                next_copy += config.target_update

            # ---- log every `report_every` decision steps (an iteration)
            if env_steps >= next_report or env_steps >= config.total_steps:
                next_report += config.report_every
                iteration += 1
                elapsed = time.perf_counter() - start
                row = report.iteration_row(
                    iteration, env_steps, config.frame_skip, wall_before + elapsed,
                    (env_steps - start_steps) / max(elapsed, 1e-9), coverage, epsilon=epsilon,
                    lr=piecewise(config.lr_schedule, env_steps, interpolate=False), loss=mean_or_nan(losses),
                    q_mean=mean_or_nan(q_means), buffer=replay.size)
                coverage, losses, q_means = [], [], []
                report.write(row, report.status(row, f'epsilon {epsilon:.2f}'))
                if iteration % config.checkpoint_every == 0:
                    checkpoint(checkpoint_path)
        checkpoint(checkpoint_path)
        checkpoint(run_dir / 'final.pt')
    finally:
        report.close()
    return row
