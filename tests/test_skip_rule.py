"""The rule for tests that need an optional extra (tests/conftest.py): skipped with a reason naming the extra
under the README's install; in CI (`CI=true`), where every extra is installed, any skip fails the run."""

from __future__ import annotations

from pathlib import Path

import pytest

from conftest import missing_extra_reason

pytest_plugins = ['pytester']

SKIPPING = '''
from conftest import needs_extra

def test_needs_a_missing_extra():
    needs_extra('a_module_that_is_not_installed')

def test_runs():
    pass
'''


@pytest.mark.parametrize('workers', [(), ('-n', '2')], ids=['one-process', 'xdist'])  # the README's command: -n auto
@pytest.mark.parametrize('ci, status', [('', 0), ('true', 1)])
def test_a_skip_fails_only_in_ci(pytester, monkeypatch, ci, status, workers):
    pytester.makeconftest((Path(__file__).parent / 'conftest.py').read_text())
    pytester.makepyfile(test_example=SKIPPING)
    monkeypatch.setenv('CI', ci)
    result = pytester.runpytest_subprocess('-ra', *workers) if workers else pytester.runpytest('-ra')
    assert result.ret == status
    result.assert_outcomes(passed=1, skipped=1)
    result.stdout.fnmatch_lines(["*needs a_module_that_is_not_installed, from the test extra*"])


def test_the_reason_names_the_extra_and_the_install_line():
    assert missing_extra_reason('ray.rllib') == "needs ray.rllib, from the rllib extra: pip install -e '.[rllib]'"
    assert missing_extra_reason('torch') == "needs torch, from the train extra: pip install -e '.[train]'"
