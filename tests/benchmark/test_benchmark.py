"""`mate benchmark`: the experiments as data, the jobs' seeds, the smoke run and its report end to end."""

from __future__ import annotations

import dataclasses
import json
import re
import shlex
import shutil

import numpy as np
import pytest

from mate.benchmark import verdicts

from mate.benchmark.experiments import EXPERIMENTS, Setting, experiment
from mate.benchmark.directory import (EXTENDED_NOTE, REUSED_NOTE, _ends_on_an_evaluation, job_status, reusable,
                                      reuse_jobs, write_manifest)
from mate.benchmark.identity import JOB_CONFIG, command_config, job_config, ran_config
from mate.benchmark.jobs import MAX_SEED, SEED_STRIDE, by_setting, parse_presets, parse_seeds, parse_settings, plan
from mate.benchmark.results import collect
from mate.benchmark.stats import iqm
from mate.cli.main import build_parser, main
from mate.learn.evaluation import ABSOLUTE_FACTOR, ABSOLUTE_SEEDS, EVALUATION_SEEDS
from mate.learn.population.psro import PSROSettings
from mate.evaluation.protocol import FRESH_SEEDS

from conftest import needs_extra

from .test_marl_eval import marl_eval_problems


def _option(command: tuple[str, ...], flag: str) -> str:
    return command[command.index(flag) + 1]


def test_every_setting_is_a_valid_command_line(tmp_path):
    """Each planned job parses with the command it names (a typo in an experiment fails here, not after hours)."""
    from mate.learn.command import trainer_parser

    parser = build_parser()
    for exp in EXPERIMENTS.values():
        for job in plan(exp, [0], tmp_path):
            for command in job.commands:
                args = parser.parse_args(list(command))
                if command[0] == 'train':
                    trainer_parser(args.algo)[0].parse_args(args.options)
                elif command[0] == 'rllib-train':        # its settings' own checks (no Ray needed)
                    from mate.integrations.rllib_train import config_of

                    config_of(args)


def test_training_seeds_never_reach_the_evaluation_seeds(tmp_path):
    """Every run of every experiment trains on env seeds below the evaluation seeds, and no two runs share one;
    the references play exactly the evaluation and absolute seeds."""
    for exp in EXPERIMENTS.values():
        jobs = plan(exp, [0, 1, MAX_SEED], tmp_path)
        used: list[tuple[int, range]] = []
        for job in jobs:
            command = job.commands[0]
            if job.kind == 'reference':
                seeds = [int(_option(c, '--seed')) for c in job.commands]
                episodes = [int(_option(c, '--episodes')) for c in job.commands]
                assert seeds == [EVALUATION_SEEDS, ABSOLUTE_SEEDS]
                assert episodes == [exp.eval_episodes, ABSOLUTE_FACTOR * exp.eval_episodes]
                continue
            seed = int(_option(command, '--seed'))
            if job.kind == 'psro':
                settings = PSROSettings(iterations=exp.iterations, seed=seed).validate()
                assert seed == job.seed
                first, last = settings.best_response_seed(1, 'camera'), settings.best_response_seed(exp.iterations,
                                                                                                    'target')
                rows = range(first, last + settings.num_envs)
            else:
                num_envs = int(_option(command, '--num-envs')) if '--num-envs' in command else 64
                assert seed == job.seed * SEED_STRIDE and num_envs <= SEED_STRIDE
                rows = range(seed, seed + num_envs)
            assert rows[-1] < EVALUATION_SEEDS
            if job.kind == 'train':
                assert int(_option(command, '--eval-every')) == exp.eval_interval(exp.steps) == exp.eval_every
            used.append((job.seed, rows))
        # runs of different seeds never share a game (the settings of one seed share theirs: common random numbers)
        spans = {}
        for seed, rows in used:
            first, last = spans.get(seed, (rows.start, rows.stop))
            spans[seed] = (min(first, rows.start), max(last, rows.stop))
        ordered = sorted(spans.values())
        assert all(a[1] <= b[0] for a, b in zip(ordered, ordered[1:]))


def test_a_smaller_budget_evaluates_at_least_four_times(tmp_path):
    """At the experiment's budget the runs evaluate every `eval_every`; `--steps` below it evaluates at least 4 times
    (every steps // 4 when that is sooner), in every training command and in the manifest the report reads."""
    from mate.benchmark.directory import read_manifest
    exp = experiment('fig6-observability')
    assert exp.eval_interval(exp.steps) == exp.eval_interval(2 * exp.steps) == exp.eval_every == 500_000
    assert exp.eval_interval(500_000) == 125_000
    assert exp.eval_interval(4_000_000) == 500_000          # 8 evaluations already
    assert exp.eval_interval(3) == 1
    jobs = plan(exp, [0], tmp_path, steps=500_000)
    intervals = {int(_option(job.commands[0], '--eval-every')) for job in jobs if job.kind == 'train'}
    assert intervals == {125_000}
    write_manifest(exp, jobs, tmp_path, 500_000, [0])
    assert read_manifest(tmp_path)['eval_every'] == 125_000


def _write_seed_manifest(out: str, seed: int) -> None:
    exp = experiment('fig6-observability')
    for _ in range(20):
        write_manifest(exp, plan(exp, [seed], out, steps=500_000), out, 500_000, [seed])


