"""`MATE_REPRODUCIBLE=1`: pin the PyTorch kernels that follow the CPU, so that runs part less between machines.

What reproduces bit for bit where, as measured (golden runs of every trainer, tests/tools/golden_spread.py):

* On one machine, the same seed and `--threads` give the same run, bit for bit, with or without the switch.
* Machines of the same CPU family, model and ISA, with the same Python, torch, numpy and numba and the same kernel
  variables, run the same kernels: the same numbers.
* Across CPU families runs are **not** bitwise equal, even with the switch: AMD EPYC (family 25, model 17)
  recordings rerun on an Intel Xeon (family 6, model 207, AVX-512 with FP16/BF16 and AMX) part by up to 6e-5 in a
  log value and 2e-5 in a weight sum after 3 PPO iterations with the switch on both; pinning oneDNN or MKL's
  instructions to AVX2 on top leaves that as it is. The Q-learners (IQL, QMIX) fork outright: a greedy action flips
  at a near tie and the run becomes another (3e-2 apart in the first log row).
* The simulation (numba, float64, no fast-math) and numpy's dispatch never part runs: numpy with its AVX-512 paths
  switched off reproduces every golden run bitwise.

The switch sets, before torch is imported:

* `MKL_CBWR=COMPATIBLE`: MKL's conditional numerical reproducibility on its SSE2 branch;
* `ATEN_CPU_CAPABILITY=avx2`: ATen's AVX2 kernels, on AVX2 and AVX-512 machines alike.

On one Intel Xeon, nine kernel settings (ATen default/AVX2/AVX-512, MKL's automatic, AVX2, AVX-512 and compatible
branches, numpy without AVX-512) part the PPO-family runs by at most 2e-4 in a log value and 3e-5 in a weight sum.
The golden tests therefore compare bitwise only on the machine a recording was made on and within a measured
tolerance elsewhere (tests/learn/golden.py, docs/contributors/testing.md). The price of the switch, measured on 2
cores of an AMD EPYC: MAPPO cameras train at 1,130 decisions/s instead of 1,780 (1.6x slower). The test suite runs
with it (tests/conftest.py), as the golden recordings were made. GPUs are not covered.
"""

from __future__ import annotations

import os
import sys
import warnings

__all__ = ['KERNEL_PINS', 'SWITCH', 'enabled', 'pin_kernels']

SWITCH = 'MATE_REPRODUCIBLE'
"""The environment variable that asks for the pinned kernels ('1'; '' or '0': off)."""
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
