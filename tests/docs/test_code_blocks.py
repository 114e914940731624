"""Every ```python block of README.md and docs/ runs; blocks followed by an output block print it.

The blocks of one page run in order in one namespace (a page reads as one session), in a fresh
temporary directory. Printed output is compared with doctest's rules: `...` matches anything and
runs of whitespace compare equal.
"""

from __future__ import annotations

import contextlib
import doctest
import io
import os
import warnings

import pytest

from .markdown_blocks import ROOT, pages, python_blocks

os.environ.setdefault('SDL_VIDEODRIVER', 'dummy')

PAGES_WITH_PYTHON = [path for path in pages() if python_blocks(path)]
NEEDS = {'docs/rllib.md': ('ray.rllib', 'ray[rllib], the rllib extra')}
"""Pages whose examples need an optional extra beyond the test extra: module to import, what to install."""
HIDDEN_FROM_USERS = ('Creating .* which inherits from WeightUpdaterBase is deprecated',)
"""DeprecationWarnings a library raises about its own code, which Python's default filters hide from users (not
raised in `__main__`): torchrl 0.14's, when `torchrl.collectors` is imported (docs/torchrl.md)."""
CHECKER = doctest.OutputChecker()
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def test_the_site_has_python_examples():
    assert len(PAGES_WITH_PYTHON) >= 10, [str(path) for path in PAGES_WITH_PYTHON]


@pytest.mark.parametrize('path', PAGES_WITH_PYTHON, ids=lambda path: str(path.relative_to(ROOT)))
def test_python_blocks_run(path, tmp_path, monkeypatch):
    module, extra = NEEDS.get(str(path.relative_to(ROOT)), (None, None))
    if module is not None:
        pytest.importorskip(module, reason=f'{path.name} needs {extra} (as tests/integrations/test_rllib.py)')
    monkeypatch.chdir(tmp_path)
    namespace = {'__name__': '__docs__'}
    for block in python_blocks(path):
        printed = io.StringIO()
        try:
            code = compile(block.code, block.where, 'exec')
            with contextlib.redirect_stdout(printed), warnings.catch_warnings():
                warnings.simplefilter('error')  # an example that warns shows users a warning: fix the example
                for message in HIDDEN_FROM_USERS:
                    warnings.filterwarnings('ignore', message=message, category=DeprecationWarning)
                exec(code, namespace)
        except Exception as error:
            raise AssertionError(f'{block.where}: the block raised {type(error).__name__}: {error}') from error
        if block.expected_output is not None:
            assert CHECKER.check_output(block.expected_output, printed.getvalue(), FLAGS), (
                f'{block.where}: printed\n{printed.getvalue()}\nbut the page shows\n{block.expected_output}')
    for name in ('env', 'vec_env', 'envs'):
        closer = getattr(namespace.get(name), 'close', None)
        if callable(closer):
            closer()
