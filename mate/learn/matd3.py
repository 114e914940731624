"""MADDPG as MA-TD3 for MATE: one deterministic actor and two centralised Q-critics per agent, continuous actions,
in one file that reads top to bottom (`mate train matd3`, alias `mate train maddpg`).

    config  ->  PolicySpec (continuous actions: each agent's share of its own action bounds, in [-1, 1]^2)
            ->  batched training envs (`TrainingEnv`: B games, the other team the greedy rules)
            ->  networks, per agent (no sharing): an actor (local observation -> action) and twin critics (global
                state and the team's joint action -> Q), all agents' networks evaluated at once (`AgentwiseMLP`),
                and their target copies
            ->  loop: uniform random actions for the first `random_steps` decision steps, then each actor's action
                plus Gaussian noise; the team's decision enters the replay ring; once `learning_starts` decision
                steps are stored, one update of `batch_size` decision steps every `update_every`: both critics
                towards the clipped double-Q target with target-policy smoothing, the actors every `policy_delay`
                updates, soft target updates (tau) after each; a log row (an iteration) every `report_every`
            ->  `Run`: logs, checkpoints, best.pt, final.pt

As the paper's MADDPG (docs/training.md, "MADDPG as MA-TD3"): independent policies (no sharing); actor MLP [512, 256]
tanh, output init 0.01, squashed to the action box; critic: concat(state, joint action) -> MLP [512, 256] tanh -> Q,
no layer norm; Huber critic loss (threshold 10); Adam, lr 1e-4 for both; tau 0.01 after every update; policy delay 2;
smoothing noise 0.2 clipped at 0.5; exploration: uniform actions for 10,000 decision steps, then Gaussian noise 0.1;
replay 500,000 decision steps, learning from 5,000. Deviations (docs/differences.md): the twin critics are two
networks (the original routed the second through the first, so its clipped double-Q was off); the noises are in units
of each agent's action bounds (actions live in [-1, 1]); the next actions of the target are every agent's target
actor's (the textbook MADDPG), not the behaviour data's; one update per 128 decision steps instead of per 3,200.

Actions in [-1, 1] are each agent's share of its own bounds (`TrainingEnv` scales them: cameras' rotation and zoom
steps, targets' step size). Rewards: the team's (repeated for every agent) or each camera's own with `--credit
difference`; the critic of agent i learns agent i's return. Horizon cuts are truncations.

Resuming: the checkpoint written at the end of a session (the run complete, its time spent, or stopped by SIGINT /
SIGTERM) holds the replay's filled rows, so the same command continues exactly as if never stopped. The periodic
checkpoints (every `checkpoint_every` iterations) leave it out (1-2 GB at the spec's sizes): a run resumed from one
(after a crash) refills the replay with `learning_starts` decision steps before it updates again (the uniform
phase is not repeated).
"""

from __future__ import annotations

import copy
import dataclasses
from typing import Literal

import numpy as np
import torch
from torch import nn

from ..cli.options import option
from .envs import TrainingEnv
from ..policies.networks import AgentwiseMLP
from .offpolicy_loop import OffPolicyConfig, OffPolicyLearner, train_off_policy
from ..policies.policy import make_actor
from .replay import TransitionRing
from .run import Run, mean_or_nan
from .schedules import check_network_options
from ..policies.spec import PolicySpec

__all__ = ['MATD3Config', 'MATD3Learner', 'TwinCritics', 'actor_inputs', 'critic_inputs', 'critic_targets',
           'policy_spec', 'smoothed_actions', 'train']


