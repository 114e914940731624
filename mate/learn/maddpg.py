"""MADDPG as MA-TD3 (centralised twin Q-critics, one deterministic actor per agent) for MATE, in one file that
reads top to bottom.

    config  ->  batched envs with continuous actions (`TeamVecEnv(levels=0)`: B games + batched greedy opponent)
            ->  per agent: an actor (local observation -> action in [-1, 1]^2) and two critics (global state and
                the team's joint action -> Q), all agents' networks evaluated at once (`AgentwiseMLP`), and
                their target copies
            ->  loop: every env step, uniform random actions for the first `random_steps` decision steps, then
                each actor's action plus Gaussian noise; the step (all agents) enters the replay ring; once
                `learning_starts` decision steps are stored, every `update_every` decision steps one update of
                `batch_size` samples: both critics towards the clipped double-Q target with target-policy
                smoothing, the actors every `policy_delay` updates, soft target updates (tau) after each
            ->  logs (progress bar, CSV, TensorBoard) and checkpoints (`checkpoint.pt`, `final.pt`, `best.pt`)

Spec training.md §2.5: independent policies (no sharing); actor MLP [512, 256] tanh, output init 0.01, squashed to
the action box; critic: concat(state, joint action) -> MLP [512, 256] tanh -> Q, no layer norm; Huber critic loss
(threshold 10); Adam, lr 1e-4 for both; tau 0.01 after every update; policy delay 2; smoothing noise 0.2 clipped at
0.5; exploration: uniform actions for 10,000 decision steps, then Gaussian noise 0.1; replay 500,000 decision
steps, learning from 5,000. Deviations (docs/differences.md): the twin critics are two networks (the original
routed the second through the first, so its clipped double-Q was off); the noises are in units of each agent's
action bounds (actions live in [-1, 1]); the next actions of the target are every agent's target actor's (the
textbook MADDPG), not the behaviour data's; one update per 128 decision steps instead of per 3,200.

Actions in [-1, 1] are each agent's share of its own bounds (`TeamVecEnv` scales them: cameras' rotation and
zoom steps, targets' step size). Rewards: the team's (repeated for every agent) or each camera's own with
`credit='difference'`; the critic of agent i learns agent i's return. Horizon cuts are truncations.

Resuming: the replay is not saved; a resumed run refills it with `learning_starts` decision steps (and the
uniform phase is not repeated).
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

from .checkpoint import load_checkpoint, save_checkpoint
from .envs import PAPER_SETTINGS, TeamVecEnv
from .logging import RunReport, mean_or_nan, out_of_time
from .networks import AgentwiseMLP, IndependentActors
from .replay import TransitionRing

__all__ = ['MADDPGConfig', 'TwinCritics', 'actor_inputs', 'critic_targets', 'smoothed_actions', 'train_maddpg']


# ============================================================================ configuration

@dataclasses.dataclass
class MADDPGConfig:
    algo: str = 'maddpg'
    team: str = 'target'                 # trained team; the other one is the batched greedy opponent
    env_id: str | None = None            # None: the paper's preset for the team
    config: str | None = None            # optional config for env_id 'MultiAgentTracking-v0'
    frame_skip: int | None = None        # None: 5 for cameras, 10 for targets
    horizon: int | None = None           # raw steps per training episode; None: 500 decisions
    credit: str = 'team'                 # cameras: 'team' or 'difference' rewards
    total_steps: int = 1_000_000         # decision steps (per env, summed over envs)
    time_limit: float = 0.0              # seconds of training wall time (resumed sessions included); 0: none
    num_envs: int = 16
    buffer_size: int = 500_000           # decision steps (all agents of a team)
    batch_size: int = 1024               # decision steps per update
    update_every: int = 128              # decision steps per update
    learning_starts: int = 5_000         # decision steps stored before the first update
    random_steps: int = 10_000           # decision steps of uniform random actions first
    exploration_noise: float = 0.1       # std of the Gaussian action noise (share of the action bounds)
    target_noise: float = 0.2            # target-policy smoothing noise std ...
    target_noise_clip: float = 0.5       # ... clipped at +-this
    policy_delay: int = 2                # critic updates per actor update
    tau: float = 0.01                    # soft target update after every update
    gamma: float = 0.99
    actor_lr: float = 1e-4
    critic_lr: float = 1e-4
    huber: float = 10.0                  # Huber threshold of the critic loss
    hidden: tuple = (512, 256)           # actor and critic MLPs
    activation: str = 'tanh'
    report_every: int = 5_120            # decision steps per log row (an "iteration")
    checkpoint_every: int = 20           # iterations
    seed: int = 0
    torch_threads: int = 1

    def resolved(self) -> MADDPGConfig:
        """A copy with the team's defaults filled in (paper preset, frame skip and horizon); ValueError for
        settings out of range."""
        if self.algo != 'maddpg':
            raise ValueError(f"unknown algorithm {self.algo!r} for this trainer; valid: 'maddpg'")
        for name in ('num_envs', 'buffer_size', 'batch_size', 'update_every', 'policy_delay'):
            if getattr(self, name) < 1:
                raise ValueError(f'{name} must be >= 1, got {getattr(self, name)}')
        if not 0.0 < self.tau <= 1.0:
            raise ValueError(f'tau must be in (0, 1], got {self.tau}')
        defaults = PAPER_SETTINGS[self.team]
        frame_skip = self.frame_skip or defaults['frame_skip']
        return dataclasses.replace(self, env_id=self.env_id or defaults['env_id'], frame_skip=frame_skip,
                                   horizon=self.horizon or 500 * frame_skip, hidden=tuple(self.hidden))

    def to_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}


# ============================================================================ critics and the formulas

class TwinCritics(nn.Module):
    """Two independent Q-critics per agent: input (..., N, S + N A) (the global state and a joint action, as
    agent i's critic sees it) -> (q1, q2), each (..., N)."""

    def __init__(self, agents: int, inputs: int, hidden=(512, 256), activation: str = 'tanh') -> None:
        super().__init__()
        self.q1 = AgentwiseMLP(agents, inputs, hidden, 1, activation)
        self.q2 = AgentwiseMLP(agents, inputs, hidden, 1, activation)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.q1(x).squeeze(-1), self.q2(x).squeeze(-1)


def critic_inputs(state: torch.Tensor, joint: torch.Tensor) -> torch.Tensor:
    """Every agent's critic input (..., N, S + N A) from the state (..., S) and one joint action (..., N, A)
    that all agents' critics see."""
    N = joint.shape[-2]
    flat = joint.flatten(-2)
    return torch.cat([state, flat], -1).unsqueeze(-2).expand(*flat.shape[:-1], N, state.shape[-1] + flat.shape[-1])


def actor_inputs(state: torch.Tensor, joint: torch.Tensor, own: torch.Tensor) -> torch.Tensor:
    """Agent i's critic input for its actor update: the stored joint action (..., N, A) with agent i's own
    entry replaced by `own[..., i, :]` (the actor's current action); (..., N, S + N A). Only agent i's actor
    receives the gradient of agent i's critic."""
    N = joint.shape[-2]
    eye = torch.eye(N, dtype=joint.dtype)[..., None]                        # (N_critic, N_slot, 1)
    joints = eye * own.unsqueeze(-3) + (1 - eye) * joint.unsqueeze(-3)     # (..., N_critic, N_slot, A)
    state = state.unsqueeze(-2).expand(*joints.shape[:-2], state.shape[-1])
    return torch.cat([state, joints.flatten(-2)], -1)


def smoothed_actions(actions: torch.Tensor, noise: torch.Tensor, noise_clip: float) -> torch.Tensor:
    """Target-policy smoothing: clip(actions + clip(noise, -c, c), -1, 1)."""
    return (actions + noise.clamp(-noise_clip, noise_clip)).clamp(-1.0, 1.0)


def critic_targets(reward, terminal, next_q1, next_q2, gamma: float) -> torch.Tensor:
    """Clipped double-Q targets (..., N): r + gamma (1 - terminal) min(Q1', Q2'), rewards (..., N), terminal
    (...,) and the target critics' values (..., N) at the smoothed next joint action."""
    return reward + gamma * (1.0 - terminal[..., None]) * torch.minimum(next_q1, next_q2)


# ============================================================================ training

def train_maddpg(config: MADDPGConfig, run_dir: str | os.PathLike, resume: bool = True, progress: bool = True,
                 callback=None, envs=None) -> dict:
    """Train; write progress.csv, tensorboard/, checkpoint.pt, final.pt and best.pt (the actors at the best mean
    return over the last 25 training episodes) under `run_dir`. Resumes from `run_dir/checkpoint.pt`
    (CheckpointError if it belongs to another experiment). `envs` replaces the `TeamVecEnv` (tests use toy
    tasks with continuous actions). Returns the last log row."""
    config = config.resolved()
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(config.torch_threads)

    # ---- environments
    envs = envs or TeamVecEnv(config.team, num_envs=config.num_envs, env_id=config.env_id, frame_skip=config.frame_skip,
                              horizon=config.horizon, levels=0, seed=config.seed, config=config.config,
                              credit=config.credit)
    B, N, D, S, A = envs.num_envs, envs.num_agents, envs.obs_dim, envs.state_dim, envs.num_actions

    # ---- networks, optimisers, replay
    torch.manual_seed(config.seed)
    meta = dict(team=config.team, env_id=config.env_id, frame_skip=config.frame_skip, levels=0, obs_dim=D,
                state_dim=S, num_agents=N, num_actions=A, action_heads=1, action_choices=A, hrl=False,
                counts=list(getattr(envs, 'counts', ())), credit=getattr(envs, 'credit', 'team'),
                actor='independent', hidden=list(config.hidden), lstm=0, algo=config.algo, continuous=True,
                deterministic=True)
    actor = IndependentActors(N, D, A, config.hidden, config.activation)
    critics = TwinCritics(N, S + N * A, config.hidden, config.activation)
    target_actor = copy.deepcopy(actor).requires_grad_(False)
    target_critics = copy.deepcopy(critics).requires_grad_(False)
    actor_optimizer = torch.optim.Adam(actor.parameters(), lr=config.actor_lr)
    critic_optimizer = torch.optim.Adam(critics.parameters(), lr=config.critic_lr)
    env_steps, iteration, updates, wall_before, best_return = 0, 0, 0, 0.0, -math.inf
    checkpoint_path = run_dir / 'checkpoint.pt'
    if resume and checkpoint_path.exists():
        saved = load_checkpoint(checkpoint_path, expect=meta)
        for module, key in ((actor, 'actor'), (critics, 'critics'), (target_actor, 'target_actor'),
                            (target_critics, 'target_critics'), (actor_optimizer, 'actor_optimizer'),
                            (critic_optimizer, 'critic_optimizer')):
            module.load_state_dict(saved[key])
        env_steps, iteration, updates = saved['env_steps'], saved['iteration'], saved['updates']
        wall_before, best_return = float(saved['wall_seconds']), float(saved['best_return'])
    learning_from = env_steps + config.learning_starts     # a fresh or resumed buffer fills first
    replay = TransitionRing(config.buffer_size, obs=((N, D), np.float32), state=((S,), np.float32),
                            action=((N, A), np.float32), reward=((N,), np.float32), next_obs=((N, D), np.float32),
                            next_state=((S,), np.float32), terminal=((), np.float32))
    rng = np.random.default_rng([config.seed, iteration])
    noise = torch.Generator().manual_seed(int(rng.integers(2 ** 62)))

    def checkpoint(path: Path) -> None:
        save_checkpoint(path, dict(actor=actor.state_dict(), critics=critics.state_dict(),
                                   target_actor=target_actor.state_dict(), target_critics=target_critics.state_dict(),
                                   actor_optimizer=actor_optimizer.state_dict(),
                                   critic_optimizer=critic_optimizer.state_dict(), env_steps=env_steps,
                                   iteration=iteration, updates=updates, config=config.to_dict(),
                                   wall_seconds=wall_before + time.perf_counter() - start,
                                   best_return=report.best_return, meta=meta))

    obs, state = envs.reset(seed=config.seed + 10_007 * iteration)
    report = RunReport(run_dir, config.total_steps, env_steps, progress, callback, best_return, save_best=lambda: (
        save_checkpoint(run_dir / 'best.pt', dict(actor=actor.state_dict(), meta=meta, config=config.to_dict(),
                                                  env_steps=env_steps))))
    start, start_steps, row = time.perf_counter(), env_steps, {}
    coverage, critic_losses, actor_losses, q_means = [], [], [], []
    next_report = (env_steps // config.report_every + 1) * config.report_every
    next_update = max(learning_from, env_steps + config.update_every)

    try:
        while env_steps < config.total_steps and not out_of_time(config.time_limit,
                                                                    wall_before + time.perf_counter() - start):
            # ---- act: uniform at first, then the actors' actions plus Gaussian noise
            if env_steps < config.random_steps:
                action = rng.uniform(-1.0, 1.0, size=(B, N, A)).astype(np.float32)
            else:
                with torch.no_grad():
                    action = actor(torch.from_numpy(obs)).numpy()
                action = np.clip(action + config.exploration_noise * rng.standard_normal(action.shape), -1.0, 1.0)
                action = action.astype(np.float32)
            next_obs, next_state, reward, done, truncated, info = envs.step(action)

            # ---- store the step; an ended episode's own last observation is its next one
            replay.add(obs=obs, state=state, action=action,
                       reward=np.broadcast_to(np.asarray(reward, dtype=np.float32).reshape(B, -1), (B, N)),
                       next_obs=np.where(done[:, None, None], info['final_obs'], next_obs),
                       next_state=np.where(done[:, None], info['final_state'], next_state),
                       terminal=(done & ~truncated).astype(np.float32))
            obs, state = next_obs, next_state
            env_steps += B
            coverage.append(float(np.mean(info['coverage'])))
            report.add_episodes(info['episodes'])

            # ---- learn: critics every `update_every` decision steps, actors every `policy_delay` critic updates
            while env_steps >= next_update:
                next_update += config.update_every
                batch = replay.sample(config.batch_size, rng)
                with torch.no_grad():
                    next_action = smoothed_actions(
                        target_actor(batch['next_obs']),
                        config.target_noise * torch.randn(batch['action'].shape, generator=noise),
                        config.target_noise_clip)
                    next_q1, next_q2 = target_critics(critic_inputs(batch['next_state'], next_action))
                    targets = critic_targets(batch['reward'], batch['terminal'], next_q1, next_q2, config.gamma)
                q1, q2 = critics(critic_inputs(batch['state'], batch['action']))
                critic_loss = (nn.functional.huber_loss(q1, targets, delta=config.huber)
                               + nn.functional.huber_loss(q2, targets, delta=config.huber))
                critic_optimizer.zero_grad()
                critic_loss.backward()
                critic_optimizer.step()
                critic_losses.append(critic_loss.item())
                q_means.append(q1.detach().mean().item())
                updates += 1
                if updates % config.policy_delay == 0:
                    own = actor(batch['obs'])
                    actor_loss = -critics.q1(actor_inputs(batch['state'], batch['action'], own)).mean()
                    actor_optimizer.zero_grad()
                    actor_loss.backward()
                    actor_optimizer.step()
                    actor_losses.append(actor_loss.item())
                with torch.no_grad():   # soft target updates after every update
                    for net, target in ((actor, target_actor), (critics, target_critics)):
                        for p, p_target in zip(net.parameters(), target.parameters()):
                            p_target.lerp_(p, config.tau)

            # ---- log every `report_every` decision steps (an iteration)
            if env_steps >= next_report or env_steps >= config.total_steps:
                next_report += config.report_every
                iteration += 1
                elapsed = time.perf_counter() - start
                row = report.iteration_row(
                    iteration, env_steps, config.frame_skip, wall_before + elapsed,
                    (env_steps - start_steps) / max(elapsed, 1e-9), coverage, critic_loss=mean_or_nan(critic_losses),
                    actor_loss=mean_or_nan(actor_losses), q_mean=mean_or_nan(q_means), buffer=replay.size)
                coverage, critic_losses, actor_losses, q_means = [], [], [], []
                report.write(row, report.status(row))
                if iteration % config.checkpoint_every == 0:
                    checkpoint(checkpoint_path)
        checkpoint(checkpoint_path)
        checkpoint(run_dir / 'final.pt')
    finally:
        report.close()
    return row
