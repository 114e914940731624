"""Where independent jobs run: in this process, in a pool of local processes or threads, or as Ray tasks.

    runner = LocalRunner(workers=2)            # ThreadRunner(2) for jobs that wait on subprocesses;
                                               # RayRunner('auto', task_cpus=2) on a cluster
    policy = runner.share(policy_bytes)        # Ray: put into the object store once, for every job that names it
    runner.run([(function, kwargs), ...], done=lambda index, result: ..., names=['job a', ...])
    runner.close()

A job is a module-level function and its keyword arguments (both picklable; a `share`d value may sit anywhere in the
arguments, inside lists and dicts too). `done(index, result)` is called in this process exactly once per job that
finishes, in the order they finish. A job that raises does not stop the others: `failed(name, reason)` (when given)
hears of it at once, the jobs still running are waited for (and their `done` called), then `run` raises `JobFailed`
naming every failed job. A `done` that returns `STOP` (a job that a signal interrupted, say) starts no further job:
the jobs not yet started are dropped, never reported; the ones already running are waited for (on Ray, cancelled:
each hears a KeyboardInterrupt and may stop cleanly) and `run` returns. On Ray, a job whose worker or node is lost
(a node dies, a worker is killed) is run again, up to `retries` times, and counted once; a job that raises is never
retried. After each finished job, `runner.timings[index]` holds its measured costs (`seconds` of its own work,
`wall` from submission to result in this process, `fetch` of its shared arguments, the `node` it ran on). Used by
`mate psro` (best responses, payoff entries) and `mate benchmark run` (training runs, references).
"""

from __future__ import annotations

import time
from collections.abc import Callable

__all__ = ['STOP', 'JobFailed', 'LocalRunner', 'RayRunner', 'RunnerError', 'Shared', 'ThreadRunner', 'describe_error']

STOP = 'stop'
"""What `done(index, result)` returns to start no further job of the `run` (a job stopped by a signal: the next
one would otherwise start, and a Ctrl-C would not stop the stage)."""

RAY_RETRIES = 3
"""How often a Ray job lost to a system failure (its worker process or node died) is run again (Ray's default)."""


class RunnerError(RuntimeError):
    """A runner that cannot start (Ray missing), or jobs that failed (`JobFailed`)."""


class JobFailed(RunnerError):
    """Jobs that raised, or that lost their worker more often than the retries allow.

    `failures`: [(job name, one-line reason)], in the order they failed. The message names each one:
    'the camera best response of iteration 2 failed: ValueError: ...'."""

    def __init__(self, failures: list[tuple[str, str]]) -> None:
        self.failures = list(failures)
        text = '; '.join(f'{name} failed: {reason}' for name, reason in self.failures)
        super().__init__(text if len(self.failures) == 1 else f'{len(self.failures)} jobs failed: {text}')


def describe_error(exc: BaseException, limit: int = 300) -> str:
    """`exc` as one line, 'TypeName: message' (whitespace collapsed, at most `limit` characters)."""
    text = ' '.join(str(exc).split())
    line = f'{type(exc).__name__}: {text}' if text else type(exc).__name__
    return line if len(line) <= limit else line[:limit - 3] + '...'


class Shared:
    """A value put into Ray's object store once (`RayRunner.share`); the job's process reads it back before the job
    starts, wherever the handle sits in the job's arguments. `ref`: the Ray ObjectRef."""

    __slots__ = ('ref',)

    def __init__(self, ref) -> None:
        self.ref = ref


def _handles(value, found: list) -> None:
    if isinstance(value, Shared):
        found.append(value)
    elif isinstance(value, (list, tuple)):
        for item in value:
            _handles(item, found)
    elif isinstance(value, dict):
        for item in value.values():
            _handles(item, found)


def _substitute(value, values: dict):
    if isinstance(value, Shared):
        return values[id(value)]
    if isinstance(value, list):
        return [_substitute(item, values) for item in value]
    if isinstance(value, tuple):
        return tuple(_substitute(item, values) for item in value)
    if isinstance(value, dict):
        return {key: _substitute(item, values) for key, item in value.items()}
    return value


def _timed_call(function: Callable, kwargs: dict) -> dict:
    """Run one job where it was sent (a pool process or thread): {'result', 'seconds' of the call}."""
    start = time.perf_counter()
    result = function(**kwargs)
    return dict(result=result, seconds=time.perf_counter() - start, fetch=0.0, node='local')


def _ray_call(function: Callable, kwargs: dict) -> dict:
    """Run one job in a Ray worker: read its shared arguments from the object store (one `ray.get`), call it.
    Returns {'result', 'seconds' of the call, 'fetch' seconds of the shared arguments, 'node' id}."""
    import ray

    start = time.perf_counter()
    handles: list[Shared] = []
    _handles(kwargs, handles)
    if handles:
        values = ray.get([handle.ref for handle in handles])
        kwargs = _substitute(kwargs, {id(handle): value for handle, value in zip(handles, values)})
    fetched = time.perf_counter()
    result = function(**kwargs)
    return dict(result=result, seconds=time.perf_counter() - fetched, fetch=fetched - start,
                node=ray.get_runtime_context().get_node_id())


