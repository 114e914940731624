"""The one PPO loop of `mate.learn`: MAPPO, IPPO, MAPPO-AS, their recurrent versions, TarMAC and I2C all train here.

    spec (what the policy sees and does)  ->  batched training envs (`TrainingEnv`: B games, the other team a
            batched opponent; with `--game-device cuda` the games on a GPU, torch tensors in and out)
        ->  networks: the actor the spec names (`make_actor`), one critic (`critic_inputs`: the global state, each
            agent's observation, or both; TarMAC's messages appended), the value normaliser, and an algorithm's own
            modules (`Auxiliary`: I2C's training signals)
        ->  loop: collect T decisions x B envs x N agents, GAE, K epochs of clipped PPO on minibatches
        ->  `Run`: logs, checkpoints, best.pt, final.pt

An algorithm file (`mappo.py`, `mappo_lstm.py`, `tarmac.py`, `i2c.py`) is a config, the spec it trains and, where it
needs them, a channel and an `Auxiliary`; `train` here does the rest. What differs between the actors is read from
the actor itself:

* a feed-forward actor (`actor(obs)` -> logits) trains on shuffled (decision, env) rows;
* a recurrent one (`recurrent = True`: `initial_state(B, N)`, `step(obs, memory)` -> (logits, memory) and
  `forward(obs (T, ...), first memory, starts (T, B))` -> logits (T, ...)) carries its memory from decision to
  decision and from iteration to iteration, zeroed where an episode starts (`restarted`); the update unrolls each
  env's sequence again from the rollout's first memory, so its log-probabilities are the rollout's before the first
  step, and minibatches are groups of whole env sequences;
* a communicating one reads a `Channel`: at every decision the mask of the deliveries that happen (`delivered`,
  stored with the rollout and replayed by the update), drawn from a generator of its own so that the actions are
  those of an unperturbed run; a TarMAC actor's messages (`memory[2]`, `heard`) are read by the critic too.

Rewards are team rewards repeated to every agent, or each agent's own (an env whose `credit` is not 'team': the
critic on the state then has one head per agent). Values are learned on normalised returns; a horizon cut's reward
gets the critic's value of the last observation (`bootstrapped`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Protocol

import torch
from torch import nn

from ..policies.checkpoint import CheckpointError
from ..policies.comm import Channel, channel_difference
from ..policies.device import resolve_device, update_threads
from ..policies.networks import Critic, restarted
from ..policies.policy import make_actor
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
from ..policies.spec import PolicySpec

__all__ = ['Auxiliary', 'Rollout', 'critic_input_dim', 'critic_inputs', 'critic_outputs', 'heard', 'per_agent',
           'train']

PPO_STATS = ('policy_loss', 'value_loss', 'entropy', 'approx_kl', 'clip_fraction')
"""The loss terms every PPO iteration logs (means over its minibatch updates)."""


# ============================================================================ the critic's view

def critic_inputs(critic: str, obs: torch.Tensor, state: torch.Tensor, messages: torch.Tensor | None = None):
    """What the critic reads: the global state (..., S) for MAPPO (one value per env: the reward is shared, so
    every agent's value is the same, as in the paper's critic), the local observations (..., N, D) for IPPO (one
    value per agent), both for MAPPO-AS, `critic='agent'`: the state with each agent's own observation appended
    (..., N, S + D), one value per agent (the agent-specific global state of Yu et al. 2022, "The Surprising
    Effectiveness of PPO in Cooperative Multi-Agent Games"). TarMAC: `messages` (..., N, M), the N messages the
    agents read at the decision, flattened and appended (..., S + N M) or (..., N, D + N M)."""
    if critic == 'agent':
        inputs = torch.cat([state.unsqueeze(-2).expand(*obs.shape[:-1], state.shape[-1]), obs], dim=-1)
    else:
        inputs = obs if critic == 'local' else state
    if messages is None:
        return inputs
    flat = messages.flatten(-2)
    if critic != 'state':
        flat = flat.unsqueeze(-2).expand(*obs.shape[:-1], flat.shape[-1])
    return torch.cat([inputs, flat], dim=-1)


def critic_input_dim(critic: str, obs_dim: int, state_dim: int, messages_dim: int = 0) -> int:
    """Size of `critic_inputs`; `messages_dim`: N x M for a TarMAC critic, else 0."""
    return {'state': state_dim, 'local': obs_dim, 'agent': state_dim + obs_dim}[critic] + messages_dim


def critic_outputs(critic: str, num_agents: int, per_agent_rewards: bool) -> int:
    """Values per critic input: N heads for MAPPO's critic on the state when each agent has its own reward (one
    state, N returns), else 1 (a team value, or one value per agent row for IPPO and MAPPO-AS)."""
    return num_agents if per_agent_rewards and critic == 'state' else 1


def per_agent(critic: str, values: torch.Tensor, num_agents: int, shared: bool = True) -> torch.Tensor:
    """Critic outputs -> (..., N): (...,) per env (MAPPO, a `shared` team value) repeated to every agent; (..., N)
    per agent (IPPO, MAPPO-AS, or MAPPO's per-agent heads when `shared` is false) unchanged."""
    return values if critic != 'state' or not shared else values.unsqueeze(-1).expand(*values.shape, num_agents)


def heard(actor: nn.Module, memory: tuple) -> torch.Tensor | None:
    """The messages (..., N, M) the agents read at a decision, which the critic reads too: a TarMAC actor's
    (`memory[2]`, its `heard_size` M > 0); None for an actor whose messages the critic does not read."""
    return memory[2] if getattr(actor, 'heard_size', 0) else None


# ============================================================================ an algorithm's own terms

@dataclasses.dataclass(frozen=True)
class Rollout:
    """One iteration's rollout as the update reads it, flattened to T x B rows (t-major): `obs` (T B, N, D),
    `state` (T B, S), `actions` (T B, N, H), `returns` (T B, N, normalised); the `generator` of the run's draws."""

    obs: torch.Tensor
    state: torch.Tensor
    actions: torch.Tensor
    returns: torch.Tensor
    generator: torch.Generator


class Auxiliary(Protocol):
    """Modules and losses an algorithm adds to PPO's (I2C's training signals: `mate.learn.i2c.I2CSignals`): an
    `nn.Module` whose parameters join the optimiser (after the actor's and the critic's) and whose state joins the
    checkpoint (as `networks[name]`), with three hooks: `prepare(rollout)` once per iteration before the epochs (no
    gradient); per minibatch `terms(actor, logits, rows)` -> (loss terms added to PPO's, their values to log, named
    in `stats`); `log(actor)` -> the iteration's own log fields."""

    name: str
    stats: tuple[str, ...]

    def prepare(self, rollout: Rollout) -> None: ...

    def terms(self, actor: nn.Module, logits: torch.Tensor, rows: torch.Tensor) -> tuple[tuple, dict]: ...

    def log(self, actor: nn.Module) -> dict: ...


# ============================================================================ training

def train(config: PPOConfig, spec: PolicySpec, envs=None, callback=None, console=None, *, critic: str = 'state',
          channel: Channel | None = None, build_actor: Callable[[PolicySpec], nn.Module] = make_actor,
          auxiliary: Callable[[int, int, int], Auxiliary] | None = None) -> Run:
    """Train `spec`'s policy as `config` says (in `config.run_dir`, default runs/ALGO-TEAM-seedN); resume from its
    checkpoint unless `config.fresh` (one trained under another `channel` is refused). `envs` replaces the training
    envs (anything with `TrainingEnv`'s attributes, `spec` and reset/step; `positions()` with a channel's range
    limit: PSRO's mixtures, tests' toy tasks); `callback(row)` sees every log row.

    `critic`: what the critic reads (`critic_inputs`: 'state', 'local' or 'agent'); `channel`: the lossy channel a
    communicating actor trains under (`config.channel` its settings); `build_actor`: the actor of `spec` (default
    `make_actor`); `auxiliary(N, S, A)`: an algorithm's own modules and losses.
    Returns the `Run` (`last_row`, `interrupted`, counters)."""
    device = resolve_device(config.device)
    run = Run.of(config, config.algo, spec, callback, console)

    # ---- environments and the channel (which messages of a decision arrive; `delivered` None: all of them)
    envs = envs or config.make_env(spec)
    B, N, D, S = envs.num_envs, envs.num_agents, envs.obs_dim, envs.state_dim
    H, C = envs.action_heads, envs.action_choices                 # A = H x C logits per agent
    per_agent_rewards = getattr(envs, 'credit', 'team') != 'team'  # rewards (B, N): one critic value per agent
    if channel is not None and channel.range_limit is not None and not hasattr(envs, 'positions'):
        raise ValueError("--communication-range needs the agents' positions; this env has no positions()")

    def delivered_now():   # (B, N, N) bool masks of this decision, or None
        positions = envs.positions() if channel.range_limit is not None else None
        delivered = channel.delivered((B, N), positions, channel_generator)
        return None if delivered is None else delivered.to(device)

    # ---- networks and optimiser (initialised on one thread: the orthogonal initialisation's QR differs with threads)
    torch.set_num_threads(1)
    torch.manual_seed(config.seed)
    actor = build_actor(spec).to(device)
    recurrent = bool(getattr(actor, 'recurrent', False))
    M = getattr(actor, 'heard_size', 0)                            # messages the critic reads (TarMAC), or 0
    value_net = Critic(critic_input_dim(critic, D, S, N * M), config.hidden, config.activation,
                       outputs=critic_outputs(critic, N, per_agent_rewards)).to(device)
    value_norm = ValueNormalizer().to(device)
    extra = auxiliary(N, S, C).to(device) if auxiliary is not None else None
    learned = [*actor.parameters(), *value_net.parameters(), *(extra.parameters() if extra is not None else ())]
    optimizer = torch.optim.Adam(learned, lr=config.lr_schedule[0][1], eps=1e-5)
    schedules, kl_coeff = Schedules(config), config.kl_coeff       # kl_coeff adapts every iteration
    generator = torch.Generator(device).manual_seed(config.seed * 1_000_003)
    channel_generator = torch.Generator().manual_seed(config.seed * 1_000_003 + 500_009)   # the masks' own draws
    modules = {'actor': actor, 'critic': value_net, 'value_norm': value_norm,
               **({extra.name: extra} if extra is not None else {})}
    memory = tuple(part.to(device) for part in actor.initial_state(B, N)) if recurrent else ()  # carried on
    starting = torch.ones(B, dtype=torch.bool, device=device)     # the env's next decision opens an episode
    saved = run.resume()
    if saved is not None:
        difference = channel_difference(saved['channel'], config.channel) if channel is not None else None
        if difference:
            raise CheckpointError(f'checkpoint {str(run.checkpoint_path)!r} does not match this experiment: '
                                  f'{difference}')
        for name, module in modules.items():
            module.load_state_dict(saved['networks'][name])
        optimizer.load_state_dict(saved['optimizer'])
        kl_coeff = float(saved['kl_coeff'])
        generator.set_state(saved['generator'])
        if channel is not None:
            channel_generator.set_state(saved['channel_generator'])
        if recurrent:
            memory = tuple(part.to(device) for part in saved['memory'])
            if run.continues_episodes(saved):     # else the envs are reset: every episode starts, memory zeroed
                starting = saved['starting'].to(device)
    elif config.init_from:
        warm_start(config.init_from, spec, actor, dict(critic=value_net, value_norm=value_norm), config.algo,
                   config.credit)
    # the envs' arrays: numpy on the host (`TrainingEnv`), or torch tensors where the games run on a device
    # (`TrainingEnv.tensors`: nothing crosses to the host but the decision's episode records)
    to_envs = (lambda x: x) if getattr(envs, 'tensors', False) else (lambda x: x.cpu().numpy())
    here = lambda x: torch.as_tensor(x, device=device)   # noqa: E731  (numpy: no copy on the CPU)
    obs, state = map(here, run.first_observations(envs, saved))
    masking = config.mask_invisible and spec.hrl

    def allowed_of(obs_t):   # (..., N, H, C) choices the policy may take, or None (all)
        return here(envs.allowed_actions(to_envs(obs_t))) if masking else None

    def values_of(obs_t, state_t, messages_t=None):   # (..., N) values of every agent, in return units
        inputs = critic_inputs(critic, obs_t, state_t, messages_t)
        return per_agent(critic, value_norm.denormalize(value_net(inputs)), N, shared=not per_agent_rewards)

    def run_state() -> dict:   # everything the run's future depends on (exact resume), an actor's memory included
        return dict(networks={name: module.state_dict() for name, module in modules.items()},
                    optimizer=optimizer.state_dict(), kl_coeff=kl_coeff, generator=generator.get_state(),
                    **(dict(channel_generator=channel_generator.get_state(), channel=config.channel)
                       if channel is not None else {}),
                    **(dict(memory=list(memory), starting=starting) if recurrent else {}),
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
    message_buf = torch.zeros(T, B, N, M, device=device) if M else None   # the messages read at each decision
    delivered_buf = torch.ones(T, B, N, N, dtype=torch.bool, device=device) \
        if channel is not None and channel.active else None
    learn_threads = update_threads(config)

    with run:
        while run.running():
            lr, entropy_coef = schedules.apply(optimizer, run.env_steps)

            # ---- collect (one torch thread: the vector env runs its own threads)
            torch.set_num_threads(1)
            coverage, episodes = [], []
            t_collect = time.perf_counter()
            memory_at_start = memory                  # a recurrent update unrolls every sequence again from here
            for t in range(T):
                with torch.no_grad():
                    if recurrent:
                        memory = restarted(memory, starting)           # a new episode starts from zero memory
                        messages = heard(actor, memory)                # the messages the agents read now
                        delivered = delivered_now() if channel is not None else None   # the update replays it
                        if delivered is not None:
                            delivered_buf[t] = delivered
                        logits, memory = actor.step(obs, memory, **({} if channel is None else
                                                                     dict(delivered=delivered)))
                    else:
                        logits, messages = actor(obs), None
                    dist = action_distribution(logits, H, C, allowed_of(obs))
                    action = torch.multinomial(dist.probs.reshape(-1, C), 1, generator=generator).reshape(B, N, H)
                    value = values_of(obs, state, messages)
                chosen = to_envs(action)
                next_obs, next_state, reward, done, truncated, info = envs.step(chosen[..., 0] if H == 1 else chosen)
                reward = here(reward).float()
                reward = reward if per_agent_rewards else reward[:, None].expand(B, N)     # (B, N)
                if truncated.any():   # horizon cut: bootstrap from the critic's value of the last observation
                    with torch.no_grad():   # (TarMAC: with the messages just sent, which the next decision reads)
                        final = values_of(here(info['final_obs']), here(info['final_state']), heard(actor, memory))
                    final = final if per_agent_rewards else final.mean(-1, keepdim=True)   # (B, N) or (B, 1)
                    reward = bootstrapped(reward, truncated, final, config.gamma)
                done = here(done)
                obs_buf[t], state_buf[t], action_buf[t] = obs, state, action
                logp_buf[t], value_buf[t] = dist.log_prob(action).sum(-1), value
                reward_buf[t], done_buf[t] = reward, done.float()
                start_buf[t], starting = starting, done.clone()
                if message_buf is not None:
                    message_buf[t] = messages
                obs, state = here(next_obs), here(next_state)
                coverage.append(float(info['coverage'].mean()))
                episodes += info['episodes']
            collect_seconds = time.perf_counter() - t_collect

            # ---- advantages (per agent: the team reward repeated, or each agent's own)
            with torch.no_grad():
                last_values = values_of(obs, state, heard(actor, restarted(memory, starting)) if recurrent else None)
            b_adv, b_ret = learning_targets(reward_buf, value_buf, done_buf, last_values, value_norm, config.gamma,
                                            config.gae_lambda)    # (T * B, N) rows, as the other buffers' below

            # ---- learn: K epochs over shuffled minibatches of (decision, env) rows, all agents of a row together,
            # or (recurrent) of whole env sequences, each unrolled from its first memory
            torch.set_num_threads(learn_threads)
            flat = lambda x: x.reshape(T * B, *x.shape[2:])   # noqa: E731
            b_obs, b_state, b_action, b_logp = flat(obs_buf), flat(state_buf), flat(action_buf), flat(logp_buf)
            b_messages = flat(message_buf) if message_buf is not None else None
            if extra is not None:
                extra.prepare(Rollout(b_obs, b_state, b_action, b_ret, generator))

            def logits_of(rows):   # (len(rows), N, A)
                if not recurrent:
                    return actor(b_obs[rows])
                group = rows[:len(rows) // T]                        # the first len/T rows are the envs at t = 0
                first = tuple(part[group] for part in memory_at_start)
                replay = {} if channel is None else \
                    dict(delivered=None if delivered_buf is None else delivered_buf[:, group])   # the deliveries
                sequences = actor(obs_buf[:, group], first, start_buf[:, group], **replay)      # (T, envs, N, A)
                return sequences.reshape(-1, *sequences.shape[2:])

            stats = UpdateStats(*PPO_STATS, *(extra.stats if extra is not None else ()))
            for _ in range(config.epochs):
                for idx in minibatch_rows(T, B, config.minibatches, recurrent, generator):
                    logits = logits_of(idx)
                    dist = action_distribution(logits, H, C, allowed_of(b_obs[idx]))
                    inputs = critic_inputs(critic, b_obs[idx], b_state[idx],
                                           None if b_messages is None else b_messages[idx])
                    predicted = per_agent(critic, value_net(inputs), N, shared=not per_agent_rewards)
                    terms, logged = extra.terms(actor, logits, idx) if extra is not None else ((), {})
                    ppo_update(optimizer, learned, config, dist, b_action[idx], b_logp[idx], b_adv[idx], predicted,
                               b_ret[idx], entropy_coef, kl_coeff, stats, extra=terms)
                    stats.add(**logged)
            means = stats.means()
            row_kl_coeff = kl_coeff                     # the coefficient this iteration used
            if kl_coeff > 0:
                kl_coeff = adapt_kl_coeff(kl_coeff, means['approx_kl'], config.kl_target)

            # ---- log, keep the best policy, checkpoint
            run.end_iteration(T * B, coverage, episodes, dict(
                collect_share=collect_seconds / max(time.perf_counter() - t_collect, 1e-9), lr=lr,
                entropy_coef=entropy_coef, **means, **(extra.log(actor) if extra is not None else {}),
                kl_coeff=row_kl_coeff), status=f"entropy {means['entropy']:.2f}",
                actor=actor.state_dict,
                save=run_state)
    run.finish(run_state(), actor.state_dict())
    return run
