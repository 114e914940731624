"""I2C on MAPPO for MATE: each agent asks the teammates its prior selects, in one file (`mate train i2c`).

    config  ->  PolicySpec (network 'i2c': one network per agent, an LSTM of `lstm` cells; flat grid actions)
            ->  `TeamVecEnv`, and the channel requests and replies go through in training (`Channel`: ideal by
                default)
            ->  networks: the `I2CActor`s, a feed-forward critic on the global state (MAPPO), and I2C's training
                signals (`I2CTraining`: a joint action-value network per agent and the labels' KL buffer)
            ->  loop: collect T decisions x B envs x N agents, the actors carrying (h, c) from decision to decision;
                GAE; the prior's labels on a sample of the rollout; K epochs on minibatches of whole env sequences
            ->  `Run`: logs, checkpoints, best.pt, final.pt

I2C ("individually inferred communication", Ding et al. 2020; docs/training.md, "I2C"): at every decision each agent's prior
network decides, from its own observation, which teammates to ask; it attends to the current observations of those
it asked, and the message joins its observation in an MLP -> LSTM -> head (`mate.learn.comm` has the computation).
No delay, peer to peer, no shared weights. The memory rules are `mappo_lstm.py`'s: zeroed where an episode starts
(`starting`), the rollout's first memory and start flags kept so that the update unrolls each env sequence again.

One optimiser minimises, besides PPO's clipped loss, value loss and entropy bonus:
* the joint action-value networks' regression Q_i(s, a) onto the value targets (normalised returns);
* the prior's binary cross-entropy on causal-influence labels: for `influence_samples` random decisions of the
  rollout, once per iteration and without gradient, whether teammate j's action moved agent i's best response more
  than the median of the recent KL values (`I2CTraining.labels`; they cost N (N - 1) A^2 joint action-value
  evaluations each, the largest share of an iteration);
* 0.01 x the policy-correlation regulariser KL(pi_i || softmax(Q_i(s, ., a_-i) / tau)), its Q targets computed once
  per iteration, before the epochs (as PPO takes its old log-probabilities).

The action-value networks read the global state, hence MAPPO only; the actions are the flat grid moves (the
labels enumerate them); a deployed agent asks its teammates for their raw observations, hence no `--memory` or
`--velocity` columns. The lossy channel of training (`message_dropout`, `communication_range`): at every decision a
mask (B, N askers, N teammates) of the replies that arrive (a reply needs its request and itself to get through,
each lost with the dropout's probability; or the two agents are farther apart than the range); a lost reply is a
zero observation in its slot, as at deployment. The masks are stored with the rollout and replayed by the update;
they come from a generator of their own (on the CPU). A reply later than its decision is never read: there is no
delay option (a delay of one decision is `message_dropout` 1).
"""

from __future__ import annotations

import dataclasses
import time

import torch

from ..options import option
from .checkpoint import CheckpointError
from .comm import I2C_REGULARISER, Channel, I2CTraining, channel_difference, check_channel
from .device import resolve_device, update_threads
from .envs import TeamVecEnv
from .networks import Critic, restarted
from .policy import make_actor
from .ppo import (
    PPOConfig,
    Schedules,
    UpdateStats,
    ValueNormalizer,
    action_distribution,
    adapt_kl_coeff,
    bootstrapped,
    learning_targets,
    minibatch_rows,
    ppo_update,
    warm_start,
)
from .run import Run
from .spec import PolicySpec

__all__ = ['I2CConfig', 'policy_spec', 'train']


