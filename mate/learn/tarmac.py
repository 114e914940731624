"""TarMAC on MAPPO or IPPO for MATE: learned messages read through attention, in one file (`mate train tarmac`).

    config  ->  PolicySpec (network 'tarmac': the MLP body, an LSTM of `lstm` cells, a head of [logits | message])
            ->  `TeamVecEnv`, and the channel the messages go through in training (`Channel`: ideal by default)
            ->  networks: one `TarMACActor` shared by the team; a feed-forward critic on the global state (MAPPO,
                `critic='state'`), on each agent's observation (IPPO, `critic='local'`) or on both (MAPPO-AS,
                `critic='agent'`, as `mappo.py`), the messages appended
            ->  loop: collect T decisions x B envs x N agents, the actor carrying (h, c, messages) from decision to
                decision; GAE; K epochs of clipped PPO on minibatches of whole env sequences, unrolled through the
                messages
            ->  `Run`: logs, checkpoints, best.pt, final.pt

At every decision each agent sends a message (key 32 + value 32) and every agent of the env, the sender included,
reads all N messages at the next decision through soft attention (`mate.learn.comm` has the computation). The
messages are part of the state the actor carries, `(h, c, messages)`, so the memory rules are `mappo_lstm.py`'s:
zeroed where an episode starts (`starting`; nothing is heard at an episode's first decision), the rollout's first
memory and its start flags kept so that the update unrolls each env sequence again, bitwise as in the rollout. The
messages stay in the graph of that unroll: the loss of a receiver's action at t + 1 trains the sender's message
head at t (within a rollout; the memory carried in from the previous one is a constant).

The critic reads the N messages of the decision too (docs/training.md, "TarMAC"): those the agents read at it (the
previous decision's; zeros at an episode's first), stored with the rollout as data (T, B, N, 64) and appended flat
(N x 64) to the global state or to each agent's critic input. A horizon cut's bootstrap value reads the messages just
sent (those the episode's next decision would read); the rollout's last value those the next decision reads.

The lossy channel of training (`message_dropout`, `communication_range`): at every decision of the rollout a mask
(B, N receivers, N senders) of the deliveries that happen (each lost with the dropout's probability, or between
agents farther apart than the range, read from `TeamVecEnv.positions`); a lost message reads as zeros in the
receiver's attention, as at deployment. The masks are stored with the rollout and the update's unroll replays them;
they are drawn from a generator of their own (on the CPU), so the actions drawn are those of an unperturbed run. The
critic still reads every message sent (centralised, like the state). `message_delay` K: teammates' messages are read
K decisions later than without (an agent's own: the last), the memory carrying a queue of the K message sets before
the last (`TarMACActor.delay`).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Literal

import torch

from ..options import option
from .checkpoint import CheckpointError
from .comm import Channel, channel_difference, check_channel
from .device import resolve_device, update_threads
from .envs import TeamVecEnv
from .mappo import critic_input_dim, critic_inputs, critic_outputs, per_agent
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

__all__ = ['TarMACConfig', 'policy_spec', 'train']


@dataclasses.dataclass
class TarMACConfig(PPOConfig):
    """Settings of a TarMAC run (`train(config)`, `mate train tarmac`)."""

    critic: Literal['state', 'local', 'agent'] = option('state', "the critic's input, the messages appended: the "
                                                                 "global state (MAPPO), each agent's observation "
                                                                 "(IPPO) or the state with each agent's observation "
                                                                 "appended (MAPPO-AS)")
    lstm: int = option(256, "LSTM cells of the actor (the paper's 256)", minimum=1)
    message_dropout: float = option(0.0, 'train under a lossy channel: each sender -> receiver delivery lost with '
                                         'this probability in [0, 1] (as RandomMessageDropout)', metavar='P')
    communication_range: float | None = option(None, 'deliver a message only between agents at most this many world '
                                                     'units apart (as RestrictedCommunicationRange); None: any '
                                                     'distance', metavar='R')
    message_delay: int = option(0, "teammates' messages arrive this many decisions late, on top of TarMAC's one (as "
                                   'ExtraCommunicationDelays of K x frame-skip steps)', metavar='K')

    def __post_init__(self) -> None:
        super().__post_init__()
        check_channel(self.message_dropout, self.communication_range, 'tarmac', self.message_delay, as_flags=True)

    @property
    def algo(self) -> str:
        return {'state': 'mappo-tarmac', 'local': 'ippo-tarmac', 'agent': 'mappo-as-tarmac'}[self.critic]

    @property
    def channel(self) -> dict:
        """The settings of the channel the team trains under (a resume must keep them)."""
        return dict(message_dropout=float(self.message_dropout), communication_range=self.communication_range,
                    message_delay=int(self.message_delay))


def policy_spec(config: TarMACConfig, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains; with `envs` given, what they say the policy sees and does (their
    `spec`) with this config's network."""
    network = dict(network='tarmac', hidden=config.hidden, activation=config.activation, lstm=config.lstm,
                   algo=config.algo)
    if envs is not None:
        return envs.spec.replace(**network)
    return config.policy_spec(action='hrl' if config.hrl else 'grid', **network)