@pytest.mark.slow
def test_runners_side_by_side_merge_their_seeds_into_one_manifest(tmp_path):
    """Two runners on one directory (`--seeds 0,2` and `--seeds 1,3`) write the manifest at the same moments:
    neither reads it half written and neither loses the other's seeds or jobs."""
    import multiprocessing

    from mate.benchmark.directory import read_manifest
    context = multiprocessing.get_context('spawn')
    workers = [context.Process(target=_write_seed_manifest, args=(str(tmp_path), seed)) for seed in range(4)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(timeout=120)
    assert [worker.exitcode for worker in workers] == [0, 0, 0, 0]
    manifest = read_manifest(tmp_path)
    assert manifest['seeds'] == [0, 1, 2, 3]
    together = plan(experiment('fig6-observability'), [0, 1, 2, 3], tmp_path, steps=500_000)
    key = lambda job: (job['kind'], job['label'], job['preset'], job['seed'])  # noqa: E731
    assert sorted(map(key, manifest['jobs']), key=str) == sorted(map(key, map(vars, together)), key=str)
    assert not list(tmp_path.glob('*.tmp'))


def test_a_job_another_runner_holds_is_skipped_not_run_twice(tmp_path):
    """A runner finds a job's directory locked by another (the same seeds started twice on one directory): it runs
    nothing there and says so (a skip, not a failure), naming it at the end as still running elsewhere; once the
    lock is gone the job runs, and a job completed meanwhile by the other runner is not run again."""
    import dataclasses
    import fcntl

    from mate.benchmark.runner import BUSY, JOB_LOCK, run_job, run_jobs
    from mate.tools.runners import ThreadRunner
    planned = plan(experiment('smoke'), [0], tmp_path)[0]
    job = dataclasses.replace(planned, commands=(('--version',),), outputs=(planned.dir / 'version.txt',))
    log = job.dir / 'job.log'
    job.dir.mkdir(parents=True)
    with open(job.dir / JOB_LOCK, 'a') as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        assert run_job(job)['returncode'] == BUSY
        assert not log.exists()
        lines: list[str] = []
        assert run_jobs([job], ThreadRunner(1), say=lines.append) == []           # skipped, not failed
        assert 'skipped, another runner is running it' in lines[-2] and JOB_LOCK in lines[-2]
        assert lines[-1] == f'1 job still running in another runner: {job.name}'
    assert run_job(job)['returncode'] == 0
    assert log.read_text().splitlines()[0] == '$ mate --version'
    job.outputs[0].write_text('done by the other runner')
    assert run_job(job) == dict(returncode=0, seconds=0.0, elsewhere=True)
    assert log.read_text().count('$ mate --version') == 1

    class OtherRunnerFinishesFirst(ThreadRunner):
        """The other runner completes the job after this one planned it (not done: queued) and before its turn."""

        def run(self, jobs, done, names=None, **kwargs):
            job.outputs[0].write_text(json.dumps({'episodes': [{job.metric: 0.5}]}))
            super().run(jobs, done, names, **kwargs)

    job.outputs[0].unlink()
    lines.clear()
    assert run_jobs([job], OtherRunnerFinishesFirst(1), say=lines.append) == []
    assert lines[-1].endswith(f'{job.name}: done by another runner meanwhile; coverage_rate 0.500 (1 episodes)'), \
        lines                                                                          # not 'done in 0.0 min'


def test_parse_seeds():
    assert parse_seeds('0-4') == [0, 1, 2, 3, 4]
    assert parse_seeds('0,2,5') == [0, 2, 5]
    assert parse_seeds('3') == [3]
    for bad, words in (('a', "'0-4'"), ('2-x', "'0-4'"), (str(MAX_SEED + 1), f'0..{MAX_SEED}')):
        with pytest.raises(ValueError, match=words):
            parse_seeds(bad)


def test_presets_restrict_the_plan_to_some_games(tmp_path, capsys):
    """`--presets MATE-4v8-0` plans that game's references and runs only, in the experiment's order, and `status`
    lists the games of the directory; an unknown or empty list names the experiment's games."""
    fig6 = experiment('fig6-observability')
    assert parse_presets('MATE-4v8-0, MATE-2v4-0', fig6) == ['MATE-2v4-0', 'MATE-4v8-0']
    for bad, words in (('MATE-4v8-9', "'MATE-4v8-9' is not one of them"), (',', 'none given')):
        with pytest.raises(ValueError, match=f'MATE-2v4-0, MATE-4v8-0; {words}'):
            parse_presets(bad, fig6)
    every = plan(fig6, [0, 1], tmp_path)
    some = plan(fig6, [0, 1], tmp_path, presets=['MATE-4v8-0'])
    assert some == [job for job in every if job.preset == 'MATE-4v8-0']
    assert len(some) == len(fig6.references) + 2 * len(fig6.settings)
    write_manifest(fig6, some, tmp_path, fig6.steps, [0, 1])
    assert main(['benchmark', 'status', str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1] == f'fig6-observability: 0 done, 0 running, 0 started, {len(some)} waiting of {len(some)} jobs'
    assert lines[-2] == (f'  not in this directory yet: the game MATE-2v4-0 (`mate benchmark run fig6-observability '
                         f'--seeds 0,1 --presets MATE-2v4-0 --out {tmp_path}` adds their jobs)')
    assert not [line for line in lines[:-2] if 'MATE-2v4-0' in line], lines


def test_settings_restrict_the_plan_to_some_settings(tmp_path, capsys):
    """`--settings` takes labels or slugs: it plans the references and those settings' runs only, in the
    experiment's order, and `status` lists the settings of the directory; an unknown or empty list names the
    experiment's settings."""
    fig5 = experiment('fig5-targets-comm')
    assert parse_settings('mappo-i2c, IPPO,MAPPO+TarMAC', fig5) == ['IPPO', 'MAPPO+TarMAC', 'MAPPO+I2C']
    for bad, words in (('I2C', "'I2C' is not one of them"), (' , ', 'none given')):
        with pytest.raises(ValueError, match=re.escape(f'--settings: the settings of fig5-targets-comm are MAPPO, '
                                                       f'IPPO, MAPPO+TarMAC, IPPO+TarMAC, MAPPO+I2C; {words}')):
            parse_settings(bad, fig5)
    every = plan(fig5, [0, 1], tmp_path)
    some = plan(fig5, [0, 1], tmp_path, settings=['IPPO', 'IPPO+TarMAC'])
    assert some == [job for job in every if job.kind == 'reference' or job.label in ('IPPO', 'IPPO+TarMAC')]
    assert len(some) == len(fig5.references) + 2 * 2
    write_manifest(fig5, some, tmp_path, fig5.steps, [0, 1])
    assert main(['benchmark', 'status', str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1] == f'fig5-targets-comm: 0 done, 0 running, 0 started, {len(some)} waiting of {len(some)} jobs'
    # the settings no job plans are named, with the command that adds them (the directory's budget and seeds)
    assert lines[-2] == ("  not in this directory yet: the settings MAPPO, MAPPO+TarMAC, MAPPO+I2C (`mate benchmark "
                         "run fig5-targets-comm --seeds 0,1 --settings 'MAPPO,MAPPO+TarMAC,MAPPO+I2C' "
                         f"--out {tmp_path}` adds their jobs)")
    assert parse_settings('MAPPO,MAPPO+TarMAC,MAPPO+I2C', fig5) == ['MAPPO', 'MAPPO+TarMAC', 'MAPPO+I2C']
    assert not [line for line in lines[:-2] if 'MAPPO' in line], lines
    # a runner of those settings merges their jobs (as `run` does): then the directory plans every job
    write_manifest(fig5, plan(fig5, [0, 1], tmp_path, settings=['MAPPO', 'MAPPO+TarMAC', 'MAPPO+I2C']), tmp_path,
                   fig5.steps, [0, 1])
    assert main(['benchmark', 'status', str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1].endswith(f'{len(every)} waiting of {len(every)} jobs')
    assert not [line for line in lines if 'not in this directory' in line], lines
    # another budget than the experiment's is part of the command (a runner of another --steps is refused there)
    other = tmp_path / 'two-million'
    write_manifest(fig5, plan(fig5, range(fig5.seeds), other, steps=2_000_000, settings=['IPPO']), other,
                   2_000_000, list(range(fig5.seeds)))
    assert main(['benchmark', 'status', str(other)]) == 0
    assert ("(`mate benchmark run fig5-targets-comm --steps 2000000 --settings 'MAPPO,MAPPO+TarMAC,IPPO+TarMAC,"
            f"MAPPO+I2C' --out {other}` adds their jobs)") in capsys.readouterr().out
    assert main(['benchmark', 'run', 'fig5-targets-comm', '--settings', 'I2C', '--out', str(tmp_path)]) == 2
    assert "--settings: the settings of fig5-targets-comm are MAPPO, IPPO" in capsys.readouterr().err


def test_a_report_says_which_games_have_no_runs():
    """A directory run with `--presets` holds some games only: the report says so of the others instead of an empty
    table."""
    from mate.benchmark.report import markdown

    empty = dict(settings={}, references={}, improvement={})
    summary = dict(experiment='fig6-observability', figure='Fig. 6', team='target', steps=100, paper_steps=100,
                   iterations=0, eval_every=50, eval_episodes=2, claim='a claim', claims=[], incomplete=[],
                   tasks={'MATE-2v4-0 targets': empty})
    text = markdown(summary, [])
    assert '### MATE-2v4-0 targets\n\nNo runs of this game in the benchmark directories' in text
    assert '| setting |' not in text


def test_slugs_and_tasks():
    assert Setting('MAPPO+TarMAC', 'tarmac').slug == 'mappo-tarmac'
    assert Setting('MAPPO full obs.', 'mappo').slug == 'mappo-full-obs'
    assert experiment('fig6-observability').task('MATE-4v8-0') == 'MATE-4v8-0 targets'
    with pytest.raises(ValueError, match='experiments: smoke'):
        experiment('fig99')
    for exp in EXPERIMENTS.values():      # file names and marl-eval keys differ
        slugs = [s.slug for s in exp.settings]
        assert len(set(slugs)) == len(slugs) and all(',' not in s.label for s in exp.settings)


@pytest.fixture(scope='module')
def smoke(tmp_path_factory):
    """The acceptance commands: mate benchmark run smoke --out DIR && mate benchmark report DIR --out DIR2."""
    needs_extra('torch')
    root = tmp_path_factory.mktemp('smoke')
    runs, report = root / 'runs', root / 'report'
    assert main(['benchmark', 'run', 'smoke', '--out', str(runs)]) == 0
    assert main(['benchmark', 'report', str(runs), '--out', str(report), '--reps', '2000']) == 0
    return runs, report


@pytest.mark.slow
def test_smoke_run_writes_every_run_and_reference(smoke):
    runs, _ = smoke
    manifest = json.loads((runs / 'benchmark.json').read_text())
    exp = experiment('smoke')
    assert manifest['seeds'] == list(range(exp.seeds))
    assert len(manifest['jobs']) == len(exp.references) + exp.seeds * len(exp.settings)
    for job in manifest['jobs']:
        folder = runs / job['dir']
        if job['kind'] == 'reference':
            absolute = json.loads((folder / 'absolute.json').read_text())
            assert len(absolute['episodes']) == ABSOLUTE_FACTOR * exp.eval_episodes
            continue
        evaluations = [json.loads(line) for line in (folder / 'evaluations.jsonl').read_text().splitlines()]
        assert [e['env_steps'] for e in evaluations] == sorted(e['env_steps'] for e in evaluations)
        assert all(len(e['episodes']) == exp.eval_episodes for e in evaluations)
        absolute = json.loads((folder / 'absolute.json').read_text())
        assert absolute['seeds'] == [ABSOLUTE_SEEDS, ABSOLUTE_SEEDS + ABSOLUTE_FACTOR * exp.eval_episodes - 1]
    log = (runs / 'benchmark.log').read_text().splitlines()
    assert sum('done in' in line for line in log) == len(manifest['jobs'])


@pytest.mark.slow
def test_smoke_run_again_runs_nothing_and_recovers_a_missing_absolute_metric(smoke, capsys):
    runs, _ = smoke
    target = runs / 'runs' / 'mappo-MATE-2v4-0-seed1' / 'absolute.json'
    before = json.loads(target.read_text())
    target.unlink()        # as if the process died between its last checkpoint and the absolute metric
    assert main(['benchmark', 'run', 'smoke', '--out', str(runs)]) == 0
    out = capsys.readouterr().out
    assert f'{len(json.loads((runs / "benchmark.json").read_text())["jobs"]) - 1} of' in out and 'running 1' in out
    assert json.loads(target.read_text())['episodes'] == before['episodes']
    assert main(['benchmark', 'run', 'smoke', '--out', str(runs)]) == 0
    assert 'running 0' in capsys.readouterr().out


@pytest.mark.slow
def test_reuse_copies_the_jobs_run_with_the_same_command_lines_only(smoke, tmp_path, capsys):
    runs, _ = smoke
    jobs = plan(experiment('smoke'), range(experiment('smoke').seeds), runs)
    other = tmp_path / 'other'
    busy = other / 'runs' / 'ippo-MATE-2v4-0-seed1'          # a run in progress there is never replaced
    busy.mkdir(parents=True)
    (busy / 'progress.csv').write_text('iteration,env_steps\n')
    from mate.benchmark.runner import JOB_LOCK
    left = other / 'runs' / 'mappo-MATE-2v4-0-seed0'         # only a lock left by a runner killed at once: reused
    left.mkdir(parents=True)
    (left / JOB_LOCK).touch()
    assert main(['benchmark', 'run', 'smoke', '--out', str(other), '--reuse', str(runs)]) == 0
    out = capsys.readouterr().out
    assert out.count('reused from') == len(jobs) - 1 and 'running 1' in out
    for job in jobs:
        copy = other / job.dir.relative_to(runs)
        if copy == busy:
            assert not (copy / REUSED_NOTE).exists() and (copy / 'absolute.json').exists()   # trained here
            continue
        assert (copy / REUSED_NOTE).read_text().startswith(f'copied from {job.dir.resolve()}')
        for output in job.outputs:
            assert (copy / output.name).read_bytes() == output.read_bytes()
    # another budget: the references are the same jobs, the training runs are not
    other_budget = tmp_path / 'budget'
    for job in plan(experiment('smoke'), [0], other_budget, steps=experiment('smoke').steps // 2):
        twin = reusable(job, other_budget, runs)
        assert (twin is not None) == (job.kind == 'reference'), job.name
    assert main(['benchmark', 'run', 'smoke', '--out', str(tmp_path / 'x'), '--reuse', str(tmp_path / 'none')]) == 2
    assert "--reuse: '" in capsys.readouterr().err


def _trained(folder):
    """A run directory's logged rows without the machine's timing columns, its evaluations and its absolute metric."""
    import csv

    from mate.learn.run import TIMING_COLUMNS

    with open(folder / 'progress.csv') as file:
        rows = [{k: v for k, v in row.items() if k not in TIMING_COLUMNS} for row in csv.DictReader(file)]
    return rows, (folder / 'evaluations.jsonl').read_text(), json.loads((folder / 'absolute.json').read_text())


@pytest.mark.slow
def test_extend_continues_a_shorter_run_to_the_same_numbers_as_a_fresh_run(smoke, tmp_path, capsys):
    """`--extend DIR`: a training job of a larger budget continues DIR's run of the same command lines but --steps
    from its last checkpoint, and ends with the very numbers a run of that budget from the start has; the result
    files are its own, and a reference, a run of another setting or one that ended on an evaluation the longer run
    does not make is not continued."""
    exp = experiment('smoke')
    shorter, longer, fresh = tmp_path / 'shorter', tmp_path / 'longer', tmp_path / 'fresh'
    short, steps = 3 * exp.eval_every, 5 * exp.eval_every     # the smoke budget or more: the same interval
    assert short >= exp.steps and exp.eval_interval(short) == exp.eval_interval(steps)
    one = ['benchmark', 'run', 'smoke', '--seeds', '0', '--threads', '1', '--steps']
    assert main([*one, str(short), '--out', str(shorter)]) == 0
    assert main([*one, str(steps), '--out', str(longer), '--extend', str(shorter)]) == 0
    out = capsys.readouterr().out
    assert out.count(': continues ') == len(exp.settings) and 'reused from' not in out
    assert main([*one, str(steps), '--out', str(fresh)]) == 0
    capsys.readouterr()
    for job in plan(exp, [0], longer, steps=steps, threads=1):
        if job.kind != 'train':
            assert not (job.dir / EXTENDED_NOTE).exists()
            continue
        note = (job.dir / EXTENDED_NOTE).read_text()
        assert f'{(shorter / job.dir.relative_to(longer)).resolve()}' in note and f'{short:,} decision' in note
        rows, evaluations, absolute = _trained(job.dir)
        assert int(rows[-1]['env_steps']) >= steps
        assert (rows, evaluations, absolute) == _trained(fresh / job.dir.relative_to(longer))
        assert job_status(job, steps)[1].endswith('(continued from a shorter run)')
    # the same budget is --reuse's job; another setting's command lines are not a shorter run; the smoke runs stop
    # at 200 decisions, between two evaluations of a longer run, so they are not either
    runs, _ = smoke
    assert exp.steps % exp.eval_every
    for job in plan(exp, [0], tmp_path / 'x', steps=short, threads=1):
        assert reusable(job, tmp_path / 'x', shorter, shorter=True) is None
    for job in plan(exp, [0], tmp_path / 'y', steps=steps, threads=1):
        if job.kind == 'train':
            twin = (shorter / job.dir.relative_to(tmp_path / 'y')).resolve()
            assert reusable(job, tmp_path / 'y', shorter, shorter=True) == twin
            other = 'ippo' if job.dir.name.startswith('mappo') else 'mappo'
            renamed = dataclasses.replace(job, dir=job.dir.with_name(other + job.dir.name.split('po', 1)[1]))
            assert reusable(renamed, tmp_path / 'y', shorter, shorter=True) is None
            assert _ends_on_an_evaluation(twin, exp.eval_every)
    manifest = json.loads((runs / 'benchmark.json').read_text())
    threads = int(_option(next(j for j in manifest['jobs'] if j['kind'] == 'train')['commands'][0], '--threads'))
    for job in plan(exp, [0], tmp_path / 'w', steps=steps, threads=threads):
        if job.kind == 'train':
            twin = runs / job.dir.relative_to(tmp_path / 'w')
            assert reusable(job, tmp_path / 'w', runs, shorter=True) is None
            assert not _ends_on_an_evaluation(twin, exp.eval_every)
    # IQL, QMIX and MA-TD3 log a row every --report-every decisions and cut one short at a budget off that grid
    from mate.learn.command import trainer_config

    def cuts(*argv):
        return trainer_config(argv[0], list(argv[1:]))[1].cuts_its_last_iteration()

    assert cuts('iql', '--report-every', '40', '--steps', '140')
    assert not cuts('iql', '--report-every', '40', '--steps', '160')
    assert cuts('matd3', '--team', 'camera', '--steps', '2000000')       # its default: 5,120
    assert not cuts('mappo', '--team', 'target', '--steps', '2000001')
    assert main(['benchmark', 'run', 'smoke', '--out', str(tmp_path / 'z'), '--extend', str(tmp_path / 'none')]) == 2
    assert "--extend: '" in capsys.readouterr().err


@pytest.mark.slow
def test_keep_copies_what_the_report_reads_and_a_run_goes_on_from_it(smoke, tmp_path, capsys):
    """`mate benchmark keep DIR DEST`: a copy without policies or checkpoints from which the report is the same; with a
    job's results missing in DIR, that job is left out of DEST, and `run` in the copy runs that job alone."""
    runs, report = smoke
    partial = tmp_path / 'partial'
    shutil.copytree(runs, partial)
    exp = experiment('smoke')
    dropped = next(job for job in plan(exp, range(exp.seeds), partial) if job.kind == 'train')
    dropped.outputs[0].unlink()                                  # this run is not complete in `partial`
    kept_dir = tmp_path / 'kept'
    assert main(['benchmark', 'keep', str(partial), str(kept_dir)]) == 0
    assert f'kept {len(plan(exp, range(exp.seeds), runs)) - 1} complete jobs' in capsys.readouterr().out
    names = {path.name for path in kept_dir.rglob('*') if path.is_file()}
    assert names <= {'benchmark.json', 'absolute.json', 'evaluation.json', 'evaluations.jsonl', 'job.log', 'job.json',
                     'config.json'}
    assert not (kept_dir / dropped.dir.relative_to(partial)).exists()
    assert main(['benchmark', 'status', str(kept_dir)]) == 0
    assert '1 waiting' in capsys.readouterr().out
    # `run` in the copy runs the missing job alone (the same command: the same numbers), and the report is then the
    # full directory's, number for number
    assert main(['benchmark', 'run', 'smoke', '--out', str(kept_dir)]) == 0
    out = capsys.readouterr().out
    assert f'{len(plan(exp, range(exp.seeds), runs)) - 1} of' in out and 'running 1' in out
    assert main(['benchmark', 'report', str(kept_dir), '--out', str(tmp_path / 'r'), '--reps', '2000']) == 0
    rebuilt, full = (json.loads((folder / 'results.json').read_text()) for folder in (tmp_path / 'r', report))
    assert rebuilt == full
    assert main(['benchmark', 'keep', str(kept_dir), str(kept_dir)]) == 2
    assert 'is the benchmark directory itself' in capsys.readouterr().err


@pytest.mark.slow
def test_a_job_is_known_by_its_resolved_config_wherever_it_is(smoke, tmp_path):
    """Every job's directory holds its resolved config (`job.json`): its command lines parsed by the commands'
    own parsers, defaults filled in, no paths. `--reuse` compares configs, so a kept copy (`mate benchmark keep`)
    stands for its jobs wherever it lies, and a directory written before jobs had a `job.json` is read from its
    `job.log`; a job of another thread count or evaluation is another job."""
    runs, _ = smoke
    exp = experiment('smoke')
    manifest = json.loads((runs / 'benchmark.json').read_text())
    threads = int(_option(next(j for j in manifest['jobs'] if j['kind'] == 'train')['commands'][0], '--threads'))
    jobs = plan(exp, range(exp.seeds), runs, threads=threads)
    for job in jobs:
        saved = json.loads((job.dir / JOB_CONFIG).read_text())
        assert saved['configs'] == job_config(job) == ran_config(job.dir)
        assert not any(key in config['settings'] for config in saved['configs']
                       for key in ('run_dir', 'json', 'out', 'dir', 'progress'))
    train = next(job for job in jobs if job.kind == 'train')
    config = json.loads((train.dir / 'config.json').read_text())['config']
    assert job_config(train)[0]['settings'] == {k: v for k, v in config.items()
                                                 if k not in ('run_dir', 'progress', 'fresh', 'wandb', 'wandb_project',
                                                              'checkpoint_every')}
    # the order of options and an option given at its default do not make another job; another value does
    command = ['evaluate', '--config', 'MATE-2v4-0', '--episodes', '4', '--json', 'a.json']
    assert command_config(command) == command_config(['evaluate', '--json', 'b.json', '--episodes', '4', '--config',
                                                       'MATE-2v4-0', '--seed', '0'])
    assert command_config(command) != command_config([*command, '--seed', '1'])
    kept = tmp_path / 'kept'
    assert main(['benchmark', 'keep', str(runs), str(kept)]) == 0
    old = tmp_path / 'old'                           # a kept directory of a mate before job.json: its job.log
    shutil.copytree(kept, old)
    for path in old.rglob(JOB_CONFIG):
        path.unlink()
    for source in (kept, old):
        other = tmp_path / f'from-{source.name}'
        said = []
        assert len(reuse_jobs(plan(exp, range(exp.seeds), other, threads=threads), other, [source],
                              say=said.append)) == len(jobs)
        assert all('(the same config)' in line for line in said)
    other = tmp_path / 'threads'
    assert reuse_jobs(plan(exp, range(exp.seeds), other, threads=threads + 1), other, [kept], say=print) == \
        [job for job in plan(exp, range(exp.seeds), other, threads=threads + 1) if job.kind == 'reference']


@pytest.mark.slow
def test_status_says_what_each_job_has_done(smoke, tmp_path, capsys):
    runs, _ = smoke
    exp = experiment('smoke')
    assert main(['benchmark', 'status', str(runs)]) == 0
    n = len(plan(exp, range(exp.seeds), runs))
    assert f'smoke: {n} done, 0 running, 0 started, 0 waiting of {n} jobs' in capsys.readouterr().out
    # a fresh directory: one training run part-way, one reference half evaluated, the rest waiting
    fresh = tmp_path / 'fresh'
    jobs = plan(exp, [0], fresh)
    write_manifest(exp, jobs, fresh, exp.steps, [0])
    reference, run = jobs[0], next(job for job in jobs if job.kind == 'train')
    reference.dir.mkdir(parents=True)
    reference.outputs[0].write_text('{}')
    run.dir.mkdir(parents=True)
    (run.dir / 'progress.csv').write_text('iteration,env_steps\n1,40\n2,80\n')
    assert job_status(reference, exp.steps) == ('started', f'{reference.name}: 1 of 2 evaluations')
    assert job_status(run, exp.steps) == ('started', f'{run.name}: 80 of {exp.steps} decision steps (40 %)')
    assert job_status(jobs[1], exp.steps) == ('waiting', f'{jobs[1].name}: waiting')
    # with the training time logged: what is left at the run's rate so far (80 steps in 2 s: 40 steps/s)
    (run.dir / 'progress.csv').write_text('iteration,env_steps,wall_seconds\n1,40,1.5\n2,80,2.0\n')
    assert job_status(run, 5_000)[1] == (f'{run.name}: 80 of 5,000 decision steps (1 %); about 2 min left at its '
                                         'rate so far (40 steps/s)')
    assert job_status(run, 300_080)[1].endswith('about 2 h 05 min left at its rate so far (40 steps/s)')
    assert 'under a minute left' in job_status(run, 100)[1]
    # with a periodic evaluation logged: its metric and step (the last one)
    (run.dir / 'evaluations.jsonl').write_text(''.join(json.dumps(dict(env_steps=40 * i, metric='coverage_rate',
                                                                        mean=0.1 * i)) + '\n' for i in (1, 2)))
    assert job_status(run, 5_000)[1] == (f'{run.name}: 80 of 5,000 decision steps (1 %); evaluated coverage_rate '
                                         '0.200 at 80; about 2 min left at its rate so far (40 steps/s)')
    (run.dir / 'evaluations.jsonl').unlink()
    (run.dir / 'progress.csv').write_text(f'iteration,env_steps\n1,{exp.steps}\n')
    assert job_status(run, exp.steps)[1].endswith('its absolute metric is missing: run again')
    assert main(['benchmark', 'status', str(fresh)]) == 0
    assert (f'smoke: 0 done, 0 running, 2 started, {len(jobs) - 2} waiting of {len(jobs)} jobs'
            in capsys.readouterr().out)
    # a runner's file: running when its process lives (here: this one), started when it is gone, as written for
    # another machine
    import os
    import socket
    import subprocess
    import sys

    from mate.benchmark.runner import JOB_RUNNER
    (run.dir / JOB_RUNNER).write_text(f'{socket.gethostname()} {os.getpid()}\n')
    assert job_status(run, exp.steps) == ('running', f'{run.name}: {exp.steps} of {exp.steps} decision steps (100 %); '
                                                     f'its absolute metric (running: pid {os.getpid()})')
    assert job_status(jobs[1], exp.steps)[0] == 'waiting'
    (jobs[1].dir).mkdir(parents=True, exist_ok=True)
    (jobs[1].dir / JOB_RUNNER).write_text('node-7 4242\n')
    assert job_status(jobs[1], exp.steps) == ('running', f'{jobs[1].name}: starting (running: node-7, pid 4242)')
    gone = subprocess.run([sys.executable, '-c', 'import os; print(os.getpid())'], capture_output=True, text=True)
    (run.dir / JOB_RUNNER).write_text(f'{socket.gethostname()} {int(gone.stdout)}\n')
    assert job_status(run, exp.steps)[0] == 'started'
    assert main(['benchmark', 'status', str(fresh)]) == 0
    assert f'smoke: 0 done, 1 running, 2 started, {len(jobs) - 3} waiting' in capsys.readouterr().out
    assert main(['benchmark', 'status', str(tmp_path)]) == 2
    assert 'no benchmark.json' in capsys.readouterr().err


@pytest.mark.slow
def test_smoke_report_has_intervals_references_and_marl_eval(smoke):
    runs, report = smoke
    exp = experiment('smoke')
    results = json.loads((report / 'results.json').read_text())['smoke']
    task = results['tasks']['MATE-2v4-0 cameras']
    assert set(task['references']) == set(exp.references)
    random, greedy = task['references']['random']['absolute'], task['references']['greedy']['absolute']
    for setting in exp.settings:
        entry = task['settings'][setting.label]
        assert entry['runs'] == exp.seeds and entry['seeds'] == list(range(exp.seeds))
        for statistic in ('IQM', 'mean'):
            interval = entry['absolute'][statistic]
            assert interval['low'] <= interval['point'] <= interval['high']
        assert entry['absolute']['mean']['point'] == pytest.approx(np.mean(entry['values']))
        scaled = (np.array(entry['values']) - random) / (greedy - random)
        assert entry['normalised_greedy']['point'] == pytest.approx(iqm(scaled))
    assert set(task['improvement']) == {'MAPPO > IPPO'}
    agree = results['claims'][-1]
    claims = {claim['better'] + ' > ' + claim['worse']: claim for claim in results['claims'][:-1]}
    assert set(claims) == {'MAPPO > IPPO', 'MAPPO > random'}
    pair = claims['MAPPO > IPPO']
    assert (pair['point'], pair['low'], pair['high']) == pytest.approx(
        tuple(task['improvement']['MAPPO > IPPO'][k] for k in ('point', 'low', 'high')))
    holm = verdicts.holm([claim['p'] for claim in results['claims']])
    assert [claim['p_holm'] for claim in results['claims']] == pytest.approx(holm)
    for claim in claims.values():
        centre = 0.5 if claim is pair else 0.0         # against a reference: the difference paired by episode
        decisive = claim['p_holm'] < verdicts.ALPHA
        tested = claim.get('mean', claim['point'] - centre)           # the tested statistic, against its centre
        expected = 'confirmed' if decisive and claim['low'] > centre and tested > 0 else \
            'refuted' if decisive and claim['high'] < centre and tested < 0 else 'unresolved'
        assert claim['verdict'] == expected
    assert claims['MAPPO > random']['test'] == verdicts.REFERENCE_TEST
    collected = collect([runs])['smoke']            # the test's p from the runs' and the reference's episodes
    played = np.array([run.absolute for run in collected.runs_of('MAPPO', 'MATE-2v4-0')])
    assert claims['MAPPO > random']['p'] == pytest.approx(
        verdicts.reference_p(played, collected.references[('random', 'MATE-2v4-0')]['absolute']))
    assert pair['p'] == pytest.approx(verdicts.mann_whitney_p(task['settings']['MAPPO']['values'],
                                                              task['settings']['IPPO']['values']))
    assert (agree['text'], agree['low'], agree['high']) == ('(pipeline check) MAPPO and IPPO agree', pair['low'],
                                                            pair['high'])
    differ = agree['p_holm'] < verdicts.ALPHA and not pair['low'] <= 0.5 <= pair['high']
    assert agree['verdict'] == ('differ' if differ else 'no difference detected')
    markdown = (report / 'results.md').read_text()
    assert '| MAPPO | 3 |' in markdown and '*upper-bound* (reference)' in markdown
    assert f'| (pipeline check) MAPPO beats IPPO | MATE-2v4-0 cameras | **{pair["verdict"]}** |' in markdown
    assert (report / 'smoke-curves.png').stat().st_size > 10_000
    assert (report / 'smoke-intervals.png').stat().st_size > 10_000 and '![smoke](smoke-intervals.png)' in markdown
    data = json.loads((report / 'marl_eval.json').read_text())
    assert marl_eval_problems(data) == []           # what marl-eval's loader needs (tests/benchmark/test_marl_eval.py)
    runs_of = data['smoke']['MATE-2v4-0 cameras']
    assert set(runs_of) == {'MAPPO', 'IPPO'}
    for algorithm in runs_of.values():
        assert set(algorithm) == {f'seed_{k}' for k in range(exp.seeds)}
        for run in algorithm.values():
            keys = list(run)
            assert keys[-1] == 'absolute_metrics' and keys[0] == 'step_0'
            assert len(run['absolute_metrics']['coverage_rate']) == ABSOLUTE_FACTOR * exp.eval_episodes
            assert len(run['step_0']['coverage_rate']) == exp.eval_episodes


@pytest.mark.slow
def test_a_report_names_the_runs_it_left_out_grouped_by_setting(smoke, tmp_path):
    """Runs not complete (no absolute metric yet) are left out of the statistics and named once per setting, seeds
    together, in results.json (which the quotes read) and results.md."""
    import shutil
    runs = tmp_path / 'runs'
    shutil.copytree(smoke[0], runs)
    jobs = json.loads((runs / 'benchmark.json').read_text())['jobs']
    gone = {('MAPPO', 2), ('MAPPO', 0), ('greedy', None)}
    for job in jobs:
        if (job['label'], job['seed']) in gone:
            (runs / job['dir'] / 'absolute.json').unlink()
    assert main(['benchmark', 'report', str(runs), '--out', str(tmp_path / 'report'), '--reps', '200']) == 0
    results = json.loads((tmp_path / 'report' / 'results.json').read_text())['smoke']
    assert results['incomplete'] == ['MAPPO on MATE-2v4-0 (seeds 0, 2)', 'greedy on MATE-2v4-0']
    assert results['tasks']['MATE-2v4-0 cameras']['settings']['MAPPO']['seeds'] == [1]
    assert ('Not complete (left out): MAPPO on MATE-2v4-0 (seeds 0, 2), greedy on MATE-2v4-0.'
            in (tmp_path / 'report' / 'results.md').read_text())


def test_by_setting_groups_seeds_in_order_of_first_appearance():
    assert by_setting([('B', 'P', 3), ('A', 'P', 1), ('B', 'P', 1), ('greedy', 'P', None), ('A', 'Q', 0)]) == [
        'B on P (seeds 3, 1)', 'A on P (seed 1)', 'greedy on P', 'A on Q (seed 0)']
    assert by_setting([]) == []


@pytest.mark.slow
def test_a_directory_of_another_budget_is_refused(smoke, capsys):
    runs, _ = smoke
    assert main(['benchmark', 'run', 'smoke', '--out', str(runs), '--steps', '400']) == 2
    assert 'steps 200, not 400' in capsys.readouterr().err


def test_report_of_a_directory_that_is_no_benchmark(tmp_path, capsys):
    assert main(['benchmark', 'report', str(tmp_path), '--out', str(tmp_path / 'r')]) == 2
    assert 'no benchmark.json' in capsys.readouterr().err


def test_shell_quoting_of_the_recipe():
    """The HRL recipe's schedule is one argument (a job's command line is not split again)."""
    setting = next(s for s in experiment('fig4a-cameras').settings if s.label == 'HRL-MAPPO')
    assert shlex.split(shlex.join(setting.options)) == list(setting.options)


@pytest.mark.slow
def test_population_smoke_run_and_report(tmp_path):
    """A population experiment end to end: mate psro jobs, then the exploitability from the payoff matrix and on
    fresh seeds, with intervals."""
    needs_extra('torch')
    runs, report = tmp_path / 'runs', tmp_path / 'report'
    assert main(['benchmark', 'run', 'smoke-psro', '--out', str(runs)]) == 0
    assert main(['benchmark', 'report', str(runs), '--out', str(report), '--reps', '2000']) == 0
    exp = experiment('smoke-psro')
    states = [json.loads(path.read_text()) for path in sorted((runs / 'runs').glob('*/state.json'))]
    assert len(states) == exp.seeds
    marl = json.loads((report / 'marl_eval.json').read_text())['smoke-psro']['MATE-2v4-0']['PSRO-Nash']
    assert sorted(marl) == [f'seed_{seed}' for seed in range(exp.seeds)]
    for state, run in zip(states, (marl[f'seed_{seed}'] for seed in range(exp.seeds))):
        last = state['iterations'][-1]           # higher is better: the exploitability negated
        assert run['step_0']['negative_exploitability'] == [-last['exploitability']['mean']]
        assert run['absolute_metrics']['negative_exploitability'] == [-last['exploitability_fresh']['mean']]
    for state in states:
        last = state['iterations'][-1]
        fresh = last['exploitability_fresh']
        assert fresh['seeds'] == FRESH_SEEDS                 # its own range (mate.evaluation.protocol.SEED_RANGES)
        assert fresh['mean'] == pytest.approx(0.5 * (fresh['camera'] + fresh['target']))
    entry = json.loads((report / 'results.json').read_text())['smoke-psro']['tasks']['MATE-2v4-0']['settings'][
        'PSRO-Nash']
    assert entry['runs'] == exp.seeds
    assert entry['final_exploitability_values'] == [s['iterations'][-1]['exploitability']['mean'] for s in states]
    assert entry['final_exploitability_fresh_values'] == [s['iterations'][-1]['exploitability_fresh']['mean']
                                                          for s in states]
    curve = entry['exploitability_by_iteration']            # the figure's curve: IQM per iteration 1..N
    assert len(curve) == exp.iterations and curve[-1] == entry['final_exploitability']['IQM']
    assert 'The exploitability by iteration' in (report / 'results.md').read_text()
    assert (report / 'smoke-psro-exploitability.png').exists() and (report / 'marl_eval.json').exists()
    assert (report / 'smoke-psro-meta-strategies.png').exists()                    # Fig. 8: every run's heat maps
    from mate.learn.population.solvers import effective_policies

    for team in ('camera', 'target'):                     # how far each last meta-strategy spreads, per run
        spread = entry['final_effective_policies'][team]
        assert spread['values'] == [effective_policies(s['iterations'][-1][f'{team}_strategy']) for s in states]
        assert spread['pool'] == [len(s['iterations'][-1][f'{team}_strategy']) for s in states]
        assert spread['IQM']['low'] <= spread['IQM']['point'] <= spread['IQM']['high']
        mean = entry['mean_effective_policies'][team]            # ... and on average over iterations 1..N
        assert mean['values'] == pytest.approx([np.mean([effective_policies(r[f'{team}_strategy'])
                                                         for r in s['iterations'][1:]]) for s in states])
        assert all(1 <= value <= len(s['iterations'][-1][f'{team}_strategy'])
                   for value, s in zip(mean['values'], states))
    assert 'How many policies the meta-strategies spread over' in (report / 'results.md').read_text()
    from mate.benchmark.quote import headline                 # the quoted table: each run's, on fresh seeds
    from mate.benchmark.report import format_each, format_interval
    summary = json.loads((report / 'results.json').read_text())['smoke-psro']
    row = next(line for line in headline(summary, 'results.md').splitlines() if '| PSRO-Nash |' in line)
    spread = '; '.join(format_interval(entry['mean_effective_policies'][t]['IQM'], 2) for t in ('camera', 'target'))
    assert row.endswith(' | ' + format_each(entry['final_exploitability_fresh_values'], 4) + f' | {spread} |')


def test_report_numbers_that_round_to_zero_carry_no_minus_sign():
    from mate.benchmark.report import format_each, format_interval, format_number
    assert format_number(-0.00004, 4) == '0.0000' and format_number(-0.0004) == '0.000'
    assert format_number(-0.0006) == '-0.001' and format_number(0.12345, 2) == '0.12'
    assert format_each([-1e-9, -0.25]) == '0.000, -0.250'
    assert format_interval(dict(point=-1e-5, low=-0.0751, high=0.1329)) == '0.000 [-0.075, 0.133]'


@pytest.mark.slow
def test_sigterm_stops_every_job_at_a_checkpoint_and_the_same_command_resumes(tmp_path):
    """SIGTERM to `mate benchmark run` (a scheduler's stop) reaches each running training job once: it checkpoints
    and exits; the benchmark exits with status 130 and says so; the same command continues the runs."""
    import os
    import signal
    import subprocess
    import sys
    import time

    needs_extra('torch')
    out = tmp_path / 'runs'
    command = [sys.executable, '-m', 'mate', 'benchmark', 'run', 'smoke', '--out', str(out), '--seeds', '0',
               '--steps', '100000']
    driver = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              env=dict(os.environ, MATE_DEBUG='1'))
    progress = out / 'runs' / 'mappo-MATE-2v4-0-seed0' / 'progress.csv'
    deadline = time.monotonic() + 600
    while not (progress.exists() and len(progress.read_text().splitlines()) > 2):
        assert driver.poll() is None and time.monotonic() < deadline, driver.stdout.read()
        time.sleep(0.5)
    driver.send_signal(signal.SIGTERM)
    output = driver.communicate(timeout=600)[0]
    assert driver.returncode == 130, output
    assert 'interrupted: stopping 1 running job' in output
    log = (progress.parent / 'job.log').read_text()
    assert 'checkpoint written' in log and (progress.parent / 'checkpoint.pt').exists()
    rows = len(progress.read_text().splitlines())
    other = subprocess.run(command[:-1] + ['40'], capture_output=True, text=True, timeout=600)
    assert other.returncode == 2 and 'not 40' in other.stderr     # another budget is refused in that directory
    resumed = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    while len(progress.read_text().splitlines()) <= rows:
        assert resumed.poll() is None, resumed.stdout.read()
        time.sleep(0.5)
    resumed.send_signal(signal.SIGTERM)
    assert resumed.wait(timeout=600) == 130
    assert 'resuming from' in (progress.parent / 'job.log').read_text()


@pytest.mark.slow
def test_minutes_stops_the_benchmark_at_its_budget_and_the_same_command_resumes(tmp_path):
    """`--minutes` stops every running job at a checkpoint once the budget is spent (exit status 75, said in the
    output and in benchmark.log); the same command goes on from there."""
    import subprocess
    import sys

    from mate.benchmark.command import TIME_BUDGET_SPENT

    needs_extra('torch')
    out = tmp_path / 'runs'
    command = [sys.executable, '-m', 'mate', 'benchmark', 'run', 'smoke', '--out', str(out), '--seeds', '0',
               '--steps', '100000', '--jobs', '1']
    # 0.75 minutes: long enough for the job to start its run under a loaded machine (a job stopped before its run
    # began has no checkpoint to stop at; CI once saw that with 0.4 beside a busy core)
    first = subprocess.run(command + ['--minutes', '0.75'], capture_output=True, text=True, timeout=600)
    assert first.returncode == TIME_BUDGET_SPENT == 75, first.stdout + first.stderr
    assert '--minutes 0.75 spent: stopping 1 running job at a checkpoint' in first.stdout
    assert '--minutes 0.75 spent' in (out / 'benchmark.log').read_text()
    started = [path.parent for path in (out / 'runs').glob('*/checkpoint.pt')]
    assert len(started) == 1 and not (started[0] / 'absolute.json').exists()
    rows = len((started[0] / 'progress.csv').read_text().splitlines())
    again = subprocess.run(command + ['--minutes', '0.75'], capture_output=True, text=True, timeout=600)
    assert again.returncode == 75 and 'resuming from' in (started[0] / 'job.log').read_text()
    assert len((started[0] / 'progress.csv').read_text().splitlines()) > rows


@pytest.mark.parametrize('minutes', ['0', '-1', 'nan', 'soon'])
def test_minutes_must_be_a_positive_number(minutes, capsys):
    from mate.cli.main import main

    with pytest.raises(SystemExit) as stop:
        main(['benchmark', 'run', 'smoke', '--minutes', minutes])
    assert stop.value.code == 2
    assert f"argument --minutes: expected a number > 0, got {minutes!r}" in capsys.readouterr().err


def test_a_claim_needs_three_runs_per_setting_to_be_weighed_and_four_to_be_decisive():
    """With one or two runs a bootstrap interval has no width: no verdict then (and none without data); with three
    a side the exact test can never reach 5 % (its smallest p is 0.1); four a side that never overlap can."""
    from mate.benchmark.report import _weigh

    def judge(scores, references=None, episodes=None, reference_episodes=None):
        rows = _weigh(exp, 'MATE-2v4-0', scores, references or {}, episodes or {}, reference_episodes or {}, 200)
        return {row['text']: row['verdict'] for row in verdicts.decide(rows)}

    exp = experiment('smoke')
    two = {'MAPPO': np.array([0.5, 0.6]), 'IPPO': np.array([0.1, 0.2])}
    assert verdicts.MIN_RUNS == 3
    assert set(judge(two, {'random': 0.0}).values()) == {'too few runs (2; a verdict needs 3)'}
    three = {'MAPPO': np.array([0.5, 0.6, 0.7]), 'IPPO': np.array([0.1, 0.2, 0.3])}
    episodes = {'MAPPO': np.array([[0.5, 0.5], [0.6, 0.6], [0.7, 0.7]]) + np.array([0.0, 0.01])}
    assert judge(three, {'random': 0.0}, episodes, {'random': np.array([0.0, 0.01])}) == {
        '(pipeline check) MAPPO beats IPPO': 'unresolved',
        '(pipeline check) MAPPO beats the random cameras': 'confirmed',
        '(pipeline check) MAPPO and IPPO agree': 'no difference detected'}
    assert judge(three, {'random': 0.0})['(pipeline check) MAPPO beats the random cameras'] == \
        'no data (the episodes are not kept)'
    four = {'MAPPO': np.array([0.5, 0.6, 0.7, 0.8]), 'IPPO': np.array([0.1, 0.2, 0.3, 0.4])}
    five = {'MAPPO': np.array([0.5, 0.6, 0.7, 0.8, 0.9]), 'IPPO': np.array([0.0, 0.1, 0.2, 0.3, 0.4])}
    # two claims test this pair: Holm doubles the smallest p, 2/70 = 0.029 at 4 a side (0.057), 2/252 at 5 (0.016)
    assert judge(four)['(pipeline check) MAPPO beats IPPO'] == 'unresolved'
    assert judge(five) == {'(pipeline check) MAPPO beats IPPO': 'confirmed',
                           '(pipeline check) MAPPO beats the random cameras': 'no data',
                           '(pipeline check) MAPPO and IPPO agree': 'differ'}
    assert set(judge({}).values()) == {'no data'}