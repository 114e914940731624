"""The local runners keep the contract of `mate.tools.runners` that the Ray runner keeps on a cluster: every finished
job reported once, a job that raises named in one line at the end after the others have run, its timings kept."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest
from conftest import needs_extra

from mate.benchmark.jobs import parse_seeds
from mate.tools.runners import STOP, JobFailed, LocalRunner, ThreadRunner, describe_error


@pytest.mark.parametrize('make', [lambda: LocalRunner(1), lambda: LocalRunner(2), lambda: ThreadRunner(2)],
                         ids=['in-process', 'process-pool', 'threads'])
def test_a_failing_job_is_named_after_the_others_have_finished(make):
    runner = make()
    texts = ['0-2', '4', 'x', '5,7']           # 'x' is no seed list: parse_seeds raises ValueError
    finished, failures = [], []
    try:
        with pytest.raises(JobFailed) as raised:
            runner.run([(parse_seeds, dict(text=text)) for text in texts], lambda i, r: finished.append((i, r)),
                       names=[f'seeds {text!r}' for text in texts], failed=lambda n, r: failures.append((n, r)))
    finally:
        runner.close()
    reason = "ValueError: --seeds: seeds as '0-4', '0,2,5' or '3', got 'x'"
    assert sorted(finished) == [(0, [0, 1, 2]), (1, [4]), (3, [5, 7])]
    assert failures == [("seeds 'x'", reason)] and raised.value.failures == failures
    assert str(raised.value) == f"seeds 'x' failed: {reason}"
    assert runner.timings[2] is None and all(runner.timings[i]['seconds'] >= 0 for i in (0, 1, 3))


def test_names_must_match_the_jobs_and_errors_read_as_one_line():
    with pytest.raises(ValueError, match='1 names for 2 jobs'):
        LocalRunner(1).run([(parse_seeds, dict(text='1'))] * 2, lambda i, r: None, names=['one'])
    assert describe_error(ValueError('two\n  lines')) == 'ValueError: two lines'
    assert describe_error(KeyError()) == 'KeyError'
    assert len(describe_error(RuntimeError('x' * 1000))) == 300
    assert str(JobFailed([('a', 'E: 1'), ('b', 'E: 2')])) == '2 jobs failed: a failed: E: 1; b failed: E: 2'


def _stopping_job(name: str, trace: str, pause: float = 0.0) -> str:
    """Appends `name` to the file `trace` (the jobs that started), waits `pause` seconds and returns `name`."""
    with open(trace, 'a') as file:
        file.write(name + '\n')
    time.sleep(pause)
    return name


@pytest.mark.parametrize('workers', [0, 1], ids=['in-process', 'threads'])
def test_a_done_that_returns_stop_starts_no_further_job(workers, tmp_path):
    """`done` returning STOP (a job a signal interrupted): the jobs not yet started never run nor are reported, and
    `run` returns without an error. In a pool, the job a free worker took at once goes on (it pauses 2 s so that
    the third is surely still queued when the first is reported)."""
    trace = tmp_path / 'started'
    runner, reported = (ThreadRunner(1) if workers else LocalRunner(1)), []

    def done(index, result):
        reported.append((index, result))
        return STOP if result == 'first' else None

    pauses = dict(first=0.0, second=2.0 if workers else 0.0, third=0.0)
    try:
        runner.run([(_stopping_job, dict(name=name, trace=str(trace), pause=pause)) for name, pause in pauses.items()],
                   done)
    finally:
        runner.close()
    started = trace.read_text().split()
    assert reported[0] == (0, 'first') and 'third' not in started and runner.timings[2] is None
    if workers:    # the second had started in the free worker: it is waited for and reported
        assert reported == [(0, 'first'), (1, 'second')][:len(started)]
    else:          # in this process nothing else runs: the second never starts
        assert reported == [(0, 'first')] and started == ['first'] and runner.timings[1] is None


@pytest.mark.slow
def test_a_stop_on_ray_cancels_the_jobs_still_pending(tmp_path):
    """On a one-CPU Ray instance: after `done` returns STOP for the first job, the third (queued behind the second)
    never starts nor is reported, and `run` returns without an error; the second, started as the first ended, is
    asked to stop (a KeyboardInterrupt), and reported only if it finished anyway."""
    from mate.tools.runners import RayRunner

    ray = needs_extra('ray')
    if ray.is_initialized():     # an instance an earlier test left: this test needs one CPU, so that jobs queue
        ray.shutdown()
    trace = tmp_path / 'started'
    runner, reported = RayRunner(None, num_cpus=1), []

    def done(index, result):
        reported.append(index)
        return STOP

    def job(name, pause):    # a function Ray's workers can import (this module they cannot): a child process
        code = f'import time; open({str(trace)!r}, "a").write({name!r} + " "); time.sleep({pause})'
        return subprocess.run, dict(args=[sys.executable, '-c', code])

    try:
        runner.run([job('first', 0), job('second', 30), job('third', 0)], done)
    finally:
        runner.close()
    assert reported in ([0], [0, 1]) and 'third' not in trace.read_text().split()
