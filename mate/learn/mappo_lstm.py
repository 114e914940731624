"""Recurrent MAPPO and IPPO for MATE: the paper's actor, MLP -> LSTM -> head, in one file (`mate train mappo-lstm`).

    config  ->  PolicySpec (the 'mlp' or 'per-target' network with an LSTM of `lstm` cells)  ->  `TeamVecEnv`
            ->  networks: one recurrent actor shared by the team (`RecurrentActor`: the feed-forward actor's body, an
                LSTM, the head on [body features, LSTM output]), a feed-forward critic on the global state (MAPPO,
                `critic='state'`), on each agent's observation (IPPO, `critic='local'`) or on both (MAPPO-AS,
                `critic='agent'`, as `mappo.py`)
            ->  loop: collect T decisions x B envs x N agents, the actor carrying its memory from decision to decision
                (and from iteration to iteration), GAE, K epochs of clipped PPO on minibatches of whole env sequences
            ->  `Run`: logs, checkpoints, best.pt, final.pt

The actor's memory (h, c) (B, N, lstm) starts at zero where an episode starts: `starting` (B,) flags the envs whose
next decision opens an episode (every env at a run's start, then those that were done), and each decision first
zeroes their memory (`restarted`). The rollout keeps the memory it began with (before that zeroing) and the flags of
every decision (`start_buf`); a minibatch is a group of envs with all their T decisions, and the update unrolls each
sequence again from its first memory, zeroing the same rows at the same decisions (`RecurrentActor.forward`), so that
its log-probabilities are those of the rollout before the first step (KL 0). The gradient flows through the T
decisions of the rollout, not into the iterations before it (truncated backpropagation through time). The memory and
the flags outlive the iteration: the next rollout continues the episodes where this one stopped.

Everything else is feed-forward MAPPO's (`mappo.py`): the action distribution (grid moves or HRL keep/ignore bits),
team or per-agent rewards, value normalisation, horizon cuts bootstrapped from the critic.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Literal

import torch

from ..options import option
from .device import resolve_device, update_threads
from .envs import TeamVecEnv
from .mappo import critic_input_dim, critic_inputs, critic_outputs, per_agent
from .networks import Critic, restarted
from .policy import make_actor
from .ppo import (
    PAPER_HELP,
    PAPER_HYPERPARAMETERS,
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

__all__ = ['RecurrentConfig', 'policy_spec', 'train']


@dataclasses.dataclass
class RecurrentConfig(PPOConfig):
    """Settings of a recurrent MAPPO / IPPO run (`train(config)`, `mate train mappo-lstm`)."""

    critic: Literal['state', 'local', 'agent'] = option('state', "the critic's input: the global state (MAPPO), each "
                                                                 "agent's observation (IPPO) or the state with each "
                                                                 "agent's observation appended (MAPPO-AS)")
    actor: Literal['mlp', 'per-target'] | None = option(None, "the body and head around the LSTM: 'mlp' (the paper's) "
                                                              "or, for cameras, 'per-target' (one shared scorer per "
                                                              'target slot); None: per-target for cameras, mlp for '
                                                              'targets')
    lstm: int = option(256, "LSTM cells of the actor (the paper's 256)", minimum=1)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.actor == 'per-target' and self.team != 'camera':
            raise ValueError("--actor per-target reads a camera's target slots; it needs --team camera")

    @property
    def algo(self) -> str:
        return {'state': 'mappo-lstm', 'local': 'ippo-lstm', 'agent': 'mappo-as-lstm'}[self.critic]


RecurrentConfig.PRESETS = {'paper': (PAPER_HELP + "; the paper's MLP actor",
                                     dict(PAPER_HYPERPARAMETERS, actor='mlp'))}


def policy_spec(config: RecurrentConfig, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains; with `envs` given, what they say the policy sees and does (their
    `spec`) with this config's network."""
    actor = config.actor or ('per-target' if config.team == 'camera' else 'mlp')
    network = dict(network=actor, hidden=config.hidden, activation=config.activation, lstm=config.lstm,
                   algo=config.algo)
    if envs is not None:
        return envs.spec.replace(**network)
    return config.policy_spec(action='hrl' if config.hrl else 'grid', **network)


# ============================================================================ training