class _Runner:
    """What every runner shares: job names, failures collected while the other jobs go on, timings."""

    timings: list
    workers: int

    @property
    def parallel(self) -> int:
        """How many jobs run at once (`workers`; Ray's runner counts its cluster's CPUs)."""
        return self.workers

    def share(self, value):
        """A handle on `value` for the jobs' arguments: the value itself here (each job receives its own copy)."""
        return value

    def _start(self, jobs: list, names: list[str] | None) -> list[str]:
        if names is not None and len(names) != len(jobs):
            raise ValueError(f'{len(names)} names for {len(jobs)} jobs')
        self.timings = [None] * len(jobs)
        self._failures: list[tuple[str, str]] = []
        self._reported: set[int] = set()
        return list(names) if names is not None else [f'{getattr(function, "__name__", "job")} #{i}'
                                                      for i, (function, _) in enumerate(jobs)]

    def _finished(self, index: int, outcome: dict, wall: float, done: Callable) -> bool:
        """Report a finished job to `done`; True when `done` asks for no further job (`STOP`)."""
        if index in self._reported:        # never: each job is reported once (a retried job has one result)
            raise RuntimeError(f'job {index} reported twice')
        self._reported.add(index)
        self.timings[index] = dict(seconds=outcome['seconds'], wall=wall, fetch=outcome['fetch'],
                                   node=outcome['node'])
        return done(index, outcome['result']) == STOP

    def _failed(self, index: int, name: str, reason: str, failed: Callable | None) -> None:
        self._reported.add(index)
        self._failures.append((name, reason))
        if failed is not None:
            failed(name, reason)

    def _end(self) -> None:
        if self._failures:
            raise JobFailed(self._failures)

    def _run_in_pool(self, jobs: list, names: list[str], done: Callable, failed: Callable | None) -> None:
        """Submit every job to `self.pool` (a `concurrent.futures` executor of processes or threads) and report
        each as it finishes; JobFailed at the end naming the jobs that raised (or whose process died)."""
        from concurrent.futures import as_completed

        submitted = time.perf_counter()
        futures = {self.pool.submit(_timed_call, function, kwargs): index
                   for index, (function, kwargs) in enumerate(jobs)}
        for future in as_completed(futures):
            index = futures[future]
            if future.cancelled():          # dropped after a STOP before it started
                continue
            try:
                outcome = future.result()
            except Exception as exc:  # noqa: BLE001  (the job raised, or its process died)
                self._failed(index, names[index], describe_error(exc), failed)
                continue
            if self._finished(index, outcome, time.perf_counter() - submitted, done):
                for other in futures:
                    other.cancel()          # the ones not started yet; the running ones go on and are reported
        self._end()


class LocalRunner(_Runner):
    """Runs jobs in this process (workers = 1) or in a pool of `workers` processes (spawned: numba and
    torch are not fork-safe once they run threads)."""

    def __init__(self, workers: int = 1) -> None:
        self.workers = int(workers)
        self.pool = None
        self.timings = []
        if self.workers > 1:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            self.pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context('spawn'))

    def run(self, jobs: list[tuple[Callable, dict]], done: Callable[[int, object], None],
            names: list[str] | None = None, failed: Callable[[str, str], None] | None = None,
            gpu_share: float = 1.0) -> None:
        """Run `jobs` [(function, kwargs)], calling `done(index, result)` as each finishes; JobFailed at the end
        naming the jobs that raised (`names[index]`; `failed(name, reason)` hears of each at once). `gpu_share`:
        for Ray's runner only."""
        names = self._start(jobs, names)
        if self.pool is None:
            for index, (function, kwargs) in enumerate(jobs):
                submitted = time.perf_counter()
                try:
                    outcome = _timed_call(function, kwargs)
                except Exception as exc:  # noqa: BLE001  (a job's own failure: named, the run goes on)
                    self._failed(index, names[index], describe_error(exc), failed)
                    continue
                if self._finished(index, outcome, time.perf_counter() - submitted, done):
                    break
            self._end()
            return
        self._run_in_pool(jobs, names, done, failed)

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(cancel_futures=True)


class ThreadRunner(_Runner):
    """Runs jobs in `workers` threads of this process: for jobs that spend their time waiting on a subprocess (the
    training runs of `mate benchmark`), so that this process keeps every child in reach (signals go to the main
    thread, which can stop the children cleanly)."""

    def __init__(self, workers: int = 1) -> None:
        from concurrent.futures import ThreadPoolExecutor

        self.workers = int(workers)
        self.pool = ThreadPoolExecutor(self.workers)
        self.timings = []

    def run(self, jobs: list[tuple[Callable, dict]], done: Callable[[int, object], None],
            names: list[str] | None = None, failed: Callable[[str, str], None] | None = None,
            gpu_share: float = 1.0) -> None:
        """Run `jobs` [(function, kwargs)], calling `done(index, result)` (in this thread) as each finishes;
        JobFailed at the end naming the jobs that raised."""
        self._run_in_pool(jobs, self._start(jobs, names), done, failed)

    def close(self) -> None:
        """Wait for the running jobs; drop the ones not started."""
        self.pool.shutdown(wait=True, cancel_futures=True)


