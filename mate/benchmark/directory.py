"""A benchmark directory (`mate benchmark run --out OUT`): its manifest `OUT/benchmark.json` (the experiment, the
budget, the seeds, every job's command line; merged by runners side by side), the reuse of another directory's
complete jobs (`--reuse`) and the continuation of its shorter runs (`--extend`), what each job has done (`mate
benchmark status`), and a light copy of what a report reads (`mate benchmark keep`).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import shutil
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from ..cli.progress import last_lines, last_logged_row, training_rate
from .experiments import Experiment, experiment_of
from .identity import JOB_CONFIG, ran_config, wanted_config
from .jobs import SEED_STRIDE, Job, horizon_of, plan
from .runner import JOB_LOCK, JOB_RUNNER, job_runner, locked

__all__ = ['BENCHMARK_FORMAT', 'BENCHMARK_FORMATS', 'EXTENDED_NOTE', 'JOB_STATES', 'KEPT_FILES',
           'REUSED_NOTE', 'extend_jobs', 'job_status', 'keep_results', 'read_manifest', 'reusable', 'reuse_jobs',
           'write_manifest']

BENCHMARK_FORMAT = 'mate.benchmark/2'
"""The manifest's format: /2 keeps the whole experiment (`definition`, `Experiment.to_dict`), so that a report needs
nothing but the directory; /1 (directories written before 2026-11-29, e.g. those kept in docs/results) names the
experiment alone, which is then the package's of that name."""
BENCHMARK_FORMATS = ('mate.benchmark/1', BENCHMARK_FORMAT)
"""The manifest formats this version reads."""


