"""`mate benchmark list | run NAME|FILE | status DIR... | keep DIR DEST | report DIR... | quote FILE...`: the
paper's experiments and the user's (argument parsing and the commands; torch is imported only by the jobs, which run
`mate train` or `mate benchmark job`, the internal command of a user's command-line or function setting, in their
own processes)."""

from __future__ import annotations

import argparse
import os
import signal
from pathlib import Path

from ..cli.arguments import CommandError, number, positive_int
from .jobs import add_job_arguments

__all__ = ['add_arguments', 'run']


def add_arguments(parser: argparse.ArgumentParser) -> None:
    commands = parser.add_subparsers(dest='benchmark_command', metavar='{list,run,status,keep,report,quote}',
                                     required=True)
    commands.add_parser('list', help='the experiments: figure, settings, budget, seeds',
                        description='List the experiments: the figure of the paper each reproduces, its settings, '
                                    'the budget per run and the default number of seeds.')
    run = commands.add_parser('run', help="run an experiment's missing (setting, seed) jobs; resumable",
                              description='Run every missing job of an experiment: the references (random, greedy, '
                                          'upper-bound cameras) on the evaluation seeds, then each (setting, task, '
                                          'seed) training run with periodic evaluations on held-out seeds and the '
                                          'absolute metric at the end. Jobs run side by side in local processes (or '
                                          'as Ray tasks with --address); the same command resumes an interrupted '
                                          'benchmark. Several runners may share OUT (a job runs under a lock of its '
                                          'directory: one a runner is running, another skips). One line per finished '
                                          'job, also in OUT/benchmark.log.')
    run.add_argument('name', metavar='NAME|FILE',
                     help='the experiment: a name of mate benchmark list, or a file of yours (.py defining EXPERIMENT, '
                          'or .yaml/.json; docs/benchmark.md "Your own experiments")')
    run.add_argument('--seeds', default=None, help="run seeds, e.g. '0-4' or '0,2,5' (default: the experiment's, "
                                                   '0-4 for the figures)')
    run.add_argument('--presets', default=None,
                     help="only these of the experiment's games, e.g. 'MATE-4v8-0' (default: all; a later run on "
                          'the same --out may add the others)')
    run.add_argument('--settings', default=None,
                     help="only these of the experiment's settings, by label or file-name slug, e.g. "
                          "'IPPO,MAPPO+TarMAC' or 'ippo,mappo-tarmac' (default: all; a later run on the same --out may "
                          'add the others)')
    run.add_argument('--out', default=None, help="the benchmark directory (default runs/benchmark/NAME, NAME the "
                                                 "experiment's name)")
    run.add_argument('--steps', type=positive_int, default=None,
                     help="decision steps per training run (PSRO: per best response); default the experiment's "
                          "budget (the paper's 10 M for the cooperative runs)")
    run.add_argument('--jobs', type=positive_int, default=None,
                     help='jobs side by side on this machine (default: cores / threads, at least 1)')
    run.add_argument('--threads', type=positive_int, default=None,
                     help='torch threads per training run (default: cores / jobs, at least 1)')
    run.add_argument('--minutes', type=number(float, above=0), default=None,
                     help='stop after this many minutes: every running job at its next checkpoint, as Ctrl-C does '
                          '(exit status 75); the same command resumes them exactly (default: no limit)')
    run.add_argument('--address', default=None,
                     help="run the jobs as Ray tasks: 'local', 'auto' or 'ray://HOST:PORT' (OUT must be on storage "
                          'every node sees)')
    run.add_argument('--reuse', action='append', default=[], metavar='DIR',
                     help="copy a missing job from the benchmark directory DIR of another experiment when that "
                          'directory holds it complete, run with the very same command lines (e.g. fig5\'s MAPPO '
                          "runs from fig6's); repeatable")
    run.add_argument('--extend', action='append', default=[], metavar='DIR',
                     help='continue a missing training job from the benchmark directory DIR of a smaller --steps when '
                          'that directory holds it complete, run with otherwise the same command lines (the 10 M runs '
                          'from the 2 M ones, exactly as if run from the start); repeatable')
    status = commands.add_parser('status', help='what each job of benchmark directories has done',
                                 description='One line per job of each benchmark directory (mate benchmark run '
                                             '--out): done with what it measured; running (with its runner) or '
                                             'started (no runner now) with how far it is (decision steps, the last '
                                             'evaluation and the time left; PSRO iterations); or waiting; then the '
                                             'counts. Reads the files only: safe while the benchmark runs.')
    status.add_argument('dirs', nargs='+', metavar='DIR', help='benchmark directories (mate benchmark run --out)')
    keep = commands.add_parser('keep', help='copy what a report reads of a benchmark directory (no policies)',
                               description='Copy into DEST what mate benchmark report reads of the benchmark directory '
                                           'DIR: the manifest and, of every complete job, its results, evaluations '
                                           'and log, without policies, checkpoints or TensorBoard files (a few kB a '
                                           'job: small enough to commit beside a report). DEST is a benchmark '
                                           'directory report and status read; copied back to where the benchmark '
                                           'ran, mate benchmark run goes on with the jobs not complete.')
    keep.add_argument('dir', metavar='DIR', help='the benchmark directory (mate benchmark run --out)')
    keep.add_argument('dest', metavar='DEST', help='where the copy goes (created; files of the same name replaced)')
    report = commands.add_parser('report', help='figures, a markdown table and marl_eval.json from benchmark '
                                                'directories',
                                 description='Aggregate benchmark directories (of one or several experiments; an '
                                             "experiment's seeds may be split over directories): IQM and mean with "
                                             '95 % stratified-bootstrap confidence intervals, probability of '
                                             'improvement, normalised scores against the references, curves with '
                                             'bands; writes results.md, results.json, the figures and '
                                             'marl_eval.json.')
    report.add_argument('dirs', nargs='+', metavar='DIR', help='benchmark directories (mate benchmark run --out)')
    report.add_argument('--out', dest='report_out', default='runs/benchmark/report',
                        help='output directory (default runs/benchmark/report)')
    report.add_argument('--reps', type=positive_int, default=50_000,
                        help='bootstrap replications per interval (default 50,000)')
    quote = commands.add_parser('quote', help="rewrite the tables of markdown files from committed reports",
                                description='Rewrite every quote block of the markdown files (between the lines '
                                            '"<!-- mate benchmark quote: RESULTS_JSON EXPERIMENT -->" and "<!-- end '
                                            'of mate benchmark quote -->") with the headline table of that report: '
                                            'IQM [95 % CI] per setting, each run\'s score, the references, the '
                                            'claims\' verdicts. '
                                            '--check only says which blocks differ (exit status 1).')
    quote.add_argument('files', nargs='+', metavar='FILE', help='markdown files (README.md, docs/*.md)')
    quote.add_argument('--root', default='.', help='the directory the markers\' paths are relative to (default .)')
    quote.add_argument('--check', action='store_true', help='change nothing; exit status 1 if a block differs')
    job = commands.add_parser('job', help=argparse.SUPPRESS,
                              description="One job of a user's command-line or function setting (what mate benchmark "
                                          'run starts; not for direct use).')
    add_job_arguments(job)


