"""IQL (independent deep Q-learning with a shared network) for MATE, in one file that reads top to bottom.

    config  ->  batched envs (`TeamVecEnv`: B games + batched greedy opponent)
            ->  a dueling Q-network shared by the team's agents, and its target copy
            ->  loop: every env step, each agent acts epsilon-greedily (one forward pass for B x N agents) and
                its transition enters the replay ring; once `learning_starts` decision steps are stored, one
                double-Q update of `batch_size` sampled agent transitions per env step; a hard copy to the
                target network every `target_update` decision steps
            ->  logs (progress bar, CSV, TensorBoard) and checkpoints (`checkpoint.pt`, `final.pt`, `best.pt`)

Spec training.md §2.3: dueling head, double-Q, 1-step targets, Huber loss, Adam (eps 1e-8), no gradient
clipping, epsilon 1.0 -> 0.02 over the first 50,000 decision steps, replay of 500,000 transitions, learning
from 5,000 steps on, target copy every 500 steps, one 1024-sample update per sampling round.

Counting as the PPO trainer does: a *decision step* is one env's decision (B per env step); a replay
*transition* is one agent's (B x N per env step). Every agent of the team shares the network, and each
agent's transition is its own sample (the team reward repeated, or each camera's own with
`credit='difference'`). Horizon cuts are truncations: their targets bootstrap from the last observation.

HRL cameras (`hrl=True`) choose keep/ignore for every target slot; the Q-value of a selection is the sum of
the slots' values (`DuelingQNetwork` with one head per slot: the argmax of the sum is each slot's own
argmax), instead of the original's one output per selection (Discrete(2^Nt)). Targets a camera does not see
are never selected (the executor would ignore them), as in the PPO trainer.

Resuming: the replay buffer is not saved (at the spec's size it is ~1 GB); a resumed run refills it with
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
from .logging import RunReport
from .networks import make_actor
from .schedules import piecewise

__all__ = ['DQNConfig', 'ReplayBuffer', 'double_q_targets', 'epsilon_greedy', 'train_dqn']


# ============================================================================ configuration

@dataclasses.dataclass
class DQNConfig:
    algo: str = 'iql'
    team: str = 'camera'                 # trained team; the other one is the batched greedy opponent
    env_id: str | None = None            # None: the paper's preset for the team
    config: str | None = None            # optional config for env_id 'MultiAgentTracking-v0'
    frame_skip: int | None = None        # None: 5 for cameras, 10 for targets
    horizon: int | None = None           # raw steps per training episode; None: 500 decisions
    levels: int = 5                      # discrete levels per action axis (25 actions)
    hrl: bool = False                    # cameras only: keep/ignore per target slot, rule executor aims
    credit: str = 'team'                 # cameras: 'team' or 'difference' rewards
    total_steps: int = 1_000_000         # decision steps (per env, summed over envs)
    time_limit: float = 0.0              # seconds of training wall time (resumed sessions included); 0: none
    num_envs: int = 16
    buffer_size: int = 500_000           # agent transitions kept
    batch_size: int = 1024               # agent transitions per update
    learning_starts: int = 5_000         # decision steps stored before the first update
    target_update: int = 500             # decision steps between hard target-network copies
    gamma: float = 0.99
    hidden: tuple = (512, 512, 256)
    activation: str = 'tanh'
    lr_schedule: tuple = ((0, 5e-4), (4_000_000, 1e-4), (8_000_000, 5e-5))    # step function of steps
    epsilon_schedule: tuple = ((0, 1.0), (50_000, 0.02))                     # piecewise linear
    report_every: int = 5_120            # decision steps per log row (an "iteration")
    checkpoint_every: int = 20           # iterations
    seed: int = 0
    torch_threads: int = 1

    def resolved(self) -> DQNConfig:
        """A copy with the team's defaults filled in (paper preset, frame skip and horizon)."""
        defaults = PAPER_SETTINGS[self.team]
        frame_skip = self.frame_skip or defaults['frame_skip']
        return dataclasses.replace(self, env_id=self.env_id or defaults['env_id'], frame_skip=frame_skip,
                                   horizon=self.horizon or 500 * frame_skip)

    def to_dict(self) -> dict:
        return {k: (list(map(list, v)) if k.endswith('schedule') else list(v) if isinstance(v, tuple) else v)
                for k, v in dataclasses.asdict(self).items()}


# ============================================================================ replay and the two formulas