@dataclasses.dataclass
class MATD3Config(OffPolicyConfig):
    """Settings of an MA-TD3 run (`train(config)`, `mate train matd3`)."""

    hrl: bool = option(False, 'MA-TD3 acts with continuous actions: no HRL target selections', cli=False)
    buffer_size: int = option(500_000, 'replay size in decision steps (all agents of the team)', minimum=1)
    batch_size: int = option(1024, 'decision steps per update', minimum=1)
    random_steps: int = option(10_000, 'decision steps of uniform random actions first', minimum=0)
    exploration_noise: float = option(0.1, 'std of the Gaussian action noise (a share of the action bounds)', minimum=0)
    target_noise: float = option(0.2, 'std of the target-policy smoothing noise', minimum=0)
    target_noise_clip: float = option(0.5, 'the smoothing noise is clipped at +- this', minimum=0)
    policy_delay: int = option(2, 'critic updates per actor update', minimum=1)
    tau: float = option(0.01, 'soft target update rate, after every update, in (0, 1]', above=0, maximum=1)
    actor_lr: float = option(1e-4, "the actors' learning rate (Adam)", above=0)
    critic_lr: float = option(1e-4, "the critics' learning rate (Adam)", above=0)
    huber: float = option(10.0, 'Huber threshold of the critic loss', above=0)
    hidden: tuple[int, ...] = option((512, 256), 'hidden layer widths of the actors and the critics', minimum=1)
    activation: Literal['tanh', 'relu'] = option('tanh', 'hidden activation')

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.hrl:
            raise ValueError('--hrl is not an option of MA-TD3: it acts with continuous actions (HRL selections are '
                             'discrete: mappo, iql, qmix)')
        check_network_options(self)
        self.hidden = tuple(self.hidden)


