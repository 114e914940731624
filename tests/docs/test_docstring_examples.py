"""The code examples inside the docstrings that the API pages show run too.

mkdocstrings renders an indented block of a docstring (after a blank line) as code. This test
finds those blocks in the docstrings of every object on the API pages and of their public members,
as griffe reads them, and runs each one that is Python (blocks that do not compile are text, such
as tables of keys) in a fresh namespace holding `mate` and `numpy as np`.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

from .markdown_blocks import ROOT
from .test_api_reference import HAVE_RAY, directives

os.environ.setdefault('SDL_VIDEODRIVER', 'dummy')


def indented_blocks(text: str) -> list[str]:
    """The blocks of lines indented by 4+ spaces that follow a blank line (Markdown code blocks)."""
    blocks, current, previous_blank = [], None, True
    for line in text.splitlines() + ['']:
        indented = line.startswith('    ')
        if current is not None and (indented or not line.strip()):
            current.append(line[4:])
        elif current is not None:
            blocks.append('\n'.join(current).strip('\n') + '\n')
            current = None
        if current is None and indented and previous_blank:
            current = [line[4:]]
        previous_blank = not line.strip()
    if current is not None:
        blocks.append('\n'.join(current).strip('\n') + '\n')
    return blocks


def shown_docstrings(package) -> dict[str, str]:
    """'path' -> docstring of every object an API page renders (directives and their public members)."""
    docstrings = {}
    for path in directives():
        item = package[path.removeprefix('mate.')]
        item = getattr(item, 'final_target', item)
        members = [item] + [member for name, member in getattr(item, 'members', {}).items()
                            if not name.startswith('_') and not getattr(member, 'is_alias', False)]
        for member in members:
            if member.docstring is not None:
                docstrings[member.path] = member.docstring.value
    return docstrings


@pytest.fixture(scope='module')
def examples():
    import griffe
    loader = griffe.GriffeLoader(search_paths=[str(ROOT)])
    package = loader.load('mate')
    loader.resolve_aliases(implicit=True, external=False)
    found = []
    for path, text in shown_docstrings(package).items():
        for block in indented_blocks(text):
            try:
                code = compile(block, f'docstring of {path}', 'exec')
            except SyntaxError:
                continue  # text laid out as a code block (a table of keys, a diagram)
            found.append((path, code))
    return found


def test_indented_blocks_finds_code_after_a_blank_line():
    text = 'Summary.\n\n    x = 1\n    y = x\n\nArgs:\n    a: not code (no blank line before)\n'
    assert indented_blocks(text) == ['x = 1\ny = x\n']


def test_docstring_examples_run(examples, tmp_path, monkeypatch):
    assert len(examples) >= 4, 'the API pages show the single-team wrappers\' examples at least'
    import mate
    monkeypatch.chdir(tmp_path)
    needs_ray = []
    for path, code in examples:
        if path.startswith('mate.integrations.rllib') and not HAVE_RAY:
            needs_ray.append(path)
            continue
        namespace = {'mate': mate, 'np': np}
        with warnings.catch_warnings():
            warnings.simplefilter('error')
            try:
                exec(code, namespace)
            except Exception as error:
                raise AssertionError(f'the example in the docstring of {path} raised {type(error).__name__}: {error}') \
                    from error
    if needs_ray:
        pytest.skip(f'the other examples ran; these need ray[rllib], the rllib extra: {needs_ray}')
