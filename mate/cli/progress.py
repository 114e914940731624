"""Progress of long commands: the one-line rich bar on a terminal, plain lines in a log file.

The bar of `mate evaluate`, `mate train` and `mate generate-config` (rich). At 80 columns:

    training ━━━━━━━━━━━╸       12,800/20,000 0:00:09 eta 0:00:05 2,345 steps/s  co…
    (description, bar, done/total, elapsed and remaining time, status)

The count and the times never shrink: when the terminal is narrow, the status text is cut
first (with an ellipsis), then the bar. The count shown never passes the total (a training
iteration can overshoot it).

When the output is not a terminal (`nohup`, a cluster job, a pipe), a bar would show nothing until the
end; `ProgressLine` prints instead one plain line at the start, one every `interval` seconds (30) and one
at the end, with the same fields:

    training: 12,800/20,000 (64%) elapsed 0:00:09 eta 0:00:05  2,345 steps/s  coverage 0.61

`logged_steps(run_dir)` reads how far a training run has come from its `progress.csv` (`last_logged_row`, and
`training_rate` of that row how fast), for the commands that watch runs in other processes (`mate psro`,
`mate benchmark status`).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, Progress, ProgressColumn, Task, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Column
from rich.text import Text

__all__ = ['PLAIN_INTERVAL', 'ProgressLine', 'StatusColumn', 'StepCountColumn', 'TimesColumn', 'clock',
           'displayed_count', 'last_logged_row', 'logged_steps', 'progress_bar', 'training_rate']

PLAIN_INTERVAL = 30.0
"""Seconds between two plain progress lines when the output is not a terminal."""


def displayed_count(completed: float, total: float | None) -> int:
    """The count a bar shows: `completed` clamped to [0, total] (no clamp at the top without a total)."""
    completed = max(0, int(completed))
    return completed if total is None else min(completed, int(total))


class StepCountColumn(ProgressColumn):
    """'done/total' with thousands separators, done clamped to the total (`displayed_count`); never cut."""

    def __init__(self) -> None:
        super().__init__(table_column=Column(no_wrap=True))

    def render(self, task: Task) -> Text:
        total = f'{int(task.total):,}' if task.total is not None else '?'
        done = f'{displayed_count(task.completed, task.total):,}'
        return Text(f'{done:>{len(total)}}/{total}', style='progress.download')


class TimesColumn(ProgressColumn):
    """'elapsed eta remaining' (H:MM:SS each; the remaining time '-:--:--' until rich can estimate it); never cut."""

    def __init__(self) -> None:
        super().__init__(table_column=Column(no_wrap=True))
        self.elapsed, self.remaining = TimeElapsedColumn(), TimeRemainingColumn()

    def render(self, task: Task) -> Text:
        return Text.assemble(self.elapsed.render(task), ' eta ', self.remaining.render(task))


class StatusColumn(ProgressColumn):
    """The task's `status` field on one line; the column the table shrinks first (cut with an ellipsis)."""

    def __init__(self) -> None:
        super().__init__(table_column=Column(no_wrap=False, min_width=0))   # wrappable: collapsed first

    def render(self, task: Task) -> Text:
        return Text(str(task.fields.get('status', '')), no_wrap=True, overflow='ellipsis')


def progress_bar(console: Console | None = None, transient: bool = False, bar_width: int = 20) -> Progress:
    """A `Progress` with the columns of the module docstring (not started: use it as a context manager,
    or `start()` / `stop()`). Add tasks with a `status` field: `add_task('training', total=N, status='')`."""
    fixed = dict(table_column=Column(no_wrap=True))
    return Progress(TextColumn('{task.description}', **fixed), BarColumn(bar_width=bar_width),
                    StepCountColumn(), TimesColumn(), StatusColumn(),
                    console=console, transient=transient)


def clock(seconds: float | None) -> str:
    """H:MM:SS of a number of seconds ('-:--:--' for None, a negative or a non-finite number)."""
    if seconds is None or not seconds >= 0 or seconds == float('inf'):
        return '-:--:--'
    seconds = int(seconds)
    return f'{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}'


