"""The `mate` command line: `mate evaluate`, `mate train`, `mate psro`, `mate bench`, `mate generate-config`, ...

Each sub-command lives in a small function that parses nothing itself: `main` builds the
argument parser, and the sub-command receives the parsed namespace.

Errors: a mistake in the arguments (a number out of range, an unknown preset or agent, a bad
checkpoint, a missing file) prints one line, `mate COMMAND: error: MESSAGE` (a sub-command named in full:
`mate benchmark report: error: ...`), and exits with status 2; `mate --debug ...` (or the environment
variable MATE_DEBUG=1) prints the traceback too.
Any other exception is a bug and shows its traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback

from rich.console import Console
from rich.table import Table

from .arguments import ArgumentParser, CommandError, non_negative_int, number, positive_int, resolving_arguments

console = Console()
USER_OS_ERRORS = (FileNotFoundError, FileExistsError, IsADirectoryError, NotADirectoryError, PermissionError)
"""Errors about the user's paths, reported in one line like argument mistakes."""
DEBUG_HELP = 'on an error, also print the traceback (or set the environment variable MATE_DEBUG=1)'


def _debugging(args: argparse.Namespace) -> bool:
    return getattr(args, 'debug', False) or os.environ.get('MATE_DEBUG', '').strip() not in ('', '0')


def _is_user_error(exc: BaseException) -> bool:
    """Whether `exc` reports a mistake in the command's input rather than a bug."""
    from ..config import ConfigError

    if isinstance(exc, (CommandError, ConfigError, *USER_OS_ERRORS)):
        return True
    checkpoint = sys.modules.get('mate.policies.checkpoint')   # imported if it raised (importing it needs torch)
    return checkpoint is not None and isinstance(exc, checkpoint.CheckpointError)


def _bench(args: argparse.Namespace) -> int:
    from ..tools import bench

    batch_sizes = (1, 64, 1024) if args.quick else tuple(args.batch_sizes)
    seconds = 0.5 if args.quick else args.seconds
    with console.status('compiling and measuring...') as status:
        results = bench.run(args.presets, batch_sizes, seconds, float32=not args.quick,
                            progress=lambda text: status.update(f'measuring {text}'), repeat=args.repeat)
    columns = (['preset', 'what', 'B', 'obs dtype', 'env-steps/s'] + (['median'] if args.repeat > 1 else [])
               + ['x single env', 'x original'])
    rounds = f', best of {args.repeat} rounds' if args.repeat > 1 else ''
    table = Table(title=f'mate throughput (random actions, observations built{rounds})')
    for column in columns:
        table.add_column(column, justify='left' if column in ('preset', 'what', 'obs dtype') else 'right')
    for r in results:
        speedup = f"{r['speedup_vs_original']:,.0f}x" if r['speedup_vs_original'] else '-'
        median = [f"{r['median_env_steps_per_second']:,.0f}"] if args.repeat > 1 else []
        table.add_row(r['preset'], r['kind'], str(r['batch_size']), r['dtype'],
                      f"{r['env_steps_per_second']:,.0f}", *median, f"{r['speedup_vs_single_env']:,.1f}x", speedup)
    console.print(table)
    facts = bench.machine_facts()
    console.print(f"machine: {facts['cpus']} cores, {facts['processor']}, numba {facts['numba']}. The ratios hold "
                  "across machines; the absolute numbers differ between CPU families by 2x and more", soft_wrap=True)
    if args.json:
        console.print(f'results written to {bench.write_json(results, args.json)}', soft_wrap=True)
    return 0


