"""What a training run reports, shared by every trainer: `RunReport` (one row per iteration to the logger,
the progress bar and a callback; the window of recent episodes; the best return so far), `Logger`
(progress.csv, and TensorBoard scalars when it imports) and `training_bar` (the one-line rich bar).
"""

from __future__ import annotations

import csv
import math
from collections import deque
from collections.abc import Callable
from pathlib import Path

import numpy as np

__all__ = ['EPISODE_WINDOW', 'Logger', 'RunReport', 'mean_or_nan', 'training_bar']

TENSORBOARD_MISSING = ("TensorBoard is not installed: the run logs to progress.csv only (for TensorBoard scalars: "
                       "pip install tensorboard, or the train extra: pip install -e '.[train]')")
"""What a run with a progress display says once at its start when `torch.utils.tensorboard` cannot be imported."""
EPISODE_WINDOW = 25
"""Episodes the episode metrics are averaged over (RLlib's smoothing, which the paper's curves show)."""


def mean_or_nan(values) -> float:
    """The mean of `values`, NaN when there are none (a log column of an iteration without updates)."""
    return float(np.mean(values)) if len(values) else math.nan


def out_of_time(time_limit: float, seconds: float) -> bool:
    """Whether `seconds` of training wall time (earlier sessions of a resumed run included) have spent a budget
    of `time_limit` seconds (0: no budget): the `--minutes` of every trainer."""
    return time_limit > 0 and seconds >= time_limit


class RunReport:
    """Where a training run's iterations go.

    `add_episodes(dicts)` keeps the last `EPISODE_WINDOW` finished episodes (`coverage`, `return`, and
    `raw_return`: the normalised target return); `episode_means()` averages them; `write(row, status)`
    writes the row (CSV/TensorBoard), calls `save_best()` when the window is full and its mean return beats
    `best_return` (then updated), calls `callback(row)` and moves the bar to `row['env_steps']` with `status`.
    """

    def __init__(self, run_dir: Path, total_steps: int, done_steps: int, progress: bool,
                 callback: Callable[[dict], None] | None, best_return: float, save_best: Callable[[], None]) -> None:
        self.episodes = deque(maxlen=EPISODE_WINDOW)
        self.logger = Logger(run_dir, resume=done_steps > 0)
        if progress and self.logger.tb is None:
            print(TENSORBOARD_MISSING, flush=True)
        self.bar = training_bar(total_steps, done_steps) if progress else None
        self.callback, self.best_return, self.save_best = callback, best_return, save_best

    def add_episodes(self, episodes) -> None:
        self.episodes.extend(episodes)

    def episode_means(self) -> dict:
        recent = list(self.episodes)

        def mean(key: str) -> float:
            return float(np.mean([e.get(key, np.nan) for e in recent])) if recent else math.nan

        return dict(episode_coverage=mean('coverage'), episode_return=mean('return'),
                    episode_normalized_target_return=mean('raw_return'), episodes=len(recent))

    def iteration_row(self, iteration: int, env_steps: int, frame_skip: int, wall_seconds: float,
                      steps_per_second: float, coverage, **columns) -> dict:
        """A log row: the columns every trainer starts with (iteration, decision and raw steps, wall seconds,
        decisions per second, the iteration's mean rollout coverage), the episode window's means, then `columns`."""
        return dict(iteration=iteration, env_steps=env_steps, raw_steps=env_steps * frame_skip,
                    wall_seconds=round(wall_seconds, 2), steps_per_second=steps_per_second,
                    rollout_coverage=float(np.mean(coverage)), **self.episode_means(), **columns)

    @staticmethod
    def status(row: dict, extra: str = '') -> str:
        """The progress bar's status text of a row: speed, coverage, return (and `extra`)."""
        return (f"{row['steps_per_second']:,.0f} steps/s  coverage {row['rollout_coverage']:.3f}  "
                f"return {row['episode_return']:.1f}" + (f'  {extra}' if extra else ''))

    def write(self, row: dict, status: str) -> None:
        self.logger.write(row)
        if len(self.episodes) == EPISODE_WINDOW and row['episode_return'] > self.best_return:
            self.best_return = row['episode_return']
            self.save_best()
        if self.callback is not None:
            self.callback(row)
        if self.bar is not None:
            self.bar[0].update(self.bar[1], completed=row['env_steps'], status=status)

    def close(self) -> None:
        self.logger.close()
        if self.bar is not None:
            self.bar[0].stop()


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
