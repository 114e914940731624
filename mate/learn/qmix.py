"""QMIX for MATE: a recurrent agent network shared by the team and a monotonic mixer of the agents' values on the
global state, in one file that reads top to bottom (`mate train qmix`).

    config  ->  PolicySpec (grid moves, or HRL target selections: `--hrl`, `--selection joint|per-target`)
            ->  batched training envs (`TrainingEnv`: B games, the other team the greedy rules)
            ->  networks: the GRU agent network, the mixer (`QMixer`), and their target copies
            ->  loop: at every decision each agent acts epsilon-greedily from its GRU state (one forward pass for
                B x N agents) and the team's decision enters the replay (`SequenceReplay`: chunks of
                `sequence_length` consecutive decisions); once `learning_starts` decision steps are stored, one
                double-Q update of the mixed value on `batch_size` decision steps (whole chunks) every
                `update_every` decision steps; a hard copy to the target networks every `target_update`; a log
                row (an iteration) every `report_every` decision steps
            ->  `Run`: logs, checkpoints, best.pt, final.pt

As the paper's QMIX (docs/training.md, "QMIX"): agent network Linear(256) + ReLU -> GRU(256) -> Q-values; mixer with
embedding 128 (hyper-network weights made non-negative by an absolute value, ELU hidden layer, a state-value MLP);
double-Q 1-step targets of the mixed value, masked MSE, RMSprop (lr 1e-4, alpha 0.99, eps 1e-5), gradient norm
clipped at 1000; epsilon 1.0 -> 0.02 over 50,000 decision steps. QMIX learns from the team reward (`--credit team`
only). Horizon cuts are truncations: their targets bootstrap from the last observation.

The replay holds chunks of `sequence_length` decision steps that never cross an episode start (an episode that
ends early leaves the rest of its chunk masked), each with the GRU state the acting network had at its first step;
the original stored whole episodes of up to 500 decisions. At the spec's 2,000 episodes (1,000,000 decision steps)
the HRL MATE-4v8-9 camera replay takes 3.25 GB, filled as it is used.

HRL cameras (`--hrl`): as in `iql.py`, one choice among the 2^Nt target subsets (`--selection joint`, the default)
or a keep/ignore head per slot (`--selection per-target`); selections that keep an invisible target are never
taken.

Resuming: the checkpoint written at the end of a session (the run complete, its time spent, or stopped by SIGINT /
SIGTERM) holds the replay's filled chunks and the rows' open ones, and the acting GRU state, so the same command
continues exactly as if never stopped. The periodic checkpoints (every `checkpoint_every` iterations) leave the
replay out (1-3 GB at the spec's sizes): a run resumed from one (after a crash) refills it with `learning_starts`
decision steps before it updates again, exploring at the rate of its step count.
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import torch
from torch import nn

from ..cli.options import option
from .envs import TrainingEnv
from .offpolicy_loop import train_off_policy
from ..policies.policy import make_actor
from .qlearning import QLearner, QLearningConfig, action_kind, allowed_choices, double_q_values
from .replay import SequenceReplay
from .run import Run
from ..policies.spec import PolicySpec

__all__ = ['QMIXConfig', 'QMIXLearner', 'QMixer', 'policy_spec', 'qmix_loss', 'train']


@dataclasses.dataclass
class QMIXConfig(QLearningConfig):
    """Settings of a QMIX run (`train(config)`, `mate train qmix`)."""

    buffer_size: int = option(1_000_000, 'replay size in decision steps (the spec: 2,000 episodes of 500)', minimum=1)
    batch_size: int = option(1024, 'decision steps per update (whole chunks: batch-size / sequence-length of them)',
                             minimum=1)
    sequence_length: int = option(25, 'decision steps per replay chunk of the recurrent agents', minimum=1)
    hidden: tuple[int, ...] = option((256,), "width of the agent network's embedding and GRU (one number)", minimum=1)
    mixer_embed: int = option(128, "the mixer's width", minimum=1)
    lr_schedule: tuple[tuple[float, float], ...] = option(
        ((0, 1e-4),), 'learning rate (RMSprop), a step function of decision steps [[step, lr], ...] '
        '(a step "P%%": P %% of --steps)')

    SCHEDULES = ('epsilon_schedule', 'lr_schedule')

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.credit != 'team':
            raise ValueError(f"QMIX learns from the team reward: credit must be 'team', not {self.credit!r}")
        if len(self.hidden) != 1:
            raise ValueError(f"QMIX's agent network has one width (--hidden N), got {tuple(self.hidden)}")
        self.hidden = tuple(self.hidden)


def policy_spec(config: QMIXConfig, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains (the GRU agent network; its Q-values are read as logits, argmax);
    with `envs` given, what they say the policy sees and does (their `spec`) with this network."""
    return config.policy_spec(action=action_kind(config), envs=envs, network='recurrent-q', hidden=config.hidden,
                              activation='relu', lstm=0, algo='qmix', deterministic=True)


