"""`mate psro ...` (run or resume a population run) and `mate psro plot DIR...` (its figures).

Argument parsing only; torch, Ray and matplotlib are imported when a command runs.
"""

from __future__ import annotations

import argparse
import os
import signal
from pathlib import Path

from ...cli.arguments import CommandError, non_negative_int, positive_int, resolving_arguments
from .jobs import TARGET_CREDITS
from .solvers import SOLVERS

__all__ = ['add_arguments', 'run']


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--solver', choices=tuple(SOLVERS), default='nash',
                        help='meta-solver: nash (PSRO-Nash, zero-sum LP), uniform (fictitious self-play, the initial '
                             'policy included) or last (self-play: the newest policies); default nash')
    parser.add_argument('--config', '--cfg', default='MATE-2v4-0',
                        help='preset name or YAML/JSON path (default MATE-2v4-0)')
    parser.add_argument('--iterations', type=non_negative_int, default=10,
                        help='iterations after iteration 0 (random vs random); default 10, the paper 40')
    parser.add_argument('--br-steps', type=positive_int, default=100_000,
                        help='decision steps of each best-response training (default 100,000; the paper 5 M)')
    parser.add_argument('--eval-episodes', type=positive_int, default=100,
                        help='episodes per payoff entry, env seeds 3,000,000 .. 3,000,000 + E - 1 '
                             '(default 100, as the paper)')
    parser.add_argument('--eval-steps', type=positive_int, default=None,
                        help="step cap of an evaluation episode (default: the preset's, 10,000 for MATE-2v4-0)")
    parser.add_argument('--seed', type=non_negative_int, default=0, help='seed of the trainings (default 0)')
    parser.add_argument('--num-envs', type=positive_int, default=16,
                        help='envs per best-response training (default 16)')
    parser.add_argument('--initial-cameras', default='random', metavar='AGENT',
                        help='first member of the camera pool: random, greedy or pretrained:NAME (default random)')
    parser.add_argument('--initial-targets', default='random', metavar='AGENT', help='as --initial-cameras')
    parser.add_argument('--target-credit', choices=TARGET_CREDITS, default='team',
                        help="the target best responses' reward: team (the team's, as the paper) or own (each "
                             "target's own part of it, which learns on MATE-4v8-0 where the team's does not); "
                             'default team')
    parser.add_argument('--out', default=None, help='run directory (default runs/psro-SOLVER-seedN); an existing run '
                                                     'with the same settings resumes')
    parser.add_argument('--workers', type=positive_int, default=None,
                        help='local processes running the two best responses (and payoff chunks) side by side; 1 runs '
                             'the jobs one after the other in this process (default: 2, or 1 on a one-core machine)')
    parser.add_argument('--device', default='auto',
                        help="where the best responses' networks train: auto (a GPU when there is one), cpu, cuda or "
                             'cuda:N (the payoff entries play there too, on the CPU with auto); with --address, cuda '
                             'makes every job ask Ray for one GPU; default auto')
    parser.add_argument('--address', default=None,
                        help="run the jobs as Ray tasks: 'local' (a local Ray instance), 'auto' or 'ray://HOST:PORT' "
                             '(an existing cluster)')
    plots = parser.add_subparsers(dest='psro_command', metavar='plot', required=False)
    plot = plots.add_parser('plot', help='draw exploitability (Fig. 7) and meta-strategy heat maps (Fig. 8)',
                            description='Draw exploitability per iteration for every solver found in the run '
                                        'directories (mean +- std over runs of a solver; Fig. 7), and each run\'s '
                                        'meta-strategy heat map (Fig. 8), as PNG files.')
    plot.add_argument('dirs', nargs='+', metavar='DIR', help='run directories of mate psro')
    plot.add_argument('--out', dest='plot_out', default='psro-plots', help='output directory (default psro-plots)')


