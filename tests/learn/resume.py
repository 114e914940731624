"""Exact resumes: a run stopped by SIGINT and resumed with the same command ends as the same run never stopped.

`stopped_and_resumed(train, config_of, stop_at, folder)` trains twice with the same seed: once straight through
(`config_of(run_dir, fresh=True)`), once stopped by a SIGINT sent to this process from the `callback` after
iteration `stop_at` (the trainer finishes that iteration, writes its checkpoint and returns) and resumed by the
same call. `assert_same_run(a, b)` then compares the two run directories: every network and optimiser state of
the final checkpoints bitwise, and the log rows but for the wall-clock columns.
"""

from __future__ import annotations

import csv
import os
import signal
from pathlib import Path

import torch

from mate.policies.checkpoint import load_checkpoint
from mate.learn.run import TIMING_COLUMNS


def stopped_and_resumed(train, config_of, stop_at: int, folder: Path, **train_kwargs) -> tuple[Path, Path]:
    """(straight run dir, stopped-and-resumed run dir); `config_of(run_dir, fresh)` makes the config."""
    straight, stopped = Path(folder) / 'straight', Path(folder) / 'stopped'
    done = train(config_of(str(straight), True), **train_kwargs)
    assert not done.interrupted

    def stop(row):
        if row['iteration'] == stop_at:
            os.kill(os.getpid(), signal.SIGINT)

    first = train(config_of(str(stopped), True), callback=stop, **train_kwargs)
    assert first.interrupted and first.iteration == stop_at, (first.interrupted, first.iteration)
    assert not (stopped / 'final.pt').exists()
    second = train(config_of(str(stopped), False), **train_kwargs)
    assert not second.interrupted and second.iteration == done.iteration
    return straight, stopped


def _equal(a, b, where: str) -> None:
    if isinstance(a, torch.Tensor):
        assert isinstance(b, torch.Tensor) and a.shape == b.shape and torch.equal(a, b), where
    elif isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), (where, sorted(a), sorted(b))
        for key in a:
            _equal(a[key], b[key], f'{where}.{key}')
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            _equal(x, y, f'{where}[{k}]')
    else:
        assert a == b, (where, a, b)


def assert_same_run(a: Path, b: Path, entries=('networks', 'optimizer')) -> None:
    """The final checkpoints' `entries` of the algorithm state (every state dict inside, bitwise) and the log rows
    (timing columns left out) of run directories `a` and `b` are the same."""
    state_a = load_checkpoint(Path(a) / 'checkpoint.pt')['state']
    state_b = load_checkpoint(Path(b) / 'checkpoint.pt')['state']
    for entry in state_a:
        if any(entry.startswith(name) for name in entries):
            _equal(state_a[entry], state_b[entry], entry)
    rows = []
    for folder in (a, b):
        with open(Path(folder) / 'progress.csv', newline='') as f:
            rows.append([{k: v for k, v in row.items() if k not in TIMING_COLUMNS} for row in csv.DictReader(f)])
    assert len(rows[0]) == len(rows[1]) and rows[0] == rows[1]
