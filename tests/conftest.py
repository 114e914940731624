"""What every test shares: how a test that needs an optional extra is skipped, and why CI refuses skips.

The README's install (`pip install -e ".[test]"`) leaves out some extras (Ray for RLlib, TensorBoard). A
test that needs one is skipped with a reason naming the extra (`needs_extra`), so a user sees what is
missing. CI (`CI=true`, `.ci/run`) installs every extra, so there a skip can only mean that something which
should run did not: the run fails and lists the skipped tests with their reasons.
"""

from __future__ import annotations

import importlib
import importlib.util
import os

os.environ.setdefault('MATE_REPRODUCIBLE', '1')   # before mate and torch load: golden runs hold on any x86-64 CPU

import pytest  # noqa: E402

EXTRAS = {'ray': 'rllib', 'ray.rllib': 'rllib', 'torch': 'train', 'tensorboard': 'train', 'pettingzoo': 'pettingzoo',
          'pygame': 'render', 'matplotlib': 'train', 'scipy': 'train', 'mkdocs': 'docs', 'griffe': 'docs',
          'numba_cuda': 'gpu', 'torchrl': 'torchrl', 'tensordict': 'torchrl'}
"""Optional modules and the extra of pyproject.toml that installs each."""


def in_ci() -> bool:
    """Whether this is a CI run (`CI` set to anything but '', '0' or 'false'), where every extra is installed."""
    return os.environ.get('CI', '').strip().lower() not in ('', '0', 'false')


def missing_extra_reason(module: str) -> str:
    """The skip reason of a test that needs `module`: the extra that installs it and the install line."""
    extra = EXTRAS.get(module, EXTRAS.get(module.partition('.')[0], 'test'))
    return f"needs {module}, from the {extra} extra: pip install -e '.[{extra}]'"


def needs_extra(module: str):
    """Import and return `module`, or skip the calling test (or module, at module level) naming its extra."""
    if importlib.util.find_spec(module.partition('.')[0]) is None or importlib.util.find_spec(module) is None:
        pytest.skip(missing_extra_reason(module), allow_module_level=True)
    return importlib.import_module(module)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """In CI, any skip fails the run (the reasons are in pytest's short summary, `-ra`)."""
    if not in_ci():
        return
    reporter = session.config.pluginmanager.get_plugin('terminalreporter')
    skipped = reporter.stats.get('skipped', []) if reporter is not None else []
    if skipped:
        reporter.write_line(f'CI: {len(skipped)} test(s) or module(s) skipped; CI installs every extra, so a skip '
                            'is a failure (reasons in the summary above)', red=True, bold=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
