"""MAPPO and IPPO for MATE, in one file that reads top to bottom.

    config  ->  batched envs (`TeamVecEnv`: B games + batched greedy opponent)
            ->  networks (shared actor; critic on the global state (MAPPO) or the local observation (IPPO))
            ->  loop: collect T decisions x B envs x N agents, GAE, K epochs of clipped PPO on minibatches
            ->  logs (rich progress bar, CSV, TensorBoard when installed) and checkpoints

One policy is shared by every agent of the trained team (full parameter sharing, as in the paper).
Its action is one or more independent categorical choices (`action_distribution`): one of 25 grid
moves for the flat learners, or one keep/ignore bit per target slot for HRL cameras (`hrl=True`,
spec training.md §3), whose rule executor runs inside `TeamVecEnv`.
Rewards are team rewards, repeated to every agent, or, for cameras with `credit='difference'`, each
camera's own share of the coverage (MAPPO's critic then gives one value per agent). Values are learned on normalised returns
(running mean/std, "value normalisation"). Schedules (learning rate, entropy coefficient) are
piecewise functions of decision steps, as in spec training.md §1.6.

With `comm='tarmac'` the actor is a TarMAC actor (`mate.learn.comm`): the agents of an env exchange learned
messages, read one decision later through attention, and the update backpropagates through them. The critic
also reads all N messages of the decision (spec §4.1): the ones the agents read at it (those of the previous
decision, zeros at an episode's first), stored with the rollout as data, appended flat (N x 64) to the global
state (MAPPO) or to each agent's observation (IPPO).

With `comm='i2c'` (MAPPO, flat discrete actions) the actor is an `I2CActor` (one network per agent; each
agent attends to the current observations of the teammates its prior network asks) and the loss adds, with
one optimiser (spec §4.2): the joint action-value networks' regression onto the value targets, the prior's
binary cross-entropy on causal-influence labels (computed without gradient, once per iteration, on
`influence_samples` random decisions of the rollout) and 0.01 x the policy-correlation regulariser.

With `message_dropout` > 0 or a `communication_range` (TarMAC or I2C) the team trains under a perturbed
channel (`mate.learn.comm.Channel`): at every decision of the rollout a mask (B, N receivers, N senders) says
which deliveries happen (each lost with the dropout's probability, or between agents farther apart than the
range, read from `TeamVecEnv.positions`); a lost message reads as zeros (TarMAC: in the receiver's attention;
I2C: the asked teammate's slot), as at deployment. The masks are stored with the rollout and the update's
unroll replays them; their draws come from a generator of their own, so the actions drawn are those of an
unperturbed run. The critic still reads every message sent (centralised, like the global state).
`message_delay` K (TarMAC): teammates' messages are read K decisions later than without (own: the last), the
actor's state carrying a queue of the K message sets before the last (`TarMACActor.delay`).

Deviations from the paper's RLlib runs, on purpose: a feed-forward actor unless `lstm` > 0 (the
paper's MLP -> LSTM -> skip-concat head) and a feed-forward critic, GAE lambda 0.95 (RLlib's default 1.0
is a flag away), no adaptive KL penalty unless `kl_coeff` > 0 (`--paper` turns on RLlib's 0.2 / target
0.01), gradient-norm clipping at 10, horizon cuts bootstrap from the critic instead of counting as terminal.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from pathlib import Path

import torch
from torch import nn

from ..core.engine import NUM_THREADS
from .checkpoint import META_DEFAULTS, CheckpointError, load_checkpoint, save_checkpoint
from .comm import I2C_REGULARISER, TARMAC_LSTM, Channel, I2CTraining, check_channel
from .envs import PAPER_SETTINGS, TeamVecEnv
from .logging import RunReport, out_of_time
from .networks import Critic, make_actor, restarted
from .schedules import piecewise

__all__ = [
    'PAPER_HYPERPARAMETERS',
    'PPOConfig',
    'ValueNormalizer',
    'action_distribution',
    'adapt_kl_coeff',
    'compute_gae',
    'minibatch_rows',
    'ppo_policy_loss',
    'sampled_kl',
    'train',
]


# ============================================================================ configuration

@dataclasses.dataclass
class PPOConfig:
    """Settings of a MAPPO / IPPO run (`train(config, run_dir)`, `mate train mappo|ippo`).

    The fields and their defaults are listed below; the comment beside each field in
    `mate/learn/ppo.py` says what it does, and `mate train mappo -h` describes the same settings as
    options. `None` fields take the team's paper setting (`resolved()`).
    """

    algo: str = 'mappo'                  # 'mappo' (centralised critic on the state) or 'ippo' (local critic)
    team: str = 'camera'                 # trained team; the other one is the batched greedy opponent
    env_id: str | None = None            # None: the paper's preset for the team (PAPER_SETTINGS)
    config: str | None = None            # optional config (YAML/JSON path) for env_id 'MultiAgentTracking-v0'
    frame_skip: int | None = None        # None: 5 for cameras, 10 for targets
    horizon: int | None = None           # raw steps per training episode; None: 500 decisions
    levels: int = 5                      # discrete levels per action axis (25 actions)
    hrl: bool = False                    # cameras only: select targets (Nt bits), rule executor aims (§3)
    mask_invisible: bool = True          # HRL: a target the camera cannot see is never selected (see below)
    full_observability: bool = False     # the trained team sees every entity (EnhancedObservation; paper Fig. 6)
    memory: int = 0                      # cameras: steps the team's shared sighting memory keeps a target (0: none)
    velocity: bool = False               # cameras: each seen target's motion over one held decision (velocity.py)
    credit: str = 'team'                 # cameras: 'team' coverage reward, or 'difference' (each camera's own share)
    actor: str | None = None             # 'mlp' (paper) or 'per-target' (cameras); None: per-target cameras, mlp targets
    lstm: int = 0                        # > 0: recurrent actor, MLP -> LSTM(lstm) -> head (paper: 256)
    comm: str = 'none'                   # 'tarmac' or 'i2c': learned communication (comm.py; lstm 0 -> 256)
    message_dropout: float = 0.0         # comm: each sender -> receiver delivery lost with this probability (Channel)
    communication_range: float | None = None   # comm: deliveries only within this many world units; None: any
    message_delay: int = 0               # TarMAC: teammates' messages read this many decisions late (besides the 1)
    influence_samples: int = 32          # I2C: decisions per iteration whose prior labels are computed (A x A Q's each)
    total_steps: int = 2_000_000         # decision steps (per env, summed over envs), as RLlib counts
    time_limit: float = 0.0              # seconds of training wall time (resumed sessions included); 0: none
    num_envs: int = 64
    rollout_length: int = 25             # decisions per env per iteration (paper: 25-step fragments)
    epochs: int = 4
    minibatches: int = 4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.3
    value_coef: float = 1.0
    kl_coeff: float = 0.0                # initial coefficient of the adaptive KL penalty; 0: off (RLlib/paper: 0.2)
    kl_target: float = 0.01              # the penalty's coefficient adapts towards this KL per iteration
    max_grad_norm: float | None = 10.0
    hidden: tuple = (256, 256)
    activation: str = 'tanh'
    lr_schedule: tuple = ((0, 5e-4), (1_500_000, 2e-4), (3_000_000, 1e-4))            # step function of steps
    entropy_schedule: tuple = ((0, 0.01), (1_000_000, 0.001), (3_000_000, 0.0))       # piecewise linear
    seed: int = 0
    torch_threads: int = 0               # threads of the update phase; 0: every core (collection uses 1)
    checkpoint_every: int = 20           # iterations
    snapshot_every: int = 0              # iterations; > 0 keeps the actor as snapshots/policy-STEPS.pt
    init_from: str | None = None         # warm start: network weights of this checkpoint/policy file, steps from 0

    def resolved(self) -> PPOConfig:
        """A copy with the team's defaults filled in (paper preset, frame skip and horizon; actor, the MLP for
        a communicating team (`make_actor` refuses another); a TarMAC actor's LSTM size)."""
        defaults = PAPER_SETTINGS[self.team]
        frame_skip = self.frame_skip or defaults['frame_skip']
        talking = self.comm != 'none'
        return dataclasses.replace(self, env_id=self.env_id or defaults['env_id'], frame_skip=frame_skip,
                                   horizon=self.horizon or 500 * frame_skip,
                                   actor=self.actor or ('per-target' if self.team == 'camera' and not talking else 'mlp'),
                                   lstm=self.lstm or (TARMAC_LSTM if talking else 0))

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


