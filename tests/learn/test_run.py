"""A training run's files and life (mate.learn.run.Run): CSV rows (TensorBoard scalars when installed, a notice
when not), one row per iteration after a resume, the budget, and the checkpoint's counters."""

from __future__ import annotations

import csv
import sys

import pytest

from conftest import needs_extra
from mate.policies.checkpoint import CheckpointError, load_checkpoint
from mate.learn.run import TENSORBOARD_MISSING, Run

from .toy import CueMatching

SPEC = CueMatching().spec


def _run(run_dir, progress=False, resume=True, total_steps=100) -> Run:
    return Run(run_dir, 'toy', {'setting': 1}, SPEC, total_steps=total_steps, checkpoint_every=2, progress=progress,
               resume=resume)


def _iterations(run: Run, count: int) -> None:
    for _ in range(count):
        run.end_iteration(10, [0.5], [dict(coverage=0.5, length=4, raw_return=0.0, **{'return': 1.0})], {'loss': 1.0},
                          save=lambda: {'marker': run.iteration})


def _rows(path) -> list[dict]:
    with open(path, newline='') as f:
        return list(csv.DictReader(f))


def test_rows_go_to_csv_and_tensorboard(tmp_path):
    needs_extra('tensorboard')
    run = _run(tmp_path)
    with run:
        _iterations(run, 2)
    assert [row['env_steps'] for row in _rows(tmp_path / 'progress.csv')] == ['10', '20']
    assert list((tmp_path / 'tensorboard').glob('events.out.tfevents.*'))


def test_a_missing_tensorboard_is_said_once_at_the_start(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, 'torch.utils.tensorboard', None)   # import fails as without the package
    run = _run(tmp_path / 'shown', progress=True)
    with run:
        _iterations(run, 1)
    out = capsys.readouterr().out
    assert out.count(TENSORBOARD_MISSING) == 1 and 'pip install tensorboard' in TENSORBOARD_MISSING
    assert not (tmp_path / 'shown' / 'tensorboard').exists() and (tmp_path / 'shown' / 'progress.csv').exists()
    with _run(tmp_path / 'quiet'):      # jobs without a display (PSRO best responses) say nothing
        pass
    assert TENSORBOARD_MISSING not in capsys.readouterr().out


def test_a_resumed_run_keeps_one_row_per_iteration(tmp_path):
    """A process killed after iteration 3 logged rows 1-3 but checkpointed at 2: the resumed run drops row 3."""
    run = _run(tmp_path)
    with run:
        _iterations(run, 3)                    # checkpoint at iteration 2 (every 2), row 3 logged after it
    assert [r['iteration'] for r in _rows(tmp_path / 'progress.csv')] == ['1', '2', '3']
    resumed = _run(tmp_path)
    assert resumed.resume() == {'marker': 2} and resumed.iteration == 2 and resumed.env_steps == 20
    with resumed:
        _iterations(resumed, 2)
    assert [r['iteration'] for r in _rows(tmp_path / 'progress.csv')] == ['1', '2', '3', '4']
    assert len(resumed.episodes) == 4           # the episode window travels in the checkpoint


def test_counters_budget_and_completion(tmp_path):
    run = _run(tmp_path, total_steps=30)
    with run:
        while run.running():
            _iterations(run, 1)
    assert run.complete and not run.interrupted and run.env_steps == 30
    run.finish({'marker': 'end'}, {})
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['run']['env_steps'] == 30 and saved['state'] == {'marker': 'end'} and (tmp_path / 'final.pt').exists()


def test_another_algorithm_or_spec_is_refused(tmp_path):
    run = _run(tmp_path)
    with run:
        _iterations(run, 2)
    other = Run(tmp_path, 'other', {}, SPEC, total_steps=100)
    with pytest.raises(CheckpointError, match='trained by toy; this run is other'):
        other.resume()
    wider = Run(tmp_path, 'toy', {}, SPEC.replace(hidden=(16,)), total_steps=100)
    with pytest.raises(CheckpointError, match='trained with --hidden 8; this run has --hidden 16'):
        wider.resume()
    assert _run(tmp_path, resume=False).resume() is None     # --fresh


class _RecordingEnvs:
    """What `Run.first_observations` asks of a TrainingEnv, recorded."""

    num_envs = 4

    def __init__(self):
        self.calls = []

    def reset(self, seed):
        self.calls.append(('reset', seed))
        return 'reset features', 'reset state'

    def load_state_dict(self, state):
        self.calls.append(('load', state))

    def observations(self):
        return 'restored features', 'restored state'


def test_first_observations_continue_the_saved_episodes_or_reset_with_a_session_seed(tmp_path):
    from types import SimpleNamespace

    from mate.evaluation.protocol import SEED_BLOCK, training_reset_seed

    run = Run(tmp_path, 'toy', SimpleNamespace(seed=7), SPEC, total_steps=100)
    envs = _RecordingEnvs()
    assert run.first_observations(envs, None) == ('reset features', 'reset state')       # a fresh run: its seed
    assert envs.calls == [('reset', 7)]
    envs.calls.clear()
    assert run.first_observations(envs, {'envs': 'batch'}) == ('restored features', 'restored state')
    assert envs.calls == [('load', 'batch')]                                             # the same episodes go on
    envs.calls.clear()
    run.iteration = 3                                                                    # an older checkpoint
    run.first_observations(envs, {'networks': {}})
    assert envs.calls == [('reset', training_reset_seed(7, 3, 4))] and 7 < envs.calls[0][1] <= SEED_BLOCK - 4
    assert not Run.continues_episodes(None) and not Run.continues_episodes({'networks': {}})
    assert Run.continues_episodes({'envs': 'batch'})
