"""Replay rings of the off-policy trainers (`dqn.py`, `maddpg.py`): preallocated arrays filled from the B envs
of a batched step at once, sampled uniformly.

`TransitionRing(capacity, obs=((D,), np.float32), action=((H,), np.int64), ...)`: one array per named field,
shape (capacity, *field shape); `add(**arrays)` writes M rows (M <= capacity), overwriting the oldest;
`sample(K, rng)` returns K stored rows as tensors. The arrays are allocated with zeros, so the memory a
ring takes grows as it is filled (`nbytes` is the full size).
"""

from __future__ import annotations

import numpy as np
import torch

__all__ = ['TransitionRing']


class TransitionRing:
    def __init__(self, capacity: int, **fields: tuple[tuple[int, ...], type]) -> None:
        self.capacity, self.size, self.cursor = int(capacity), 0, 0
        self.fields = tuple(fields)
        for name, (shape, dtype) in fields.items():
            setattr(self, name, np.zeros((self.capacity, *shape), dtype=dtype))

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, name).nbytes for name in self.fields)

    def add(self, **arrays) -> None:
        count = len(next(iter(arrays.values())))
        if count > self.capacity:
            raise ValueError(f'{count} transitions do not fit a buffer of {self.capacity}')
        if set(arrays) != set(self.fields):
            raise ValueError(f'a transition has the fields {", ".join(self.fields)}; got {", ".join(arrays)}')
        rows = (self.cursor + np.arange(count)) % self.capacity
        for name, values in arrays.items():
            getattr(self, name)[rows] = values
        self.cursor = int((self.cursor + count) % self.capacity)
        self.size = min(self.size + count, self.capacity)

    def sample(self, count: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
        rows = rng.integers(self.size, size=count)
        return {name: torch.from_numpy(getattr(self, name)[rows]) for name in self.fields}