class RayRunner(_Runner):
    """Runs jobs as Ray tasks: on an existing cluster (`address` 'auto' or 'ray://host:port') or a local
    Ray instance (`address` None, with `num_cpus` CPUs); when Ray is already initialised (a test's cluster), on
    that one. Each task asks for `task_cpus` CPUs (and `task_gpus` GPUs, a fraction allowed).

    Faults: a task whose worker process or node dies is run again by Ray, up to `retries` times, on any node with
    room (jobs are deterministic given their arguments, so the retry gives the result the lost run would have);
    `done` still hears of it once. A task that raises is not retried: `run` raises JobFailed naming it."""

    def __init__(self, address: str | None = None, num_cpus: int | None = None, task_cpus: int = 1,
                 retries: int = RAY_RETRIES, task_gpus: float = 0) -> None:
        try:
            import ray
        except ImportError:
            raise RunnerError("running on Ray needs Ray: pip install 'mate[rllib]'") from None
        if int(retries) < 0:
            raise ValueError(f'retries must be >= 0, got {retries!r}')
        self.task_cpus, self.task_gpus, self.retries = int(task_cpus), float(task_gpus), int(retries)
        self.ray = ray
        self.timings = []
        self.owned = not ray.is_initialized()
        if self.owned:
            kwargs = (dict(address=address) if address else           # None: a new local instance, always
                      dict(address='local', num_cpus=num_cpus, include_dashboard=False))
            try:
                ray.init(log_to_driver=False, configure_logging=False, **kwargs)
            except ConnectionError as exc:
                raise RunnerError(f'cannot reach the Ray cluster at {address!r}: {" ".join(str(exc).split())}') \
                    from None
        if self.task_gpus > 0 and ray.cluster_resources().get('GPU', 0) < self.task_gpus:
            found = ray.cluster_resources().get('GPU', 0)
            self.close()
            raise RunnerError(f'jobs on GPUs (--device cuda) need a Ray cluster with GPUs; this one has {found:g}')
        self._remote = ray.remote(num_cpus=self.task_cpus, num_gpus=self.task_gpus, max_retries=self.retries,
                                  retry_exceptions=False)(_ray_call)

    @property
    def parallel(self) -> int:
        return max(1, int(self.ray.cluster_resources().get('CPU', 1)) // max(1, self.task_cpus))

    def share(self, value):
        """Put `value` into the object store once; the handle travels in any number of jobs' arguments (each node
        fetches the value once, not each job)."""
        return Shared(self.ray.put(value))

    def run(self, jobs: list[tuple[Callable, dict]], done: Callable[[int, object], None],
            names: list[str] | None = None, failed: Callable[[str, str], None] | None = None,
            gpu_share: float = 1.0) -> None:
        """Run `jobs` [(function, kwargs)] as tasks named `names`, calling `done(index, result)` as each finishes;
        JobFailed at the end naming the jobs that raised or were lost more than `retries` times. `gpu_share`: the
        share of `task_gpus` each of these jobs asks for (small jobs can share a GPU)."""
        ray = self.ray
        names = self._start(jobs, names)
        refs, submitted = {}, {}
        options = dict(num_gpus=self.task_gpus * float(gpu_share)) if self.task_gpus and gpu_share != 1 else {}
        for index, (function, kwargs) in enumerate(jobs):
            ref = self._remote.options(name=names[index][:200], **options).remote(function, kwargs)
            refs[ref], submitted[index] = index, time.perf_counter()
        pending, stopping = list(refs), False
        try:
            while pending:
                finished, pending = ray.wait(pending, num_returns=1)
                index = refs[finished[0]]
                try:
                    outcome = ray.get(finished[0])
                except ray.exceptions.RayError as exc:
                    cause = getattr(exc, 'cause', None)
                    cancelled = ray.exceptions.TaskCancelledError
                    if stopping and (isinstance(exc, cancelled) or isinstance(cause, cancelled)):
                        continue                                    # cancelled after a STOP (running or queued)
                    if isinstance(exc, ray.exceptions.RayTaskError):   # the job raised: its own failure
                        self._failed(index, names[index], describe_error(cause if cause is not None else exc), failed)
                        continue
                    self._failed(index, names[index], f'lost after {self.retries} retries ({describe_error(exc)})',
                                 failed)                            # lost more often than the retries allow
                    continue
                if self._finished(index, outcome, time.perf_counter() - submitted[index], done) and not stopping:
                    stopping = True
                    for ref in pending:
                        ray.cancel(ref)
        except KeyboardInterrupt:
            # stop the tasks (a KeyboardInterrupt inside each: a job may stop its own work cleanly) and give them
            # time to do so before the runner closes
            for ref in pending:
                ray.cancel(ref)
            ray.wait(pending, num_returns=len(pending), timeout=600)
            raise
        self._end()

    def close(self) -> None:
        if self.owned:
            self.ray.shutdown()
