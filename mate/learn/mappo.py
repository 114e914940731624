"""MAPPO and IPPO for MATE, feed-forward, in one file that reads top to bottom (`mate train mappo|ippo`).

    config  ->  PolicySpec (what the policy sees and does)  ->  batched training envs (`TeamVecEnv`: B games,
                the other team a batched opponent, the greedy rules by default)
            ->  networks: one actor shared by every agent of the team (full parameter sharing, as in the paper),
                a critic on the global state (MAPPO, `critic='state'`), on each agent's observation (IPPO,
                `critic='local'`) or on both (MAPPO with the agent-specific global state, `critic='agent'`)
            ->  loop: collect T decisions x B envs x N agents, GAE, K epochs of clipped PPO on minibatches
            ->  `Run`: logs (progress line, CSV, TensorBoard when installed), checkpoints, best.pt, final.pt

The actor's output is one or more independent categorical choices (`action_distribution`): one of 25 grid moves,
or one keep/ignore bit per target slot for HRL cameras (`--hrl`, the paper's hierarchical cameras), whose rule executor runs
inside the env. Rewards are team rewards, repeated to every agent, or each camera's own share of the coverage
(`--credit difference`; MAPPO's critic then gives one value per agent). Values are learned on normalised returns
(running mean/std, "value normalisation"). The recurrent variant is `mappo_lstm.py`; with learned messages,
`tarmac.py` and `i2c.py`.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Literal

import torch

from ..options import option
from .device import resolve_device, update_threads
from .envs import TeamVecEnv
from .networks import Critic
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

__all__ = ['HRL_CAMERA_HIDDEN', 'MAPPOConfig', 'critic_input_dim', 'critic_inputs', 'critic_outputs', 'per_agent',
           'policy_spec', 'train']


HRL_CAMERA_HIDDEN = (64, 64)
"""The default widths of HRL cameras: at 1 M decisions on MATE-4v8-9 (3 seeds each) hidden layers of 64, 128 and
256 units cover alike on held-out episodes (0.605 / 0.607 / 0.604), and 64 trains 1.6x faster than 256 on 2 cores;
the targets learn faster with 256 (docs/training.md, "Network width")."""


@dataclasses.dataclass
class MAPPOConfig(PPOConfig):
    """Settings of a feed-forward MAPPO / IPPO / MAPPO-AS run (`train(config)`, `mate train mappo|ippo|mappo-as`)."""

    critic: Literal['state', 'local', 'agent'] = option('state', "the critic's input: the global state (MAPPO), each "
                                                                 "agent's observation (IPPO), or the global state with "
                                                                 "each agent's observation appended (MAPPO-AS)")
    actor: Literal['mlp', 'per-target'] | None = option(None, "policy network: 'mlp' (the paper's) or, for cameras, "
                                                              "'per-target' (one shared scorer per target slot); None: "
                                                              'per-target for cameras, mlp for targets')

    hidden: tuple[int, ...] | None = option(None, 'hidden layer widths of the actor and the critic; None: 64 64 for '
                                                  'HRL cameras, 256 256 otherwise (the width study, docs/training.md)',
                                            minimum=1)

    def __post_init__(self) -> None:
        if self.hidden is None:
            object.__setattr__(self, 'hidden', HRL_CAMERA_HIDDEN if self.hrl and self.team == 'camera' else (256, 256))
        super().__post_init__()
        if self.actor == 'per-target' and self.team != 'camera':
            raise ValueError("--actor per-target reads a camera's target slots; it needs --team camera")

    @property
    def algo(self) -> str:
        return {'state': 'mappo', 'local': 'ippo', 'agent': 'mappo-as'}[self.critic]


MAPPOConfig.PRESETS = {'paper': (PAPER_HELP + "; the paper's MLP actor", dict(PAPER_HYPERPARAMETERS, actor='mlp'))}


def policy_spec(config: MAPPOConfig, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains; with `envs` given, what they say the policy sees and does (their
    `spec`: PSRO's envs, the tests' toy tasks) with this config's network."""
    actor = config.actor or ('per-target' if config.team == 'camera' else 'mlp')
    network = dict(network=actor, hidden=config.hidden, activation=config.activation, lstm=0, algo=config.algo)
    if envs is not None:
        return envs.spec.replace(**network)
    return config.policy_spec(action='hrl' if config.hrl else 'grid', **network)


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