def run(args: argparse.Namespace, console) -> int:
    say = _say(console)
    if args.benchmark_command == 'list':
        return _list(say)
    if args.benchmark_command == 'report':
        from .report import write_report

        try:
            files = write_report(args.dirs, args.report_out, reps=args.reps, say=say)
        except ValueError as exc:
            raise CommandError(str(exc)) from None
        say(f'report: {", ".join(str(path) for path in files.values())}')
        return 0
    if args.benchmark_command == 'status':
        return _status(args.dirs, say)
    if args.benchmark_command == 'keep':
        from .directory import keep_results

        try:
            kept = keep_results(args.dir, args.dest, say=say)
        except ValueError as exc:
            raise CommandError(str(exc)) from None
        say(f'kept {len(kept)} complete job{"s" * (len(kept) != 1)} of {args.dir} in {args.dest}')
        return 0
    if args.benchmark_command == 'job':
        return _job(args, say)
    if args.benchmark_command == 'quote':
        from .quote import quote_files

        try:
            changed = quote_files(args.files, args.root, check=args.check, say=say)
        except ValueError as exc:
            raise CommandError(str(exc)) from None
        except OSError as exc:              # 'README.mdx: no such file or directory'
            raise CommandError(f'{exc.filename}: {(exc.strerror or str(exc)).lower()}' if exc.filename else str(exc)) \
                from None
        return 1 if args.check and changed else 0
    return _run(args, say)


