"""A job run again gives what its first run gave: the case of a best response whose training was complete when
its result was lost (its node died before the driver had it, or the driver died before saving it)."""

from __future__ import annotations

import pytest
from conftest import needs_extra

needs_extra('torch')

from mate.learn.population.jobs import best_response   # noqa: E402

ENV = dict(env_id='MATE-2v4-0-v0', config=None)


@pytest.mark.slow
def test_a_best_response_run_again_on_its_finished_run_directory_returns_the_same_result(tmp_path):
    # 4 envs x 600 decisions: each env finishes an episode of 500 decisions (the trainer's horizon)
    arguments = dict(team='target', env=ENV, opponents=['random'], weights=[1.0], steps=2400, seed=0,
                     run_dir=str(tmp_path / 'br'), num_envs=4)
    first = best_response(**arguments)
    again = best_response(**arguments)          # nothing left to train: resumes at its end
    first.pop('seconds'), again.pop('seconds')
    assert first['steps'] == 2400 and first['episode_return'] == first['episode_return']     # (not NaN)
    assert again == first