def policy_spec(config: MATD3Config, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains (the agents' actors, continuous actions); with `envs` given, what they
    say the policy sees and does (their `spec`: the tests' toy tasks) with this network."""
    return config.policy_spec(action='continuous', envs=envs, network='independent', hidden=config.hidden,
                              activation=config.activation, lstm=0, algo='matd3', deterministic=True)


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
    eye = torch.eye(N, dtype=joint.dtype, device=joint.device)[..., None]     # (N_critic, N_slot, 1)
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

class MATD3Learner(OffPolicyLearner):
    """MA-TD3 on the off-policy loop (`mate.learn.offpolicy_loop`): every agent's actor and twin critics (evaluated
    at once), their target copies, a replay ring of the team's decisions; uniform actions for `random_steps` decision
    steps, then the actors' plus Gaussian noise; per update both critics, the actors every `policy_delay` updates,
    soft target updates after each."""

    def __init__(self, config: MATD3Config, spec: PolicySpec, envs, device, rng: np.random.Generator) -> None:
        B, N, D, S, A = envs.num_envs, envs.num_agents, envs.obs_dim, envs.state_dim, spec.num_actions
        self.config, self.device, self.shape = config, device, (B, N, A)
        self.actor = make_actor(spec).to(device)
        self.critics = TwinCritics(N, S + N * A, config.hidden, config.activation).to(device)
        self.target_actor = copy.deepcopy(self.actor).requires_grad_(False)
        self.target_critics = copy.deepcopy(self.critics).requires_grad_(False)
        self.actor_optimizer = torch.optim.Adam(self.actor.parameters(), lr=config.actor_lr)
        self.critic_optimizer = torch.optim.Adam(self.critics.parameters(), lr=config.critic_lr)
        self.replay = TransitionRing(config.buffer_size, obs=((N, D), np.float32), state=((S,), np.float32),
                                     action=((N, A), np.float32), reward=((N,), np.float32),
                                     next_obs=((N, D), np.float32), next_state=((S,), np.float32),
                                     terminal=((), np.float32))
        self.networks = dict(actor=self.actor, critics=self.critics, target_actor=self.target_actor,
                             target_critics=self.target_critics)
        self.noise = torch.Generator(device).manual_seed(int(rng.integers(2 ** 62)))    # target-policy smoothing
        self.updates = 0
        self.critic_losses, self.actor_losses, self.q_means = [], [], []

    def state_dict(self) -> dict:
        return dict(optimizers=dict(actor=self.actor_optimizer.state_dict(), critic=self.critic_optimizer.state_dict()),
                    updates=self.updates, noise=self.noise.get_state())

    def load_state_dict(self, saved: dict) -> None:
        super().load_state_dict(saved)
        self.actor_optimizer.load_state_dict(saved['optimizers']['actor'])
        self.critic_optimizer.load_state_dict(saved['optimizers']['critic'])
        self.noise.set_state(saved['noise'])
        self.updates = int(saved['updates'])

    def act(self, obs, state, steps, rng):
        """Uniform at first, then the actors' actions plus Gaussian noise."""
        if steps < self.config.random_steps:
            action = rng.uniform(-1.0, 1.0, size=self.shape).astype(np.float32)
        else:
            with torch.no_grad():
                action = self.actor(torch.from_numpy(obs).to(self.device)).cpu().numpy()
            action = np.clip(action + self.config.exploration_noise * rng.standard_normal(action.shape), -1.0, 1.0)
            action = action.astype(np.float32)
        return action, action

    def store(self, obs, state, action, reward, done, truncated, next_obs, next_state, info) -> None:
        """The team's decision; an ended episode's own last observation is its next one."""
        B, N, _ = self.shape
        self.replay.add(obs=obs, state=state, action=action,
                        reward=np.broadcast_to(np.asarray(reward, dtype=np.float32).reshape(B, -1), (B, N)),
                        next_obs=np.where(done[:, None, None], info['final_obs'], next_obs),
                        next_state=np.where(done[:, None], info['final_state'], next_state),
                        terminal=(done & ~truncated).astype(np.float32))

    def update(self, steps, rng) -> None:
        """The critics, the actors every `policy_delay` updates, then the soft target updates."""
        config, device = self.config, self.device
        batch = {key: value.to(device) for key, value in self.replay.sample(config.batch_size, rng).items()}
        with torch.no_grad():
            smoothing = torch.randn(batch['action'].shape, generator=self.noise, device=device)
            next_action = smoothed_actions(self.target_actor(batch['next_obs']), config.target_noise * smoothing,
                                           config.target_noise_clip)
            next_q1, next_q2 = self.target_critics(critic_inputs(batch['next_state'], next_action))
            targets = critic_targets(batch['reward'], batch['terminal'], next_q1, next_q2, config.gamma)
        q1, q2 = self.critics(critic_inputs(batch['state'], batch['action']))
        critic_loss = (nn.functional.huber_loss(q1, targets, delta=config.huber)
                       + nn.functional.huber_loss(q2, targets, delta=config.huber))
        self.critic_optimizer.zero_grad()
        critic_loss.backward()
        self.critic_optimizer.step()
        self.critic_losses.append(critic_loss.item())
        self.q_means.append(q1.detach().mean().item())
        self.updates += 1
        if self.updates % config.policy_delay == 0:
            own = self.actor(batch['obs'])
            actor_loss = -self.critics.q1(actor_inputs(batch['state'], batch['action'], own)).mean()
            self.actor_optimizer.zero_grad()
            actor_loss.backward()
            self.actor_optimizer.step()
            self.actor_losses.append(actor_loss.item())
        with torch.no_grad():   # soft target updates after every update
            for net, target in ((self.actor, self.target_actor), (self.critics, self.target_critics)):
                for p, p_target in zip(net.parameters(), target.parameters()):
                    p_target.lerp_(p, config.tau)

    def row(self, steps: int) -> dict:
        row = dict(critic_loss=mean_or_nan(self.critic_losses), actor_loss=mean_or_nan(self.actor_losses),
                   q_mean=mean_or_nan(self.q_means), buffer=self.replay.size)
        self.critic_losses, self.actor_losses, self.q_means = [], [], []
        return row


def train(config: MATD3Config, envs: TrainingEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/matd3-TEAM-seedN); resume from its checkpoint
    unless `config.fresh`. `envs` replaces the training envs (anything with `TrainingEnv`'s attributes, `spec`
    and reset/step: tests' toy tasks with continuous actions); `callback(row)` sees every log row. Returns the
    `Run`."""
    return train_off_policy(config, 'matd3', policy_spec(config, envs), MATD3Learner, envs, callback, console)
