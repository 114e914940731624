"""IQL for MATE: independent deep Q-learning with one dueling network shared by the team's agents, in one file that
reads top to bottom (`mate train iql`).

    config  ->  PolicySpec (grid moves, or HRL target selections: `--hrl`, `--selection joint|per-target`)
            ->  batched training envs (`TrainingEnv`: B games, the other team the greedy rules)
            ->  networks: the agents' dueling Q-network and its target copy
            ->  loop: at every decision each agent acts epsilon-greedily (one forward pass for B x N agents) and the
                B x N agent transitions enter the replay ring; once `learning_starts` decision steps are stored,
                one double-Q update of `batch_size` agent transitions every `update_every` decision steps; a hard
                copy to the target network every `target_update` decision steps; a log row (an iteration) every
                `report_every` decision steps
            ->  `Run`: logs, checkpoints, best.pt, final.pt

As the paper's IQL (docs/training.md, "IQL"): dueling head, double-Q, 1-step targets, Huber loss, Adam (eps 1e-8), no
gradient clipping, epsilon 1.0 -> 0.02 over the first 50,000 decision steps, replay of 500,000 agent transitions,
learning from 5,000 decision steps on, target copy every 500. Counting as the PPO trainers do: a *decision step* is
one env's decision (B per batched step); the replay holds *agent transitions* (B x N per batched step), each agent's
own sample with the team reward repeated, or each camera's own reward with `--credit difference`. Horizon cuts are
truncations: their targets bootstrap from the last observation.

HRL cameras (`--hrl`) choose a subset of the target slots. `--selection joint` (the spec's Discrete(2^Nt), the
default): one choice among the 2^Nt subsets, those keeping an invisible target never taken (the executor would
ignore such a target; deployed policies mask them too, since their values are untrained). `--selection
per-target`: a keep/ignore head per slot, the value of a subset the sum of its slots' values.

Resuming: the checkpoint written at the end of a session (the run complete, its time spent, or stopped by SIGINT /
SIGTERM) holds the replay's filled rows, so the same command continues exactly as if never stopped. The periodic
checkpoints (every `checkpoint_every` iterations) leave it out (at the spec's sizes it is about half a gigabyte): a
run resumed from one (after a crash) refills the replay with `learning_starts` decision steps before it updates
again, exploring at the rate of its step count.
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
from .offpolicy_loop import train_off_policy
from ..policies.policy import make_actor
from .qlearning import QLearner, QLearningConfig, action_kind, allowed_choices, double_q_targets
from .replay import ReplayBuffer
from .run import Run
from ..policies.spec import PolicySpec

__all__ = ['IQLConfig', 'IQLLearner', 'iql_loss', 'policy_spec', 'train']


@dataclasses.dataclass
class IQLConfig(QLearningConfig):
    """Settings of an IQL run (`train(config)`, `mate train iql`)."""

    buffer_size: int = option(500_000, 'replay size in agent transitions (B x N per batched step)', minimum=1)
    batch_size: int = option(1024, 'agent transitions per update', minimum=1)
    hidden: tuple[int, ...] = option((512, 512, 256), "widths of the Q-network's trunk", minimum=1)
    activation: Literal['tanh', 'relu'] = option('tanh', "the trunk's activation")
    lr_schedule: tuple[tuple[float, float], ...] = option(
        ((0, 5e-4), (4_000_000, 1e-4), (8_000_000, 5e-5)), 'learning rate (Adam), a step function of decision '
        'steps [[step, lr], ...] (a step "P%%": P %% of --steps)')

    SCHEDULES = ('epsilon_schedule', 'lr_schedule')

    def __post_init__(self) -> None:
        super().__post_init__()
        self.hidden = tuple(self.hidden)


def policy_spec(config: IQLConfig, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains (its Q-values are read as logits, argmax); with `envs` given, what
    they say the policy sees and does (their `spec`: PSRO's envs, the tests' toy tasks) with this network."""
    return config.policy_spec(action=action_kind(config), envs=envs, network='dueling', hidden=config.hidden,
                              activation=config.activation, lstm=0, algo='iql', deterministic=True)


