"""`mate benchmark SUBCOMMAND` mistakes: one line on stderr naming the sub-command (`mate benchmark report: error:
...`) and the problem, exit status 2: a folder that does not exist is told from one that is not a run (empty, a
report's folder, another folder) and from a file; nothing is written."""

from __future__ import annotations

from pathlib import Path

import pytest

from mate.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
REPORT = ROOT / 'docs' / 'results' / 'fig5-targets-comm'          # a committed report: results.json, no run


def error_of(capsys, *argv: str) -> str:
    assert main(['benchmark', *argv]) == 2
    out, err = capsys.readouterr()
    assert len(err.strip().splitlines()) == 1 and 'Traceback' not in out + err, err
    assert err.startswith(f'mate benchmark {argv[0]}: error: '), err
    return err


@pytest.mark.parametrize('command', ['report', 'status'])
def test_a_folder_that_is_missing_is_told_from_one_that_is_not_a_run(command, tmp_path, capsys):
    out = ['--out', str(tmp_path / 'report')] if command == 'report' else []
    missing = error_of(capsys, command, str(tmp_path / 'none'), *out)
    assert f'{tmp_path / "none"}: no such directory' in missing
    (tmp_path / 'empty').mkdir()
    empty = error_of(capsys, command, str(tmp_path / 'empty'), *out)
    assert f'{tmp_path / "empty"}: no benchmark.json: an empty directory, not a benchmark directory' in empty
    assert 'no such directory' not in empty and 'the --out of mate benchmark run' in empty
    report = error_of(capsys, command, str(REPORT), *out)
    assert 'a report (results.json) of mate benchmark report, not a benchmark directory' in report
    (tmp_path / 'file').write_text('x')
    assert f'{tmp_path / "file"}: a file, not a directory' in error_of(capsys, command, str(tmp_path / 'file'), *out)
    assert not (tmp_path / 'report').exists()           # the report wrote nothing


def test_keep_and_quote_name_their_sub_command_and_the_path(tmp_path, capsys):
    assert f'{tmp_path / "none"}: no such directory' in error_of(capsys, 'keep', str(tmp_path / 'none'),
                                                                  str(tmp_path / 'kept'))
    err = error_of(capsys, 'quote', str(tmp_path / 'none.md'))
    assert err.strip() == f'mate benchmark quote: error: {tmp_path / "none.md"}: no such file or directory'
    assert 'unknown experiment' in error_of(capsys, 'run', 'fig99')