class ReplayBuffer:
    """A ring of agent transitions in preallocated arrays: obs and next_obs (C, D) float32, action (C, H)
    int64, reward and terminal (C,) float32. `add` takes M transitions at once (M <= C); `sample`
    draws uniformly among those stored. Memory: C x (2 D x 4 + H x 8 + 8) bytes."""

    def __init__(self, capacity: int, obs_dim: int, heads: int) -> None:
        self.capacity, self.size, self.cursor = int(capacity), 0, 0
        self.obs = np.zeros((self.capacity, obs_dim), dtype=np.float32)
        self.next_obs = np.zeros((self.capacity, obs_dim), dtype=np.float32)
        self.action = np.zeros((self.capacity, heads), dtype=np.int64)
        self.reward = np.zeros(self.capacity, dtype=np.float32)
        self.terminal = np.zeros(self.capacity, dtype=np.float32)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.obs, self.next_obs, self.action, self.reward, self.terminal))

    def add(self, obs, action, reward, next_obs, terminal) -> None:
        count = len(obs)
        if count > self.capacity:
            raise ValueError(f'{count} transitions do not fit a buffer of {self.capacity}')
        rows = (self.cursor + np.arange(count)) % self.capacity
        self.obs[rows], self.action[rows], self.reward[rows] = obs, action, reward
        self.next_obs[rows], self.terminal[rows] = next_obs, terminal
        self.cursor = int((self.cursor + count) % self.capacity)
        self.size = min(self.size + count, self.capacity)

    def sample(self, batch: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
        rows = rng.integers(self.size, size=batch)
        return {name: torch.from_numpy(getattr(self, name)[rows])
                for name in ('obs', 'action', 'reward', 'next_obs', 'terminal')}


def _masked(q: torch.Tensor, allowed: torch.Tensor | None) -> torch.Tensor:
    return q if allowed is None else q.masked_fill(~allowed, -math.inf)


def double_q_targets(reward, terminal, next_online, next_target, gamma: float, allowed=None) -> torch.Tensor:
    """1-step double-Q targets (M,): r + gamma (1 - terminal) sum_h Q'_h(s', argmax_c Q_h(s', c)), the online
    network's per-head values `next_online` (M, H, C) choosing and the target network's `next_target`
    (M, H, C) evaluating; `allowed` (M, H, C) bool restricts the choice."""
    choice = _masked(next_online, allowed).argmax(-1, keepdim=True)
    value = next_target.gather(-1, choice).squeeze(-1).sum(-1)
    return reward + gamma * (1.0 - terminal) * value


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
    """Train; write progress.csv, tensorboard/, checkpoint.pt, final.pt and best.pt (the network at the best
    mean return over the last 25 training episodes) under `run_dir`. Resumes from `run_dir/checkpoint.pt`
    (CheckpointError if it belongs to another experiment). `envs` replaces the `TeamVecEnv` (tests use toy
    tasks). Returns the last log row."""
    config = config.resolved()
    if config.algo != 'iql':
        raise ValueError(f"unknown value-based algorithm {config.algo!r}; valid: 'iql'")
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(config.torch_threads)

    # ---- environments
    envs = envs or TeamVecEnv(config.team, num_envs=config.num_envs, env_id=config.env_id, frame_skip=config.frame_skip,
                              horizon=config.horizon, levels=config.levels, seed=config.seed, config=config.config,
                              hrl=config.hrl, credit=config.credit)
    B, N, D = envs.num_envs, envs.num_agents, envs.obs_dim
    H = getattr(envs, 'action_heads', 1)
    C = getattr(envs, 'action_choices', envs.num_actions)
    hrl = bool(getattr(envs, 'hrl', False))

    # ---- networks, optimiser, replay
    torch.manual_seed(config.seed)
    meta = dict(team=config.team, env_id=config.env_id, frame_skip=config.frame_skip, levels=config.levels,
                obs_dim=D, state_dim=envs.state_dim, num_agents=N, num_actions=H * C, action_heads=H,
                action_choices=C, hrl=hrl, counts=list(getattr(envs, 'counts', ())),
                credit=getattr(envs, 'credit', 'team'), actor='dueling', lstm=0, algo=config.algo, deterministic=True)
    q_net = make_actor('dueling', D, H * C, config.hidden, config.activation, meta)
    target_net = copy.deepcopy(q_net).requires_grad_(False)
    optimizer = torch.optim.Adam(q_net.parameters(), lr=config.lr_schedule[0][1], eps=1e-8)
    env_steps, iteration, wall_before, best_return = 0, 0, 0.0, -math.inf
    checkpoint_path = run_dir / 'checkpoint.pt'
    if resume and checkpoint_path.exists():
        saved = load_checkpoint(checkpoint_path, expect=meta)
        q_net.load_state_dict(saved['actor'])
        target_net.load_state_dict(saved['target'])
        optimizer.load_state_dict(saved['optimizer'])
        env_steps, iteration = saved['env_steps'], saved['iteration']
        wall_before, best_return = float(saved['wall_seconds']), float(saved['best_return'])
    learning_from = env_steps + config.learning_starts     # a fresh or resumed buffer fills first
    replay = ReplayBuffer(config.buffer_size, D, H)
    rng = np.random.default_rng([config.seed, iteration])
    masking = hrl and hasattr(envs, 'allowed_actions')

    def allowed_of(obs: np.ndarray):   # (..., H, C) bool or None
        return torch.from_numpy(envs.allowed_actions(obs)) if masking else None

    def checkpoint(path: Path) -> None:
        save_checkpoint(path, dict(actor=q_net.state_dict(), target=target_net.state_dict(),
                                   optimizer=optimizer.state_dict(), env_steps=env_steps, iteration=iteration,
                                   config=config.to_dict(), wall_seconds=wall_before + time.perf_counter() - start,
                                   best_return=report.best_return, meta=meta))

    obs, _ = envs.reset(seed=config.seed + 10_007 * iteration)
    report = RunReport(run_dir, config.total_steps, env_steps, progress, callback, best_return, save_best=lambda: (
        save_checkpoint(run_dir / 'best.pt', dict(actor=q_net.state_dict(), meta=meta, config=config.to_dict(),
                                                  env_steps=env_steps))))
    start, start_steps, row = time.perf_counter(), env_steps, {}
    coverage, losses, q_means = [], [], []
    next_report = (env_steps // config.report_every + 1) * config.report_every
    next_copy = (env_steps // config.target_update + 1) * config.target_update

    def out_of_time() -> bool:
        return config.time_limit > 0 and wall_before + time.perf_counter() - start >= config.time_limit

    try:
        while env_steps < config.total_steps and not out_of_time():
            # ---- act: epsilon-greedy for every agent of every env, one forward pass
            epsilon = piecewise(config.epsilon_schedule, env_steps, interpolate=True)
            with torch.no_grad():
                q = q_net(torch.from_numpy(obs)).unflatten(-1, (H, C))            # (B, N, H, C)
            action = epsilon_greedy(q, epsilon, rng, allowed_of(obs))            # (B, N, H)
            next_obs, _, reward, done, truncated, info = envs.step(action if hrl else action[..., 0])

            # ---- store each agent's transition; an ended episode's own last observation is its next one
            reward = np.broadcast_to(np.asarray(reward, dtype=np.float32).reshape(B, -1), (B, N))
            landing = np.where(done[:, None, None], info['final_obs'], next_obs)
            terminal = np.repeat((done & ~truncated).astype(np.float32), N)
            replay.add(obs.reshape(B * N, D), action.reshape(B * N, H), reward.reshape(-1),
                       landing.reshape(B * N, D), terminal)
            obs = next_obs
            env_steps += B
            coverage.append(float(np.mean(info['coverage'])))
            report.add_episodes(info['episodes'])

            # ---- learn: one double-Q update per env step, once the buffer holds `learning_starts` steps
            if env_steps >= learning_from:
                lr = piecewise(config.lr_schedule, env_steps, interpolate=False)
                for group in optimizer.param_groups:
                    group['lr'] = lr
                batch = replay.sample(config.batch_size, rng)
                q_all = q_net(batch['obs']).unflatten(-1, (H, C))
                q_taken = q_all.gather(-1, batch['action'][..., None]).squeeze(-1).sum(-1)
                with torch.no_grad():
                    next_q = torch.cat([q_net(batch['next_obs']), target_net(batch['next_obs'])]).unflatten(-1, (H, C))
                    online, evaluated = next_q.chunk(2)
                    targets = double_q_targets(batch['reward'], batch['terminal'], online, evaluated, config.gamma,
                                               allowed_of(batch['next_obs'].numpy()))
                loss = nn.functional.smooth_l1_loss(q_taken, targets)
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
                losses.append(loss.item())
                q_means.append(q_taken.detach().mean().item())
            if env_steps >= next_copy:
                target_net.load_state_dict(q_net.state_dict())
                next_copy += config.target_update

            # ---- log every `report_every` decision steps (an iteration)
            if env_steps >= next_report or env_steps >= config.total_steps:
                next_report += config.report_every
                iteration += 1
                elapsed = time.perf_counter() - start
                row = dict(iteration=iteration, env_steps=env_steps, raw_steps=env_steps * config.frame_skip,
                           wall_seconds=round(wall_before + elapsed, 2),
                           steps_per_second=(env_steps - start_steps) / max(elapsed, 1e-9),
                           rollout_coverage=float(np.mean(coverage)),
                           **report.episode_means(), epsilon=epsilon,
                           lr=piecewise(config.lr_schedule, env_steps, interpolate=False),
                           loss=float(np.mean(losses)) if losses else math.nan,
                           q_mean=float(np.mean(q_means)) if q_means else math.nan, buffer=replay.size)
                coverage, losses, q_means = [], [], []
                report.write(row, f"{row['steps_per_second']:,.0f} steps/s  coverage {row['rollout_coverage']:.3f}  "
                                  f"return {row['episode_return']:.1f}  epsilon {epsilon:.2f}")
                if iteration % config.checkpoint_every == 0:
                    checkpoint(checkpoint_path)
        checkpoint(checkpoint_path)
        checkpoint(run_dir / 'final.pt')
    finally:
        report.close()
    return row