def iql_loss(q_net, target_net, batch: dict, gamma: float, heads: int,
             next_allowed: torch.Tensor | None = None) -> tuple[torch.Tensor, float]:
    """Huber loss of the double-Q targets on a batch of agent transitions (`ReplayBuffer.sample`), and the mean
    value of the taken actions. `next_allowed` (K, H, C) bool: the choices allowed at the next observations."""
    q_taken = q_net(batch['obs']).unflatten(-1, (heads, -1)).gather(-1, batch['action'][..., None]).squeeze(-1).sum(-1)
    with torch.no_grad():
        next_q = torch.cat([q_net(batch['next_obs']), target_net(batch['next_obs'])]).unflatten(-1, (heads, -1))
        online, evaluated = next_q.chunk(2)
        targets = double_q_targets(batch['reward'], batch['terminal'], online, evaluated, gamma, next_allowed)
    return nn.functional.smooth_l1_loss(q_taken, targets), q_taken.detach().mean().item()


# ============================================================================ training

class IQLLearner(QLearner):
    """IQL on the off-policy loop (`mate.learn.offpolicy_loop`): the agents' shared dueling Q-network and its target
    copy, one replay ring of agent transitions (B x N per decision step), one double-Q update of `batch_size` of
    them per `update_every` decision steps (Adam, eps 1e-8, no gradient clipping)."""

    def __init__(self, config: IQLConfig, spec: PolicySpec, envs, device, rng: np.random.Generator) -> None:
        super().__init__(config, spec, device)
        self.q_net = make_actor(spec).to(device)
        self.target_net = copy.deepcopy(self.q_net).requires_grad_(False)
        self.optimizer = torch.optim.Adam(self.q_net.parameters(), lr=config.lr_schedule[0][1], eps=1e-8)
        self.replay = ReplayBuffer(config.buffer_size, envs.obs_dim, self.heads)
        self.networks = dict(actor=self.q_net, target=self.target_net)
        self.shape = (envs.num_envs, envs.num_agents, envs.obs_dim)

    def act(self, obs, state, steps, rng):
        with torch.no_grad():
            q = self.q_net(torch.from_numpy(obs).to(self.device)).cpu()
        return self.explore(q, obs, steps, rng)

    def store(self, obs, state, action, reward, done, truncated, next_obs, next_state, info) -> None:
        """The B x N agent transitions; an ended episode's own last observation is its next one."""
        B, N, D = self.shape
        landing = np.where(done[:, None, None], info['final_obs'], next_obs)
        terminal = (done & ~truncated).astype(np.float32)
        reward = np.broadcast_to(np.asarray(reward, dtype=np.float32).reshape(B, -1), (B, N))
        self.replay.add(obs.reshape(B * N, D), action.reshape(B * N, self.heads), reward.reshape(-1),
                        landing.reshape(B * N, D), np.repeat(terminal, N))

    def update(self, steps, rng) -> None:
        self.set_learning_rate(steps)
        batch = self.replay.sample(self.config.batch_size, rng)
        next_allowed = allowed_choices(self.spec, batch['next_obs'].numpy(), self.device)
        batch = {key: value.to(self.device) for key, value in batch.items()}
        loss, q_mean = iql_loss(self.q_net, self.target_net, batch, self.config.gamma, self.heads, next_allowed)
        self.optimizer.zero_grad()
        loss.backward()
        self.optimizer.step()
        self.losses.append(loss.item())
        self.q_means.append(q_mean)

    def copy_targets(self) -> None:
        self.target_net.load_state_dict(self.q_net.state_dict())


def train(config: IQLConfig, envs: TrainingEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/iql-TEAM-seedN); resume from its checkpoint
    unless `config.fresh`. `envs` replaces the training envs (anything with `TrainingEnv`'s attributes, `spec`
    and reset/step: tests' toy tasks); `callback(row)` sees every log row. Returns the `Run`."""
    return train_off_policy(config, 'iql', policy_spec(config, envs), IQLLearner, envs, callback, console)
