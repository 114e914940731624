"""One function body for numpy arrays and torch tensors: the few helpers the array-generic code of mate shares.

Code that must run on the host (numpy) and on a CUDA device (torch tensors), in the core (the episode statistics,
full observability) and above it (the envs, the training env, the policy spec's pipeline), is written once over the
array namespace of its inputs (`array_api_compat.array_namespace`: numpy's functions for numpy arrays, torch's for
tensors). What that namespace does not give:

* `on_device_of(constant, like)`: a numpy constant (index arrays, box bounds) as an array of `like`'s kind and
  device, made once per device (a host-to-device copy at every call would wait for the device);
* `copied(x)`: a copy of either kind; `float64_copy(x)` a float64 copy (anything array-like gives numpy);
* `maybe_any(mask)`: whether a (B,) mask may hold a true entry; on the host the exact answer (a free test that
  lets the caller skip work), for a tensor always True (reading the answer back would wait for the device: the
  caller does the work for every row and selects with the mask, which gives the same values).
"""

from __future__ import annotations

import array_api_compat
import array_api_compat.numpy as _numpy_namespace
import numpy as np
from array_api_compat import device as device_of
from array_api_compat import is_numpy_array

__all__ = ['array_namespace', 'as_kind_of', 'copied', 'device_of', 'float64_copy', 'host_array', 'host_copy', 'is_host',
           'maybe_any', 'on_device_of']


def array_namespace(*arrays):
    """The array namespace of `arrays` (`array_api_compat.array_namespace`), with a fast path for one numpy array
    (the host's hot loops call this at every step)."""
    if len(arrays) == 1 and type(arrays[0]) is np.ndarray:
        return _numpy_namespace
    return array_api_compat.array_namespace(*arrays)


def is_host(x) -> bool:
    """Whether `x` is a numpy array (the host path) rather than a tensor (a fast test for a plain ndarray first)."""
    return type(x) is np.ndarray or is_numpy_array(x)


class _Constants:
    """numpy constants converted once per device and kept with the numpy array they came from."""

    LIMIT = 256
    """Conversions kept (the oldest go first: a constant made for one call is not kept for ever)."""

    def __init__(self) -> None:
        self._held: dict[tuple[int, str], tuple[np.ndarray, object]] = {}

    def get(self, constant: np.ndarray, like):
        if is_host(like):
            return constant
        key = (id(constant), str(like.device))
        held = self._held.get(key)
        if held is None or held[0] is not constant:
            import torch

            held = (constant, torch.as_tensor(np.array(constant), device=like.device))
            self._held[key] = held
            if len(self._held) > self.LIMIT:
                del self._held[next(iter(self._held))]
        return held[1]


_CONSTANTS = _Constants()


def on_device_of(constant: np.ndarray, like):
    """`constant` (a numpy array that lives as long as its owner: a cached layout, a pipeline's field) as an array of
    `like`'s kind: itself for a numpy `like`, a tensor on `like`'s device otherwise (converted once per device)."""
    return _CONSTANTS.get(constant, like)


def as_kind_of(array: np.ndarray, like):
    """A host array as an array of `like`'s kind: itself for a numpy `like`, a tensor on `like`'s device otherwise
    (a state the caller keeps, unlike `on_device_of`'s shared constants)."""
    if is_host(like):
        return array
    import torch

    return torch.as_tensor(array, device=like.device)


def host_array(x):
    """The array or tensor `x` as a numpy array: itself on the host, a tensor brought there (no copy where none is
    needed: read it, do not keep it)."""
    return x if is_host(x) else x.detach().cpu().numpy()


def host_copy(x):
    """A numpy copy of the array or tensor `x` (None stays None): plain data for a state_dict."""
    return None if x is None else host_array(x).copy()


def copied(x):
    """A copy of the array or tensor `x`."""
    return x.copy() if is_host(x) else x.clone()


def float64_copy(x):
    """A float64 copy of `x`: a tensor on its device for a tensor, a numpy array for anything else."""
    if hasattr(x, 'detach') and hasattr(x, 'double'):         # a torch tensor
        y = x.double()
        return y.clone() if y is x else y
    return np.array(x, dtype=np.float64, copy=True)


def maybe_any(mask) -> bool:
    """Whether the bool mask may hold a true entry: `mask.any()` for a numpy array; True for a tensor (module
    docstring)."""
    return bool(mask.any()) if is_host(mask) else True
