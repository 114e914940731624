"""What a training run reports: `Logger` (progress.csv, and TensorBoard scalars when it imports) and
`training_bar` (the one-line rich progress bar of `mate train`). Shared by every trainer."""

from __future__ import annotations

import csv
import math
from pathlib import Path

__all__ = ['Logger', 'training_bar']


class Logger:
    """CSV rows (+ TensorBoard scalars when `torch.utils.tensorboard` imports)."""

    def __init__(self, run_dir: Path, resume: bool) -> None:
        self.path = run_dir / 'progress.csv'
        self.fields = None
        self.append = resume and self.path.exists()
        try:
            from torch.utils.tensorboard import SummaryWriter
            self.tb = SummaryWriter(str(run_dir / 'tensorboard'))
        except Exception:  # noqa: BLE001  (tensorboard missing or broken: CSV only)
            self.tb = None

    def write(self, row: dict) -> None:
        if self.fields is None:
            header = None
            if self.append:   # a resumed run keeps its file's columns (a newer version's extra ones are dropped)
                with open(self.path, newline='') as f:
                    header = next(csv.reader(f), None)
            self.fields = header or list(row)
            if header is None:
                with open(self.path, 'w', newline='') as f:
                    csv.DictWriter(f, self.fields).writeheader()
        with open(self.path, 'a', newline='') as f:
            csv.DictWriter(f, self.fields, extrasaction='ignore').writerow(row)
        if self.tb is not None:
            for key, value in row.items():
                if key != 'env_steps' and isinstance(value, (int, float)) and not math.isnan(value):
                    self.tb.add_scalar(key, value, row['env_steps'])
            self.tb.flush()

    def close(self) -> None:
        if self.tb is not None:
            self.tb.close()


def training_bar(total: int, done: int):
    """The started training bar (`mate.progress`) and its task, at `done` of `total` decision steps."""
    from ..progress import progress_bar

    progress = progress_bar()
    task = progress.add_task('training', total=total, completed=done, status='')
    progress.start()
    return progress, task
