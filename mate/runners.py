"""Where independent jobs run: in this process, in a pool of local processes or threads, or as Ray tasks.

    runner = LocalRunner(workers=2)            # ThreadRunner(2) for jobs that wait on subprocesses;
                                               # RayRunner('auto', task_cpus=2) on a cluster
    runner.run([(function, kwargs), ...], done=lambda index, result: ...)
    runner.close()

A job is a module-level function and its keyword arguments (both picklable); `done(index, result)` is called in
this process as each job finishes, in the order they finish. Used by `mate psro` (best responses, payoff chunks)
and `mate benchmark run` (training runs, references).
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ['LocalRunner', 'RayRunner', 'RunnerError', 'ThreadRunner']


class RunnerError(RuntimeError):
    """A runner that cannot start (Ray missing)."""


class LocalRunner:
    """Runs jobs in this process (workers = 1) or in a pool of `workers` processes (spawned: numba and
    torch are not fork-safe once they run threads)."""

    def __init__(self, workers: int = 1) -> None:
        self.workers = int(workers)
        self.pool = None
        if self.workers > 1:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            self.pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context('spawn'))

    @property
    def parallel(self) -> int:
        return self.workers

    def run(self, jobs: list[tuple[Callable, dict]], done: Callable[[int, object], None]) -> None:
        """Run `jobs` [(function, kwargs)], calling `done(index, result)` as each finishes."""
        if self.pool is None:
            for index, (function, kwargs) in enumerate(jobs):
                done(index, function(**kwargs))
            return
        from concurrent.futures import as_completed

        futures = {self.pool.submit(function, **kwargs): index for index, (function, kwargs) in enumerate(jobs)}
        for future in as_completed(futures):
            done(futures[future], future.result())

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(cancel_futures=True)


class ThreadRunner:
    """Runs jobs in `workers` threads of this process: for jobs that spend their time waiting on a subprocess (the
    training runs of `mate benchmark`), so that this process keeps every child in reach (signals go to the main
    thread, which can stop the children cleanly)."""

    def __init__(self, workers: int = 1) -> None:
        from concurrent.futures import ThreadPoolExecutor

        self.workers = int(workers)
        self.pool = ThreadPoolExecutor(self.workers)

    @property
    def parallel(self) -> int:
        return self.workers

    def run(self, jobs: list[tuple[Callable, dict]], done: Callable[[int, object], None]) -> None:
        """Run `jobs` [(function, kwargs)], calling `done(index, result)` (in this thread) as each finishes."""
        from concurrent.futures import as_completed

        futures = {self.pool.submit(function, **kwargs): index for index, (function, kwargs) in enumerate(jobs)}
        for future in as_completed(futures):
            done(futures[future], future.result())

    def close(self) -> None:
        """Wait for the running jobs; drop the ones not started."""
        self.pool.shutdown(wait=True, cancel_futures=True)


class RayRunner:
    """Runs jobs as Ray tasks: on an existing cluster (`address` 'auto' or 'ray://host:port') or a local
    Ray instance (`address` None, with `num_cpus` CPUs). Each task asks for `task_cpus` CPUs."""

    def __init__(self, address: str | None = None, num_cpus: int | None = None, task_cpus: int = 1) -> None:
        try:
            import ray
        except ImportError:
            raise RunnerError("running on Ray needs Ray: pip install 'mate[rllib]'") from None
        self.task_cpus = int(task_cpus)
        self.ray = ray
        self.owned = not ray.is_initialized()
        if self.owned:
            kwargs = dict(address=address) if address else dict(num_cpus=num_cpus, include_dashboard=False)
            ray.init(log_to_driver=False, configure_logging=False, **kwargs)
        self._remote = {}

    @property
    def parallel(self) -> int:
        return max(1, int(self.ray.cluster_resources().get('CPU', 1)) // self.task_cpus)

    def run(self, jobs: list[tuple[Callable, dict]], done: Callable[[int, object], None]) -> None:
        refs = {}
        for index, (function, kwargs) in enumerate(jobs):
            remote = self._remote.setdefault(function, self.ray.remote(num_cpus=self.task_cpus)(function))
            refs[remote.remote(**kwargs)] = index
        pending = list(refs)
        try:
            while pending:
                finished, pending = self.ray.wait(pending, num_returns=1)
                done(refs[finished[0]], self.ray.get(finished[0]))
        except KeyboardInterrupt:
            # stop the tasks (a KeyboardInterrupt inside each: a job may stop its own work cleanly) and give them
            # time to do so before the runner closes
            for ref in pending:
                self.ray.cancel(ref)
            self.ray.wait(pending, num_returns=len(pending), timeout=600)
            raise

    def close(self) -> None:
        if self.owned:
            self.ray.shutdown()
