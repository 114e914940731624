"""What a run reports (mate.learn.logging): CSV rows, TensorBoard scalars when TensorBoard is installed, and a
notice at the start of a run when it is not."""

from __future__ import annotations

import csv
import sys

from conftest import needs_extra
from mate.learn.logging import TENSORBOARD_MISSING, RunReport


def _report(run_dir, progress: bool) -> RunReport:
    run_dir.mkdir(parents=True, exist_ok=True)
    return RunReport(run_dir, total_steps=100, done_steps=0, progress=progress, callback=None,
                     best_return=float('-inf'), save_best=lambda: None)


def _row(step: int) -> dict:
    return dict(iteration=step, env_steps=10 * step, episode_return=float(step))


def test_rows_go_to_csv_and_tensorboard(tmp_path):
    needs_extra('tensorboard')
    report = _report(tmp_path, progress=False)
    for step in (1, 2):
        report.write(_row(step), status='')
    report.close()
    with open(tmp_path / 'progress.csv', newline='') as f:
        rows = list(csv.DictReader(f))
    assert [row['env_steps'] for row in rows] == ['10', '20']
    assert list((tmp_path / 'tensorboard').glob('events.out.tfevents.*'))


def test_a_missing_tensorboard_is_said_once_at_the_start(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, 'torch.utils.tensorboard', None)   # import fails as without the package
    report = _report(tmp_path / 'shown', progress=True)
    report.write(_row(1), status='')
    report.close()
    out = capsys.readouterr().out
    assert out.count(TENSORBOARD_MISSING) == 1 and 'pip install tensorboard' in TENSORBOARD_MISSING
    assert not (tmp_path / 'shown' / 'tensorboard').exists() and (tmp_path / 'shown' / 'progress.csv').exists()
    quiet = _report(tmp_path / 'quiet', progress=False)     # jobs without a display (PSRO best responses) say nothing
    quiet.close()
    assert TENSORBOARD_MISSING not in capsys.readouterr().out