def write_manifest(experiment: Experiment, jobs: list[Job], out, steps: int, seeds: list[int]) -> Path:
    """`OUT/benchmark.json`: what the directory holds (read by `mate benchmark report`). A directory of another
    experiment or budget raises ValueError (use another --out).

    Runners started side by side on one directory (`--seeds 0,2,4` and `--seeds 1,3`) each merge their jobs
    into it: the read, merge and write hold a lock on `OUT/.benchmark.lock`, and the file is replaced whole
    (a reader never sees it half written)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with locked(out / '.benchmark.lock'):
        return _merge_manifest(experiment, jobs, out, steps, seeds)


def _merge_manifest(experiment: Experiment, jobs: list[Job], out: Path, steps: int, seeds: list[int]) -> Path:
    path = out / 'benchmark.json'
    manifest = dict(format=BENCHMARK_FORMAT, experiment=experiment.name, steps=steps,
                    eval_every=experiment.eval_interval(steps), eval_episodes=experiment.eval_episodes,
                    horizon=horizon_of(experiment), seed_stride=SEED_STRIDE, definition=experiment.to_dict())
    if path.exists():
        old = read_manifest(out)
        for key in ('experiment', 'steps', 'eval_every', 'eval_episodes', 'horizon'):
            if old.get(key) != manifest[key]:
                raise ValueError(f'{out} holds a benchmark with {key} {old.get(key)!r}, not {manifest[key]!r}; '
                                 'use another --out')
        if experiment.source == 'user' and old.get('definition') not in (None, manifest['definition']):
            raise ValueError(f'{out} holds a benchmark of another definition of {experiment.name!r} (its settings, '
                             'games, claims or references changed since); use another --out')
        seeds = sorted(set(old.get('seeds', [])) | set(seeds))
    manifest['seeds'] = seeds
    manifest['jobs'] = [dict(kind=job.kind, label=job.label, preset=job.preset, seed=job.seed,
                             dir=os.path.relpath(job.dir, out), commands=[list(c) for c in job.commands])
                        for job in jobs]
    if path.exists():       # keep the jobs of seeds run before
        known = {(j['kind'], j['label'], j['preset'], j['seed']) for j in manifest['jobs']}
        manifest['jobs'] += [j for j in json.loads(path.read_text())['jobs']
                             if (j['kind'], j['label'], j['preset'], j['seed']) not in known]
    tmp = path.with_name(f'benchmark.json.{os.getpid()}.tmp')
    tmp.write_text(json.dumps(manifest, indent=1))
    os.replace(tmp, path)
    return path


def read_manifest(out) -> dict:
    """The `benchmark.json` of a benchmark directory (any of `BENCHMARK_FORMATS`; `experiment_of` gives its
    experiment); ValueError, saying which, for a folder that does not exist, a file, a folder without one (a
    report's folder named as such) or one of another format."""
    path = Path(out) / 'benchmark.json'
    where = 'a benchmark directory is the --out of mate benchmark run'
    if not Path(out).exists():
        raise ValueError(f'{out}: no such directory ({where})')
    if not Path(out).is_dir():
        raise ValueError(f'{out}: a file, not a directory ({where})')
    if not path.exists():
        what = ('a report (results.json) of mate benchmark report' if (Path(out) / 'results.json').exists() else
                'an empty directory' if not any(Path(out).iterdir()) else 'a directory')
        raise ValueError(f'{out}: no benchmark.json: {what}, not a benchmark directory ({where})')
    manifest = json.loads(path.read_text())
    if manifest.get('format') not in BENCHMARK_FORMATS:
        raise ValueError(f'{path}: format {manifest.get("format")!r}, expected one of {", ".join(BENCHMARK_FORMATS)} '
                         '(a newer mate wrote it?)')
    return manifest


REUSED_NOTE = 'reused.txt'
"""The file a reused job's directory gets: where it was copied from, and why that is the same job."""
EXTENDED_NOTE = 'extended.txt'
"""The file a job continued from a shorter run (`--extend`) gets: where the run was copied from, at which budget."""


def reusable(job: Job, out, source, shorter: bool = False) -> Path | None:
    """The directory of the same job in the benchmark directory `source`, when it can stand for `job` of `out`:
    it is complete there and ran `job`'s resolved config (`mate.benchmark.identity`: every option, seed, budget,
    evaluation and thread count, with defaults filled in; not its directory); None otherwise. Experiments that
    share a setting (fig5's MAPPO is fig6's, fig4b's HRL-MAPPO is fig4a's) share its runs this way: a run is a
    function of its config.

    With `shorter`, the twin must instead be a `mate train` run complete at a smaller budget whose config is
    `job`'s but for `steps`: its checkpoint is where a run of `job`'s budget is at that step (the schedules count
    steps from 0, not in fractions of the budget) provided it stopped at an iteration where a run of `job`'s budget
    evaluates too (`_ends_on_an_evaluation`) and did not cut its last iteration short for its budget
    (`RunConfig.cuts_its_last_iteration`), and `extend_jobs` continues it."""
    out, source = Path(out).resolve(), Path(source).resolve()
    twin = _complete_twin(job, out, source)
    if twin is None or (ran := ran_config(twin.dir)) is None or (wanted := wanted_config(job)) is None:
        return None
    if not shorter:
        return twin.dir if ran == wanted else None
    if not (job.kind == 'train' and job.commands[0][0] == 'train' and (twin.dir / 'checkpoint.pt').exists()):
        return None
    budget = ran[0]['settings']['steps'] if len(ran) == 1 and ran[0]['command'] == 'train' else None
    if budget is None or budget >= wanted[0]['settings']['steps']:
        return None
    if ran != [dict(wanted[0], settings=dict(wanted[0]['settings'], steps=budget))]:
        return None
    from ..learn.command import trainer_config

    _, config = trainer_config(job.commands[0][1], list(job.commands[0][2:]))
    if dataclasses.replace(config, steps=budget).cuts_its_last_iteration():
        return None
    return twin.dir if _ends_on_an_evaluation(twin.dir, config.eval_every) else None


def _twin(job: Job, out, source) -> Job:
    """`job` of the benchmark directory `out` as it is in the benchmark directory `source` (its folder and result
    files there)."""
    out, source = Path(out).resolve(), Path(source).resolve()
    return dataclasses.replace(job, dir=source / job.dir.resolve().relative_to(out),
                               outputs=tuple(source / path.resolve().relative_to(out) for path in job.outputs))


def _complete_twin(job: Job, out, source) -> Job | None:
    """`_twin(job, out, source)` when it is done; None otherwise."""
    twin = _twin(job, out, source)
    return twin if twin.done() else None


def _ends_on_an_evaluation(folder: Path, every: int) -> bool:
    """Whether the complete run in `folder` stopped at an iteration where a longer run evaluates too (the first
    iteration at or past a multiple of `every` decision steps; 0: no periodic evaluation): a run evaluates at its
    last iteration whatever its step, and an evaluation a longer run does not make would stay in its record and
    might stand as its best policy."""
    with open(folder / 'progress.csv') as file:
        steps = [int(row['env_steps']) for row in csv.DictReader(file)]
    if not every or not steps:
        return bool(steps)
    before = steps[-2] if len(steps) > 1 else 0
    return steps[-1] // every > before // every


def _twins(jobs: list[Job], out, sources: Sequence, shorter: bool):
    """(job, folder) for every job of `jobs` with nothing of it in `out` yet (a directory holding something besides
    a runner's lock is a run in progress, never replaced) and a twin in one of the benchmark directories `sources`
    (the first found): `reusable`, with `shorter` as given."""
    for job in jobs:
        if job.done() or _in_progress(job):
            continue
        folder = next((found for source in sources if (found := reusable(job, out, source, shorter)) is not None),
                      None)
        if folder is not None:
            yield job, folder


def _in_progress(job: Job) -> bool:
    """Whether `job`'s directory holds something besides a runner's lock: a run in progress, never replaced."""
    return job.dir.exists() and any(path.name not in (JOB_LOCK, JOB_RUNNER) for path in job.dir.iterdir())


def _copy(folder: Path, dest: Path, note_name: str, note: str, leave_out: Sequence[str] = ()) -> None:
    """Copy the job directory `folder` to `dest` (but a runner's lock and `leave_out`) and write `note` in
    `dest / note_name`."""
    shutil.copytree(folder, dest, dirs_exist_ok=True, ignore=shutil.ignore_patterns(JOB_LOCK, JOB_RUNNER, *leave_out))
    (dest / note_name).write_text(note + '\n')


def reuse_jobs(jobs: list[Job], out, sources: Sequence, say: Callable[[str], None] = print) -> list[Job]:
    """Copy into `out` every job of `jobs` not there yet whose twin in one of the benchmark directories `sources`
    is `reusable`; its directory gets a `REUSED_NOTE`. Says one line per copied job; returns them."""
    copied = []
    for job, folder in _twins(jobs, out, sources, shorter=False):
        _copy(folder, job.dir, REUSED_NOTE, f'copied from {folder} on {time.strftime("%Y-%m-%dT%H:%M:%S")}: that '
                                            f'job ran the same config ({JOB_CONFIG})')
        say(f'{job.name}: reused from {folder} (the same config)')
        copied.append(job)
    return copied


def extend_jobs(jobs: list[Job], out, sources: Sequence, say: Callable[[str], None] = print) -> list[Job]:
    """Copy into `out`, for every training job of `jobs` not there yet, its run in one of the benchmark directories
    `sources` that is complete at a smaller budget and otherwise ran the same command lines (`reusable` with
    `shorter`), less its result files, final policy and log (the note names where the log is): the job then resumes
    from that run's last checkpoint and trains on to its own budget, exactly as if it had run from the start (the
    schedules count decision steps from 0). Its directory gets an `EXTENDED_NOTE`. Says one line per copied job;
    returns them."""
    copied = []
    for job, folder in _twins(jobs, out, sources, shorter=True):
        steps = int(last_logged_row(folder)['env_steps'])
        _copy(folder, job.dir, EXTENDED_NOTE, f'continued from {folder} on {time.strftime("%Y-%m-%dT%H:%M:%S")}: '
              f'that run ran the same config with a smaller budget (steps) and stopped complete at {steps:,} decision '
              'steps', leave_out=(*(path.name for path in job.outputs), 'final.pt', 'job.log', JOB_CONFIG, REUSED_NOTE))
        say(f'{job.name}: continues {folder} from {steps:,} decision steps (the same config but its budget)')
        copied.append(job)
    return copied


KEPT_FILES = ('job.log', JOB_CONFIG, 'config.json', 'evaluations.jsonl', REUSED_NOTE, EXTENDED_NOTE)
"""What `keep_results` copies of a complete job besides its result files (`Job.outputs`), when the job has them."""


def keep_results(out, dest, say: Callable[[str], None] = print) -> list[Job]:
    """Copy into `dest` what `mate benchmark report` reads of the benchmark directory `out`: its manifest and, of
    every complete job, its result files (a training run's `absolute.json`, a population run's `state.json`, a
    reference's evaluations), its periodic evaluations and its log; no policy, checkpoint or TensorBoard file (a few
    kB to a few tens of kB a job). `dest` is then a benchmark directory `report` and `status` read as they read
    `out`, and copied to where the benchmark ran, one `run` goes on with the jobs not complete alone. Says one line
    per kept job; returns them. ValueError when `dest` is `out` or `out` is no benchmark directory."""
    out, dest = Path(out), Path(dest)
    if dest.resolve() == out.resolve():
        raise ValueError(f'{dest} is the benchmark directory itself; keep its results in another directory')
    manifest = read_manifest(out)
    seeds = sorted({job['seed'] for job in manifest['jobs'] if job['seed'] is not None})
    jobs = plan(experiment_of(manifest), seeds, out, steps=manifest['steps'])
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copy2(out / 'benchmark.json', dest / 'benchmark.json')
    kept = []
    for job in jobs:
        if not job.done():
            continue
        for path in (*job.outputs, *(job.dir / name for name in KEPT_FILES)):
            if path.exists():
                copy = dest / path.relative_to(out)
                copy.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(path, copy)
        kept.append(job)
        say(f'{job.name}: kept in {dest / job.dir.relative_to(out)}')
    return kept


def _duration(seconds: float) -> str:
    """'about 2 h 05 min', 'about 7 min', 'under a minute'."""
    minutes = round(seconds / 60)
    if minutes < 1:
        return 'under a minute'
    return f'about {minutes // 60} h {minutes % 60:02d} min' if minutes >= 60 else f'about {minutes} min'


JOB_STATES = ('done', 'running', 'started', 'waiting')
"""What `job_status` says of a job."""


def job_status(job: Job, steps: int) -> tuple[str, str]:
    """(state, line) of a job of a benchmark directory whose runs train `steps` decision steps: 'done' with what
    it measured ('reused' when copied by --reuse, 'continued' when by --extend); 'running' (a runner runs it now:
    `job_runner`) or 'started' (part done, no runner now) with how far it is (a training run's logged decision
    steps and the time left at its rate so far, a population run's iterations, a reference's evaluations); or
    'waiting'. A training run's line also has its last periodic evaluation."""
    if job.done():
        reused = ' (reused)' if (job.dir / REUSED_NOTE).exists() else \
            ' (continued from a shorter run)' if (job.dir / EXTENDED_NOTE).exists() else ''
        return 'done', f'{job.name}: done{job.measured()}{reused}'
    runner = job_runner(job)
    progress = _progress(job, steps, running=runner is not None)
    if runner is not None:
        return 'running', f'{job.name}: {progress or "starting"} (running: {runner})'
    if progress is not None:
        return 'started', f'{job.name}: {progress}'
    return 'waiting', f'{job.name}: waiting'


def _last_evaluation(folder: Path) -> str:
    """'; evaluated coverage_rate 0.612 at 1,500,000': the last periodic evaluation of the training run in `folder`
    (its `evaluations.jsonl`), or '' before the first."""
    lines = last_lines(folder / 'evaluations.jsonl') or []            # from the file's end: one line a few kB
    last = next((json.loads(line) for line in reversed(lines) if line.strip()), None)
    return '' if last is None else f'; evaluated {last["metric"]} {last["mean"]:.3f} at {last["env_steps"]:,}'


def _progress(job: Job, steps: int, running: bool) -> str | None:
    """How far a job that is not done has come, or None before anything of it was written."""
    if job.kind == 'psro' and job.outputs[0].exists():
        state = json.loads(job.outputs[0].read_text())
        done, total = max(len(state['iterations']) - 1, 0), int(state['settings']['iterations'])
        return f'{done} of {total} iterations'
    if job.kind == 'reference' and any(path.exists() for path in job.outputs):
        return f'{sum(path.exists() for path in job.outputs)} of {len(job.outputs)} evaluations'
    row = last_logged_row(job.dir) if job.kind == 'train' else None   # one read: the steps and the rate agree
    if row is None:
        return None
    logged, rate = int(row['env_steps']), training_rate(row)
    text = f'{logged:,} of {steps:,} decision steps ({100 * min(logged, steps) // steps} %)' + _last_evaluation(job.dir)
    if rate and logged < steps:
        return f'{text}; {_duration((steps - logged) / rate)} left at its rate so far ({rate:,.0f} steps/s)'
    if logged >= steps:
        return f'{text}; {"its absolute metric" if running else "its absolute metric is missing: run again"}'
    return text