class QMixer(nn.Module):
    """QMIX's mixing network (Rashid et al. 2018): the agents' chosen values q (..., N) and the global
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


def qmix_loss(q_net, target_net, mixer, target_mixer, batch: dict, gamma: float, heads: int,
              next_allowed: torch.Tensor | None = None) -> tuple[torch.Tensor, float]:
    """Masked MSE between the mixed value of the taken joint actions and its double-Q target, on a batch of K
    chunks (`SequenceReplay.sample`), and the mean mixed value. Both agent networks unroll every chunk from its
    stored GRU state; the online network picks each agent's next action (among `next_allowed` (L, K, N, H, C)
    bool, the choices allowed at the next observations), the target networks evaluate."""
    obs = batch['obs'].transpose(0, 1)                                     # (L + 1, K, N, D)
    state = batch['state'].transpose(0, 1)                                 # (L + 1, K, S)
    action = batch['action'].transpose(0, 1).long()                        # (L, K, N, H)
    reward, terminal, mask = (batch[k].transpose(0, 1) for k in ('reward', 'terminal', 'mask'))    # (L, K)
    q = q_net(obs, batch['h0']).unflatten(-1, (heads, -1))                 # (L + 1, K, N, H, C)
    taken = q[:-1].gather(-1, action[..., None]).squeeze(-1).sum(-1)       # (L, K, N)
    q_tot = mixer(taken, state[:-1])                                       # (L, K)
    with torch.no_grad():
        evaluated = target_net(obs, batch['h0']).unflatten(-1, (heads, -1))[1:]
        next_values = double_q_values(q[1:].detach(), evaluated, next_allowed)                 # (L, K, N)
        targets = reward + gamma * (1.0 - terminal) * target_mixer(next_values, state[1:])
    loss = ((q_tot - targets) ** 2 * mask).sum() / mask.sum().clamp_min(1.0)
    return loss, ((q_tot.detach() * mask).sum() / mask.sum().clamp_min(1.0)).item()


# ============================================================================ training

class QMIXLearner(QLearner):
    """QMIX on the off-policy loop (`mate.learn.offpolicy_loop`): the agents' shared recurrent Q-network, the mixer,
    their target copies, a replay of the team's decision sequences with the GRU states they started from, one
    double-Q update of the mixed value from `batch_size` decisions of whole chunks per `update_every` decision steps
    (RMSprop, gradients clipped at norm 1,000)."""

    def __init__(self, config: QMIXConfig, spec: PolicySpec, envs, device, rng: np.random.Generator) -> None:
        super().__init__(config, spec, device)
        B, N, D, S = envs.num_envs, envs.num_agents, envs.obs_dim, envs.state_dim
        self.q_net = make_actor(spec).to(device)
        self.target_net = copy.deepcopy(self.q_net).requires_grad_(False).to(device)   # (the GRU's weights: one block)
        self.mixer = QMixer(S, N, config.mixer_embed).to(device)
        self.target_mixer = copy.deepcopy(self.mixer).requires_grad_(False)
        self.learned = [*self.q_net.parameters(), *self.mixer.parameters()]
        self.optimizer = torch.optim.RMSprop(self.learned, lr=config.lr_schedule[0][1], alpha=0.99, eps=1e-5)
        self.replay = SequenceReplay(config.buffer_size, config.sequence_length, B, N, D, S, self.heads,
                                     self.q_net.width)
        self.networks = dict(actor=self.q_net, target=self.target_net, mixer=self.mixer,
                             target_mixer=self.target_mixer)
        self.hidden = self.q_net.initial_state(B, N)[0].to(device)          # (B, N, G) the acting GRU state
        self._next_hidden = None
        self.chunks = math.ceil(config.batch_size / config.sequence_length)   # per update

    def state_dict(self) -> dict:
        return dict(super().state_dict(), hidden=self.hidden.cpu())

    def load_state_dict(self, saved: dict) -> None:
        super().load_state_dict(saved)
        self.hidden = torch.as_tensor(saved['hidden']).to(self.device)

    def start(self, run, saved) -> None:
        if not run.continues_episodes(saved):
            self.hidden.zero_()                                              # the envs were reset: so is the memory

    def begin_replay(self) -> None:
        self.replay.begin(self.hidden.cpu().numpy())

    def act(self, obs, state, steps, rng):
        """Epsilon-greedy for every agent of every env from its GRU state, one forward pass."""
        with torch.no_grad():
            q, (self._next_hidden,) = self.q_net.step(torch.from_numpy(obs).to(self.device), (self.hidden,))
        return self.explore(q.cpu(), obs, steps, rng)

    def store(self, obs, state, action, reward, done, truncated, next_obs, next_state, info) -> None:
        """The team's decision; an ended episode's own last observation is its next one, and its memory starts from
        zero."""
        next_hidden = self._next_hidden
        next_hidden[torch.from_numpy(done).to(self.device)] = 0.0
        self.replay.record(obs, state, action, np.asarray(reward, dtype=np.float32),
                           (done & ~truncated).astype(np.float32), done,
                           np.where(done[:, None, None], info['final_obs'], next_obs),
                           np.where(done[:, None], info['final_state'], next_state), next_hidden.cpu().numpy())
        self.hidden = next_hidden

    def update(self, steps, rng) -> None:
        """One double-Q update of the mixed value."""
        self.set_learning_rate(steps)
        batch = self.replay.sample(self.chunks, rng)
        next_allowed = allowed_choices(self.spec, batch['obs'].transpose(0, 1)[1:].numpy(), self.device)
        batch = {key: value.to(self.device) for key, value in batch.items()}
        loss, q_mean = qmix_loss(self.q_net, self.target_net, self.mixer, self.target_mixer, batch, self.config.gamma,
                                 self.heads, next_allowed)
        self.optimizer.zero_grad()
        loss.backward()
        nn.utils.clip_grad_norm_(self.learned, 1000.0)
        self.optimizer.step()
        self.losses.append(loss.item())
        self.q_means.append(q_mean)

    def copy_targets(self) -> None:
        self.target_net.load_state_dict(self.q_net.state_dict())
        self.target_mixer.load_state_dict(self.mixer.state_dict())


def train(config: QMIXConfig, envs: TrainingEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/qmix-TEAM-seedN); resume from its checkpoint
    unless `config.fresh`. `envs` replaces the training envs (anything with `TrainingEnv`'s attributes, `spec`
    and reset/step: tests' toy tasks); `callback(row)` sees every log row. Returns the `Run`."""
    return train_off_policy(config, 'qmix', policy_spec(config, envs), QMIXLearner, envs, callback, console)
