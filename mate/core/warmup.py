"""On a cold compile cache, compile the step kernel in a second process while this one compiles the reset.

A first run spends ~15 s (quiet 2-core machine) compiling two entry points: `_reset_rows` (~11 s
of CPU with its helpers) and `_step_rows` (~3.5 s more; docs/performance.md). A process runs its
reset before its first step, so it compiles them one after the other on one core. When the first
reset of a process misses the cache, `compiling_step_aside` starts a helper process that compiles
`_step_rows` for the same argument types and writes it to numba's cache; helpers both need
(observations, perception, cargo) are compiled once, by whichever process reaches them first,
and loaded from the cache by the other. Before its first step this process waits for the helper
(`wait_for_step_compile`) and then loads the step from the cache instead of compiling it.

Nothing changes in what runs: the helper only fills the cache. It is skipped when the cache is
warm (no compile event), when `MATE_PARALLEL_COMPILE=0`, on one-core machines and when numba's JIT
is disabled; if it fails, this process compiles the step itself, as before.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys

import numpy as np
from numba.core import event
from numba.core.config import DISABLE_JIT

from .jit import NUM_THREADS

HELPER_SECONDS = 120.0
"""The longest a first step waits for the helper (then it compiles the step itself)."""

_helper: subprocess.Popen | None = None
_tried = False


def _wanted() -> bool:
    return os.environ.get('MATE_PARALLEL_COMPILE', '1').strip() != '0' and NUM_THREADS > 1 and not DISABLE_JIT


class _FirstMateCompile(event.Listener):
    """Calls `start` once, when numba starts compiling one of mate's functions (a cache miss)."""

    def __init__(self, start) -> None:
        self.start = start

    def on_start(self, ev) -> None:
        if self.start is not None and getattr(ev.data['dispatcher'].py_func, '__module__', '').startswith('mate.'):
            start, self.start = self.start, None
            start()

    def on_end(self, ev) -> None:
        pass


_NOTHING = contextlib.nullcontext()


def compiling_step_aside(camera_obs: np.ndarray, target_obs: np.ndarray) -> contextlib.AbstractContextManager:
    """A context for the first reset of a process: if it compiles, the step for observation buffers of these
    dtypes (camera_obs (B, Nc, D_c), target_obs (B, Nt, D_t)) compiles in a helper process meanwhile. Later
    resets get a context that does nothing."""
    global _tried
    if _tried:
        return _NOTHING
    _tried = True
    if not _wanted():
        return _NOTHING
    dtypes = (np.dtype(camera_obs.dtype).name, np.dtype(target_obs.dtype).name)
    return event.install_listener('numba:compile', _FirstMateCompile(lambda: _start_helper(*dtypes)))


def _start_helper(camera_dtype: str, target_dtype: str) -> None:
    global _helper
    environment = {**os.environ, 'MATE_PARALLEL_COMPILE': '0', 'MATE_COMPILE_NOTICE': '0',
                   'PYTHONPATH': os.pathsep.join(path or os.getcwd() for path in sys.path)}   # this process's mate
    code = f'from mate.core.engine import compile_step; compile_step({camera_dtype!r}, {target_dtype!r})'
    try:
        _helper = subprocess.Popen([sys.executable, '-c', code], env=environment, stdin=subprocess.DEVNULL,
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:   # no new process here: compile everything in this one
        _helper = None


def wait_for_step_compile() -> None:
    """Before a process's first step: let a running helper finish, so the step loads from the cache."""
    global _helper
    helper, _helper = _helper, None
    if helper is not None:
        try:
            helper.wait(timeout=HELPER_SECONDS)
        except subprocess.TimeoutExpired:   # leave it to finish on its own; compile here
            pass
