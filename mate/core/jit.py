"""The compilation decorators of the core, and the notice printed while they compile.

Every kernel runs with numba's reference counting switched off: kernels allocate nothing, and
with it on, every access to an array field of the `World`/`Params` tuples inside a branch costs
an atomic increment/decrement pair, which measured 5-10x slower (benchmarks/throughput.py).

Compile time (a cold cache, docs/performance.md): each helper is compiled once, as its own
function, and LLVM inlines it into its callers (`inline_kernel`). Helpers are called from
compiled code only, so they are compiled without numba's Python entry wrappers, which unbox
the ~40 arrays of a `World` and cost 0.7-1 s of compile time per function (busy machine). numba's own inlining
(`ir_inline_kernel`, the body copied into the caller before typing) is kept for the small
observation writers, where LLVM's inlining made the step 5-10% slower (B = 64); it copies and
retypes the body at every call site, which made the step's compile take ~5x longer when it was
used for everything.
"""

from __future__ import annotations

import os
import sys
import time

from numba import njit
from numba.core import event
from numba.core.registry import CPUDispatcher

NUM_THREADS = max(1, len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count() or 1)
"""The cores this process may use: threads that share a large batch, and whether the step compiles in a helper
process meanwhile (`warmup`)."""
COMPILE_NOTICE = 'mate: compiling the simulation kernels (first run only, ~{seconds} s)...'
COMPILE_SECONDS = '10-30'
"""Cold compile time of a first `mate evaluate`, quiet to busy 2-core machine (docs/performance.md)."""


class _CompiledCallersOnly(CPUDispatcher):
    """A dispatcher compiled without the Python entry wrappers, for calls from compiled code.

    A call from Python (tests, debugging) runs a twin compiled with the wrappers; the twin is
    not cached, because numba's cache key ignores these options and would hand a wrapperless
    entry point to Python.
    """

    _python_twin = None

    def __call__(self, *args, **kwargs):
        if self._python_twin is None:
            self._python_twin = njit(_nrt=False)(self.py_func)
        return self._python_twin(*args, **kwargs)


def _compiled_helper(**options):
    def decorate(function):
        dispatcher = _CompiledCallersOnly(py_func=function, targetoptions=dict(
            _nrt=False, no_cpython_wrapper=True, no_cfunc_wrapper=True, **options))
        dispatcher.enable_caching()
        return dispatcher
    return decorate


kernel = _compiled_helper()
"""A helper called from compiled code, compiled (and cached) once as its own function."""
inline_kernel = _compiled_helper(forceinline=True)
"""A `kernel` that LLVM inlines into every caller (the step path: no call overhead)."""
ir_inline_kernel = njit(cache=True, _nrt=False, inline='always')
"""A helper whose body numba copies into its callers before typing (observation writers)."""
entry_kernel = njit(cache=True, nogil=True, _nrt=False)
"""An entry point of the core, called from Python with the GIL released."""


def compile_notice_wanted() -> bool:
    """Whether to print the compile notice: MATE_COMPILE_NOTICE=1 / 0 forces it on / off;
    otherwise only when stderr is a terminal or a Jupyter kernel shows it (captured output,
    pipes and logs stay as they were)."""
    forced = os.environ.get('MATE_COMPILE_NOTICE', '').strip()
    if forced in ('0', '1'):
        return forced == '1'
    isatty = getattr(sys.stderr, 'isatty', None)
    return bool(isatty and isatty()) or 'ipykernel' in sys.modules


class _CompileNotice(event.Listener):
    """Prints `COMPILE_NOTICE` once per process, when numba starts compiling one of mate's
    functions (a cache miss; loads from the cache send no compile event), and counts the wall time
    spent compiling them (`compile_seconds`; nested compilations counted once)."""

    def __init__(self) -> None:
        self.shown = False
        self.depth, self.started, self.seconds = 0, 0.0, 0.0

    @staticmethod
    def _ours(ev) -> bool:
        return getattr(ev.data['dispatcher'].py_func, '__module__', '').startswith('mate.')

    def on_start(self, ev) -> None:
        if not self._ours(ev):
            return
        if self.depth == 0:
            self.started = time.perf_counter()
        self.depth += 1
        if self.shown:
            return
        self.shown = True
        if compile_notice_wanted():
            print(COMPILE_NOTICE.format(seconds=COMPILE_SECONDS), file=sys.stderr, flush=True)

    def on_end(self, ev) -> None:
        if not self._ours(ev) or self.depth == 0:
            return
        self.depth -= 1
        if self.depth == 0:
            self.seconds += time.perf_counter() - self.started


_NOTICE = _CompileNotice()
event.register('numba:compile', _NOTICE)


def compile_seconds() -> float:
    """Wall seconds this process has spent compiling mate's kernels so far (0 when they all came from the cache):
    what a first run's timings include."""
    return _NOTICE.seconds
