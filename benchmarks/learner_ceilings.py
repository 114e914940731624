"""Ceilings of the slow learners' networks: what their learning step costs in a tight loop, beside what the
trainer spends on it (issue 68, docs/performance.md "The learners' speed").

    python benchmarks/learner_ceilings.py [--only NAME ...] [--threads 1] [--repeat 5] [--bf16] [--json FILE]

For every setting of `benchmarks/trainers.py` that is not feed-forward PPO this builds the trainer's own networks
(its default config and spec: `make_actor`, the critics, I2C's training signals, the mixer, the twin critics) and
runs, on random inputs of the shapes the trainer feeds them, the work one *unit* of training does:

* PPO learners (MAPPO-LSTM, TarMAC, I2C): one iteration's learning (64 envs x 25 decisions = 1,600): I2C's
  once-per-iteration labels and regulariser targets, then 4 epochs x 4 minibatches of 16 whole env sequences,
  each forward (the actor unrolled over the 25 decisions, the critic), backward and Adam step;
* off-policy learners (IQL, QMIX, MA-TD3): one update (a batch of 1,024; QMIX: 41 chunks of 26 observations)
  and the acting of the 128 decisions between two updates (8 batched forward passes of 16 envs).

It prints, per setting: the seconds per unit (best of `--repeat` rounds, after a warm-up round; on one thread the
process's CPU time, which is the wall time of a quiet machine and less noisy than it on a shared one; on more
threads the wall time), the decisions per second that this alone allows (the ceiling of a trainer that spent
nothing else), the matrix FLOPs per unit (`torch.utils.flop_counter`: matrix products forward and backward, counted
with oneDNN off so that the fused LSTM shows its products) and the rate they run at, and the rate of one large
single-precision matrix product on the same threads (`sgemm`), the machine's reference. `--bf16` runs the units
under CPU autocast to bfloat16: a prototype of what lower precision would buy, not what any trainer does.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from pathlib import Path

import mate  # noqa: F401  (first: it pins the kernels when MATE_REPRODUCIBLE asks)

import torch  # noqa: E402
from torch import nn  # noqa: E402
from torch.utils.flop_counter import FlopCounterMode  # noqa: E402

SETTINGS = ('mappo-lstm-target', 'tarmac-target', 'i2c-target', 'iql-hrl-camera', 'qmix-hrl-camera', 'iql-target',
            'matd3-target', 'matd3-camera')


def sgemm_rate(threads: int, size: int = 1024, repeat: int = 20) -> float:
    """GFLOP/s of a (size x size) @ (size x size) float32 product on `threads` threads (best of `repeat`)."""
    torch.set_num_threads(threads)
    a, b = torch.randn(size, size), torch.randn(size, size)
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        a @ b
        best = min(best, time.perf_counter() - start)
    return 2 * size ** 3 / best / 1e9


# ============================================================================ the units of training

def ppo_unit(name: str):
    """(work, decisions): one PPO iteration's learning on random rollouts of the trainer's shapes."""
    from mate.learn import ppo_loop
    from mate.learn.i2c import I2CConfig, I2CSignals
    from mate.learn.i2c import policy_spec as i2c_spec
    from mate.learn.mappo_lstm import RecurrentConfig
    from mate.learn.mappo_lstm import policy_spec as lstm_spec
    from mate.policies.networks import Critic
    from mate.policies.policy import make_actor
    from mate.learn.ppo import UpdateStats, action_distribution, minibatch_rows, ppo_update
    from mate.learn.tarmac import TarMACConfig
    from mate.learn.tarmac import policy_spec as tarmac_spec

    config = {'mappo-lstm-target': lambda: RecurrentConfig(team='target', actor='mlp'),
              'tarmac-target': lambda: TarMACConfig(team='target'),
              'i2c-target': lambda: I2CConfig(team='target')}[name]()
    spec = {'mappo-lstm-target': lstm_spec, 'tarmac-target': tarmac_spec, 'i2c-target': i2c_spec}[name](config)
    torch.manual_seed(0)
    T, B, N, D, S = config.rollout_length, config.num_envs, spec.num_agents, spec.obs_dim, spec.state_dim
    H, C = spec.heads, spec.choices
    actor = make_actor(spec)
    M = getattr(actor, 'heard_size', 0)
    critic = Critic(ppo_loop.critic_input_dim('state', D, S, N * M), config.hidden, config.activation)
    extra = (I2CSignals(N, S, C, config.hidden, config.activation, config.influence_samples)
             if name == 'i2c-target' else None)
    learned = [*actor.parameters(), *critic.parameters(), *(extra.parameters() if extra is not None else ())]
    optimizer = torch.optim.Adam(learned, lr=1e-4, eps=1e-5)
    generator = torch.Generator().manual_seed(0)
    obs = torch.rand(T, B, N, D) * 2 - 1
    state = torch.rand(T, B, S) * 2 - 1
    actions = torch.randint(C, (T, B, N, H))
    starts = torch.rand(T, B) < spec.frame_skip / config.resolved_horizon   # episode starts at the game's rate
    memory = tuple(torch.randn_like(part) * 0.1 for part in actor.initial_state(B, N))
    messages = torch.rand(T, B, N, M) if M else None
    with torch.no_grad():
        old_logp = action_distribution(actor(obs, memory, starts), H, C).log_prob(actions).sum(-1)
    flat = lambda x: x.reshape(T * B, *x.shape[2:])   # noqa: E731
    b_obs, b_state, b_action, b_logp = flat(obs), flat(state), flat(actions), flat(old_logp)
    b_adv, b_ret = torch.randn(T * B, N), torch.randn(T * B, N)
    b_messages = flat(messages) if M else None

    def work():
        if extra is not None:
            extra.prepare(ppo_loop.Rollout(b_obs, b_state, b_action, b_ret, generator))
        stats = UpdateStats(*ppo_loop.PPO_STATS, *(extra.stats if extra is not None else ()))
        for _ in range(config.epochs):
            for rows in minibatch_rows(T, B, config.minibatches, True, generator):
                group = rows[:len(rows) // T]
                first = tuple(part[group] for part in memory)
                logits = actor(obs[:, group], first, starts[:, group]).reshape(len(rows), N, -1)
                dist = action_distribution(logits, H, C)
                inputs = ppo_loop.critic_inputs('state', b_obs[rows], b_state[rows],
                                                None if b_messages is None else b_messages[rows])
                predicted = ppo_loop.per_agent('state', critic(inputs), N)
                terms, logged = extra.terms(actor, logits, rows) if extra is not None else ((), {})
                ppo_update(optimizer, learned, config, dist, b_action[rows], b_logp[rows], b_adv[rows], predicted,
                           b_ret[rows], 0.01, 0.0, stats, extra=terms)
    return work, T * B


def offpolicy_unit(name: str):
    """(work, decisions): one off-policy update and the acting between two updates, random data."""
    from mate.policies.policy import make_actor

    torch.manual_seed(0)
    if name.startswith('iql'):
        from mate.learn.iql import IQLConfig, iql_loss
        from mate.learn.iql import policy_spec as iql_spec

        config = IQLConfig(hrl=True) if name == 'iql-hrl-camera' else IQLConfig(team='target')
        spec = iql_spec(config)
        N, D, H, C, K = spec.num_agents, spec.obs_dim, spec.heads, spec.choices, config.batch_size
        q_net = make_actor(spec)
        target = make_actor(spec).requires_grad_(False)
        optimizer = torch.optim.Adam(q_net.parameters(), lr=5e-4, eps=1e-8)
        acting = torch.rand(config.num_envs, N, D) * 2 - 1
        allowed = torch.rand(K, H, C) < 0.5 if spec.hrl else None
        if allowed is not None:
            allowed[..., 0] = True
        batch = dict(obs=torch.rand(K, D) * 2 - 1, next_obs=torch.rand(K, D) * 2 - 1, action=torch.randint(C, (K, H)),
                     reward=torch.randn(K), terminal=torch.zeros(K))

        def work():
            for _ in range(config.update_every // config.num_envs):
                with torch.no_grad():
                    q_net(acting)
            loss, _ = iql_loss(q_net, target, batch, config.gamma, H, allowed)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
        return work, config.update_every
    if name.startswith('qmix'):
        from mate.learn.qmix import QMIXConfig, QMixer, qmix_loss
        from mate.learn.qmix import policy_spec as qmix_spec

        config = QMIXConfig(hrl=True)
        spec = qmix_spec(config)
        N, D, S, H, C = spec.num_agents, spec.obs_dim, spec.state_dim, spec.heads, spec.choices
        L, K = config.sequence_length, math.ceil(config.batch_size / config.sequence_length)
        q_net, target = make_actor(spec), make_actor(spec).requires_grad_(False)
        mixer, target_mixer = QMixer(S, N, config.mixer_embed), QMixer(S, N, config.mixer_embed).requires_grad_(False)
        learned = [*q_net.parameters(), *mixer.parameters()]
        optimizer = torch.optim.RMSprop(learned, lr=1e-4, alpha=0.99, eps=1e-5)
        acting, hidden = torch.rand(config.num_envs, N, D) * 2 - 1, torch.zeros(config.num_envs, N, q_net.width)
        allowed = torch.rand(L, K, N, H, C) < 0.5
        allowed[..., 0] = True
        batch = dict(obs=torch.rand(K, L + 1, N, D) * 2 - 1, state=torch.rand(K, L + 1, S) * 2 - 1,
                     action=torch.randint(C, (K, L, N, H)), reward=torch.randn(K, L), terminal=torch.zeros(K, L),
                     mask=torch.ones(K, L), h0=torch.randn(K, N, q_net.width) * 0.1)

        def work():
            for _ in range(config.update_every // config.num_envs):
                with torch.no_grad():
                    q_net.step(acting, (hidden,))
            loss, _ = qmix_loss(q_net, target, mixer, target_mixer, batch, config.gamma, H, allowed)
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(learned, 1000.0)
            optimizer.step()
        return work, config.update_every
    from mate.learn.matd3 import MATD3Config, TwinCritics, actor_inputs, critic_inputs, critic_targets, smoothed_actions
    from mate.learn.matd3 import policy_spec as td3_spec

    config = MATD3Config(team='target' if name == 'matd3-target' else 'camera')
    spec = td3_spec(config)
    N, D, S, A, K = spec.num_agents, spec.obs_dim, spec.state_dim, spec.num_actions, config.batch_size
    actor, target_actor = make_actor(spec), make_actor(spec).requires_grad_(False)
    critics = TwinCritics(N, S + N * A, config.hidden, config.activation)
    target_critics = TwinCritics(N, S + N * A, config.hidden, config.activation).requires_grad_(False)
    actor_optimizer = torch.optim.Adam(actor.parameters(), lr=1e-4)
    critic_optimizer = torch.optim.Adam(critics.parameters(), lr=1e-4)
    acting = torch.rand(config.num_envs, N, D) * 2 - 1
    batch = dict(obs=torch.rand(K, N, D) * 2 - 1, state=torch.rand(K, S) * 2 - 1, action=torch.rand(K, N, A) * 2 - 1,
                 reward=torch.randn(K, N), next_obs=torch.rand(K, N, D) * 2 - 1, next_state=torch.rand(K, S) * 2 - 1,
                 terminal=torch.zeros(K))
    updates = [0]

    def work():   # as matd3.train's update (the acting phase past the uniform steps)
        for _ in range(config.update_every // config.num_envs):
            with torch.no_grad():
                actor(acting)
        with torch.no_grad():
            next_action = smoothed_actions(target_actor(batch['next_obs']),
                                           config.target_noise * torch.randn(batch['action'].shape),
                                           config.target_noise_clip)
            next_q1, next_q2 = target_critics(critic_inputs(batch['next_state'], next_action))
            targets = critic_targets(batch['reward'], batch['terminal'], next_q1, next_q2, config.gamma)
        q1, q2 = critics(critic_inputs(batch['state'], batch['action']))
        critic_loss = nn.functional.huber_loss(q1, targets, delta=10.0) + nn.functional.huber_loss(q2, targets,
                                                                                                 delta=10.0)
        critic_optimizer.zero_grad()
        critic_loss.backward()
        critic_optimizer.step()
        updates[0] += 1
        if updates[0] % config.policy_delay == 0:
            actor_loss = -critics.q1(actor_inputs(batch['state'], batch['action'], actor(batch['obs']))).mean()
            actor_optimizer.zero_grad()
            actor_loss.backward()
            actor_optimizer.step()
        with torch.no_grad():
            for net, target in ((actor, target_actor), (critics, target_critics)):
                for p, p_target in zip(net.parameters(), target.parameters()):
                    p_target.lerp_(p, 0.01)

    def two_updates():   # the actors learn every second update: a unit of two
        work()
        work()
    return two_updates, 2 * config.update_every


def measure(name: str, threads: int, repeat: int, bf16: bool = False) -> dict:
    unit, decisions = ppo_unit(name) if name in SETTINGS[:3] else offpolicy_unit(name)

    def work():
        with torch.autocast('cpu', dtype=torch.bfloat16, enabled=bf16):
            unit()

    torch.set_num_threads(threads)
    work()                                                       # warm-up (allocations, lazy initialisations)
    with warnings.catch_warnings():                              # (the flags' note on Intel GPUs' TF32)
        warnings.simplefilter('ignore', UserWarning)
        with FlopCounterMode(display=False) as counter, torch.backends.mkldnn.flags(enabled=False):
            unit()                                               # (oneDNN's fused LSTM hides its products)
    flops = counter.get_total_flops()
    best, best_wall = math.inf, math.inf
    for _ in range(repeat):
        start, wall = time.process_time(), time.perf_counter()
        work()
        best, best_wall = min(best, time.process_time() - start), min(best_wall, time.perf_counter() - wall)
    seconds = best if threads == 1 else best_wall   # one thread: its CPU time (a busy neighbour's share left out)
    return dict(setting=name, seconds_per_unit=round(seconds, 4), cpu_seconds=round(best, 4),
                wall_seconds=round(best_wall, 4), decisions_per_unit=decisions,
                ceiling_decisions_per_second=round(decisions / seconds, 1), gflop_per_unit=round(flops / 1e9, 2),
                gflop_per_second=round(flops / seconds / 1e9, 1))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--only', nargs='+', choices=SETTINGS, default=list(SETTINGS))
    parser.add_argument('--threads', type=int, default=1, help="torch threads (the trainers' default: 1)")
    parser.add_argument('--repeat', type=int, default=5, help='timed rounds per setting (the best is kept)')
    parser.add_argument('--bf16', action='store_true',
                        help="a prototype, not the trainers': the units under CPU autocast to bfloat16 (AMX where the "
                             'CPU has it)')
    parser.add_argument('--json', type=Path, default=None)
    args = parser.parse_args(argv)
    reference = sgemm_rate(args.threads)
    print(f'sgemm 1024^3 on {args.threads} thread(s): {reference:.1f} GFLOP/s')
    print('| setting | s per unit | decisions per unit | ceiling decisions/s | GFLOP per unit | GFLOP/s |\n'
          '|---|---:|---:|---:|---:|---:|', flush=True)
    results = []
    for name in args.only:
        row = measure(name, args.threads, args.repeat, args.bf16)
        results.append(row)
        print(f"| {name} | {row['seconds_per_unit']:.3f} | {row['decisions_per_unit']:,} | "
              f"{row['ceiling_decisions_per_second']:,.0f} | {row['gflop_per_unit']:.1f} | "
              f"{row['gflop_per_second']:.1f} |", flush=True)
    if args.json:
        from mate.tools.bench import machine_facts

        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(dict(machine=machine_facts(), threads=args.threads, bf16=args.bf16,
                                             sgemm_gflops=reference,
                                             results=results), indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
