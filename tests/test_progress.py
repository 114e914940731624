"""The progress bar of `mate evaluate` / `mate train` (mate.cli.progress): the count never passes the total, and
the count and the remaining time stay visible in a narrow terminal (the status text is cut first); the log
readers read whole lines from a file's end."""

import io

import pytest
from rich.console import Console

from mate.cli.progress import ProgressLine, displayed_count, last_lines, progress_bar

STATUS = '2,345 steps/s  coverage 0.575  return 123.4  entropy 1.23'


@pytest.mark.parametrize('completed, total, shown', [
    (20_800, 20_000, 20_000),    # an iteration overshoots the total
    (12_800, 20_000, 12_800),
    (20_000, 20_000, 20_000),
    (-3, 20_000, 0),
    (5, None, 5),                # no total: nothing to clamp to
])
def test_displayed_count_is_clamped_to_the_total(completed, total, shown):
    assert displayed_count(completed, total) == shown


def render(width: int, completed: int, total: int = 20_000) -> str:
    out = io.StringIO()
    console = Console(file=out, width=width, force_terminal=True, color_system=None)
    progress = progress_bar(console=console)
    task = progress.add_task('training', total=total, completed=0, status='')
    progress.update(task, completed=completed, status=STATUS)
    console.print(progress.get_renderable())
    return out.getvalue().rstrip('\n')


def test_the_bar_shows_the_clamped_count():
    line = render(120, 20_800)
    assert '20,000/20,000' in line and '20,800' not in line


@pytest.mark.parametrize('width', [80, 60, 50])
def test_count_and_eta_stay_visible_in_a_narrow_terminal(width):
    line = render(width, 12_800)
    assert '\n' not in line and len(line) <= width
    assert line.startswith('training ')
    assert '12,800/20,000' in line and ' eta ' in line
    assert STATUS not in line                # the status is what gets cut
    if width == 80:
        assert '2,345 steps/s' in line and line.endswith('…')


def test_a_wide_terminal_shows_the_whole_status():
    assert render(160, 12_800).endswith(STATUS)


def test_plain_lines_when_the_output_is_not_a_terminal(monkeypatch):
    """A log file gets a line at the start, every `interval` seconds, and at the end; no bar escape codes."""
    from mate.cli import progress as progress_module

    now = [100.0]
    monkeypatch.setattr(progress_module.time, 'perf_counter', lambda: now[0])
    out = io.StringIO()
    console = Console(file=out, width=200)                   # a file: not a terminal
    with progress_module.ProgressLine('training', total=1000, console=console, interval=30.0) as line:
        assert line.plain
        for step in range(1, 11):
            now[0] += 10.0                                   # 10 s per update
            line.update(completed=100 * step, status=f'coverage 0.{step}')
    lines = out.getvalue().splitlines()
    assert lines[0] == 'training: 0/1,000 (0%) elapsed 0:00:00 eta -:--:--'
    assert lines[1] == 'training: 300/1,000 (30%) elapsed 0:00:30 eta 0:01:10  coverage 0.3'
    assert len(lines) == 1 + 3 + 1 and lines[-1].startswith('training: 1,000/1,000 (100%) elapsed 0:01:40 eta 0:00:00')
    assert '\x1b' not in out.getvalue()


def test_a_terminal_gets_the_bar():
    out = io.StringIO()
    console = Console(file=out, width=100, force_terminal=True, color_system=None)
    with ProgressLine('evaluating', total=10, console=console) as line:
        assert not line.plain
        line.update(advance=5, status='x')
    assert 'evaluating' in out.getvalue() and '5/10' in out.getvalue()


def test_last_lines_reads_whole_lines_from_the_end_of_a_file(tmp_path):
    path = tmp_path / 'evaluations.jsonl'
    assert last_lines(path) is None                                      # no file
    path.write_text('')
    assert last_lines(path) == []
    long = [f'{k}:' + 'x' * 20_000 for k in range(3)]                    # each line longer than the first window
    path.write_text('\n'.join(long) + '\n' + '{"half written')
    lines = last_lines(path, window=1024)
    assert lines and lines[-1] == long[-1]                               # widened until a whole line fits
    assert all(line in long for line in lines)                           # no line cut at the window's start
    path.write_text('a\nb\n')
    assert last_lines(path, window=1024) == ['a', 'b']                   # the whole file when it is short
