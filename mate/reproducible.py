"""`MATE_REPRODUCIBLE=1`: the same numbers, bit for bit, on any x86-64 CPU (Intel or AMD, AVX2 or AVX-512).

Where runs part between machines: the simulation (numba, float64, no fast-math) and numpy's dispatch do not (checked
by switching numpy's AVX-512 paths off: every golden run bitwise equal); the learners' PyTorch kernels do. MKL's
matrix products choose their kernels by processor vendor, ISA and matrix size (setting its reproducibility mode
changes every golden run on an AMD EPYC; on an Intel Xeon the golden runs recorded on AMD parted: policy losses
4e-5 apart by the second iteration, a Q-learner's coverage 4.5 % apart after its greedy actions flipped), and
ATen's own vectorised kernels follow the CPU's ISA (AVX-512 or AVX2: 10 of 15 golden runs differ between the two on
one machine).

With the environment variable `MATE_REPRODUCIBLE=1`, `import mate` pins both before torch is imported:

* `MKL_CBWR=COMPATIBLE`: MKL's conditional numerical reproducibility on its SSE2 branch, the one branch MKL
  supports on Intel and non-Intel processors alike;
* `ATEN_CPU_CAPABILITY=avx2`: ATen's AVX2 kernels, on AVX2 and AVX-512 machines alike.

With the same `--threads` (the golden runs use one) a run then gives the same numbers on every CPU family. The
price, measured on 2 cores of an AMD EPYC: MAPPO cameras train at 1,130 decisions/s instead of 1,780 (1.6x slower).
Without the switch a run reproduces bitwise on the same machine, and on machines of the same CPU family and ISA.
The test suite runs with it (tests/conftest.py), so its golden runs hold on any x86-64 CPU. GPUs are not covered.
"""

from __future__ import annotations

import os
import sys
import warnings

__all__ = ['KERNEL_PINS', 'SWITCH', 'enabled', 'pin_kernels']

SWITCH = 'MATE_REPRODUCIBLE'
"""The environment variable that asks for cross-CPU reproducible numbers ('1'; '' or '0': off)."""
KERNEL_PINS = {'MKL_CBWR': 'COMPATIBLE', 'ATEN_CPU_CAPABILITY': 'avx2'}
"""The environment variables the switch sets, and their values (module docstring)."""


def enabled() -> bool:
    """Whether `MATE_REPRODUCIBLE` asks for reproducible kernels."""
    return os.environ.get(SWITCH, '').strip().lower() not in ('', '0', 'false', 'no')


def pin_kernels() -> dict[str, str]:
    """With the switch on, set `KERNEL_PINS` in the environment (torch reads them when it loads); returns what was
    set ({} with the switch off). Warns when torch was imported before: its kernels are chosen already."""
    if not enabled():
        return {}
    if 'torch' in sys.modules and any(os.environ.get(key) != value for key, value in KERNEL_PINS.items()):
        warnings.warn(f'{SWITCH}=1 but torch was imported before mate: its kernels are not pinned; import mate first '
                      f'or set {", ".join(f"{k}={v}" for k, v in KERNEL_PINS.items())} yourself', stacklevel=3)
    os.environ.update(KERNEL_PINS)
    return dict(KERNEL_PINS)