class ProgressLine:
    """One task's progress: the rich bar on a terminal, else plain lines (module docstring).

    Use as a context manager (or `start()` / `stop()`); `update(completed=..., advance=..., status=...)`.

    Args:
        description: what is measured ('training', 'evaluating', ...).
        total: the count at the end (None: unknown).
        completed: the count at the start (a resumed run).
        console: where to write (default: a new rich Console on stdout).
        transient: the terminal bar disappears at the end.
        interval: seconds between plain lines.
        plain: force the plain lines (True) or the bar (False); None: the bar on a terminal only.
    """

    def __init__(self, description: str, total: float | None, completed: float = 0, console: Console | None = None,
                 transient: bool = False, interval: float = PLAIN_INTERVAL, plain: bool | None = None) -> None:
        self.console = console or Console()
        self.description, self.total, self.completed, self.status = description, total, completed, ''
        self.plain = (not self.console.is_terminal) if plain is None else bool(plain)
        self.interval = float(interval)
        self._started = self._printed = None
        self._start_count = completed
        self._bar = None if self.plain else progress_bar(console=self.console, transient=transient)
        self._task = None

    def __enter__(self) -> ProgressLine:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop(finished=exc[0] is None)

    def start(self) -> None:
        self._started = self._printed = time.perf_counter()
        if self._bar is not None:
            self._task = self._bar.add_task(self.description, total=self.total, completed=self.completed,
                                            status=self.status)
            self._bar.start()
        else:
            self._print()

    def update(self, completed: float | None = None, advance: float = 0, status: str | None = None,
               total: float | None = None) -> None:
        self.completed = (self.completed if completed is None else completed) + advance
        if status is not None:
            self.status = status
        if total is not None:
            self.total = total
        if self._bar is not None:
            self._bar.update(self._task, completed=self.completed, status=self.status,
                             **({} if total is None else dict(total=total)))
        elif time.perf_counter() - self._printed >= self.interval:
            self._print()

    def stop(self, finished: bool = True) -> None:
        if self._bar is not None:
            self._bar.stop()
        elif self._started is not None and finished:
            self._print()
        self._started = None

    def line(self) -> str:
        """The plain line of the current state."""
        elapsed = time.perf_counter() - (self._started or time.perf_counter())
        done = displayed_count(self.completed, self.total)
        if self.total:
            rate = (self.completed - self._start_count) / elapsed if elapsed > 0 else 0.0
            eta = (self.total - done) / rate if rate > 0 else None
            count = f'{done:,}/{int(self.total):,} ({100 * done / self.total:.0f}%)'
        else:
            eta, count = None, f'{done:,}'
        text = f'{self.description}: {count} elapsed {clock(elapsed)} eta {clock(eta)}'
        return text + (f'  {self.status}' if self.status else '')

    def _print(self) -> None:
        self._printed = time.perf_counter()
        self.console.print(self.line(), highlight=False, soft_wrap=True)
        file = self.console.file
        if hasattr(file, 'flush'):
            file.flush()


def logged_steps(run_dir) -> int | None:
    """Decision steps a training run (`mate train`, `mate rllib-train`) in the directory `run_dir` has logged:
    `env_steps` of the last complete row of its `progress.csv`, read from the file's end (cheap on long logs, safe
    while the run writes); None before its first row."""
    row = last_logged_row(run_dir)
    return None if row is None else int(row['env_steps'])


def training_rate(row: dict[str, str]) -> float | None:
    """Decision steps per second of training so far from a row of `progress.csv` (`last_logged_row`): `env_steps` /
    `wall_seconds`, evaluations and checkpoints included, the time between resumed sessions not; None when the row
    has no time."""
    try:
        seconds = float(row['wall_seconds'])
    except (TypeError, KeyError, ValueError):
        return None
    return int(row['env_steps']) / seconds if seconds > 0 else None


def last_lines(path, window: int = 8192) -> list[str] | None:
    """The complete lines (each ended by a newline; a last line still being written is left out) at the end of the
    text file `path`, read from the file's end: `window` bytes, widened until they hold a whole line or the whole
    file; None when there is no such file."""
    try:
        with open(path, 'rb') as f:
            size = f.seek(0, os.SEEK_END)
            while True:
                start = max(size - window, 0)
                f.seek(start)
                complete = f.read(size - start).split(b'\n')[:-1]
                if start > 0:
                    complete = complete[1:]           # it may begin mid-line
                if complete or start == 0:
                    return [line.decode('utf-8', 'replace') for line in complete]
                window *= 4
    except FileNotFoundError:
        return None


def last_logged_row(run_dir) -> dict[str, str] | None:
    """The last complete row of `run_dir/progress.csv` ({column: text}, with an `env_steps` count), read from
    the file's end; None when there is none yet."""
    path = Path(run_dir) / 'progress.csv'
    try:
        with open(path, 'rb') as f:
            header = f.readline().decode('utf-8', 'replace').rstrip('\r\n').split(',')
    except FileNotFoundError:
        return None
    if 'env_steps' not in header:
        return None
    column = header.index('env_steps')
    for line in reversed(last_lines(path) or []):
        fields = line.rstrip('\r').split(',')
        if len(fields) == len(header) and fields[column].isdigit():
            return dict(zip(header, fields))
    return None