def _say(console):
    def say(line: str) -> None:
        console.print(line, soft_wrap=True, highlight=False, markup=False)
    return say


def _job(args: argparse.Namespace, say) -> int:
    from .directory import read_manifest
    from .user import run_user_job, user_job

    try:
        manifest = read_manifest(args.dir)
        setting, values = user_job(manifest, args.dir, args.label, args.preset, args.seed, args.threads)
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    return run_user_job(setting, values, values['eval_episodes'], say=say)


def _experiment(name: str):
    """The experiment `mate benchmark run NAME|FILE` names: the package's, or the one of a user's file."""
    from .experiments import experiment as experiment_named
    from .user import is_experiment_file, load_experiment

    return load_experiment(name) if is_experiment_file(name) else experiment_named(name)


def _status(dirs: list[str], say) -> int:
    from .directory import JOB_STATES, job_status, read_manifest
    from .experiments import experiment_of
    from .jobs import plan

    for folder in dirs:
        try:
            manifest = read_manifest(folder)
            experiment = experiment_of(manifest)
        except ValueError as exc:
            raise CommandError(str(exc)) from None
        presets = {job['preset'] for job in manifest['jobs']}               # (run --presets, --settings:
        settings = {job['label'] for job in manifest['jobs'] if job['kind'] != 'reference'}   # some of them)
        jobs = plan(experiment, manifest['seeds'], folder, steps=manifest['steps'], presets=presets, settings=settings)
        counts = dict.fromkeys(JOB_STATES, 0)
        say(f'{folder}: {experiment.name}, seeds {",".join(map(str, manifest["seeds"]))}, '
            f'{manifest["steps"]:,} decision steps per run')
        for job in jobs:
            state, line = job_status(job, manifest['steps'])
            counts[state] += 1
            say(f'  {state:<8} {line}')
        unplanned = _unplanned(experiment, manifest, folder, presets, settings)
        if unplanned:
            say(f'  not in this directory yet: {unplanned}')
        say(f'{experiment.name}: ' + ', '.join(f'{counts[state]} {state}' for state in JOB_STATES)
            + f' of {len(jobs)} jobs')
    return 0


def _unplanned(experiment, manifest: dict, folder: str, presets: set[str], settings: set[str]) -> str:
    """The experiment's settings and games that no job of the directory `folder` plans (a runner given --settings
    or --presets plans only those), and the command that adds their jobs to it, in words; '' when there are none."""
    labels = [setting.label for setting in experiment.settings if setting.label not in settings]
    games = [preset for preset in experiment.presets if preset not in presets]
    if not labels and not games:
        return ''
    words = '; '.join(f'the {noun}{"s" * (len(names) > 1)} {", ".join(names)}'
                      for noun, names in (('setting', labels), ('game', games)) if names)
    command = ['mate benchmark run', 'FILE' if experiment.source == 'user' else experiment.name]
    if manifest['steps'] != experiment.steps:
        command.append(f'--steps {manifest["steps"]}')
    if manifest['seeds'] != list(range(experiment.seeds)):
        command.append(f'--seeds {",".join(map(str, manifest["seeds"]))}')
    if not games:
        command.append(f"--settings '{','.join(labels)}'")
    elif not labels:
        command.append(f"--presets {','.join(games)}")
    return f'{words} (`{" ".join(command)} --out {folder}` adds their jobs)'


def _list(say) -> int:
    from .experiments import EXPERIMENTS

    for experiment in EXPERIMENTS.values():
        budget = (f'{experiment.iterations} iterations, {experiment.steps:,} decision steps per best response'
                  if experiment.population else f'{experiment.steps:,} decision steps per run')
        say(f'{experiment.name}: {experiment.figure}')
        say(f'    {", ".join(experiment.presets)}; {", ".join(s.label for s in experiment.settings)}; {budget}; '
            f'{experiment.seeds} seeds')
    return 0