def _generate_config(args: argparse.Namespace) -> int:
    from ..tools.generator import (GENERATION_SECONDS, ITERATIONS, RESTARTS, check_config_path, generate_config,
                                   plot_config, write_config)
    from .progress import ProgressLine

    with resolving_arguments():
        check_config_path(args.path)
        if args.num_cameras:
            console.print(f'placing {args.num_cameras} cameras: {RESTARTS} runs of up to {ITERATIONS:,} Adam steps '
                          f'over a 101 x 101 mesh ({GENERATION_SECONDS} s for 6 cameras on 2 cores)', soft_wrap=True)
        with ProgressLine('placing cameras', total=RESTARTS * ITERATIONS, console=console, transient=True) as line:
            def placed(restart: int, iteration: int, covering: float) -> None:
                line.update(completed=restart * ITERATIONS + iteration,
                            status=f'run {restart + 1}/{RESTARTS}, covering distance {covering:.1f}')

            config = generate_config(args.num_cameras, args.num_targets, args.num_obstacles,
                                     args.num_cargoes_per_target, args.obstacle_transmittance, args.seed,
                                     progress=placed)
    path = write_config(config, args.path)
    console.print(f"wrote {path}: {config['name']}")
    if 'camera' in config:
        console.print(f"camera max_sight_range {config['camera']['max_sight_range']:.1f}, "
                      f"radius {config['camera']['radius']:.1f}")
    if args.plot:
        try:
            console.print(f'plot written to {plot_config(config, args.plot)}', soft_wrap=True)
        except ImportError as exc:   # matplotlib missing
            raise CommandError(str(exc)) from exc
    return 0


def _presets(args: argparse.Namespace) -> int:
    from ..config import list_presets, read_config

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


def _evaluate(args: argparse.Namespace) -> int:
    from ..evaluation.command import run

    return run(args)


def _rllib_train(args: argparse.Namespace) -> int:
    from ..integrations import rllib_train

    return rllib_train.run(args, console)


def _train(args: argparse.Namespace) -> int:
    from .extras import require
    from ..learn import command

    require('train', 'mate train')

    return command.run(args, console)


def _psro(args: argparse.Namespace) -> int:
    from .extras import require
    from ..learn.population import command

    require('train', 'mate psro')

    return command.run(args, console)


def _benchmark(args: argparse.Namespace) -> int:
    from ..benchmark import command
    from .extras import require

    require('train', 'mate benchmark')   # its jobs train, its reports need scipy's statistics and matplotlib

    return command.run(args, console)


