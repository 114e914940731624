"""The shipped policies' numbers in README and the docs are those of the committed tables that measured them
(`docs/results/pretrained/NAME.md`, written by `docs/tools/evaluate_table.py --markdown`): a number edited by hand, or
a table measured again without the pages following, fails here."""

from __future__ import annotations

import re

import pytest

from mate.policies.policy import PRETRAINED_DIR

from .markdown_blocks import ROOT

TABLES = ROOT / 'docs' / 'results' / 'pretrained'
PAGES = ('README.md', 'docs/pretrained.md', 'docs/contributors/training-record.md')
SHIPPED = sorted(p.stem for p in PRETRAINED_DIR.glob('*.pt'))


def measured(name: str) -> dict[str, str]:
    """The 320-episode table of `pretrained:NAME`: its mean, the greedy team's, and the paired difference."""
    text = (TABLES / f'{name}.md').read_text()
    mean = re.search(rf'^\| pretrained:{re.escape(name)} \| (\S+) ±', text, re.M)
    greedy = re.search(r'^\| greedy \| (\S+) ±', text, re.M)
    paired = re.search(rf'^\| pretrained:{re.escape(name)} - greedy \| (\S+ \[\S+, \S+\]) \|', text, re.M)
    assert mean and greedy and paired, f'{TABLES / name}.md: not a table of docs/tools/evaluate_table.py --against greedy'
    return dict(mean=mean[1], greedy=greedy[1], paired=paired[1])


@pytest.mark.parametrize('name', SHIPPED)
def test_every_shipped_policy_has_its_table(name):
    text = (TABLES / f'{name}.md').read_text()
    assert text.startswith('`python docs/tools/evaluate_table.py ') and '--episodes 320' in text.splitlines()[0]
    measured(name)


@pytest.mark.parametrize('page', PAGES)
@pytest.mark.parametrize('name', SHIPPED)
def test_the_pages_quote_the_table(page, name):
    numbers = measured(name)
    rows = [line for line in (ROOT / page).read_text().splitlines()
            if line.startswith('|') and f'`{name}`' in line.replace('pretrained:', '')]
    assert rows, f'{page}: no table row of {name}'
    for row in rows:
        assert numbers['paired'] in row, f'{page}: the row of {name} does not say {numbers["paired"]}: {row}'
        if page != 'docs/contributors/training-record.md':
            assert f"({numbers['mean']} vs {numbers['greedy']})" in row, f'{page}: {row}'
