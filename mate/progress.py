"""The one-line progress bar of `mate evaluate` and `mate train` (rich). At 80 columns:

    training ━━━━━━━━━━━╸       12,800/20,000 0:00:09 eta 0:00:05 2,345 steps/s  co…
    (description, bar, done/total, elapsed and remaining time, status)

The count and the times never shrink: when the terminal is narrow, the status text is cut
first (with an ellipsis), then the bar. The count shown never passes the total (a training
iteration can overshoot it).
"""

from __future__ import annotations

from rich.console import Console
from rich.progress import BarColumn, Progress, ProgressColumn, Task, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Column
from rich.text import Text

__all__ = ['StatusColumn', 'StepCountColumn', 'TimesColumn', 'displayed_count', 'progress_bar']


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
