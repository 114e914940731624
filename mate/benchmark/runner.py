"""`mate benchmark run`: the jobs of an experiment (`mate.benchmark.jobs`) run as independent processes, on this
machine (`mate.tools.runners.ThreadRunner`) or as Ray tasks (`RayRunner`), one line per finished job.

    from mate.benchmark.directory import write_manifest
    from mate.benchmark.experiments import experiment
    from mate.benchmark.jobs import plan
    from mate.benchmark.runner import run_jobs
    from mate.tools.runners import ThreadRunner

    smoke = experiment('smoke')                 # or mate.benchmark.user.load_experiment('my_experiment.py')
    jobs = plan(smoke, seeds=[0], out='bench/smoke')
    write_manifest(smoke, jobs, 'bench/smoke', steps=smoke.steps, seeds=[0])   # what report and status read
    failed = run_jobs(jobs, ThreadRunner(2), say=print)     # runs the missing ones, two at a time

Each job runs under a lock of its directory (`JOB_LOCK`; two runners never run one job) and names its process in
`JOB_RUNNER` while it runs (`mate benchmark status` reads it). Every job resumes from what it left: a training run
from its checkpoint, a population run from its state. Ctrl-C or SIGTERM (`stop_children`) stop every running job
at a checkpoint.
"""

from __future__ import annotations

import contextlib
import os
import shlex
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from .identity import wanted_config, write_job_config
from .jobs import Job

__all__ = ['BUSY', 'INTERRUPTED', 'JOB_LOCK', 'JOB_RUNNER', 'job_runner', 'locked', 'run_command', 'run_job',
           'run_jobs', 'stop_children', 'tied_to_parent']

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
    returncode = 0
    with open(log, 'a') as f:
        for index, command in enumerate(commands):
            if index < len(outputs) and outputs[index] and Path(outputs[index]).exists():
                continue
            if _STOPPING.is_set():
                returncode = INTERRUPTED
                break
            f.write(f'$ mate {shlex.join(command)}\n')
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
    return dict(returncode=returncode, seconds=time.perf_counter() - start)


def run_job(job: Job) -> dict:
    """`run_command` of `job` (its commands, its `job.log`), holding the lock of its directory (`JOB_LOCK`): when
    another runner holds it (two runners of the same seeds on one directory, on this machine or on others sharing
    it) nothing runs and the status is `BUSY`; a job another runner has completed meanwhile is not run again
    (status 0, `elsewhere` true). The lock goes with the process that held it, however it ends. As it starts the
    job it writes the job's resolved config to `JOB_DIR/job.json` (`mate.benchmark.identity`), what `--reuse` and
    `--extend` compare."""
    job.dir.mkdir(parents=True, exist_ok=True)
    with locked(job.dir / JOB_LOCK, wait=False) as holding:
        if not holding:
            return dict(returncode=BUSY, seconds=0.0)
        if job.done():
            return dict(returncode=0, seconds=0.0, elsewhere=True)
        runner = job.dir / JOB_RUNNER
        runner.write_text(f'{socket.gethostname()} {os.getpid()}\n')
        if (configs := wanted_config(job)) is not None:     # a refused command line says why in the log
            write_job_config(job, configs)
        try:
            each = job.kind == 'reference' and len(job.outputs) == len(job.commands)   # a command per output file
            return run_command(job.commands, str(job.dir / 'job.log'), [str(p) for p in job.outputs] if each else [])
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


@contextlib.contextmanager
def locked(path: Path, wait: bool = True):
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


def run_jobs(jobs: list[Job], runner, say: Callable[[str], None] = print) -> list[Job]:
    """Run every job of `jobs` not yet done on `runner` (`mate.tools.runners.ThreadRunner` or `RayRunner`), saying one
    line when each finishes; returns the jobs that did not complete here: failed (their log names why) or
    interrupted. A job another runner is running is skipped (`BUSY`), not failed: the last line says how many of
    those are still running there."""
    todo = [job for job in jobs if not job.done()]
    say(f'{len(jobs) - len(todo)} of {len(jobs)} jobs done before; running {len(todo)}')
    failed: list[Job] = []
    elsewhere: list[Job] = []
    finished = 0

    def done(index: int, result: dict) -> None:
        nonlocal finished
        finished += 1
        job = todo[index]
        minutes = result['seconds'] / 60
        if result['returncode'] == 0 and job.done():
            how = 'done by another runner meanwhile' if result.get('elsewhere') else f'done in {minutes:.1f} min'
            say(f'[{finished}/{len(todo)}] {job.name}: {how}{job.measured()}')
            return
        if result['returncode'] == BUSY:
            elsewhere.append(job)
            say(f'[{finished}/{len(todo)}] {job.name}: skipped, another runner is running it (it holds '
                f'{job.dir / JOB_LOCK})')
            return
        failed.append(job)
        why = 'interrupted' if result['returncode'] in (INTERRUPTED, -signal.SIGTERM, -signal.SIGINT) else \
            f'failed (exit status {result["returncode"]})'
        say(f'[{finished}/{len(todo)}] {job.name}: {why} after {minutes:.1f} min; log: {job.dir / "job.log"}')

    runner.run([(run_job, dict(job=job)) for job in todo], done, names=[job.name for job in todo])
    running = [job for job in elsewhere if not job.done()]
    if running:
        say(f'{len(running)} job{"s" * (len(running) > 1)} still running in another runner: '
            f'{", ".join(job.name for job in running)}')
    return failed
