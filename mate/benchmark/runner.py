"""`mate benchmark run`: an experiment's runs as independent jobs, resumable, one line per finished job.

    from mate.benchmark.experiments import experiment
    from mate.benchmark.runner import plan

    jobs = plan(experiment('fig4a-cameras'), seeds=range(5), out='bench/fig4a')
    print(len(jobs), jobs[-1].name)        # 38 MA-TD3 on MATE-4v8-9 seed 4
    # run_jobs(jobs, mate.runners.LocalRunner(2), say=print) runs the missing ones

A job is one command line of the package (`python -m mate ...`) whose output goes to a log file:

* a training run (`mate train COMMAND ... --seed S --eval-every K --eval-episodes E --run-dir OUT/runs/...`) per
  (setting, preset, seed), done when its `absolute.json` exists (the run completed and its best policy was
  re-evaluated);
* a population run (`mate psro ... --out OUT/runs/...`) per (setting, preset, seed), done when its `state.json`
  holds every iteration;
* a reference (`mate evaluate` of a rule team against the greedy rules) per (preset, reference): the evaluation
  episodes (seeds `EVALUATION_SEEDS`, ..., E episodes) and the absolute ones (seeds `ABSOLUTE_SEEDS`, ..., 10 E),
  each cut at the training horizon, the same episodes the learners are scored on; done when both JSON files exist.

Every job resumes from what it left: a training run from its checkpoint, a population run from its state. The
runner writes `OUT/benchmark.json` (the experiment, the budget, the seeds, every job's command line) and appends
each line it says to `OUT/benchmark.log`.

Run seeds: seed k trains with `mate train --seed k * SEED_STRIDE`, so no two runs share a training env (the rows
of a run are seeded `seed + row`) and every run stays below the evaluation seeds; a population run with `mate psro
--seed k`, which spaces its best responses' seeds by 1,000 itself (`PSROSettings.best_response_seed`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from ..learn.envs import PAPER_SETTINGS
from ..learn.evaluation import ABSOLUTE_FACTOR, ABSOLUTE_SEEDS, EVALUATION_SEEDS, TEAM_METRIC
from ..progress import logged_rate, logged_steps
from .experiments import Experiment, Setting

__all__ = ['BENCHMARK_FORMAT', 'BUSY', 'JOB_LOCK', 'JOB_RUNNER', 'Job', 'PATH_OPTIONS', 'REUSED_NOTE', 'SEED_STRIDE',
           'horizon_of', 'job_runner', 'job_status', 'parse_seeds', 'plan', 'read_manifest', 'reusable', 'reuse_jobs',
           'run_command', 'run_job', 'run_jobs', 'stop_children', 'tied_to_parent']

BENCHMARK_FORMAT = 'mate.benchmark/1'
SEED_STRIDE = 1000
"""Run seed k trains with `--seed k * SEED_STRIDE`: the training env rows of different runs never share a seed."""
MAX_SEED = EVALUATION_SEEDS // SEED_STRIDE - 1
"""The largest run seed: its training envs (up to SEED_STRIDE rows) stay below the evaluation seeds."""


@dataclasses.dataclass(frozen=True)
class Job:
    """One command of an experiment.

    Args:
        kind: 'train', 'psro' or 'reference'.
        label: the setting's label (training, population) or the reference's agent name.
        preset: the game.
        seed: the run seed (None for a reference).
        dir: the job's directory (the run directory, or the reference's).
        commands: the command lines after `python -m mate`, run in order.
        outputs: the files whose existence marks the job done.
        metric: the per-episode metric the job is scored by (the trained team's: `TEAM_METRIC`; '' for PSRO).
    """

    kind: str
    label: str
    preset: str
    seed: int | None
    dir: Path
    commands: tuple[tuple[str, ...], ...]
    outputs: tuple[Path, ...]
    metric: str = ''

    @property
    def name(self) -> str:
        seed = '' if self.seed is None else f' seed {self.seed}'
        return f'{self.label} on {self.preset}{seed}'

    def done(self) -> bool:
        if self.kind == 'psro':
            return _psro_complete(self.outputs[0])
        return all(path.exists() for path in self.outputs)


def _psro_complete(state_path: Path) -> bool:
    if not state_path.exists():
        return False
    state = json.loads(state_path.read_text())
    return len(state['iterations']) > int(state['settings']['iterations'])


def parse_seeds(text: str) -> list[int]:
    """Run seeds from '0-4', '0,2,5' or '3' (ranges inclusive); ValueError naming the valid form otherwise."""
    seeds: list[int] = []
    try:
        for part in str(text).split(','):
            first, _, last = part.strip().partition('-')
            seeds.extend(range(int(first), int(last or first) + 1))
    except ValueError:
        raise ValueError(f"--seeds: seeds as '0-4', '0,2,5' or '3', got {text!r}") from None
    if not seeds:
        raise ValueError(f'--seeds: no seeds in {text!r}')
    bad = [s for s in seeds if not 0 <= s <= MAX_SEED]
    if bad:
        raise ValueError(f'--seeds: run seeds are 0..{MAX_SEED}, got {bad[0]}')
    return sorted(set(seeds))


def horizon_of(experiment: Experiment) -> int | None:
    """Env steps per training (and evaluation) episode: the experiment's, or the trainer's default of 500 decisions
    at the paper's frame skip of the team (None for a population experiment: `mate psro` sets its own)."""
    if experiment.population:
        return experiment.horizon
    return experiment.horizon or 500 * PAPER_SETTINGS[experiment.team]['frame_skip']


def _training(experiment: Experiment, setting: Setting, preset: str, seed: int, steps: int, out: Path,
              threads: int) -> Job:
    folder = out / 'runs' / f'{setting.slug}-{preset}-seed{seed}'
    trainer = ('rllib-train',) if setting.command == 'rllib-ppo' else ('train', setting.command)
    command = (*trainer, *setting.options, '--team', experiment.team, '--config', preset,
               '--steps', str(steps), '--seed', str(seed * SEED_STRIDE), '--horizon', str(horizon_of(experiment)),
               '--eval-every', str(experiment.eval_interval(steps)), '--eval-episodes', str(experiment.eval_episodes),
               '--threads', str(threads), '--run-dir', str(folder), '--no-progress')
    return Job('train', setting.label, preset, seed, folder, (command,), (folder / 'absolute.json',),
               TEAM_METRIC[experiment.team])


def _population(experiment: Experiment, setting: Setting, preset: str, seed: int, steps: int, out: Path) -> Job:
    folder = out / 'runs' / f'{setting.slug}-{preset}-seed{seed}'
    command = ('psro', *setting.options, '--config', preset, '--iterations', str(experiment.iterations),
               '--br-steps', str(steps), '--seed', str(seed), '--workers', '1', '--out', str(folder))
    return Job('psro', setting.label, preset, seed, folder, (command,), (folder / 'state.json',))


def _reference(experiment: Experiment, agent: str, preset: str, out: Path) -> Job:
    folder = out / 'references' / f'{agent}-{preset}'
    own, other = ('--camera-agent', '--target-agent') if experiment.team == 'camera' else \
        ('--target-agent', '--camera-agent')
    commands, outputs = [], []
    for name, seed, episodes in (('evaluation', EVALUATION_SEEDS, experiment.eval_episodes),
                                 ('absolute', ABSOLUTE_SEEDS, ABSOLUTE_FACTOR * experiment.eval_episodes)):
        path = folder / f'{name}.json'
        commands.append(('evaluate', '--config', preset, own, agent, other, 'greedy', '--episodes', str(episodes),
                         '--seed', str(seed), '--max-episode-steps', str(horizon_of(experiment)), '--no-render',
                         '--json', str(path)))
        outputs.append(path)
    return Job('reference', agent, preset, None, folder, tuple(commands), tuple(outputs), TEAM_METRIC[experiment.team])


def plan(experiment: Experiment, seeds: Iterable[int], out, steps: int | None = None, threads: int = 1) -> list[Job]:
    """Every job of `experiment` for the run seeds `seeds` in the directory `out`: the references first, then each
    (setting, preset) for each seed. `steps`: decision steps per training run (None: the experiment's budget);
    `threads`: torch threads per training run."""
    out = Path(out)
    steps = int(steps or experiment.steps)
    jobs = [] if experiment.population else [
        _reference(experiment, agent, preset, out) for preset in experiment.presets for agent in experiment.references]
    for seed in seeds:
        for preset in experiment.presets:
            for setting in experiment.settings:
                jobs.append(_population(experiment, setting, preset, seed, steps, out) if setting.command == 'psro'
                            else _training(experiment, setting, preset, seed, steps, out, threads))
    return jobs


_CHILDREN: set[subprocess.Popen] = set()
_CHILDREN_LOCK = threading.Lock()
_STOPPING = threading.Event()
INTERRUPTED = 130
"""The exit status of a job stopped by a signal (`mate train` and `mate psro` checkpoint first)."""
BUSY = 75
"""The status of a job not run because another runner holds its lock (it is running there)."""
JOB_LOCK = '.job.lock'
"""The file in a job's directory locked while a runner runs the job."""
JOB_RUNNER = '.job.runner'
"""The file in a job's directory naming the process running it ('HOST PID'), there while it runs."""


def run_command(commands: Sequence[Sequence[str]], log: str, outputs: Sequence[str] = ()) -> dict:
    """Run the command lines `commands` (after `python -m mate`) one after the other with their output appended to
    `log`, skipping a command whose output file (`outputs[i]`, when given) exists; stops at the first failure.
    Returns {'returncode', 'seconds'}. A job of `run_jobs`, in a thread of this process or a Ray task.

    Each command runs in its own session, so a Ctrl-C at the terminal does not reach it directly: `stop_children`
    (the benchmark command, on Ctrl-C or SIGTERM) or a KeyboardInterrupt here (a cancelled Ray task) sends it one
    SIGTERM, on which `mate train` finishes its iteration, writes its checkpoint and exits with status 130."""
    start = time.perf_counter()
    Path(log).parent.mkdir(parents=True, exist_ok=True)
    return dict(returncode=_run_in_order(commands, log, outputs), seconds=time.perf_counter() - start)


def run_job(job: Job) -> dict:
    """`run_command` of `job` (its commands, its `job.log`), holding the lock of its directory (`JOB_LOCK`): when
    another runner holds it (two runners of the same seeds on one directory, on this machine or on others sharing
    it) nothing runs and the status is `BUSY`; a job another runner has completed meanwhile is not run again
    (status 0). The lock goes with the process that held it, however it ends."""
    job.dir.mkdir(parents=True, exist_ok=True)
    with _locked(job.dir / JOB_LOCK, wait=False) as locked:
        if not locked:
            return dict(returncode=BUSY, seconds=0.0)
        if job.done():
            return dict(returncode=0, seconds=0.0)
        runner = job.dir / JOB_RUNNER
        runner.write_text(f'{socket.gethostname()} {os.getpid()}\n')
        try:
            return run_command(job.commands, str(job.dir / 'job.log'),
                               [str(p) for p in job.outputs] if job.kind == 'reference' else [])
        finally:
            runner.unlink(missing_ok=True)


def job_runner(job: Job) -> str | None:
    """Who runs `job` now, from its `JOB_RUNNER` file: 'pid N' (this machine: checked alive), 'HOST, pid N'
    (another machine: as its runner wrote, not checked); None when no runner runs it (no file, or the process
    that wrote it on this machine is gone, say killed with its runner)."""
    try:
        host, pid = (job.dir / JOB_RUNNER).read_text().split()
        pid = int(pid)
    except (OSError, ValueError):
        return None
    if host != socket.gethostname():
        return f'{host}, pid {pid}'
    if os.name == 'posix':                       # (elsewhere os.kill would end the process)
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return None
        except PermissionError:                  # alive, another user's
            pass
    return f'pid {pid}'


def _run_in_order(commands: Sequence[Sequence[str]], log: str, outputs: Sequence[str]) -> int:
    returncode = 0
    with open(log, 'a') as f:
        for index, command in enumerate(commands):
            if index < len(outputs) and outputs[index] and Path(outputs[index]).exists():
                continue
            if _STOPPING.is_set():
                returncode = INTERRUPTED
                break
            f.write(f'$ mate {" ".join(command)}\n')
            f.flush()
            child = subprocess.Popen(tied_to_parent([sys.executable, '-m', 'mate', *command]), stdout=f,
                                     stderr=subprocess.STDOUT, start_new_session=True)
            with _CHILDREN_LOCK:
                _CHILDREN.add(child)
            try:
                returncode = _wait(child)
            finally:
                with _CHILDREN_LOCK:
                    _CHILDREN.discard(child)
            if returncode:
                break
    return returncode


_TIE = ('import ctypes, os, sys\n'
        'parent = int(sys.argv[1])\n'
        'ctypes.CDLL(None, use_errno=True).prctl(1, 9)\n'        # PR_SET_PDEATHSIG: SIGKILL when the parent dies
        'if os.getppid() != parent:\n'                           # (it died before the line above)
        '    sys.exit(137)\n'
        'os.execv(sys.argv[2], sys.argv[2:])\n')


def tied_to_parent(argv: list[str]) -> list[str]:
    """The command line `argv` made to die with this process (Linux; elsewhere `argv` as it is).

    A job's command runs in its own session (so that a Ctrl-C reaches it only through `stop_children`); if the
    process running the job dies without stopping it (a Ray worker killed, its raylet lost while the machine
    lives on), the command would go on as an orphan while Ray runs the job again, two processes writing one run
    directory. Tied, it is killed with its parent (SIGKILL: it resumes from its last checkpoint, like a lost
    node's job), through a small launcher that asks the kernel for it and then replaces itself with `argv`."""
    if not sys.platform.startswith('linux'):
        return list(argv)
    return [sys.executable, '-c', _TIE, str(os.getpid()), *argv]


def _wait(child: subprocess.Popen) -> int:
    try:
        return child.wait()
    except KeyboardInterrupt:
        child.send_signal(signal.SIGTERM)
        return child.wait()


def stop_children(kill: bool = False) -> int:
    """Ask every running job of this process to stop (SIGTERM: checkpoint, then exit; `kill`: SIGKILL), and start
    no other; returns how many were running."""
    _STOPPING.set()
    with _CHILDREN_LOCK:
        children = [child for child in _CHILDREN if child.poll() is None]
    for child in children:
        child.send_signal(signal.SIGKILL if kill else signal.SIGTERM)
    return len(children)


def write_manifest(experiment: Experiment, jobs: list[Job], out, steps: int, seeds: list[int]) -> Path:
    """`OUT/benchmark.json`: what the directory holds (read by `mate benchmark report`). A directory of another
    experiment or budget raises ValueError (use another --out).

    Runners started side by side on one directory (`--seeds 0,2,4` and `--seeds 1,3`) each merge their jobs
    into it: the read, merge and write hold a lock on `OUT/.benchmark.lock`, and the file is replaced whole
    (a reader never sees it half written)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with _locked(out / '.benchmark.lock'):
        return _merge_manifest(experiment, jobs, out, steps, seeds)


@contextlib.contextmanager
def _locked(path: Path, wait: bool = True):
    """Hold an exclusive lock on `path` (POSIX flock) for the block, yielding True; with `wait` False, yield False
    at once when another process holds it. Where there is no flock (Windows), no lock: True."""
    try:
        import fcntl
    except ImportError:         # pragma: no cover - Windows
        yield True
        return
    with open(path, 'a') as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _merge_manifest(experiment: Experiment, jobs: list[Job], out: Path, steps: int, seeds: list[int]) -> Path:
    path = out / 'benchmark.json'
    manifest = dict(format=BENCHMARK_FORMAT, experiment=experiment.name, steps=steps,
                    eval_every=experiment.eval_interval(steps), eval_episodes=experiment.eval_episodes,
                    horizon=horizon_of(experiment), seed_stride=SEED_STRIDE)
    if path.exists():
        old = read_manifest(out)
        for key in ('experiment', 'steps', 'eval_every', 'eval_episodes', 'horizon'):
            if old.get(key) != manifest[key]:
                raise ValueError(f'{out} holds a benchmark with {key} {old.get(key)!r}, not {manifest[key]!r}; '
                                 'use another --out')
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
    """The `benchmark.json` of a benchmark directory; ValueError when it has none or another format."""
    path = Path(out) / 'benchmark.json'
    if not path.exists():
        raise ValueError(f'{out}: no benchmark.json (not a directory of mate benchmark run)')
    manifest = json.loads(path.read_text())
    if manifest.get('format') != BENCHMARK_FORMAT:
        raise ValueError(f'{path}: format {manifest.get("format")!r}, expected {BENCHMARK_FORMAT!r}')
    return manifest


PATH_OPTIONS = ('--run-dir', '--json', '--out')
"""The options of a job's command lines whose values are paths inside the benchmark directory."""
REUSED_NOTE = 'reused.txt'
"""The file a reused job's directory gets: where it was copied from, and why that is the same job."""


_PATH_VALUE = re.compile(r'(%s) (\S+)' % '|'.join(map(re.escape, PATH_OPTIONS)))


def _masked(line: str) -> tuple[str, set[Path]]:
    """A command line (after 'mate ') with the values of `PATH_OPTIONS` replaced by '<PATH>'; and those paths,
    resolved from the current directory (as the benchmark command that wrote them ran: reuse from the same working
    directory)."""
    paths = {Path(match.group(2)).resolve() for match in _PATH_VALUE.finditer(line)}
    return _PATH_VALUE.sub(lambda match: f'{match.group(1)} <PATH>', line), paths


def _logged_commands(log: Path) -> tuple[set[str], set[Path]]:
    """The distinct command lines a job's log ran ('$ mate ...' lines, written by `run_command`; a resumed run logs
    its line once per session), `_masked`; and all their paths."""
    lines, paths = set(), set()
    for line in log.read_text(errors='replace').splitlines():
        if line.startswith('$ mate '):
            masked, found = _masked(line[len('$ mate '):])
            lines.add(masked)
            paths |= found
    return lines, paths


def reusable(job: Job, out, source) -> Path | None:
    """The directory of the same job in the benchmark directory `source`, when it can stand for `job` of `out`:
    it is complete there and its log ran exactly `job`'s command lines (every option, seed, budget, evaluation
    and thread count), with `source` where `out` is; None otherwise. Experiments that share a setting (fig5's
    MAPPO is fig6's, fig4b's HRL-MAPPO is fig4a's) share its runs this way: a run is a function of its command."""
    out, source = Path(out).resolve(), Path(source).resolve()
    folder = source / job.dir.resolve().relative_to(out)
    twin = dataclasses.replace(job, dir=folder, outputs=tuple(source / p.resolve().relative_to(out)
                                                               for p in job.outputs))
    log = folder / 'job.log'
    if not twin.done() or not log.exists():
        return None
    expected, wanted_paths = set(), set()
    for command in job.commands:
        line, paths = _masked(' '.join(command))      # as `run_command` logs it
        expected.add(line)
        wanted_paths |= {source / path.relative_to(out) for path in paths}
    logged, logged_paths = _logged_commands(log)
    return folder if logged == expected and logged_paths == wanted_paths else None


def reuse_jobs(jobs: list[Job], out, sources: Sequence, say: Callable[[str], None] = print) -> list[Job]:
    """Copy into `out` every job of `jobs` not done there whose twin in one of the benchmark directories `sources`
    is `reusable` (the first found), unless the job's directory already holds something (a run in progress is
    never replaced); its directory gets a `REUSED_NOTE`. Says one line per copied job; returns them."""
    copied = []
    for job in jobs:
        if job.done() or (job.dir.exists() and any(job.dir.iterdir())):
            continue
        for source in sources:
            folder = reusable(job, out, source)
            if folder is None:
                continue
            shutil.copytree(folder, job.dir, dirs_exist_ok=True, ignore=shutil.ignore_patterns(JOB_LOCK, JOB_RUNNER))
            (job.dir / REUSED_NOTE).write_text(
                f'copied from {folder} on {time.strftime("%Y-%m-%dT%H:%M:%S")}: that job ran the same command lines '
                f'(its directory in place of this one)\n')
            say(f'{job.name}: reused from {folder} (the same command lines)')
            copied.append(job)
            break
    return copied


def run_jobs(jobs: list[Job], runner, say: Callable[[str], None] = print) -> list[Job]:
    """Run every job of `jobs` not yet done on `runner` (`mate.runners.ThreadRunner` or `RayRunner`), saying one
    line when each finishes; returns the jobs that did not complete: failed (their log names why), interrupted, or
    skipped because another runner is running them."""
    todo = [job for job in jobs if not job.done()]
    say(f'{len(jobs) - len(todo)} of {len(jobs)} jobs done before; running {len(todo)}')
    failed: list[Job] = []
    finished = 0

    def done(index: int, result: dict) -> None:
        nonlocal finished
        finished += 1
        job = todo[index]
        minutes = result['seconds'] / 60
        if result['returncode'] == 0 and job.done():
            say(f'[{finished}/{len(todo)}] {job.name}: done in {minutes:.1f} min{_summary(job)}')
            return
        failed.append(job)
        if result['returncode'] == BUSY:
            say(f'[{finished}/{len(todo)}] {job.name}: skipped, another runner is running it (it holds '
                f'{job.dir / JOB_LOCK})')
            return
        why = 'interrupted' if result['returncode'] in (INTERRUPTED, -signal.SIGTERM, -signal.SIGINT) else \
            f'failed (exit status {result["returncode"]})'
        say(f'[{finished}/{len(todo)}] {job.name}: {why} after {minutes:.1f} min; log: {job.dir / "job.log"}')

    runner.run([(run_job, dict(job=job)) for job in todo], done, names=[job.name for job in todo])
    return failed


def _summary(job: Job) -> str:
    """What a finished job measured, for its line."""
    if job.kind == 'train':
        absolute = json.loads(job.outputs[0].read_text())
        return f'; absolute {absolute["metric"]} {absolute["mean"]:.3f} ({len(absolute["episodes"])} episodes)'
    if job.kind == 'psro':
        state = json.loads(job.outputs[0].read_text())
        gains = state['iterations'][-1].get('exploitability')
        return '' if gains is None else f'; last exploitability {gains["mean"]:.4f}'
    values = [episode[job.metric] for episode in json.loads(job.outputs[-1].read_text())['episodes']]
    return f'; {job.metric} {sum(values) / len(values):.3f} ({len(values)} episodes)'


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
    it measured ('reused' when copied by --reuse); 'running' (a runner runs it now: `job_runner`) or 'started' (part
    done, no runner now) with how far it is (a training run's logged decision steps and the time left at its rate
    so far, a population run's iterations, a reference's evaluations); or 'waiting'."""
    if job.done():
        reused = ' (reused)' if (job.dir / REUSED_NOTE).exists() else ''
        return 'done', f'{job.name}: done{_summary(job)}{reused}'
    runner = job_runner(job)
    progress = _progress(job, steps, running=runner is not None)
    if runner is not None:
        return 'running', f'{job.name}: {progress or "starting"} (running: {runner})'
    if progress is not None:
        return 'started', f'{job.name}: {progress}'
    return 'waiting', f'{job.name}: waiting'


def _progress(job: Job, steps: int, running: bool) -> str | None:
    """How far a job that is not done has come, or None before anything of it was written."""
    if job.kind == 'psro' and job.outputs[0].exists():
        state = json.loads(job.outputs[0].read_text())
        done, total = max(len(state['iterations']) - 1, 0), int(state['settings']['iterations'])
        return f'{done} of {total} iterations'
    if job.kind == 'reference' and any(path.exists() for path in job.outputs):
        return f'{sum(path.exists() for path in job.outputs)} of {len(job.outputs)} evaluations'
    logged = logged_steps(job.dir) if job.kind == 'train' else None
    if logged is None:
        return None
    text = f'{logged:,} of {steps:,} decision steps ({100 * min(logged, steps) // steps} %)'
    rate = logged_rate(job.dir)
    if rate and logged < steps:
        return f'{text}; {_duration((steps - logged) / rate)} left at its rate so far ({rate:,.0f} steps/s)'
    if logged >= steps:
        return f'{text}; {"its absolute metric" if running else "its absolute metric is missing: run again"}'
    return text
