"""The local runners keep the contract of `mate.runners` that the Ray runner keeps on a cluster: every finished job
reported once, a job that raises named in one line at the end after the others have run, its timings kept."""

from __future__ import annotations

import pytest

from mate.benchmark.jobs import parse_seeds
from mate.runners import JobFailed, LocalRunner, ThreadRunner, describe_error


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