def run(args: argparse.Namespace, console) -> int:
    if getattr(args, 'psro_command', None) == 'plot':
        return _plot(args, console)
    try:
        from .psro import LocalRunner, PSROError, PSROSettings, RayRunner, env_of, run_psro
    except ImportError as exc:
        raise CommandError(f"needs PyTorch ({exc}); install the training extra: pip install 'mate[train]'") from None
    from ...config import ConfigError
    from ...tools.runners import JobFailed, RunnerError

    settings = PSROSettings(solver=args.solver, config=args.config, iterations=args.iterations, br_steps=args.br_steps,
                            eval_episodes=args.eval_episodes, eval_steps=args.eval_steps, seed=args.seed,
                            num_envs=args.num_envs, initial_cameras=args.initial_cameras,
                            initial_targets=args.initial_targets, target_credit=args.target_credit)
    out = Path(args.out or f'runs/psro-{args.solver}-seed{args.seed}')
    for flag, spec in (('--initial-cameras', args.initial_cameras), ('--initial-targets', args.initial_targets)):
        if not (spec in ('random', 'greedy') or spec.startswith('pretrained:')):
            raise CommandError(f'{flag} must be random, greedy or pretrained:NAME, got {spec!r}')
    if args.address and args.workers is not None:
        raise CommandError('--workers is for local processes; with --address Ray places the jobs')
    workers = args.workers or min(2, os.cpu_count() or 1)
    from ...policies.device import resolve_device

    on_gpus = bool(args.address) and str(args.device).startswith('cuda')
    if not on_gpus:     # (on a cluster the GPUs are the workers': the runner checks that the cluster has some)
        with resolving_arguments():
            resolve_device(args.device)       # CUDA asked for and absent: one line, before any job starts
    previous = signal.signal(signal.SIGTERM, _interrupt)   # a scheduler's SIGTERM stops like Ctrl-C (resumable)
    try:
        env_of(settings.config)   # a bad preset or file fails before any worker or Ray starts
        runner = RayRunner(None if args.address == 'local' else args.address, task_gpus=1 if on_gpus else 0) \
            if args.address else LocalRunner(workers)
        where = f'Ray ({args.address})' if args.address else f'{workers} local process{"es" if workers > 1 else ""}'
        console.print(f'population run: {settings.solver} on {settings.config}, {settings.iterations} iterations, '
                      f'{settings.br_steps:,} decision steps per best response, {settings.eval_episodes} episodes per '
                      f'payoff entry, on {where} -> {out}', soft_wrap=True)
        state = run_psro(settings, out, runner, say=lambda line: console.print(line, soft_wrap=True, highlight=False),
                         device=args.device)
    except JobFailed as exc:
        raise CommandError(f'{exc}; every finished job is saved in {out}: fix the cause and run the same command '
                           'again to resume') from None
    except (PSROError, ConfigError, RunnerError) as exc:
        raise CommandError(str(exc)) from None
    except KeyboardInterrupt:
        console.print(f'interrupted; run the same command again to resume from {out / "state.json"} (a best '
                      'response in training continues from its own checkpoint)', soft_wrap=True)
        return 130
    finally:
        signal.signal(signal.SIGTERM, previous)
    last = state['iterations'][-1]
    console.print(f'done: {len(state["iterations"]) - 1} iterations; state, payoff matrices and policies in {out}'
                  + ('' if last.get('exploitability') is None else
                     f'; last exploitability {last["exploitability"]["mean"]:.4f}'))
    return 0


def _interrupt(number, frame):
    raise KeyboardInterrupt(signal.Signals(number).name)


def _plot(args: argparse.Namespace, console) -> int:
    from .plots import plot_exploitability, plot_meta_strategies
    from .psro import PSROError, load_state

    states = []
    for folder in args.dirs:
        try:
            state = load_state(folder)
        except PSROError as exc:
            raise CommandError(str(exc)) from None
        if state is None:
            raise CommandError(f'{folder!r} holds no population run (no state.json)')
        states.append((Path(folder), state))
    out = Path(args.plot_out)
    try:
        written = [plot_exploitability([s for _, s in states], out / 'exploitability.png')]
    except ValueError as exc:
        console.print(f'no exploitability plot: {exc}')
        written = []
    for folder, state in states:
        if state['iterations']:
            written.append(plot_meta_strategies(state, out / f'meta-strategies-{folder.name}.png'))
    for path in written:
        console.print(f'wrote {path}')
    return 0
