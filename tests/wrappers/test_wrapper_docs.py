"""Every Python snippet of docs/wrappers.md runs."""

from __future__ import annotations

import pathlib
import re

import pytest

DOC = pathlib.Path(__file__).resolve().parents[2] / 'docs' / 'wrappers.md'
SNIPPETS = re.findall(r'```python\n(.*?)```', DOC.read_text(), flags=re.DOTALL)


def test_there_are_snippets():
    assert len(SNIPPETS) >= 20


@pytest.mark.parametrize('index', range(len(SNIPPETS)))
def test_snippet_runs(index, capsys):
    exec(compile(  # noqa: S102  (the snippets are our own documentation)
        SNIPPETS[index], f'{DOC.name}[{index}]', 'exec'), {})
