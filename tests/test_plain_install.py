"""A plain `pip install mate` (no extras) works: every command parses, `mate evaluate` plays, and a command that needs
an extra says which in one line with exit status 2. Each case runs in a fresh interpreter in which the optional
modules are made unimportable (`sys.modules[name] = None`), as on a machine without them."""

from __future__ import annotations

import subprocess
import sys

import pytest

from mate.cli.extras import EXTRAS

OPTIONAL = sorted({module for modules in EXTRAS.values() for module in modules} | {'tensorboard', 'hypothesis'})

RUN_WITHOUT_EXTRAS = f"""
import sys
for name in {OPTIONAL!r}:
    sys.modules[name] = None
from mate.cli.main import main
status = main(sys.argv[1:])
for name in {OPTIONAL!r}:          # nothing imported them behind the block's back
    assert sys.modules[name] is None, name
sys.exit(status)
"""


def mate_without_extras(tmp_path, *arguments: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-c', RUN_WITHOUT_EXTRAS, *arguments], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600, env={**__import__('os').environ, 'COLUMNS': '200'})


def test_the_parser_and_help_need_no_extra(tmp_path):
    result = mate_without_extras(tmp_path, '--help')
    assert result.returncode == 0, result.stderr
    for command in ('evaluate', 'train', 'psro', 'benchmark', 'rllib-train', 'bench'):
        assert command in result.stdout
    version = mate_without_extras(tmp_path, '--version')
    assert version.returncode == 0 and version.stdout.startswith('mate '), version.stderr


@pytest.mark.slow
def test_evaluate_plays_without_extras_and_leaves_the_gif_out(tmp_path):
    result = mate_without_extras(tmp_path, 'evaluate', '--episodes', '2', '--max-episode-steps', '50')
    assert result.returncode == 0, result.stderr
    assert 'coverage rate' in result.stdout and 'render extra' in result.stdout
    assert not (tmp_path / 'mate-evaluate.gif').exists()
    quiet = mate_without_extras(tmp_path, 'evaluate', '--episodes', '2', '--max-episode-steps', '50', '--no-render')
    assert quiet.returncode == 0 and 'render extra' not in quiet.stdout, quiet.stderr


@pytest.mark.parametrize('arguments, extra', [
    (('train', 'mappo'), 'train'), (('psro',), 'train'), (('benchmark', 'list'), 'train'),
    (('evaluate', '--camera-agent', 'pretrained:hrl-mappo-camera-4v8-9'), 'train'),
    (('evaluate', '--episodes', '1', '--save-gif', 'x.gif'), 'render'), (('rllib-train',), 'rllib')])
def test_a_command_that_needs_an_extra_says_which_in_one_line(tmp_path, arguments, extra):
    result = mate_without_extras(tmp_path, *arguments)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and 'error' in lines[0] and f"mate[{extra}]" in lines[0], result.stderr
