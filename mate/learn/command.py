"""`mate train ALGO --team camera|target ...`: argument parser and runner (torch imported only when run)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ['add_arguments', 'run']


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('algo', choices=('mappo', 'ippo'), help='centralised (MAPPO) or local (IPPO) critic')
    parser.add_argument('--team', choices=('camera', 'target'), default='camera', help='team to train (default camera)')
    parser.add_argument('--config', '--cfg', default=None,
                        help='preset name (e.g. MATE-4v8-9) or YAML/JSON path; default: the paper preset of the team '
                             '(cameras MATE-4v8-9, targets MATE-2v4-0)')
    parser.add_argument('--steps', type=float, default=2e6, help='decision steps in total (default 2e6)')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--num-envs', type=int, default=64, help='batched games (default 64)')
    parser.add_argument('--rollout-length', type=int, default=25, help='decisions per env per iteration (default 25)')
    parser.add_argument('--epochs', type=int, default=4)
    parser.add_argument('--minibatches', type=int, default=4)
    parser.add_argument('--hrl', action='store_true',
                        help='cameras only: the policy selects targets (one bit per target), a rule executor aims (paper §HRL)')
    parser.add_argument('--actor', choices=('mlp', 'per-target'), default='mlp',
                        help="policy network: 'mlp' (paper) or, with --hrl, 'per-target' (one shared scorer per target slot)")
    parser.add_argument('--lstm', type=int, default=0, metavar='SIZE',
                        help='recurrent actor: MLP -> LSTM(SIZE) -> head, as in the paper (256); default 0, feed-forward')
    parser.add_argument('--frame-skip', type=int, default=None, help='default: 5 cameras, 10 targets')
    parser.add_argument('--horizon', type=int, default=None, help='raw steps per training episode (default 500 decisions)')
    parser.add_argument('--gae-lambda', type=float, default=0.95)
    parser.add_argument('--entropy-schedule', default=None, metavar='JSON',
                        help='[[step, coef], ...] piecewise linear (default paper: 0.05 -> 0.01 @2M -> 0.001 @4M -> 0 @10M)')
    parser.add_argument('--lr-schedule', default=None, metavar='JSON', help='[[step, lr], ...] step function')
    parser.add_argument('--snapshot-every', type=int, default=0, metavar='N',
                        help='keep the policy every N iterations as RUN_DIR/snapshots/policy-STEPS.pt (default off)')
    parser.add_argument('--threads', type=int, default=1, help='torch threads (default 1)')
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


def run(args: argparse.Namespace, console) -> int:
    from .checkpoint import CheckpointError
    from .ppo import PPOConfig, train

    extra = {}
    for key in ('entropy_schedule', 'lr_schedule'):
        text = getattr(args, key)
        if text:
            try:
                extra[key] = tuple(tuple(p) for p in json.loads(text))
            except (ValueError, TypeError) as exc:
                raise SystemExit(f'mate train: --{key.replace("_", "-")} must be JSON [[step, value], ...]: {exc}')
    config = PPOConfig(algo=args.algo, team=args.team, total_steps=int(args.steps), seed=args.seed,
                       num_envs=args.num_envs, rollout_length=args.rollout_length, epochs=args.epochs,
                       minibatches=args.minibatches, frame_skip=args.frame_skip, horizon=args.horizon,
                       gae_lambda=args.gae_lambda, torch_threads=args.threads,
                       snapshot_every=args.snapshot_every, actor=args.actor, lstm=args.lstm, hrl=args.hrl, **_env(args.config), **extra)
    if args.hrl and args.team != 'camera':
        raise SystemExit('mate train: --hrl exists for cameras only')
    if args.lstm and args.actor != 'mlp':
        raise SystemExit(f'mate train: --lstm works with --actor mlp only (got --actor {args.actor})')
    if args.lstm < 0:
        raise SystemExit(f'mate train: --lstm must be >= 0 (0 = feed-forward), got {args.lstm}')
    if args.actor == 'per-target' and not args.hrl:
        raise SystemExit("mate train: --actor per-target scores target slots; it needs --hrl")
    name = f'hrl-{args.algo}' if args.hrl else args.algo
    run_dir = Path(args.run_dir or f'runs/{name}-{args.team}-seed{args.seed}')
    resolved = config.resolved()
    console.print(f'training {name.upper()} {args.team}s on {resolved.env_id} (frame skip {resolved.frame_skip}, '
                  f'{config.num_envs} envs, {config.total_steps:,} decision steps) -> {run_dir}')
    if (run_dir / 'checkpoint.pt').exists() and not args.fresh:
        console.print(f'resuming from {run_dir / "checkpoint.pt"}')
    try:
        row = train(config, run_dir, resume=not args.fresh, progress=not args.no_progress)
    except CheckpointError as exc:
        raise SystemExit(f'mate train: {exc} (use --fresh or another --run-dir to start over)') from None
    except KeyboardInterrupt:
        console.print(f'interrupted; run the same command again to resume from {run_dir / "checkpoint.pt"}')
        return 130
    console.print(f"done: {row.get('env_steps', 0):,} decision steps, coverage {row.get('rollout_coverage', float('nan')):.3f}, "
                  f"episode return {row.get('episode_return', float('nan')):.1f}; final policy {run_dir / 'final.pt'}")
    return 0