# ============================================================================ training

def train(config: TarMACConfig, envs: TeamVecEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/ALGO-TEAM-seedN); resume from its checkpoint
    unless `config.fresh` (a checkpoint trained under another channel is refused). `envs` replaces the training envs
    (anything with `TeamVecEnv`'s attributes, `spec` and reset/step; `positions()` with a `communication_range`);
    `callback(row)` sees every log row. Returns the `Run`."""
    device = resolve_device(config.device)
    spec = policy_spec(config, envs)
    run = Run.of(config, config.algo, spec, callback, console)

    # ---- environments and the channel (which messages of a decision arrive; `delivered` None: all of them)
    envs = envs or config.make_env(spec)
    B, N, D, S = envs.num_envs, envs.num_agents, envs.obs_dim, envs.state_dim
    H, C = envs.action_heads, envs.action_choices                 # A = H x C logits per agent
    per_agent_rewards = getattr(envs, 'credit', 'team') != 'team'  # rewards (B, N): one critic value per agent
    channel = Channel(config.message_dropout, config.communication_range)
    if config.communication_range is not None and not hasattr(envs, 'positions'):
        raise ValueError("--communication-range needs the agents' positions; this env has no positions()")

    def delivered_now():   # (B, N, N) bool masks of this decision, or None
        positions = envs.positions() if channel.range_limit is not None else None
        delivered = channel.delivered((B, N), positions, channel_generator)
        return None if delivered is None else delivered.to(device)

    # ---- networks, optimiser, the actor's memory
    threads = update_threads(config)          # torch threads of the updates and of the initialisation, whose
    torch.set_num_threads(threads)           # orthogonal matrices (QR) depend on the thread count
    torch.manual_seed(config.seed)
    actor = make_actor(spec)                                       # a `TarMACActor`
    actor.delay = config.message_delay                             # training's delay: a queue in the memory
    actor = actor.to(device)
    M = actor.key_size + actor.value_size                          # message size
    critic = Critic(critic_input_dim(config.critic, D, S, N * M), config.hidden, config.activation,
                    outputs=critic_outputs(config.critic, N, per_agent_rewards)).to(device)
    value_norm = ValueNormalizer().to(device)
    learned = [*actor.parameters(), *critic.parameters()]
    optimizer = torch.optim.Adam(learned, lr=config.lr_schedule[0][1], eps=1e-5)
    schedules, kl_coeff = Schedules(config), config.kl_coeff       # kl_coeff adapts every iteration
    generator = torch.Generator(device).manual_seed(config.seed * 1_000_003)
    channel_generator = torch.Generator().manual_seed(config.seed * 1_000_003 + 500_009)   # the masks' own draws
    memory = tuple(part.to(device) for part in actor.initial_state(B, N))   # (h, c, messages[, queue])
    starting = torch.ones(B, dtype=torch.bool, device=device)     # the env's next decision opens an episode
    saved = run.resume()
    if saved is not None:
        difference = channel_difference(saved['channel'], config.channel)
        if difference:
            raise CheckpointError(f'checkpoint {str(run.checkpoint_path)!r} does not match this experiment: '
                                  f'{difference}')
        for module, name in ((actor, 'actor'), (critic, 'critic'), (value_norm, 'value_norm')):
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
    masking = config.mask_invisible and spec.hrl

    def allowed_of(obs_t):   # (..., N, H, C) choices the policy may take, or None (all)
        return torch.from_numpy(envs.allowed_actions(obs_t.cpu().numpy())).to(device) if masking else None

    def values_of(obs_t, state_t, messages_t):   # (..., N) values of every agent, in return units
        inputs = critic_inputs(config.critic, obs_t, state_t, messages_t)
        return per_agent(config.critic, value_norm.denormalize(critic(inputs)), N, shared=not per_agent_rewards)

    def networks() -> dict:
        return dict(actor=actor.state_dict(), critic=critic.state_dict(), value_norm=value_norm.state_dict())

    def run_state() -> dict:   # everything the run's future depends on (exact resume), the actor's memory included
        return dict(networks=networks(), optimizer=optimizer.state_dict(), kl_coeff=kl_coeff,
                    generator=generator.get_state(), channel_generator=channel_generator.get_state(),
                    channel=config.channel, memory=list(memory), starting=starting,
                    **({'envs': envs.state_dict()} if hasattr(envs, 'state_dict') else {}))

    # ---- rollout storage: T decisions x B envs x N agents
    T = config.rollout_length
    obs_buf = torch.zeros(T, B, N, D, device=device)
    state_buf = torch.zeros(T, B, S, device=device)
    action_buf = torch.zeros(T, B, N, H, dtype=torch.long, device=device)
    logp_buf = torch.zeros(T, B, N, device=device)
    value_buf = torch.zeros(T, B, N, device=device)
    reward_buf = torch.zeros(T, B, N, device=device)
    done_buf = torch.zeros(T, B, device=device)
    start_buf = torch.zeros(T, B, dtype=torch.bool, device=device)   # an episode begins at this decision
    message_buf = torch.zeros(T, B, N, M, device=device)             # the messages read at each decision (critic)
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
                    heard = memory[2]                                  # the messages the agents read now
                    delivered = delivered_now()                        # who reads whom; the update replays it
                    if delivered is not None:
                        delivered_buf[t] = delivered
                    logits, memory = actor.step(obs, memory, delivered=delivered)
                    dist = action_distribution(logits, H, C, allowed_of(obs))
                    action = torch.multinomial(dist.probs.reshape(-1, C), 1, generator=generator).reshape(B, N, H)
                    value = values_of(obs, state, heard)
                chosen = action.cpu().numpy()
                next_obs, next_state, reward, done, truncated, info = envs.step(chosen[..., 0] if H == 1 else chosen)
                reward = torch.from_numpy(reward).float().to(device)
                reward = reward if per_agent_rewards else reward[:, None].expand(B, N)     # (B, N)
                if truncated.any():   # horizon cut: bootstrap from the critic, with the messages just sent
                    with torch.no_grad():
                        final = values_of(torch.from_numpy(info['final_obs']).to(device),
                                          torch.from_numpy(info['final_state']).to(device), memory[2])
                    final = final if per_agent_rewards else final.mean(-1, keepdim=True)   # (B, N) or (B, 1)
                    reward = bootstrapped(reward, truncated, final, config.gamma)
                done = torch.from_numpy(done).to(device)
                obs_buf[t], state_buf[t], action_buf[t] = obs, state, action
                logp_buf[t], value_buf[t] = dist.log_prob(action).sum(-1), value
                reward_buf[t], done_buf[t] = reward, done.float()
                start_buf[t], starting = starting, done.clone()
                message_buf[t] = heard
                obs, state = torch.from_numpy(next_obs).to(device), torch.from_numpy(next_state).to(device)
                coverage.append(float(info['coverage'].mean()))
                episodes += info['episodes']
            collect_seconds = time.perf_counter() - t_collect

            # ---- advantages (per agent: the team reward repeated, or each agent's own)
            with torch.no_grad():
                last_values = values_of(obs, state, restarted(memory, starting)[2])
            b_adv, b_ret = learning_targets(reward_buf, value_buf, done_buf, last_values, value_norm, config.gamma,
                                            config.gae_lambda)    # (T * B, N) rows, as the other buffers' below

            # ---- learn: K epochs over minibatches of whole env sequences, each unrolled from its first memory
            torch.set_num_threads(threads)
            flat = lambda x: x.reshape(T * B, *x.shape[2:])   # noqa: E731
            b_obs, b_state, b_action, b_logp = flat(obs_buf), flat(state_buf), flat(action_buf), flat(logp_buf)
            b_messages = flat(message_buf)

            def logits_of(rows):   # (len(rows), N, A): rows t * B + b of a group of envs, t-major
                group = rows[:len(rows) // T]                        # the first len/T rows are the envs at t = 0
                first = tuple(part[group] for part in memory_at_start)
                masks = None if delivered_buf is None else delivered_buf[:, group]      # the rollout's deliveries
                sequences = actor(obs_buf[:, group], first, start_buf[:, group], delivered=masks)   # (T, envs, N, A)
                return sequences.reshape(-1, *sequences.shape[2:])

            stats = UpdateStats('policy_loss', 'value_loss', 'entropy', 'approx_kl', 'clip_fraction')
            for _ in range(config.epochs):
                for idx in minibatch_rows(T, B, config.minibatches, True, generator):
                    dist = action_distribution(logits_of(idx), H, C, allowed_of(b_obs[idx]))
                    inputs = critic_inputs(config.critic, b_obs[idx], b_state[idx], b_messages[idx])
                    predicted = per_agent(config.critic, critic(inputs), N, shared=not per_agent_rewards)
                    ppo_update(optimizer, learned, config, dist, b_action[idx], b_logp[idx], b_adv[idx], predicted,
                               b_ret[idx], entropy_coef, kl_coeff, stats)
            means = stats.means()
            row_kl_coeff = kl_coeff                     # the coefficient this iteration used
            if kl_coeff > 0:
                kl_coeff = adapt_kl_coeff(kl_coeff, means['approx_kl'], config.kl_target)

            # ---- log, keep the best policy, checkpoint
            run.end_iteration(T * B, coverage, episodes, dict(
                collect_share=collect_seconds / max(time.perf_counter() - t_collect, 1e-9), lr=lr,
                entropy_coef=entropy_coef, **means, kl_coeff=row_kl_coeff), status=f"entropy {means['entropy']:.2f}",
                actor=actor.state_dict,
                save=run_state)
    run.finish(run_state(), actor.state_dict())
    return run