@dataclasses.dataclass
class I2CConfig(PPOConfig):
    """Settings of an I2C run (`train(config)`, `mate train i2c`; MAPPO's critic, flat grid actions)."""

    lstm: int = option(256, "LSTM cells of each agent's actor (the paper's 256)", minimum=1)
    influence_samples: int = option(32, "decisions per iteration whose causal-influence labels are computed (each "
                                        "costs N_agents x (N_agents - 1) x 25 x 25 joint action-value evaluations: "
                                        'the largest share of an iteration)', minimum=1, metavar='N')
    message_dropout: float = option(0.0, 'train under a lossy channel: each request and each reply lost with this '
                                         'probability in [0, 1] (as RandomMessageDropout)', metavar='P')
    communication_range: float | None = option(None, 'requests and replies get through only between agents at most '
                                                     'this many world units apart (as RestrictedCommunicationRange); '
                                                     'None: any distance', metavar='R')

    def __post_init__(self) -> None:
        super().__post_init__()
        for flag, given, reason in (('--hrl', self.hrl, 'needs the flat discrete actions'),
                                    ('--memory', self.memory, 'exchanges raw observations'),
                                    ('--velocity', self.velocity, 'exchanges raw observations')):
            if given:
                raise ValueError(f'I2C {reason}; {flag} does not combine with it')
        check_channel(self.message_dropout, self.communication_range, 'i2c', as_flags=True)

    @property
    def algo(self) -> str:
        return 'mappo-i2c'

    @property
    def channel(self) -> dict:
        """The settings of the channel the team trains under (a resume must keep them)."""
        return dict(message_dropout=float(self.message_dropout), communication_range=self.communication_range)