PAPER_HYPERPARAMETERS = dict(
    actor='mlp',
    mask_invisible=False,
    lr_schedule=((0, 5e-4), (4_000_000, 1e-4), (8_000_000, 5e-5)),
    entropy_schedule=((0, 0.05), (2_000_000, 0.01), (4_000_000, 0.001), (10_000_000, 0.0)),
    kl_coeff=0.2,
)
"""The paper's settings where `PPOConfig`'s defaults differ (spec training.md §1.5-1.6; `mate train --paper`).
Our defaults are tuned for budgets of a few million decision steps (docs/training.md has the measurements):
the paper's schedules are stretched over 10 M steps and its entropy bonus of 0.05 keeps the policies
nearly uniform for the first million steps; the per-target camera actor learns faster than the MLP.
`mask_invisible` (HRL): the executor ignores selected targets that the camera does not see, so masking
them changes no behaviour; it removes their random bits from the log-probabilities and the entropy,
which otherwise add noise to every gradient (the paper's code had the mask, unused)."""


# ============================================================================ PPO's network pieces (the shared blocks: networks.py)

def action_distribution(logits: torch.Tensor, heads: int, choices: int, allowed: torch.Tensor | None = None):
    """Independent categoricals: logits (..., heads x choices) -> batch shape (..., heads). Flat discrete
    actions are one head of levels**2 choices; HRL selections are Nt heads of 2 (keep/ignore). The
    joint log-probability and entropy are sums over the heads. `allowed` (..., heads, choices) bool
    masks choices out (probability 0); a head with a single allowed choice adds nothing to either."""
    logits = logits.reshape(*logits.shape[:-1], heads, choices)
    if allowed is not None:
        logits = logits.masked_fill(~allowed, torch.finfo(logits.dtype).min)
    return torch.distributions.Categorical(logits=logits)


