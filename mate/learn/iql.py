"""IQL for MATE: independent deep Q-learning with one dueling network shared by the team's agents, in one file that
reads top to bottom (`mate train iql`).

    config  ->  PolicySpec (grid moves, or HRL target selections: `--hrl`, `--selection joint|per-target`)
            ->  batched training envs (`TeamVecEnv`: B games, the other team the greedy rules)
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

from ..options import option
from .device import resolve_device, update_threads
from .envs import TeamVecEnv
from .policy import make_actor
from .qlearning import QLearningConfig, action_kind, allowed_choices, double_q_targets, epsilon_greedy
from .replay import ReplayBuffer
from .run import Run, mean_or_nan
from .schedules import piecewise, resolve_schedule
from .spec import PolicySpec

__all__ = ['IQLConfig', 'iql_loss', 'policy_spec', 'train']


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
    network = dict(network='dueling', hidden=config.hidden, activation=config.activation, lstm=0, algo='iql',
                   deterministic=True)
    if envs is not None:
        return envs.spec.replace(**network)
    return config.policy_spec(action=action_kind(config), **network)


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

def train(config: IQLConfig, envs: TeamVecEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/iql-TEAM-seedN); resume from its checkpoint
    unless `config.fresh`. `envs` replaces the training envs (anything with `TeamVecEnv`'s attributes, `spec`
    and reset/step: tests' toy tasks); `callback(row)` sees every log row. Returns the `Run`."""
    device = resolve_device(config.device)
    spec = policy_spec(config, envs)
    run = Run.of(config, 'iql', spec, callback, console)

    # ---- environments
    envs = envs or config.make_env(spec)
    B, N, D = envs.num_envs, envs.num_agents, envs.obs_dim
    H, C = spec.heads, spec.choices                                  # values per agent: H heads of C choices

    # ---- networks, optimiser, replay, exploration
    # one torch thread for acting (the vector env runs its own threads) and for the initialisation, whose
    # orthogonal matrices (QR decompositions) differ with the thread count
    torch.set_num_threads(1)
    torch.manual_seed(config.seed)
    q_net = make_actor(spec).to(device)
    target_net = copy.deepcopy(q_net).requires_grad_(False)
    optimizer = torch.optim.Adam(q_net.parameters(), lr=config.lr_schedule[0][1], eps=1e-8)
    replay = ReplayBuffer(config.buffer_size, D, H)
    rng = np.random.default_rng([config.seed, 0])                   # exploration and replay sampling
    saved = run.resume()
    if saved is not None:
        q_net.load_state_dict(saved['networks']['actor'])
        target_net.load_state_dict(saved['networks']['target'])
        optimizer.load_state_dict(saved['optimizer'])
        rng.bit_generator.state = saved['rng']
    obs = run.first_observations(envs, saved)[0]

    # ---- the schedule, in decision steps: updates, target copies, log rows
    steps = run.env_steps
    if saved is not None and replay.fits(saved.get('replay')):       # the end of a session: continue exactly
        replay.load_state_dict(saved['replay'])
        learning_from, next_update, next_copy, next_report = (saved['schedule'][key] for key in (
            'learning_from', 'next_update', 'next_copy', 'next_report'))
    else:                                                            # fresh, or a periodic checkpoint: fill first
        learning_from = steps + config.learning_starts
        next_update = max(learning_from, steps + config.update_every)
        next_copy = (steps // config.target_update + 1) * config.target_update
        next_report = (steps // config.report_every + 1) * config.report_every
        if saved is not None:
            next_copy, next_report = saved['schedule']['next_copy'], saved['schedule']['next_report']

    def run_state(with_replay: bool = False) -> dict:   # everything the run's future depends on
        algorithm = dict(networks=dict(actor=q_net.state_dict(), target=target_net.state_dict()),
                         optimizer=optimizer.state_dict(), rng=rng.bit_generator.state,
                         schedule=dict(learning_from=learning_from, next_update=next_update, next_copy=next_copy,
                                       next_report=next_report))
        if hasattr(envs, 'state_dict'):
            algorithm['envs'] = envs.state_dict()
        if with_replay:
            algorithm['replay'] = replay.state_dict()
        return algorithm

    learn_threads = update_threads(config)
    epsilon_schedule, lr_schedule = (resolve_schedule(points, config.steps)    # shares of the budget: steps
                                     for points in (config.epsilon_schedule, config.lr_schedule))
    coverage, episodes, losses, q_means = [], [], [], []
    with run:
        while run.running():
            while True:   # one iteration: decisions until the next log row
                # ---- act: epsilon-greedy for every agent of every env, one forward pass
                epsilon = piecewise(epsilon_schedule, steps, interpolate=True)
                with torch.no_grad():
                    q = q_net(torch.from_numpy(obs).to(device)).cpu()
                action = epsilon_greedy(q.unflatten(-1, (H, C)), epsilon, rng, allowed_choices(spec, obs))  # (B, N, H)
                next_obs, _, reward, done, truncated, info = envs.step(action[..., 0] if H == 1 else action)

                # ---- store the B x N agent transitions; an ended episode's own last observation is its next one
                landing = np.where(done[:, None, None], info['final_obs'], next_obs)
                terminal = (done & ~truncated).astype(np.float32)
                reward = np.broadcast_to(np.asarray(reward, dtype=np.float32).reshape(B, -1), (B, N))
                replay.add(obs.reshape(B * N, D), action.reshape(B * N, H), reward.reshape(-1),
                           landing.reshape(B * N, D), np.repeat(terminal, N))
                obs = next_obs
                steps += B
                coverage.append(float(np.mean(info['coverage'])))
                episodes += info['episodes']

                # ---- learn: one double-Q update every `update_every` decision steps, from `learning_from` on
                if steps >= next_update and replay.size:
                    torch.set_num_threads(learn_threads)
                    while steps >= next_update and replay.size:
                        next_update += config.update_every
                        lr = piecewise(lr_schedule, steps, interpolate=False)
                        for group in optimizer.param_groups:
                            group['lr'] = lr
                        batch = replay.sample(config.batch_size, rng)
                        next_allowed = allowed_choices(spec, batch['next_obs'].numpy(), device)
                        batch = {key: value.to(device) for key, value in batch.items()}
                        loss, q_mean = iql_loss(q_net, target_net, batch, config.gamma, H, next_allowed)
                        optimizer.zero_grad()
                        loss.backward()
                        optimizer.step()
                        losses.append(loss.item())
                        q_means.append(q_mean)
                    torch.set_num_threads(1)
                if steps >= next_copy:
                    target_net.load_state_dict(q_net.state_dict())
                    next_copy += config.target_update
                if steps >= next_report or steps >= config.steps or run.out_of_time():
                    break

            # ---- log, keep the best policy, checkpoint
            next_report += config.report_every
            run.end_iteration(steps - run.env_steps, coverage, episodes, dict(
                epsilon=epsilon, lr=piecewise(lr_schedule, steps, interpolate=False), loss=mean_or_nan(losses),
                q_mean=mean_or_nan(q_means), buffer=replay.size), status=f'epsilon {epsilon:.2f}',
                actor=q_net.state_dict,
                save=run_state)
            coverage, episodes, losses, q_means = [], [], [], []
    run.finish(run_state(with_replay=True), q_net.state_dict())
    return run
