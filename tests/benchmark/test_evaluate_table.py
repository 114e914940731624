"""docs/tools/evaluate_table.py: the paired differences it reports (how a shipped policy is tested against the one
before it and the greedy agent), and the tables it writes, on two real `mate evaluate` runs."""

from __future__ import annotations

import re

import numpy as np
import pytest

from modules import load_script


@pytest.fixture(scope='module')
def table():
    return load_script('evaluate_table')


def row(policy, scores, seeds=None):
    return dict(policy=policy, scores=list(scores), seeds=list(seeds if seeds is not None else range(len(scores))))


def numbers(line):
    return [float(x) for x in re.findall(r'[-+]?\d+\.\d+', line)]


def test_paired_difference_is_the_mean_per_episode_difference_with_an_interval_around_it(table):
    rng = np.random.default_rng(0)
    base = rng.normal(0.3, 0.05, 200)
    better = base + 0.02 + rng.normal(0, 0.01, 200)
    lines = table.paired_rows([row('new', better), row('old', base)], 'old')
    assert len(lines) == 1 and lines[0].startswith('| new - old |')
    point, low, high, share = numbers(lines[0])
    assert point == pytest.approx(np.mean(better - base), abs=5e-4)
    assert low < point < high and low > 0                           # paired: the shared noise cancels
    assert share == pytest.approx(np.mean(better > base), abs=5e-3)


def test_only_policies_listed_before_the_reference_are_compared(table):
    rows = [row('a', [1.0, 2.0]), row('b', [0.0, 1.0]), row('c', [0.5, 0.5])]
    assert [line.split('|')[1].strip() for line in table.paired_rows(rows, 'b')] == ['a - b']
    assert [line.split('|')[1].strip() for line in table.paired_rows(rows, 'c')] == ['a - c', 'b - c']


def test_different_seeds_cannot_be_paired(table):
    with pytest.raises(ValueError, match='different seeds'):
        table.paired_rows([row('a', [1.0, 2.0], seeds=[0, 1]), row('b', [1.0, 2.0], seeds=[5, 6])], 'b')


def test_the_reference_must_be_one_of_the_policies(table, capsys):
    with pytest.raises(SystemExit):
        table.main(['--team', 'camera', '--against', 'greedy', 'random'])
    assert "--against 'greedy': must be one of the policies" in capsys.readouterr().err


@pytest.mark.slow
def test_markdown_holds_the_command_and_both_tables(table, tmp_path):
    out = tmp_path / 'table.md'
    argv = ['--team', 'camera', '--episodes', '2', '--max-episode-steps', '20', '--against', 'random',
            '--markdown', str(out), 'greedy', 'random']
    assert table.main(argv) == 0
    text = out.read_text()
    assert text.startswith('`python docs/tools/evaluate_table.py --team camera')
    assert '| greedy |' in text and '| random |' in text and '| greedy - random |' in text