# ============================================================================ training

def train(config: MAPPOConfig, envs: TeamVecEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/ALGO-TEAM-seedN); resume from its checkpoint
    unless `config.fresh`. `envs` replaces the training envs (anything with `TeamVecEnv`'s attributes, `spec`
    and reset/step: PSRO's mixtures, tests' toy tasks); `callback(row)` sees every log row. Returns the `Run`
    (`last_row`, `interrupted`, counters)."""
    device = resolve_device(config.device)
    spec = policy_spec(config, envs)
    run = Run.of(config, config.algo, spec, callback, console)

    # ---- environments
    envs = envs or config.make_env(spec)
    B, N, D, S = envs.num_envs, envs.num_agents, envs.obs_dim, envs.state_dim
    H, C = envs.action_heads, envs.action_choices                 # A = H x C logits per agent
    per_agent_rewards = getattr(envs, 'credit', 'team') != 'team'  # rewards (B, N): one critic value per agent

    # ---- networks and optimiser (initialised on one thread: the orthogonal initialisation's QR differs with threads)
    torch.set_num_threads(1)
    torch.manual_seed(config.seed)
    actor = make_actor(spec).to(device)
    critic = Critic(critic_input_dim(config.critic, D, S), config.hidden, config.activation,
                    outputs=critic_outputs(config.critic, N, per_agent_rewards)).to(device)
    value_norm = ValueNormalizer().to(device)
    learned = [*actor.parameters(), *critic.parameters()]
    optimizer = torch.optim.Adam(learned, lr=config.lr_schedule[0][1], eps=1e-5)
    schedules, kl_coeff = Schedules(config), config.kl_coeff       # kl_coeff adapts every iteration
    generator = torch.Generator(device).manual_seed(config.seed * 1_000_003)
    saved = run.resume()
    if saved is not None:
        for module, name in ((actor, 'actor'), (critic, 'critic'), (value_norm, 'value_norm')):
            module.load_state_dict(saved['networks'][name])
        optimizer.load_state_dict(saved['optimizer'])
        kl_coeff = float(saved['kl_coeff'])
        generator.set_state(saved['generator'])
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

    def run_state() -> dict:   # everything the run's future depends on (exact resume)
        return dict(networks=networks(), optimizer=optimizer.state_dict(), kl_coeff=kl_coeff,
                    generator=generator.get_state(),
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
    learn_threads = update_threads(config)

    with run:
        while run.running():
            lr, entropy_coef = schedules.apply(optimizer, run.env_steps)

            # ---- collect (one torch thread: the vector env runs its own threads)
            torch.set_num_threads(1)
            coverage, episodes = [], []
            t_collect = time.perf_counter()
            for t in range(T):
                with torch.no_grad():
                    dist = action_distribution(actor(obs), H, C, allowed_of(obs))
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
                obs_buf[t], state_buf[t], action_buf[t] = obs, state, action
                logp_buf[t], value_buf[t] = dist.log_prob(action).sum(-1), value
                reward_buf[t], done_buf[t] = reward, torch.from_numpy(done).float().to(device)
                obs, state = torch.from_numpy(next_obs).to(device), torch.from_numpy(next_state).to(device)
                coverage.append(float(info['coverage'].mean()))
                episodes += info['episodes']
            collect_seconds = time.perf_counter() - t_collect

            # ---- advantages (per agent: the team reward repeated, or each agent's own)
            with torch.no_grad():
                last_values = values_of(obs, state)
            b_adv, b_ret = learning_targets(reward_buf, value_buf, done_buf, last_values, value_norm, config.gamma,
                                            config.gae_lambda)    # (T * B, N) rows, as the other buffers' below

            # ---- learn: K epochs over shuffled minibatches of (decision, env) rows, all agents of a row together
            torch.set_num_threads(learn_threads)
            flat = lambda x: x.reshape(T * B, *x.shape[2:])   # noqa: E731
            b_obs, b_state, b_action, b_logp = flat(obs_buf), flat(state_buf), flat(action_buf), flat(logp_buf)
            stats = UpdateStats('policy_loss', 'value_loss', 'entropy', 'approx_kl', 'clip_fraction')
            for _ in range(config.epochs):
                for idx in minibatch_rows(T, B, config.minibatches, False, generator):
                    dist = action_distribution(actor(b_obs[idx]), H, C, allowed_of(b_obs[idx]))
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