def policy_spec(config: I2CConfig, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains; with `envs` given, what they say the policy sees and does (their
    `spec`) with this config's network."""
    network = dict(network='i2c', hidden=config.hidden, activation=config.activation, lstm=config.lstm,
                   algo=config.algo)
    if envs is not None:
        return envs.spec.replace(**network)
    return config.policy_spec(action='grid', **network)


# ============================================================================ training

def train(config: I2CConfig, envs: TeamVecEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/ALGO-TEAM-seedN); resume from its checkpoint
    unless `config.fresh` (a checkpoint trained under another channel is refused). `envs` replaces the training envs
    (anything with `TeamVecEnv`'s attributes, `spec` and reset/step; `positions()` with a `communication_range`);
    `callback(row)` sees every log row. Returns the `Run`."""
    device = resolve_device(config.device)
    spec = policy_spec(config, envs)
    run = Run.of(config, config.algo, spec, callback, console)

    # ---- environments and the channel (which replies of a decision arrive; `delivered` None: all of them)
    envs = envs or config.make_env(spec)
    B, N, S = envs.num_envs, envs.num_agents, envs.state_dim
    A = envs.action_choices                                        # one head: the grid moves
    per_agent_rewards = getattr(envs, 'credit', 'team') != 'team'  # rewards (B, N): one critic value per agent
    channel = Channel(config.message_dropout, config.communication_range, legs=2)   # the request, then the reply
    if config.communication_range is not None and not hasattr(envs, 'positions'):
        raise ValueError("--communication-range needs the agents' positions; this env has no positions()")

    def delivered_now():   # (B, N, N) bool masks of this decision, or None
        positions = envs.positions() if channel.range_limit is not None else None
        delivered = channel.delivered((B, N), positions, channel_generator)
        return None if delivered is None else delivered.to(device)

    # ---- networks (the actors, the critic, I2C's training signals), optimiser, the actors' memory
    threads = update_threads(config)          # torch threads of the updates and of the initialisation, whose
    torch.set_num_threads(threads)           # orthogonal matrices (QR) depend on the thread count
    torch.manual_seed(config.seed)
    actor = make_actor(spec).to(device)                            # an `I2CActor`: N networks
    critic = Critic(S, config.hidden, config.activation, outputs=N if per_agent_rewards else 1).to(device)
    value_norm = ValueNormalizer().to(device)
    signals = I2CTraining(N, S, A, config.hidden, config.activation).to(device)
    learned = [*actor.parameters(), *critic.parameters(), *signals.parameters()]
    optimizer = torch.optim.Adam(learned, lr=config.lr_schedule[0][1], eps=1e-5)
    schedules, kl_coeff = Schedules(config), config.kl_coeff       # kl_coeff adapts every iteration
    generator = torch.Generator(device).manual_seed(config.seed * 1_000_003)
    channel_generator = torch.Generator().manual_seed(config.seed * 1_000_003 + 500_009)   # the masks' own draws
    memory = tuple(part.to(device) for part in actor.initial_state(B, N))   # (h, c), carried across iterations
    starting = torch.ones(B, dtype=torch.bool, device=device)     # the env's next decision opens an episode
    saved = run.resume()
    if saved is not None:
        difference = channel_difference(saved['channel'], config.channel)
        if difference:
            raise CheckpointError(f'checkpoint {str(run.checkpoint_path)!r} does not match this experiment: '
                                  f'{difference}')
        for module, name in ((actor, 'actor'), (critic, 'critic'), (value_norm, 'value_norm'),
                             (signals, 'comm_training')):
            module.load_state_dict(saved['networks'][name])
        optimizer.load_state_dict(saved['optimizer'])
        kl_coeff = float(saved['kl_coeff'])
        generator.set_state(saved['generator'])
        channel_generator.set_state(saved['channel_generator'])
        memory = tuple(part.to(device) for part in saved['memory'])
        if run.continues_episodes(saved):     # else the envs are reset: every episode starts, memory zeroed
            starting = saved['starting'].to(device)
    elif config.init_from:
        warm_start(config.init_from, spec, actor, dict(critic=critic, value_norm=value_norm), config.algo,
                   config.credit)
    obs, state = run.first_observations(envs, saved)
    obs, state = torch.from_numpy(obs).to(device), torch.from_numpy(state).to(device)

    def values_of(state_t):   # (..., N) values of every agent, in return units
        values = value_norm.denormalize(critic(state_t))
        return values if per_agent_rewards else values.unsqueeze(-1).expand(*values.shape, N)

    def networks() -> dict:
        return dict(actor=actor.state_dict(), critic=critic.state_dict(), value_norm=value_norm.state_dict(),
                    comm_training=signals.state_dict())

    def run_state() -> dict:   # everything the run's future depends on (exact resume), the actors' memory included
        return dict(networks=networks(), optimizer=optimizer.state_dict(), kl_coeff=kl_coeff,
                    generator=generator.get_state(), channel_generator=channel_generator.get_state(),
                    channel=config.channel, memory=list(memory), starting=starting,
                    **({'envs': envs.state_dict()} if hasattr(envs, 'state_dict') else {}))

    # ---- rollout storage: T decisions x B envs x N agents
    T = config.rollout_length
    obs_buf = torch.zeros(T, B, N, envs.obs_dim, device=device)
    state_buf = torch.zeros(T, B, S, device=device)
    action_buf = torch.zeros(T, B, N, 1, dtype=torch.long, device=device)
    logp_buf = torch.zeros(T, B, N, device=device)
    value_buf = torch.zeros(T, B, N, device=device)
    reward_buf = torch.zeros(T, B, N, device=device)
    done_buf = torch.zeros(T, B, device=device)
    start_buf = torch.zeros(T, B, dtype=torch.bool, device=device)   # an episode begins at this decision
    delivered_buf = torch.ones(T, B, N, N, dtype=torch.bool, device=device) if channel.active else None

    with run:
        while run.running():
            lr, entropy_coef = schedules.apply(optimizer, run.env_steps)

            # ---- collect (one torch thread: the vector env runs its own threads)
            torch.set_num_threads(1)
            coverage, episodes = [], []
            t_collect = time.perf_counter()
            memory_at_start = memory                  # the update unrolls every sequence again from here
            for t in range(T):
                with torch.no_grad():
                    memory = restarted(memory, starting)               # a new episode starts from zero memory
                    delivered = delivered_now()                        # whose replies arrive; the update replays it
                    if delivered is not None:
                        delivered_buf[t] = delivered
                    logits, memory = actor.step(obs, memory, delivered=delivered)
                    dist = action_distribution(logits, 1, A)
                    action = torch.multinomial(dist.probs.reshape(-1, A), 1, generator=generator).reshape(B, N, 1)
                    value = values_of(state)
                next_obs, next_state, reward, done, truncated, info = envs.step(action.cpu().numpy()[..., 0])
                reward = torch.from_numpy(reward).float().to(device)
                reward = reward if per_agent_rewards else reward[:, None].expand(B, N)     # (B, N)
                if truncated.any():   # horizon cut: bootstrap from the critic's value of the last state
                    with torch.no_grad():
                        final = values_of(torch.from_numpy(info['final_state']).to(device))
                    final = final if per_agent_rewards else final.mean(-1, keepdim=True)   # (B, N) or (B, 1)
                    reward = bootstrapped(reward, truncated, final, config.gamma)
                done = torch.from_numpy(done).to(device)
                obs_buf[t], state_buf[t], action_buf[t] = obs, state, action
                logp_buf[t], value_buf[t] = dist.log_prob(action).sum(-1), value
                reward_buf[t], done_buf[t] = reward, done.float()
                start_buf[t], starting = starting, done.clone()
                obs, state = torch.from_numpy(next_obs).to(device), torch.from_numpy(next_state).to(device)
                coverage.append(float(info['coverage'].mean()))
                episodes += info['episodes']
            collect_seconds = time.perf_counter() - t_collect

            # ---- advantages (per agent: the team reward repeated, or each agent's own)
            with torch.no_grad():
                last_values = values_of(state)
            b_adv, b_ret = learning_targets(reward_buf, value_buf, done_buf, last_values, value_norm, config.gamma,
                                            config.gae_lambda)    # (T * B, N) rows, as the other buffers' below

            # ---- learn: the prior's labels and the regulariser's targets, once; then K epochs over minibatches of
            # whole env sequences, each unrolled from its first memory
            torch.set_num_threads(threads)
            flat = lambda x: x.reshape(T * B, *x.shape[2:])   # noqa: E731
            b_obs, b_state, b_action, b_logp = flat(obs_buf), flat(state_buf), flat(action_buf), flat(logp_buf)
            label_rows = torch.randperm(T * B, generator=generator, device=device)[:config.influence_samples]
            labels, influence = signals.labels(b_state[label_rows], b_action[label_rows, :, 0])   # (R, N, N - 1)
            label_obs = b_obs[label_rows]
            own_values = signals.own_action_values(b_state, b_action[..., 0])      # (T B, N, A), no gradient

            def logits_of(rows):   # (len(rows), N, A): rows t * B + b of a group of envs, t-major
                group = rows[:len(rows) // T]                        # the first len/T rows are the envs at t = 0
                first = tuple(part[group] for part in memory_at_start)
                masks = None if delivered_buf is None else delivered_buf[:, group]      # the rollout's deliveries
                sequences = actor(obs_buf[:, group], first, start_buf[:, group], delivered=masks)   # (T, envs, N, A)
                return sequences.reshape(-1, *sequences.shape[2:])

            stats = UpdateStats('policy_loss', 'value_loss', 'entropy', 'approx_kl', 'clip_fraction', 'q_loss',
                                'prior_loss', 'regulariser')
            for _ in range(config.epochs):
                for idx in minibatch_rows(T, B, config.minibatches, True, generator):
                    logits = logits_of(idx)
                    dist = action_distribution(logits, 1, A)
                    predicted = critic(b_state[idx])
                    predicted = predicted if per_agent_rewards else predicted.unsqueeze(-1).expand(*predicted.shape, N)
                    # I2C's own terms: the joint action-value regression, the prior's labels, the correlation
                    # regulariser
                    q_loss, regulariser = signals.losses(logits, b_state[idx], b_action[idx][..., 0], b_ret[idx],
                                                         own_values[idx])
                    prior_loss = signals.prior_loss(actor, label_obs, labels)
                    ppo_update(optimizer, learned, config, dist, b_action[idx], b_logp[idx], b_adv[idx], predicted,
                               b_ret[idx], entropy_coef, kl_coeff, stats,
                               extra=(q_loss, prior_loss, I2C_REGULARISER * regulariser))
                    stats.add(q_loss=q_loss.item(), prior_loss=prior_loss.item(), regulariser=regulariser.item())
            means = stats.means()
            row_kl_coeff = kl_coeff                     # the coefficient this iteration used
            if kl_coeff > 0:
                kl_coeff = adapt_kl_coeff(kl_coeff, means['approx_kl'], config.kl_target)

            # ---- log (edges: teammates asked per agent; the labels' mean KL and threshold), keep the best policy,
            # checkpoint
            with torch.no_grad():
                edges = (actor.request_logits(label_obs) >= 0).float().sum(-1).mean()
            run.end_iteration(T * B, coverage, episodes, dict(
                collect_share=collect_seconds / max(time.perf_counter() - t_collect, 1e-9), lr=lr,
                entropy_coef=entropy_coef, **means, edges=float(edges), influence_kl=float(influence.mean()),
                influence_threshold=signals.threshold.threshold(), kl_coeff=row_kl_coeff),
                status=f"entropy {means['entropy']:.2f}",
                actor=actor.state_dict,
                save=run_state)
    run.finish(run_state(), actor.state_dict())
    return run
