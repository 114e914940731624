"""`mate train ALGO --team camera|target ...`: argument parser and runner (torch imported only when run)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ['add_arguments', 'config_from_args', 'run']


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('algo', choices=('mappo', 'ippo'), help='centralised (MAPPO) or local (IPPO) critic')
    parser.add_argument('--team', choices=('camera', 'target'), default='camera', help='team to train (default camera)')
    parser.add_argument('--config', '--cfg', default=None,
                        help='preset name (e.g. MATE-4v8-9) or YAML/JSON path; default: the paper preset of the team '
                             '(cameras MATE-4v8-9, targets MATE-2v4-0)')
    parser.add_argument('--steps', type=float, default=2e6, help='decision steps in total (default 2e6)')
    parser.add_argument('--minutes', type=float, default=0.0,
                        help='also stop after this many minutes of training wall time (resumed sessions included); '
                             'default 0: no time limit')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--num-envs', type=int, default=64, help='batched games (default 64)')
    parser.add_argument('--rollout-length', type=int, default=25, help='decisions per env per iteration (default 25)')
    parser.add_argument('--epochs', type=int, default=4)
    parser.add_argument('--minibatches', type=int, default=4)
    parser.add_argument('--hrl', action='store_true',
                        help='cameras only: the policy selects targets (one bit per target), a rule executor aims (paper §HRL)')
    parser.add_argument('--actor', choices=('mlp', 'per-target'), default=None,
                        help="policy network: 'mlp' (paper) or, for cameras, 'per-target' (one shared scorer per target "
                             "slot); default per-target for cameras, mlp for targets")
    parser.add_argument('--paper', action='store_true',
                        help="the paper's MLP actor, its adaptive KL penalty (0.2, target 0.01) and its schedules "
                             "stretched over 10M steps (lr 5e-4 -> 1e-4 @4M -> 5e-5 @8M; entropy 0.05 -> 0.01 @2M -> "
                             "0.001 @4M -> 0 @10M); explicit options still win")
    parser.add_argument('--lstm', type=int, default=0, metavar='SIZE',
                        help='recurrent actor: MLP -> LSTM(SIZE) -> head, as in the paper (256); default 0, feed-forward')
    parser.add_argument('--full-observability', action='store_true',
                        help='the trained team sees every entity (the EnhancedObservation wrapper; the paper\'s Fig. 6 '
                             'ablation); evaluate such a policy with `mate evaluate --enhanced-observation TEAM`')
    parser.add_argument('--memory', type=int, default=0, metavar='STEPS',
                        help="cameras only: the team's shared memory of target sightings (every camera tells its "
                             "teammates what it sees; a sighting is kept STEPS env steps, the greedy cameras' 25), "
                             "appended to each camera's observation; default 0: none")
    parser.add_argument('--velocity', action='store_true',
                        help="cameras only: append each seen target's displacement over one held decision at its "
                             "current velocity (so that a policy holding its decision can aim ahead)")
    parser.add_argument('--credit', choices=('team', 'difference'), default='team',
                        help="cameras only: 'team' (default): every camera is rewarded with the team's coverage rate; "
                             "'difference': each camera with its own marginal contribution to it (the share of the "
                             "targets only it tracks), with one critic value per camera")
    parser.add_argument('--frame-skip', type=int, default=None, help='default: 5 cameras, 10 targets')
    parser.add_argument('--horizon', type=int, default=None, help='raw steps per training episode (default 500 decisions)')
    parser.add_argument('--gae-lambda', type=float, default=0.95)
    parser.add_argument('--kl-coeff', type=float, default=None,
                        help='initial coefficient of the adaptive KL penalty (RLlib and the paper: 0.2); '
                             'default 0: off (0.2 with --paper)')
    parser.add_argument('--kl-target', type=float, default=0.01,
                        help='KL per iteration the penalty adapts towards (x1.5 above twice, x0.5 below half; default 0.01)')
    parser.add_argument('--entropy-schedule', default=None, metavar='JSON',
                        help='[[step, coef], ...] piecewise linear (default 0.01 -> 0.001 @1M -> 0 @3M)')
    parser.add_argument('--lr-schedule', default=None, metavar='JSON',
                        help='[[step, lr], ...] step function (default 5e-4, 2e-4 @1.5M, 1e-4 @3M)')
    parser.add_argument('--snapshot-every', type=int, default=0, metavar='N',
                        help='keep the policy every N iterations as RUN_DIR/snapshots/policy-STEPS.pt (default off)')
    parser.add_argument('--init-from', default=None, metavar='PATH',
                        help='warm start from the networks of a checkpoint or exported policy of the same setting '
                             '(steps and schedules start from 0)')
    parser.add_argument('--threads', type=int, default=0,
                        help='torch threads of the update phase (default 0: every core; collection always uses 1)')
    parser.add_argument('--run-dir', default=None, help='output directory (default runs/ALGO-TEAM-seedN)')
    parser.add_argument('--fresh', action='store_true', help='ignore an existing checkpoint in the run directory')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar (CSV and TensorBoard only)')


def _env(config: str | None) -> dict:
    if config is None:
        return {}
    from ..registration import registered_ids

    name = config.removesuffix('-v0')
    if f'{name}-v0' in registered_ids():
        return dict(env_id=f'{name}-v0')
    if not Path(config).is_file():
        raise SystemExit(f'mate train: --config {config!r} is neither a preset name nor a file')
    return dict(env_id='MultiAgentTracking-v0', config=config)


def config_from_args(args: argparse.Namespace):
    """The `PPOConfig` of parsed `mate train` arguments (SystemExit with a message for bad ones)."""
    from .ppo import PAPER_HYPERPARAMETERS, PPOConfig

    extra = dict(PAPER_HYPERPARAMETERS) if args.paper else {}
    if args.actor:
        extra['actor'] = args.actor
    for key in ('entropy_schedule', 'lr_schedule'):
        text = getattr(args, key)
        if text:
            try:
                extra[key] = tuple(tuple(p) for p in json.loads(text))
            except (ValueError, TypeError) as exc:
                raise SystemExit(f'mate train: --{key.replace("_", "-")} must be JSON [[step, value], ...]: {exc}')
    if args.hrl and args.team != 'camera':
        raise SystemExit('mate train: --hrl exists for cameras only')
    if args.kl_coeff is not None:
        if not args.kl_coeff >= 0:
            raise SystemExit(f'mate train: --kl-coeff must be >= 0 (0 = no KL penalty), got {args.kl_coeff}')
        extra['kl_coeff'] = args.kl_coeff
    if not args.kl_target > 0:
        raise SystemExit(f'mate train: --kl-target must be > 0, got {args.kl_target}')
    if not args.minutes >= 0:
        raise SystemExit(f'mate train: --minutes must be >= 0 (0 = no time limit), got {args.minutes}')
    if args.lstm < 0:
        raise SystemExit(f'mate train: --lstm must be >= 0 (0 = feed-forward), got {args.lstm}')
    if args.memory < 0:
        raise SystemExit(f'mate train: --memory must be >= 0 steps (0 = no memory), got {args.memory}')
    if args.memory and args.team != 'camera':
        raise SystemExit('mate train: --memory (shared sightings of targets) exists for cameras only')
    if args.velocity and args.team != 'camera':
        raise SystemExit('mate train: --velocity (motion of the seen targets) exists for cameras only')
    if args.credit != 'team' and args.team != 'camera':
        raise SystemExit(f'mate train: --credit {args.credit} (each camera\'s own share of the coverage) exists for '
                         'cameras only')
    if args.actor == 'per-target' and args.team != 'camera':
        raise SystemExit("mate train: --actor per-target reads a camera's target slots; it needs --team camera")
    return PPOConfig(algo=args.algo, team=args.team, total_steps=int(args.steps), seed=args.seed,
                     time_limit=60.0 * args.minutes,
                     num_envs=args.num_envs, rollout_length=args.rollout_length, epochs=args.epochs,
                     minibatches=args.minibatches, frame_skip=args.frame_skip, horizon=args.horizon,
                     gae_lambda=args.gae_lambda, kl_target=args.kl_target, torch_threads=args.threads,
                     snapshot_every=args.snapshot_every,
                     lstm=args.lstm, hrl=args.hrl, full_observability=args.full_observability, memory=args.memory,
                     velocity=args.velocity, credit=args.credit, init_from=args.init_from, **_env(args.config), **extra)


def run(args: argparse.Namespace, console) -> int:
    from .checkpoint import CheckpointError
    from .ppo import train

    config = config_from_args(args)
    name = (f'hrl-{args.algo}' if args.hrl else args.algo) + ('-full-obs' if args.full_observability else '')
    run_dir = Path(args.run_dir or f'runs/{name}-{args.team}-seed{args.seed}')
    resolved = config.resolved()
    console.print(f'training {name.upper()} {args.team}s on {resolved.env_id} ({resolved.actor} actor, frame skip '
                  f'{resolved.frame_skip}, {config.num_envs} envs, {config.total_steps:,} decision steps) -> {run_dir}')
    if (run_dir / 'checkpoint.pt').exists() and not args.fresh:
        console.print(f'resuming from {run_dir / "checkpoint.pt"}')
    try:
        row = train(config, run_dir, resume=not args.fresh, progress=not args.no_progress)
    except CheckpointError as exc:
        raise SystemExit(f'mate train: {exc} (use --fresh or another --run-dir to start over)') from None
    except KeyboardInterrupt:
        console.print(f'interrupted; run the same command again to resume from {run_dir / "checkpoint.pt"}')
        return 130
    if config.time_limit and row.get('env_steps', config.total_steps) < config.total_steps:
        console.print(f'stopped at the time limit of {args.minutes:g} minutes')
    console.print(f"done: {row.get('env_steps', 0):,} decision steps, coverage {row.get('rollout_coverage', float('nan')):.3f}, "
                  f"episode return {row.get('episode_return', float('nan')):.1f}; final policy {run_dir / 'final.pt'}")
    return 0
