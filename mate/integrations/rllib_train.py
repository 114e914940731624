"""`mate rllib-train`: PPO cameras against a rule-based target team, with Ray RLlib.

This module imports nothing from Ray until the command runs, so `mate --help` works without
the optional extra. The training itself is `mate.integrations.rllib.train`.
"""

from __future__ import annotations

import argparse

from ..arguments import CommandError, non_negative_int, number, positive_int, resolving_arguments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The command's options (see docs/rllib.md)."""
    parser.add_argument('--config', default='MATE-4v4-9', help='preset name or YAML/JSON path (default MATE-4v4-9)')
    parser.add_argument('--opponent', default='greedy',
                        help="target team: greedy (default), naive, random, uniform or 'package.module:name'")
    parser.add_argument('--iterations', type=positive_int, default=20, help='PPO iterations (default 20)')
    parser.add_argument('--max-episode-steps', type=positive_int, default=500,
                        help='episode length cap (default 500; the presets allow 10000)')
    parser.add_argument('--address', default=None,
                        help="an existing Ray cluster ('auto', 'ray://host:10001'); default: start a local Ray")
    parser.add_argument('--num-cpus', type=positive_int, default=None, help='CPUs of the local Ray instance (default: all)')
    parser.add_argument('--num-env-runners', type=non_negative_int, default=0,
                        help='remote rollout workers (default 0: sample on the driver)')
    parser.add_argument('--train-batch-size', type=positive_int, default=4000, help='env steps per iteration (default 4000)')
    parser.add_argument('--minibatch-size', type=positive_int, default=500)
    parser.add_argument('--epochs', type=positive_int, default=5, help='SGD passes over each batch (default 5)')
    parser.add_argument('--lr', type=number(float, above=0), default=3e-4)
    parser.add_argument('--hidden', type=positive_int, nargs='+', default=[256, 256], help='MLP layer sizes (default 256 256)')
    parser.add_argument('--policy-per-camera', action='store_true',
                        help='one policy per camera instead of one shared camera policy')
    parser.add_argument('--seed', type=non_negative_int, default=0)
    parser.add_argument('--checkpoint-dir', default=None, help='save the final algorithm checkpoint here')


def run(args: argparse.Namespace, console) -> int:
    """Train as `args` says, printing one line per iteration; 0 on success (CommandError without Ray
    or for a bad config or opponent, checked before Ray starts)."""
    try:
        from . import rllib
    except ImportError as exc:
        raise CommandError(f"needs Ray RLlib ({exc}); install the optional extra: pip install 'mate[rllib]' "
                           '(see docs/rllib.md for the versions)') from None

    def progress(summary: dict) -> None:
        returns = ', '.join(f'{policy} {value:,.0f}' for policy, value in sorted(summary['returns'].items()))
        console.print(f"iter {summary['iteration']:>3}  steps {summary['env_steps']:>9,}  return {returns or '-'}  "
                      f"coverage {summary['coverage_rate']:.3f}  delivered {summary['delivered_cargoes']:.1f}  "
                      f"{summary['seconds']:.1f}s", soft_wrap=True)

    env_config = {'config': args.config, 'overrides': {'max_episode_steps': args.max_episode_steps},
                  'team': 'camera', 'opponent': args.opponent}
    with resolving_arguments():   # the config and the opponent, here rather than inside Ray's workers
        rllib.MateMultiAgentEnv(env_config).close()
    where = f'Ray cluster at {args.address}' if args.address else 'a local Ray instance'
    console.print(f'PPO cameras vs {args.opponent} targets on {args.config} ({where}), {args.iterations} iterations',
                  soft_wrap=True)
    summaries = rllib.train(env_config, args.iterations, address=args.address, num_cpus=args.num_cpus,
                            checkpoint_dir=args.checkpoint_dir, progress=progress,
                            policy_per_agent=args.policy_per_camera, num_env_runners=args.num_env_runners,
                            train_batch_size=args.train_batch_size, minibatch_size=args.minibatch_size,
                            num_epochs=args.epochs, lr=args.lr, hidden=tuple(args.hidden), seed=args.seed)
    if summaries and summaries[-1].get('checkpoint'):
        console.print(f"checkpoint saved to {summaries[-1]['checkpoint']}")
    return 0
