"""The compilation decorators of the core.

`kernel` compiles a step-path function with numba's reference counting switched off. Step
kernels allocate nothing; without the switch, every access to an array field of the
`World`/`Params` tuples inside a branch costs an atomic increment/decrement pair, which
measured 5-10x slower (benchmarks/throughput.py). Functions that allocate (reset scratch
arrays, lists) use `allocating_kernel` instead.
"""

from __future__ import annotations

from numba import njit

kernel = njit(cache=True, _nrt=False)
inline_kernel = njit(cache=True, _nrt=False, inline='always')
allocating_kernel = njit(cache=True)