def build_parser() -> argparse.ArgumentParser:
    debug = argparse.ArgumentParser(add_help=False)   # --debug before or after the command name
    debug.add_argument('--debug', action='store_true', default=argparse.SUPPRESS, help=DEBUG_HELP)
    parser = ArgumentParser(
        prog='mate', description='MATE: the Multi-Agent Tracking Environment', parents=[debug],
        epilog='A mistake in the arguments prints one line and exits with status 2; add --debug (mate --debug '
               'COMMAND ...) or set MATE_DEBUG=1 to see the traceback too.')
    from ..version import __version__
    parser.add_argument('--version', action='version', version=f'mate {__version__}')
    commands = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')

    def command(name: str, **kwargs) -> argparse.ArgumentParser:
        return commands.add_parser(name, parents=[debug], **kwargs)

    bench = command('bench', help='measure env-steps/s of the single env and the batched core')
    bench.add_argument('--presets', nargs='+', default=['MATE-4v8-9', 'MATE-8v8-9'])
    bench.add_argument('--batch-sizes', nargs='+', type=positive_int, default=[1, 64, 1024, 4096, 16384])
    bench.add_argument('--seconds', type=number(float, above=0), default=2.0, help='time per measurement (default 2)')
    bench.add_argument('--repeat', type=positive_int, default=1,
                       help="rounds of the whole plan; report each measurement's best round and the median "
                            '(default 1)')
    bench.add_argument('--quick', action='store_true', help='small batches, 0.5 s each, no float32 runs')
    bench.add_argument('--json', default=None, help='also write the results to this JSON file')
    bench.set_defaults(run=_bench)

    from ..evaluation.command import DESCRIPTION as EVALUATE_DESCRIPTION, add_arguments as add_evaluate_arguments
    evaluate = command('evaluate', help='play camera agents against target agents and summarise the episodes',
                       description=EVALUATE_DESCRIPTION)
    add_evaluate_arguments(evaluate)
    evaluate.set_defaults(run=_evaluate)

    generate = command('generate-config', help='write a config with camera placement covering the terrain')
    generate.add_argument('--path', default='config.yaml', help='output YAML file (default config.yaml)')
    generate.add_argument('--num-cameras', type=non_negative_int, default=4, help='default 4')
    generate.add_argument('--num-targets', type=positive_int, default=8, help='default 8')
    generate.add_argument('--num-obstacles', type=non_negative_int, default=0, help='default 0')
    generate.add_argument('--num-cargoes-per-target', type=number(int, minimum=4), default=8,
                          help='at least 4 (default 8)')
    generate.add_argument('--obstacle-transmittance', type=number(float), default=0.1, help='clipped to [0, 1]')
    generate.add_argument('--seed', type=non_negative_int, default=0)
    generate.add_argument('--plot', default=None, metavar='PNG', help='also save a picture of the placement')
    generate.set_defaults(run=_generate_config)

    presets = command('presets', help='list the shipped configuration presets')
    presets.set_defaults(run=_presets)

    from ..integrations.rllib_train import add_arguments as add_rllib_train_arguments  # imports no Ray
    rllib_train = command('rllib-train',
                          help="train a team with RLlib's PPO as a mate train run (the witness; Ray RLlib)")
    add_rllib_train_arguments(rllib_train)
    rllib_train.set_defaults(run=_rllib_train)

    from ..learn.command import add_arguments as add_train_arguments  # imports no torch
    train = command('train',
                    help='train MAPPO/IPPO/IQL/QMIX/MADDPG cameras or targets against greedy opponents (PyTorch)')
    add_train_arguments(train)
    train.set_defaults(run=_train)

    from ..learn.population.command import add_arguments as add_psro_arguments  # imports no torch
    psro = command('psro',
                   help='population training: PSRO-Nash, fictitious self-play or self-play, with exploitability',
                   description='Grow a camera pool and a target pool by best responses to the other pool\'s '
                               'meta-strategy (paper §5.3): HRL-MAPPO cameras, MAPPO targets, payoff '
                               'entries played in batches, exploitability (paper Eq. 2) per iteration. Everything is '
                               'saved after each stage; the same command resumes a killed run. "mate psro plot '
                               'DIR..." draws the figures.')
    add_psro_arguments(psro)
    psro.set_defaults(run=_psro)

    from ..benchmark.command import add_arguments as add_benchmark_arguments  # imports no torch
    benchmark = command('benchmark', help="the paper's experiments: list, run (resumable jobs), report (IQM, CIs, "
                                          'marl_eval.json)',
                        description="The paper's experiments as data: \"mate benchmark list\" names them, \"mate "
                                    'benchmark run NAME\" runs every missing (setting, seed) job with evaluations on '
                                    'held-out seeds, "mate benchmark report DIR..." writes figures, a markdown table '
                                    'and marl_eval.json with interquartile means and 95 % bootstrap intervals.')
    add_benchmark_arguments(benchmark)
    benchmark.set_defaults(run=_benchmark)
    return parser


def _chosen_parser(parser: argparse.ArgumentParser, args: argparse.Namespace) -> argparse.ArgumentParser:
    """The parser of the (sub)command `args` chose: `mate evaluate`'s, `mate benchmark run`'s, ..."""
    while True:
        commands = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
        chosen = getattr(args, commands[0].dest, None) if commands else None
        if chosen not in (commands[0].choices if commands else {}):
            return parser
        parser = commands[0].choices[chosen]


def main(argv: list[str] | None = None) -> int:
    """Run `mate ARGS`; returns the exit status (argparse's own errors exit with status 2; Ctrl-C: 130)."""
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown:                         # said by the subcommand that was given them: `mate evaluate: error: ...`
        _chosen_parser(parser, args).error(f'unrecognized arguments: {" ".join(unknown)}')
    name = _chosen_parser(parser, args).prog       # 'mate evaluate', 'mate benchmark report', ...
    try:
        return args.run(args)
    except KeyboardInterrupt:
        if _debugging(args):
            traceback.print_exc()
        print(f'{name}: interrupted', file=sys.stderr)
        return 130
    except BaseException as exc:
        if not _is_user_error(exc):
            raise
        if _debugging(args):
            traceback.print_exc()
        print(f'{name}: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':   # `python -m mate.cli.main`: run the package's module, whose classes the commands import
    from mate.cli.main import main as package_main

    sys.exit(package_main())