def critic_inputs(algo: str, obs: torch.Tensor, state: torch.Tensor, messages: torch.Tensor | None = None):
    """What the critic reads: the global state (..., S) for MAPPO (one value per env: the reward is
    shared, so every agent's value is the same, as in the paper's critic), the local observations
    (..., N, D) for IPPO (one value per agent). TarMAC: `messages` (..., N, M), the N messages the agents
    read at the decision, flattened and appended (..., S + N M) or (..., N, D + N M)."""
    inputs = obs if algo == 'ippo' else state
    if messages is None:
        return inputs
    flat = messages.flatten(-2)
    if algo == 'ippo':
        flat = flat.unsqueeze(-2).expand(*obs.shape[:-1], flat.shape[-1])
    return torch.cat([inputs, flat], dim=-1)


def critic_input_dim(algo: str, obs_dim: int, state_dim: int, messages_dim: int = 0) -> int:
    """Size of `critic_inputs`; `messages_dim`: N x M for a TarMAC critic, else 0."""
    return (obs_dim if algo == 'ippo' else state_dim) + messages_dim


def per_agent(algo: str, values: torch.Tensor, num_agents: int, shared: bool = True) -> torch.Tensor:
    """Critic outputs -> (..., N): (...,) per env (MAPPO, `shared` team value) repeated to every agent;
    (..., N) per agent (IPPO, or MAPPO's per-agent heads when `shared` is false) unchanged."""
    return values if algo == 'ippo' or not shared else values.unsqueeze(-1).expand(*values.shape, num_agents)


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


