"""The `mate` command line: `mate evaluate`, `mate bench`, `mate generate-config`, `mate presets`.

Each sub-command lives in a small function that parses nothing itself: `main` builds the
argument parser, and the sub-command receives the parsed namespace.
"""

from __future__ import annotations

import argparse
import sys

from rich.console import Console
from rich.table import Table

console = Console()


def _bench(args: argparse.Namespace) -> int:
    from . import bench

    batch_sizes = (1, 64, 1024) if args.quick else tuple(args.batch_sizes)
    seconds = 0.5 if args.quick else args.seconds
    with console.status('compiling and measuring...') as status:
        results = bench.run(args.presets, batch_sizes, seconds, float32=not args.quick,
                            progress=lambda text: status.update(f'measuring {text}'))
    table = Table(title='mate throughput (random actions, observations built)')
    for column in ('preset', 'what', 'B', 'obs dtype', 'env-steps/s', 'x original'):
        table.add_column(column, justify='right' if column in ('B', 'env-steps/s', 'x original') else 'left')
    for r in results:
        speedup = f"{r['speedup_vs_original']:,.0f}x" if r['speedup_vs_original'] else '-'
        table.add_row(r['preset'], r['kind'], str(r['batch_size']), r['dtype'],
                      f"{r['env_steps_per_second']:,.0f}", speedup)
    console.print(table)
    facts = bench.machine_facts()
    console.print(f"machine: {facts['cpus']} cores, {facts['processor']}, numba {facts['numba']}")
    if args.json:
        console.print(f'results written to {bench.write_json(results, args.json)}')
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    import numpy as np
    from rich.progress import Progress

    from .registration import make

    env = make('MultiAgentTracking-v0', config=args.config)
    if args.max_episode_steps is not None:
        env = make('MultiAgentTracking-v0', config=env.config, max_episode_steps=args.max_episode_steps)
    rows = []
    with Progress(console=console, transient=True) as progress:
        task = progress.add_task(f'{env.name}: random vs random', total=args.episodes)
        for episode in range(args.episodes):
            rows.append(_random_episode(env, args.seed + episode))
            progress.advance(task)
    table = Table(title=f'{env.name}, {args.episodes} episodes, random cameras vs random targets')
    table.add_column('metric')
    table.add_column('mean ± std', justify='right')
    for key in rows[0]:
        values = np.array([row[key] for row in rows], dtype=float)
        table.add_row(key.replace('_', ' '), f'{values.mean():.4f} ± {values.std(ddof=1) if len(values) > 1 else 0:.4f}')
    console.print(table)
    return 0


def _random_episode(env, seed: int) -> dict:
    """One episode with uniform random actions; per-episode means and sums."""
    import numpy as np

    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    p = env.params
    camera_high = np.array([p.camera_rotation_step, p.camera_zooming_step])
    coverage, real_coverage, returns = [], [], np.zeros(2)
    done = False
    while not done:
        action = (rng.uniform(-1, 1, (p.num_cameras, 2)) * camera_high,
                  rng.uniform(-p.target_step_size, p.target_step_size, (p.num_targets, 2)))
        _, rewards, terminated, truncated, infos = env.step(action)
        info = infos[1][0]
        coverage.append(info['coverage_rate'])
        real_coverage.append(info['real_coverage_rate'])
        returns += rewards
        done = terminated or truncated
    return {'coverage_rate': np.mean(coverage), 'real_coverage_rate': np.mean(real_coverage),
            'transport_rate': info['mean_transport_rate'], 'camera_return': returns[0],
            'target_return': returns[1], 'delivered_cargoes': info['num_delivered_cargoes'],
            'episode_length': len(coverage)}


def _generate_config(args: argparse.Namespace) -> int:
    from .generator import generate_config, plot_config, write_config

    with console.status('placing cameras (Adam over a 101 x 101 mesh)...'):
        config = generate_config(args.num_cameras, args.num_targets, args.num_obstacles,
                                 args.num_cargoes_per_target, args.obstacle_transmittance, args.seed)
    path = write_config(config, args.path)
    console.print(f"wrote {path}: {config['name']}")
    if 'camera' in config:
        console.print(f"camera max_sight_range {config['camera']['max_sight_range']:.1f}, "
                      f"radius {config['camera']['radius']:.1f}")
    if args.plot:
        console.print(f'plot written to {plot_config(config, args.plot)}')
    return 0


def _presets(args: argparse.Namespace) -> int:
    from .config import list_presets, read_config

    table = Table(title='shipped presets')
    for column in ('preset', 'cameras', 'targets', 'obstacles', 'reward'):
        table.add_column(column)
    for name in list_presets():
        config = read_config(name)
        counts = [len(config.get(section, {}).get('location', [])) +
                  len(config.get(section, {}).get('location_random_range', []))
                  for section in ('camera', 'target', 'obstacle')]
        table.add_row(name, *map(str, counts), config['reward_type'])
    console.print(table)
    return 0


def _rllib_train(args: argparse.Namespace) -> int:
    from .integrations import rllib_train

    return rllib_train.run(args, console)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='mate', description='MATE: the Multi-Agent Tracking Environment')
    commands = parser.add_subparsers(dest='command', required=True)

    bench = commands.add_parser('bench', help='measure env-steps/s of the single env and the batched core')
    bench.add_argument('--presets', nargs='+', default=['MATE-4v8-9', 'MATE-8v8-9'])
    bench.add_argument('--batch-sizes', nargs='+', type=int, default=[1, 64, 1024, 4096, 16384])
    bench.add_argument('--seconds', type=float, default=2.0, help='time per measurement (default 2)')
    bench.add_argument('--quick', action='store_true', help='small batches, 0.5 s each, no float32 runs')
    bench.add_argument('--json', default=None, help='also write the results to this JSON file')
    bench.set_defaults(run=_bench)

    evaluate = commands.add_parser('evaluate', help='play episodes and summarise coverage, transport and returns')
    evaluate.add_argument('--config', default='MATE-4v8-9', help='preset name or YAML/JSON path (default MATE-4v8-9)')
    evaluate.add_argument('--episodes', type=int, default=5)
    evaluate.add_argument('--seed', type=int, default=0, help='episode i uses seed + i')
    evaluate.add_argument('--max-episode-steps', type=int, default=1000,
                          help='episode length cap (default 1000; the presets allow 10000)')
    evaluate.set_defaults(run=_evaluate)

    generate = commands.add_parser('generate-config', help='write a config with camera placement covering the terrain')
    generate.add_argument('--path', default='config.yaml', help='output YAML file (default config.yaml)')
    generate.add_argument('--num-cameras', type=int, default=4)
    generate.add_argument('--num-targets', type=int, default=8)
    generate.add_argument('--num-obstacles', type=int, default=0)
    generate.add_argument('--num-cargoes-per-target', type=int, default=8, help='at least 4')
    generate.add_argument('--obstacle-transmittance', type=float, default=0.1, help='clipped to [0, 1]')
    generate.add_argument('--seed', type=int, default=0)
    generate.add_argument('--plot', default=None, metavar='PNG', help='also save a picture of the placement')
    generate.set_defaults(run=_generate_config)

    presets = commands.add_parser('presets', help='list the shipped configuration presets')
    presets.set_defaults(run=_presets)

    from .integrations.rllib_train import add_arguments as add_rllib_train_arguments  # imports no Ray
    rllib_train = commands.add_parser('rllib-train', help='train PPO cameras against rule-based targets (Ray RLlib)')
    add_rllib_train_arguments(rllib_train)
    rllib_train.set_defaults(run=_rllib_train)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.run(args)


if __name__ == '__main__':
    sys.exit(main())
