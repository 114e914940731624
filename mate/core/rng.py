"""Counter-based random numbers: one explicit stream per environment row.

Each world row carries `rng[b] = (key, counter)` (uint64). A draw hashes
`key + counter * GAMMA` with the SplitMix64 finaliser and bumps the counter, so a row's
stream depends only on its own key: a batch of B rows draws exactly what B single
environments with the same keys draw. Keys come from `numpy.random.SeedSequence`.
"""

from __future__ import annotations

import numpy as np

from .jit import inline_kernel

_GAMMA = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_TO_UNIT = 1.0 / 9007199254740992.0  # 2 ** -53


@inline_kernel
def uniform(rng, b):
    """Next float in [0, 1) from row b's stream; advances rng[b, 1]."""
    counter = rng[b, 1] + np.uint64(1)
    rng[b, 1] = counter
    z = rng[b, 0] + counter * _GAMMA
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    z = z ^ (z >> _S31)
    return np.float64(z >> _S11) * _TO_UNIT


@inline_kernel
def randint(rng, b, n):
    """Next integer uniform in [0, n) from row b's stream (n >= 1)."""
    k = int(uniform(rng, b) * n)
    return min(k, n - 1)


def mix64(values: np.ndarray) -> np.ndarray:
    """The SplitMix64 finaliser `uniform` applies, on uint64 numpy arrays (wrapping): to derive stream keys."""
    with np.errstate(over='ignore'):
        z = np.asarray(values, dtype=np.uint64)
        z = (z ^ (z >> _S30)) * _MIX1
        z = (z ^ (z >> _S27)) * _MIX2
        return z ^ (z >> _S31)


def key_from_seed(seed: int | None) -> np.uint64:
    """A 64-bit stream key derived from `seed` (None: fresh OS entropy) with SeedSequence."""
    return np.random.SeedSequence(seed).generate_state(1, dtype=np.uint64)[0]
