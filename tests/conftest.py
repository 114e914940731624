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
import tempfile

os.environ.setdefault('MATE_REPRODUCIBLE', '1')   # before mate and torch load: the kernels the golden runs were recorded with
# no test reads a cache outside the repository (mate.evaluation.protocol's reference cache, ~/.cache/mate by default):
# a fresh folder of this session's, inherited by the subprocesses the tests start
os.environ['MATE_CACHE_DIR'] = tempfile.mkdtemp(prefix='mate-test-cache-')

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


SIMULATOR_PRELUDE = """
try:   # mate's kernels never synchronise the threads of a block (a thread is a game): wait on them with join()
    import numpy as _np
    from numba.cuda.simulator import kernel as _kernel

    def _run_block(self, grid_point, *args):
        threads = [_kernel.BlockThread(lambda: self._f(*args), self, grid_point, point, self._debug)
                   for point in _np.ndindex(*self._block_dim)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        for thread in threads:
            if thread.exception:
                raise thread.exception[0].with_traceback(thread.exception[1])

    if hasattr(_kernel, 'BlockThread') and hasattr(_kernel.BlockManager, 'run'):
        _kernel.BlockManager.run = _run_block
except ImportError:
    pass
"""
"""Put before a simulated script by `run_simulated`: the simulator polls its threads in a busy loop, which takes the
GIL from them (about half the time of a launch); joining them instead changes nothing a kernel computes, for kernels
without `cuda.syncthreads()` (mate has none; one that had would hang, and the test time out)."""


def run_simulated(script: str, *args: str, timeout: float = 600):
    """Run the Python `script` (with `args`) in its own process under numba's CUDA simulator (the switch is read
    when numba.cuda loads) and return its `subprocess.CompletedProcess` (text output captured)."""
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_ENABLE_CUDASIM='1')
    return subprocess.run([sys.executable, '-c', SIMULATOR_PRELUDE + script, *args], env=env, capture_output=True,
                          text=True, timeout=timeout)


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