def train(config: RecurrentConfig, envs: TeamVecEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/ALGO-TEAM-seedN); resume from its checkpoint
    unless `config.fresh`. `envs` replaces the training envs (anything with `TeamVecEnv`'s attributes, `spec`
    and reset/step); `callback(row)` sees every log row. Returns the `Run`."""
    device = resolve_device(config.device)
    spec = policy_spec(config, envs)
    run = Run.of(config, config.algo, spec, callback, console)

    # ---- environments
    envs = envs or config.make_env(spec)
    B, N, D, S = envs.num_envs, envs.num_agents, envs.obs_dim, envs.state_dim
    H, C = envs.action_heads, envs.action_choices                 # A = H x C logits per agent
    per_agent_rewards = getattr(envs, 'credit', 'team') != 'team'  # rewards (B, N): one critic value per agent

    # ---- networks, optimiser, the actor's memory
    threads = update_threads(config)          # torch threads of the updates and of the initialisation, whose
    torch.set_num_threads(threads)           # orthogonal matrices (QR) depend on the thread count
    torch.manual_seed(config.seed)
    actor = make_actor(spec).to(device)                            # a `RecurrentActor`
    critic = Critic(critic_input_dim(config.critic, D, S), config.hidden, config.activation,
                    outputs=critic_outputs(config.critic, N, per_agent_rewards)).to(device)
    value_norm = ValueNormalizer().to(device)
    learned = [*actor.parameters(), *critic.parameters()]
    optimizer = torch.optim.Adam(learned, lr=config.lr_schedule[0][1], eps=1e-5)
    schedules, kl_coeff = Schedules(config), config.kl_coeff       # kl_coeff adapts every iteration
    generator = torch.Generator(device).manual_seed(config.seed * 1_000_003)
    memory = tuple(part.to(device) for part in actor.initial_state(B, N))   # (h, c), carried across iterations
    starting = torch.ones(B, dtype=torch.bool, device=device)     # the env's next decision opens an episode
    saved = run.resume()
    if saved is not None:
        for module, name in ((actor, 'actor'), (critic, 'critic'), (value_norm, 'value_norm')):
            module.load_state_dict(saved['networks'][name])
        optimizer.load_state_dict(saved['optimizer'])
        kl_coeff = float(saved['kl_coeff'])
        generator.set_state(saved['generator'])
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

    def values_of(obs_t, state_t):   # (..., N) values of every agent, in return units
        inputs = critic_inputs(config.critic, obs_t, state_t)
        return per_agent(config.critic, value_norm.denormalize(critic(inputs)), N, shared=not per_agent_rewards)

    def networks() -> dict:
        return dict(actor=actor.state_dict(), critic=critic.state_dict(), value_norm=value_norm.state_dict())

    def run_state() -> dict:   # everything the run's future depends on (exact resume), the actor's memory included
        return dict(networks=networks(), optimizer=optimizer.state_dict(), kl_coeff=kl_coeff,
                    generator=generator.get_state(), memory=list(memory), starting=starting,
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
                    logits, memory = actor.step(obs, memory)
                    dist = action_distribution(logits, H, C, allowed_of(obs))
                    action = torch.multinomial(dist.probs.reshape(-1, C), 1, generator=generator).reshape(B, N, H)
                    value = values_of(obs, state)
                chosen = action.cpu().numpy()
                next_obs, next_state, reward, done, truncated, info = envs.step(chosen[..., 0] if H == 1 else chosen)
                reward = torch.from_numpy(reward).float().to(device)
                reward = reward if per_agent_rewards else reward[:, None].expand(B, N)     # (B, N)
                if truncated.any():   # horizon cut: bootstrap from the critic's value of the last observation
                    with torch.no_grad():
                        final = values_of(torch.from_numpy(info['final_obs']).to(device),
                                          torch.from_numpy(info['final_state']).to(device))
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
                last_values = values_of(obs, state)
            b_adv, b_ret = learning_targets(reward_buf, value_buf, done_buf, last_values, value_norm, config.gamma,
                                            config.gae_lambda)    # (T * B, N) rows, as the other buffers' below

            # ---- learn: K epochs over minibatches of whole env sequences, each unrolled from its first memory
            torch.set_num_threads(threads)
            flat = lambda x: x.reshape(T * B, *x.shape[2:])   # noqa: E731
            b_obs, b_state, b_action, b_logp = flat(obs_buf), flat(state_buf), flat(action_buf), flat(logp_buf)

            def logits_of(rows):   # (len(rows), N, A): rows t * B + b of a group of envs, t-major
                group = rows[:len(rows) // T]                        # the first len/T rows are the envs at t = 0
                first = tuple(part[group] for part in memory_at_start)
                sequences = actor(obs_buf[:, group], first, start_buf[:, group])      # (T, envs, N, A)
                return sequences.reshape(-1, *sequences.shape[2:])

            stats = UpdateStats('policy_loss', 'value_loss', 'entropy', 'approx_kl', 'clip_fraction')
            for _ in range(config.epochs):
                for idx in minibatch_rows(T, B, config.minibatches, True, generator):
                    dist = action_distribution(logits_of(idx), H, C, allowed_of(b_obs[idx]))
                    predicted = per_agent(config.critic, critic(critic_inputs(config.critic, b_obs[idx], b_state[idx])),
                                          N, shared=not per_agent_rewards)
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