def _run(args: argparse.Namespace, say) -> int:
    from ..tools.runners import RayRunner, RunnerError, ThreadRunner
    from .directory import extend_jobs, reuse_jobs, write_manifest
    from .jobs import parse_presets, parse_seeds, parse_settings, plan
    from .runner import run_jobs, stop_children

    try:
        experiment = _experiment(args.name)
        seeds = parse_seeds(args.seeds) if args.seeds else list(range(experiment.seeds))
        presets = parse_presets(args.presets, experiment) if args.presets else list(experiment.presets)
        settings = parse_settings(args.settings, experiment) if args.settings else None
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    if args.address and args.jobs is not None:
        raise CommandError('--jobs is for this machine; with --address Ray places the jobs')
    for option, folders in (('--reuse', args.reuse), ('--extend', args.extend)):
        missing = [folder for folder in folders if not Path(folder).is_dir()]
        if missing:
            raise CommandError(f'{option}: {missing[0]!r} is not a directory (a benchmark directory of mate benchmark '
                               'run)')
    cores = os.cpu_count() or 1
    jobs = args.jobs or max(1, cores // (args.threads or 2))
    threads = args.threads or max(1, cores // jobs)
    out = Path(args.out or f'runs/benchmark/{experiment.name}')
    steps = args.steps or experiment.steps
    planned = plan(experiment, seeds, out, steps=steps, threads=threads, presets=presets, settings=settings)
    try:
        write_manifest(experiment, planned, out, steps, seeds)
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    def say_and_log(line: str) -> None:
        say(line)
        with open(out / 'benchmark.log', 'a') as log:
            log.write(line + '\n')

    where = f'Ray ({args.address})' if args.address else f'{jobs} job{"s" * (jobs > 1)} at a time on this machine'
    games = '' if presets == list(experiment.presets) else f' on {", ".join(presets)}'
    games += '' if settings is None else f' ({", ".join(settings)} only)'
    say_and_log(f'benchmark {experiment.name}{games}: seeds {",".join(map(str, seeds))}, {steps:,} decision steps '
                f'per run, {threads} thread{"s" * (threads > 1)} per run, on {where} -> {out}')
    reuse_jobs(planned, out, args.reuse, say=say_and_log)
    extend_jobs(planned, out, args.extend, say=say_and_log)
    previous = signal.signal(signal.SIGTERM, _interrupt)
    budget = _TimeBudget(args.minutes) if args.minutes else None
    runner = None
    try:
        runner = RayRunner(None if args.address == 'local' else args.address, task_cpus=threads) if args.address \
            else ThreadRunner(jobs)
        failed = run_jobs(planned, runner, say=say_and_log)
    except RunnerError as exc:
        raise CommandError(str(exc)) from None
    except KeyboardInterrupt:
        running = stop_children()
        jobs_now = f'{running} running job{"s" * (running != 1)}'
        spent = budget is not None and budget.spent
        say_and_log(f'--minutes {args.minutes:g} spent: stopping {jobs_now} at a checkpoint; run the same command '
                    'again to resume' if spent else
                    f'interrupted: stopping {jobs_now} at a checkpoint (Ctrl-C again: at once); run the same command '
                    'again to resume')
        try:
            if runner is not None:
                runner.close()
        except KeyboardInterrupt:
            stop_children(kill=True)
        return TIME_BUDGET_SPENT if spent else 130
    finally:
        if budget is not None:
            budget.cancel()
        signal.signal(signal.SIGTERM, previous)
        if runner is not None:
            runner.close()
    if failed:
        say_and_log(f'{len(failed)} job{"s" * (len(failed) > 1)} did not complete; their logs name why; run the same '
                    'command again to retry them')
        return 1
    if not all(job.done() for job in planned):
        say_and_log(f'every job of this runner done; the others are running in another runner (mate benchmark status '
                    f'{out})')
        return 0
    say_and_log(f'all jobs done; the report: mate benchmark report {out} --out REPORT_DIR')
    return 0


def _interrupt(signal_number, frame):
    raise KeyboardInterrupt(signal.Signals(signal_number).name)


TIME_BUDGET_SPENT = 75
"""The exit status of `mate benchmark run --minutes` when the budget ran out before every job was done (75,
EX_TEMPFAIL: run the same command again)."""


class _TimeBudget:
    """Stops the benchmark (as SIGTERM does: `_interrupt`) once `minutes` have passed; `spent` says whether it did."""

    def __init__(self, minutes: float):
        import threading

        self.spent = False
        self._timer = threading.Timer(60.0 * minutes, self._expire)
        self._timer.daemon = True
        self._timer.start()

    def _expire(self) -> None:
        self.spent = True
        os.kill(os.getpid(), signal.SIGTERM)     # a real signal: it also wakes a main thread blocked in a wait

    def cancel(self) -> None:
        self._timer.cancel()