# ============================================================================ training

def train(config: PPOConfig, run_dir: str | os.PathLike, resume: bool = True, progress: bool = True,
          callback=None, envs=None) -> dict:
    """Train; write progress.csv, tensorboard/ and checkpoint.pt (+ final.pt) under `run_dir`, and best.pt:
    the actor (as `snapshot`) at the best mean return over the last 25 training episodes, looked at once
    25 episodes have finished (the paper's PSRO players are their runs' best checkpoints).

    Resumes from `run_dir/checkpoint.pt` when it exists and `resume` is true (the config stored in the
    checkpoint must describe the same experiment, else `CheckpointError`). `callback(row)` sees every
    log row. `envs` replaces the `TeamVecEnv` (anything with its attributes and reset/step; tests use
    toy tasks). Returns the last log row.
    """
    config = config.resolved()
    if config.comm == 'i2c':
        check_i2c(config)
    check_channel(config.message_dropout, config.communication_range, config.comm, config.message_delay)
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    learn_threads = config.torch_threads or NUM_THREADS

    # ---- environments
    envs = envs or TeamVecEnv(config.team, num_envs=config.num_envs, env_id=config.env_id, frame_skip=config.frame_skip,
                      horizon=config.horizon, levels=config.levels, seed=config.seed, config=config.config,
                      hrl=config.hrl, full_observability=config.full_observability, memory=config.memory,
                      velocity=config.velocity, credit=config.credit)
    B, N, D, S, A = envs.num_envs, envs.num_agents, envs.obs_dim, envs.state_dim, envs.num_actions
    H, C = getattr(envs, 'action_heads', 1), getattr(envs, 'action_choices', A)   # A = H x C logits per agent
    i2c = config.comm == 'i2c'
    # the perturbed channel (dropout, range) between the agents of a communicating team; None masks: every message
    channel = Channel(config.message_dropout, config.communication_range, legs=2 if i2c else 1)
    perturbed = channel.active
    if config.communication_range is not None and not hasattr(envs, 'positions'):
        raise ValueError('communication_range needs the agents\' positions; this env has no positions()')

    # ---- networks and optimiser
    torch.manual_seed(config.seed)
    meta = dict(team=config.team, env_id=config.env_id, frame_skip=config.frame_skip, levels=config.levels,
                obs_dim=D, state_dim=S, num_agents=N, num_actions=A, action_heads=H, action_choices=C,
                hrl=bool(getattr(envs, 'hrl', False)), counts=list(getattr(envs, 'counts', ())),
                full_observability=bool(getattr(envs, 'full_observability', False)),
                memory=int(getattr(getattr(envs, 'memory', None), 'period', 0)),
                velocity=bool(getattr(envs, 'velocity', False)), credit=getattr(envs, 'credit', 'team'),
                actor=config.actor, lstm=config.lstm, comm=config.comm,
                message_dropout=float(config.message_dropout),
                communication_range=None if config.communication_range is None else float(config.communication_range),
                message_delay=int(config.message_delay))
    talking = config.comm == 'tarmac'     # TarMAC: the critic reads the N messages of every decision too
    if talking:
        meta['critic_messages'] = True    # slice-1 TarMAC checkpoints (critic without them) do not resume
    per_agent_rewards = meta['credit'] != 'team'     # rewards (B, N): the MAPPO critic gives one value per agent
    actor = make_actor(config.actor, D, A, config.hidden, config.activation, meta, config.lstm)
    recurrent = getattr(actor, 'recurrent', False)
    if config.message_delay:          # TarMAC: a queue of late messages in the carried state (not in the weights)
        actor.delay = int(config.message_delay)
    M = actor.key_size + actor.value_size if talking else 0          # message size
    critic = Critic(critic_input_dim(config.algo, D, S, N * M), config.hidden, config.activation,
                    outputs=N if per_agent_rewards and config.algo == 'mappo' else 1)
    value_norm = ValueNormalizer()
    # I2C: joint action-value networks and the labels' KL buffer (training only; in the checkpoint as `comm_training`)
    signals = I2CTraining(N, S, A, config.hidden, config.activation) if i2c else None
    learned = [*actor.parameters(), *critic.parameters(), *(signals.parameters() if i2c else ())]
    optimizer = torch.optim.Adam(learned, lr=config.lr_schedule[0][1], eps=1e-5)
    env_steps, iteration, wall_before = 0, 0, 0.0     # wall_before: training seconds of earlier sessions
    kl_coeff = config.kl_coeff                          # adapts every iteration (`adapt_kl_coeff`)
    best_return = -math.inf                             # of best.pt
    checkpoint_path = run_dir / 'checkpoint.pt'
    if resume and checkpoint_path.exists():
        saved = load_checkpoint(checkpoint_path, expect=dict(meta, algo=config.algo))
        actor.load_state_dict(saved['actor'])
        critic.load_state_dict(saved['critic'])
        value_norm.load_state_dict(saved['value_norm'])
        if i2c:
            signals.load_state_dict(saved['comm_training'])
        optimizer.load_state_dict(saved['optimizer'])
        env_steps, iteration = saved['env_steps'], saved['iteration']
        kl_coeff = float(saved.get('kl_coeff', config.kl_coeff))
        wall_before = float(saved.get('wall_seconds', 0.0))
        best_return = float(saved.get('best_return', -math.inf))
    elif config.init_from:
        _warm_start(config.init_from, dict(meta, algo=config.algo), actor, critic, value_norm)
    generator = torch.Generator().manual_seed(config.seed * 1_000_003 + iteration)
    channel_generator = torch.Generator().manual_seed(config.seed * 1_000_003 + iteration + 500_009)   # its own draws

    def checkpoint(path: Path) -> None:
        save_checkpoint(path, dict(actor=actor.state_dict(), critic=critic.state_dict(),
                                   value_norm=value_norm.state_dict(), optimizer=optimizer.state_dict(),
                                   env_steps=env_steps, iteration=iteration, config=config.to_dict(),
                                   kl_coeff=kl_coeff, wall_seconds=wall_before + time.perf_counter() - start,
                                   best_return=report.best_return, meta=dict(meta, algo=config.algo),
                                   **(dict(comm_training=signals.state_dict()) if i2c else {})))

    def snapshot(path: Path) -> None:   # the acting part only (the format of `export_policy`): small files
        save_checkpoint(path, dict(actor=actor.state_dict(), meta=dict(meta, algo=config.algo),
                                   config=config.to_dict(), env_steps=env_steps, note=f'iteration {iteration}'))

    masking = config.mask_invisible and hasattr(envs, 'allowed_actions') and meta['hrl']

    def allowed_of(obs_t):   # (..., N, H, C) choices the policy may take, or None (all)
        return torch.from_numpy(envs.allowed_actions(obs_t.numpy())) if masking else None

    def values_of(obs_t, state_t, messages_t=None):   # (..., N) values of every agent, in return units
        inputs = critic_inputs(config.algo, obs_t, state_t, messages_t)
        return per_agent(config.algo, value_norm.denormalize(critic(inputs)), N, shared=not per_agent_rewards)

    def read(state):   # TarMAC: the messages (B, N, M) the agents read at a decision from this memory, else None
        return state[2] if talking else None

    # ---- rollout storage: T decisions x B envs x N agents
    T = config.rollout_length
    obs_buf = torch.zeros(T, B, N, D)
    state_buf = torch.zeros(T, B, S)
    action_buf = torch.zeros(T, B, N, H, dtype=torch.long)
    logp_buf = torch.zeros(T, B, N)
    value_buf = torch.zeros(T, B, N)
    reward_buf = torch.zeros(T, B, N)
    done_buf = torch.zeros(T, B)
    start_buf = torch.zeros(T, B, dtype=torch.bool)      # an episode begins at this decision (recurrent actor)
    message_buf = torch.zeros(T, B, N, M)                # TarMAC: the messages read at each decision (critic input)
    delivered_buf = torch.ones(T, B, N, N, dtype=torch.bool) if perturbed else None   # the channel's masks, replayed
    memory = actor.initial_state(B, N) if recurrent else None
    starting = torch.ones(B, dtype=torch.bool)

    obs, state = envs.reset(seed=config.seed + 10_007 * iteration)
    obs, state = torch.from_numpy(obs), torch.from_numpy(state)
    report = RunReport(run_dir, config.total_steps, env_steps, progress, callback, best_return,
                       save_best=lambda: snapshot(run_dir / 'best.pt'))
    start, start_steps, row = time.perf_counter(), env_steps, {}

    try:
        while env_steps < config.total_steps and not out_of_time(config.time_limit,
                                                                    wall_before + time.perf_counter() - start):
            lr = piecewise(config.lr_schedule, env_steps, interpolate=False)
            entropy_coef = piecewise(config.entropy_schedule, env_steps, interpolate=True)
            for group in optimizer.param_groups:
                group['lr'] = lr

            # ---- collect (one torch thread: the vector env runs its own threads)
            torch.set_num_threads(1)
            coverage = []
            t_collect = time.perf_counter()
            memory_at_start = memory
            for t in range(T):
                with torch.no_grad():
                    if recurrent:
                        memory = restarted(memory, starting)
                        heard = read(memory)
                        if perturbed:   # who reads whom at this decision; the update replays the same masks
                            delivered = channel.delivered((B, N), envs.positions() if channel.range_limit is not None
                                                          else None, channel_generator)
                            delivered_buf[t] = delivered
                            logits, memory = actor.step(obs, memory, delivered=delivered)
                        else:
                            logits, memory = actor.step(obs, memory)
                    else:
                        logits, heard = actor(obs), None
                    dist = action_distribution(logits, H, C, allowed_of(obs))
                    action = torch.multinomial(dist.probs.reshape(-1, C), 1, generator=generator).reshape(B, N, H)
                    value = values_of(obs, state, heard)
                next_obs, next_state, reward, done, truncated, info = envs.step(action.numpy()[..., 0] if H == 1 else action.numpy())
                reward = torch.from_numpy(reward).float()
                reward = reward if per_agent_rewards else reward[:, None].expand(B, N)     # (B, N)
                if truncated.any():   # horizon cut: bootstrap from the critic's value of the last observation
                    with torch.no_grad():
                        final = values_of(torch.from_numpy(info['final_obs']), torch.from_numpy(info['final_state']),
                                          read(memory))   # the episode's next decision would read these messages
                    final = final if per_agent_rewards else final.mean(-1, keepdim=True)   # team: one value per env
                    reward = reward + config.gamma * torch.from_numpy(truncated).float()[:, None] * final
                obs_buf[t], state_buf[t], action_buf[t] = obs, state, action
                logp_buf[t], value_buf[t] = dist.log_prob(action).sum(-1), value
                reward_buf[t], done_buf[t] = reward, torch.from_numpy(done).float()
                start_buf[t], starting = starting, torch.from_numpy(done).clone()
                if talking:
                    message_buf[t] = heard
                obs, state = torch.from_numpy(next_obs), torch.from_numpy(next_state)
                coverage.append(float(info['coverage'].mean()))
                report.add_episodes(info['episodes'])
            env_steps += T * B
            collect_seconds = time.perf_counter() - t_collect

            # ---- advantages (per agent: the team reward repeated, or each agent's own)
            with torch.no_grad():
                last_values = values_of(obs, state, read(restarted(memory, starting)) if talking else None)
            dones = done_buf.unsqueeze(-1).expand(T, B, N)
            advantages, returns = compute_gae(reward_buf, value_buf, dones, last_values, config.gamma,
                                              config.gae_lambda)
            value_norm.update(returns)

            # ---- learn: K epochs over shuffled minibatches of (decision, env) rows, all agents of a row together
            # (recurrent actor: minibatches of whole env sequences, replayed from the rollout's first memory)
            torch.set_num_threads(learn_threads)
            def logits_of(rows):
                if not recurrent:
                    return actor(b_obs[rows])
                envs_ = rows[:len(rows) // T]          # rows are t-major: the first T-th are t = 0, i.e. the envs
                first = tuple(part[envs_] for part in memory_at_start)
                masks = dict(delivered=delivered_buf[:, envs_]) if perturbed else {}
                seq = actor(obs_buf[:, envs_], first, start_buf[:, envs_], **masks)
                return seq.reshape(-1, *seq.shape[2:])

            flat = lambda x: x.reshape(T * B, *x.shape[2:])
            b_obs, b_state, b_action, b_logp = flat(obs_buf), flat(state_buf), flat(action_buf), flat(logp_buf)
            b_messages = flat(message_buf) if talking else None
            b_adv, b_ret = flat(advantages), value_norm.normalize(flat(returns))
            b_adv = (b_adv - b_adv.mean()) / (b_adv.std() + 1e-8)
            stats = dict(policy_loss=0.0, value_loss=0.0, entropy=0.0, approx_kl=0.0, clip_fraction=0.0)
            updates = 0
            if i2c:   # the prior's labels, once per iteration, on a sample of the rollout's decisions
                label_rows = torch.randperm(T * B, generator=generator)[:config.influence_samples]
                labels, influence = signals.labels(b_state[label_rows], b_action[label_rows, :, 0])
                label_obs = b_obs[label_rows]
                b_own_values = signals.own_action_values(b_state, b_action[..., 0])   # the regulariser's targets
                stats.update(q_loss=0.0, prior_loss=0.0, regulariser=0.0)
            for _ in range(config.epochs):
                for idx in minibatch_rows(T, B, config.minibatches, recurrent, generator):
                    logits = logits_of(idx)
                    dist = action_distribution(logits, H, C, allowed_of(b_obs[idx]))
                    new_logp = dist.log_prob(b_action[idx]).sum(-1)
                    policy_loss = ppo_policy_loss(new_logp, b_logp[idx], b_adv[idx], config.clip)
                    inputs = critic_inputs(config.algo, b_obs[idx], b_state[idx],
                                           b_messages[idx] if talking else None)
                    predicted = per_agent(config.algo, critic(inputs), N, shared=not per_agent_rewards)
                    value_loss = 0.5 * (predicted - b_ret[idx]).pow(2).mean()
                    entropy = dist.entropy().sum(-1).mean()
                    kl = sampled_kl(new_logp, b_logp[idx])
                    loss = policy_loss + config.value_coef * value_loss - entropy_coef * entropy
                    if kl_coeff > 0:
                        loss = loss + kl_coeff * kl
                    if i2c:
                        q_loss, regulariser = signals.losses(logits, b_state[idx], b_action[idx][..., 0], b_ret[idx],
                                                             b_own_values[idx])
                        prior_loss = signals.prior_loss(actor, label_obs, labels)
                        loss = loss + q_loss + prior_loss + I2C_REGULARISER * regulariser
                        stats['q_loss'] += q_loss.item()
                        stats['prior_loss'] += prior_loss.item()
                        stats['regulariser'] += regulariser.item()
                    optimizer.zero_grad()
                    loss.backward()
                    if config.max_grad_norm:
                        nn.utils.clip_grad_norm_(learned, config.max_grad_norm)
                    optimizer.step()
                    with torch.no_grad():
                        log_ratio = new_logp - b_logp[idx]
                        stats['approx_kl'] += kl.item()
                        stats['clip_fraction'] += float(((log_ratio.exp() - 1).abs() > config.clip).float().mean())
                    stats['policy_loss'] += policy_loss.item()
                    stats['value_loss'] += value_loss.item()
                    stats['entropy'] += entropy.item()
                    updates += 1
            iteration += 1
            row_kl_coeff = kl_coeff                     # the coefficient this iteration used
            if kl_coeff > 0:
                kl_coeff = adapt_kl_coeff(kl_coeff, stats['approx_kl'] / updates, config.kl_target)

            # ---- log
            if i2c:   # the iteration's means of the loss terms; edges: teammates asked per agent; labels' KL
                with torch.no_grad():
                    edges = (actor.request_logits(label_obs) >= 0).float().sum(-1).mean()
                stats.update(edges=float(edges) * updates, influence_kl=float(influence.mean()) * updates,
                             influence_threshold=signals.threshold.threshold() * updates)
            elapsed = time.perf_counter() - start
            row = report.iteration_row(
                iteration, env_steps, config.frame_skip, wall_before + elapsed,
                (env_steps - start_steps) / max(elapsed, 1e-9), coverage,
                collect_share=collect_seconds / max(time.perf_counter() - t_collect, 1e-9), lr=lr,
                entropy_coef=entropy_coef, **{k: v / updates for k, v in stats.items()}, kl_coeff=row_kl_coeff)
            report.write(row, report.status(row, f"entropy {row['entropy']:.2f}"))
            if iteration % config.checkpoint_every == 0:
                checkpoint(checkpoint_path)
            if config.snapshot_every and iteration % config.snapshot_every == 0:
                snapshot(run_dir / 'snapshots' / f'policy-{env_steps:010d}.pt')
        checkpoint(checkpoint_path)
        checkpoint(run_dir / 'final.pt')
    finally:
        report.close()
    return row


def check_i2c(config: PPOConfig) -> None:
    """ValueError unless an I2C run is one it supports: MAPPO, flat discrete actions, no memory/velocity columns
    (a deployed agent asks its teammates for their raw observations and must rebuild what training read)."""
    if config.algo != 'mappo':
        raise ValueError(f"comm 'i2c' is a MAPPO add-on (its Q-networks and critic read the global state); "
                         f"algo {config.algo!r} is not")
    if config.hrl:
        raise ValueError("comm 'i2c' needs the flat discrete actions (25 moves); HRL selections do not combine with it")
    if config.memory or config.velocity:
        raise ValueError("comm 'i2c' exchanges raw observations; --memory and --velocity columns do not combine "
                         "with it")


WARM_START_KEYS = ('team', 'env_id', 'obs_dim', 'num_actions', 'action_heads', 'hrl', 'actor', 'lstm',
                   'full_observability', 'memory', 'velocity', 'comm')
"""Metadata a warm-start file must share with the experiment (the actor's shape and meaning)."""


def _warm_start(path, meta: dict, actor: nn.Module, critic: nn.Module, value_norm: ValueNormalizer) -> None:
    """Load the actor of `path` (a checkpoint or an exported policy) and, from a full checkpoint of the
    same algorithm and credit, the critic and value normaliser too; CheckpointError if the actor does not fit."""
    saved = load_checkpoint(path, expect={key: meta[key] for key in WARM_START_KEYS})
    try:
        actor.load_state_dict(saved['actor'])
    except RuntimeError as exc:
        raise CheckpointError(f'warm start {str(path)!r}: actor weights do not fit: {str(exc).splitlines()[0]}') from None
    same_critic = all(saved['meta'].get(k, META_DEFAULTS.get(k)) == meta.get(k, META_DEFAULTS.get(k))
                      for k in ('algo', 'credit', 'critic_messages'))
    if 'critic' in saved and same_critic:   # the critic's inputs and outputs depend on these
        critic.load_state_dict(saved['critic'])
        value_norm.load_state_dict(saved['value_norm'])
