"""Exact resumes of the off-policy trainers (IQL, QMIX, MA-TD3): a run stopped by SIGINT and resumed with the same
config ends as the run never stopped (its end-of-session checkpoint holds the replay); a run resumed from a
periodic checkpoint (no replay: after a crash) refills its replay and runs to its end."""

from __future__ import annotations

import numpy as np
import pytest

from mate.learn import iql, matd3, qmix
from mate.policies.checkpoint import load_checkpoint

from .resume import assert_same_run, stopped_and_resumed

# 8 MATE-4v8-9 games (cameras; targets: MATE-2v4-0) x 10 decisions per episode, a log row every 64 decision steps:
# 5 iterations; updates every 16 decision steps from step 64 on, replays of 200 that wrap before the stop
SMALL = dict(seed=1, steps=320, num_envs=8, horizon=50, buffer_size=200, batch_size=16, update_every=16,
             learning_starts=64, report_every=64, hidden=(16,), threads=1, progress=False)
STATE = ('networks', 'optimizer', 'rng', 'schedule', 'hidden', 'noise', 'updates')
"""The algorithm state's entries compared bitwise (whichever a trainer has)."""

TRAINERS = {
    'iql': (iql.train, lambda **kw: iql.IQLConfig(**{**SMALL, 'hrl': True, 'target_update': 48, **kw})),
    'qmix': (qmix.train, lambda **kw: qmix.QMIXConfig(**{**SMALL, 'sequence_length': 4, 'mixer_embed': 8,
                                                          'target_update': 48, **kw})),
    'matd3': (matd3.train, lambda **kw: matd3.MATD3Config(**{**SMALL, 'team': 'target', 'horizon': 100,
                                                             'random_steps': 96, **kw})),
}
"""Each trainer and its small config (keyword arguments override the settings)."""


def _replays_equal(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for key in a:
        if isinstance(a[key], dict):
            _replays_equal(a[key], b[key])
        else:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)


@pytest.mark.parametrize('name', list(TRAINERS))
def test_a_stopped_run_resumes_exactly(name, tmp_path):
    train, config = TRAINERS[name]
    straight, stopped = stopped_and_resumed(
        train, lambda run_dir, fresh: config(run_dir=run_dir, fresh=fresh), stop_at=2, folder=tmp_path)
    assert_same_run(straight, stopped, entries=STATE)
    a, b = (load_checkpoint(folder / 'checkpoint.pt')['state'] for folder in (straight, stopped))
    _replays_equal(a['replay'], b['replay'])
    assert a['schedule']['next_report'] == 384 and a['replay']['size'] > 0


@pytest.mark.parametrize('name', list(TRAINERS))
def test_a_run_resumed_from_a_periodic_checkpoint_refills_its_replay(name, tmp_path):
    train, config = TRAINERS[name]

    def crash(row):
        if row['iteration'] == 3:
            periodic = load_checkpoint(tmp_path / 'checkpoint.pt')
            assert periodic['run']['iteration'] == 2 and 'replay' not in periodic['state']
            raise RuntimeError('crash')

    # learning from decision step 96 on: updates in iterations 2 (steps 65-128) and 3 of the first session
    settings = dict(run_dir=str(tmp_path), checkpoint_every=2, learning_starts=96)
    with pytest.raises(RuntimeError, match='crash'):
        train(config(**settings, fresh=True), callback=crash)
    rows = []
    resumed = train(config(**settings), callback=rows.append)
    assert not resumed.interrupted and resumed.iteration == 5 and resumed.env_steps == 320
    assert [row['iteration'] for row in rows] == [3, 4, 5]
    # resumed at step 128 with an empty replay: no update before step 128 + 96 (in iteration 4)
    loss = 'critic_loss' if name == 'matd3' else 'loss'
    assert np.isnan(rows[0][loss]) and np.isfinite(rows[1][loss]) and np.isfinite(rows[2][loss])
    assert (tmp_path / 'final.pt').exists()
