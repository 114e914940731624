"""Replay rings of the off-policy trainers (`iql.py`, `qmix.py`, `matd3.py`): preallocated numpy arrays filled from
the B envs of a batched step at once, sampled uniformly with the trainer's numpy generator.

* `TransitionRing(capacity, obs=((D,), np.float32), action=((H,), np.int64), ...)`: one array per named field,
  shape (capacity, *field shape); `add(**arrays)` writes M rows (M <= capacity), overwriting the oldest;
  `sample(K, rng)` returns K stored rows as tensors (MA-TD3's ring of team decisions);
* `ReplayBuffer(capacity, obs_dim, heads)`: IQL's ring of agent transitions (a `TransitionRing`);
* `SequenceReplay`: QMIX's ring of chunks of consecutive team decisions, each with the GRU state it starts from.

The arrays are allocated with zeros, so the memory a ring takes grows as it is filled (`nbytes` is the full size).
`state_dict()` holds the filled rows only (numpy arrays, which a checkpoint stores as tensors) and the write
position; `load_state_dict` puts them back into a ring of the same capacity, so that a resumed run samples what
the uninterrupted run would have.
"""

from __future__ import annotations

import numpy as np
import torch

__all__ = ['ReplayBuffer', 'SequenceReplay', 'TransitionRing']


class TransitionRing:
    """A ring of `capacity` rows with one preallocated array per named field, `name=(shape, dtype)`: arrays of
    shape (capacity, *shape). `add(**arrays)` writes M rows (M <= capacity), overwriting the oldest;
    `sample(K, rng)` returns K stored rows, uniformly drawn with the numpy generator `rng`, as tensors.
    `nbytes` is the full size (the zero-allocated arrays take memory as they are filled); `state_dict()` holds
    the filled rows and the write position."""

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

    def state_dict(self) -> dict:
        """The filled rows (the first `size`: a ring fills from row 0 and wraps once full) and the write position."""
        return dict(capacity=self.capacity, size=self.size, cursor=self.cursor,
                    rows={name: getattr(self, name)[:self.size] for name in self.fields})

    def fits(self, state: dict | None) -> bool:
        """Whether `state` (a `state_dict()` or None) loads into this ring (it has the same capacity)."""
        return state is not None and int(state['capacity']) == self.capacity

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output, taken from a ring of the same capacity and fields."""
        if not self.fits(state):
            raise ValueError(f"a replay of {state['capacity']} rows does not load into one of {self.capacity}")
        self.size, self.cursor = int(state['size']), int(state['cursor'])
        for name in self.fields:
            getattr(self, name)[:self.size] = state['rows'][name]


class ReplayBuffer(TransitionRing):
    """IQL's ring of agent transitions: obs and next_obs (C, D) float32, action (C, H) int64, reward and
    terminal (C,) float32; `add(obs, action, reward, next_obs, terminal)` takes M transitions at once.
    Memory: C x (2 D x 4 + H x 8 + 8) bytes."""

    def __init__(self, capacity: int, obs_dim: int, heads: int) -> None:
        super().__init__(capacity, obs=((obs_dim,), np.float32), action=((heads,), np.int64),
                         reward=((), np.float32), next_obs=((obs_dim,), np.float32), terminal=((), np.float32))

    def add(self, obs, action, reward, next_obs, terminal) -> None:
        super().add(obs=obs, action=action, reward=reward, next_obs=next_obs, terminal=terminal)


class SequenceReplay:
    """A ring of chunks of up to L consecutive team decisions (QMIX), filled from B envs at once.

    Stored per chunk: obs (L + 1, N, D) and state (L + 1, S) float32 (the chunk's decisions and the
    observation after its last one), action (L, N, H) int16, reward, terminal and mask (L,) float32 (mask 0
    after an episode that ended inside the chunk), h0 (N, G) float32: the acting GRU state at its first step.
    `record` appends one env step of every row to the row's open chunk and closes (stores) the chunks that
    are full or whose episode ended; `sample(K)` draws K stored chunks as tensors with a leading K axis.
    Memory: C x ((L + 1)(N D + S) x 4 + L (2 N H + 12) + 4 N G) bytes for C = capacity // L chunks.
    """

    FIELDS = ('obs', 'state', 'action', 'reward', 'terminal', 'mask', 'h0')

    def __init__(self, capacity: int, length: int, rows: int, agents: int, obs_dim: int, state_dim: int,
                 heads: int, hidden: int) -> None:
        self.length, self.chunks, self.size, self.cursor = int(length), max(int(capacity) // int(length), 1), 0, 0
        L, N = self.length, agents

        def arrays(count: int) -> dict[str, np.ndarray]:
            return dict(obs=np.zeros((count, L + 1, N, obs_dim), np.float32),
                        state=np.zeros((count, L + 1, state_dim), np.float32),
                        action=np.zeros((count, L, N, heads), np.int16), reward=np.zeros((count, L), np.float32),
                        terminal=np.zeros((count, L), np.float32), mask=np.zeros((count, L), np.float32),
                        h0=np.zeros((count, N, hidden), np.float32))

        self.stored, self.open = arrays(self.chunks), arrays(rows)
        self.position = np.zeros(rows, dtype=np.int64)             # decisions in each row's open chunk

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.stored.values())

    def begin(self, h0: np.ndarray) -> None:
        """Open every row's chunk at the GRU state `h0` (B, N, G) (a run resumed without its replay, mid-episode)."""
        self.open['h0'][...] = h0

    def record(self, obs, state, action, reward, terminal, ended, next_obs, next_state, next_h) -> None:
        """One env step of the B rows: obs (B, N, D), state (B, S), action (B, N, H), reward and terminal (B,),
        `ended` (B,) bool: the episode is over (its next observation `next_obs` (B, N, D) / `next_state` is its
        last one); `next_h` (B, N, G): the GRU state for the next decision (zero where an episode restarts)."""
        rows = np.arange(len(obs))
        at = self.position
        chunk = self.open
        chunk['obs'][rows, at], chunk['state'][rows, at], chunk['action'][rows, at] = obs, state, action
        chunk['reward'][rows, at], chunk['terminal'][rows, at], chunk['mask'][rows, at] = reward, terminal, 1.0
        self.position = at = at + 1
        closing = np.flatnonzero(ended | (at == self.length))
        if len(closing) == 0:
            return
        chunk['obs'][closing, at[closing]] = next_obs[closing]
        chunk['state'][closing, at[closing]] = next_state[closing]
        slots = (self.cursor + np.arange(len(closing))) % self.chunks
        for name in self.FIELDS:
            self.stored[name][slots] = chunk[name][closing]
        self.cursor = int((self.cursor + len(closing)) % self.chunks)
        self.size = min(self.size + len(closing), self.chunks)
        # the closed rows open new chunks at their next decision
        chunk['mask'][closing] = 0.0
        chunk['obs'][closing, 0], chunk['state'][closing, 0] = next_obs[closing], next_state[closing]
        chunk['h0'][closing] = next_h[closing]
        self.position[closing] = 0

    def sample(self, count: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
        rows = rng.integers(self.size, size=count)
        return {name: torch.from_numpy(self.stored[name][rows]) for name in self.FIELDS}

    def state_dict(self) -> dict:
        """The stored chunks (the first `size`), the rows' open chunks and the write position."""
        return dict(chunks=self.chunks, size=self.size, cursor=self.cursor, position=self.position.copy(),
                    stored={name: self.stored[name][:self.size] for name in self.FIELDS},
                    open={name: self.open[name].copy() for name in self.FIELDS})

    def fits(self, state: dict | None) -> bool:
        """Whether `state` (a `state_dict()` or None) loads into this replay (it has as many chunks of as many rows)."""
        return (state is not None and int(state['chunks']) == self.chunks
                and state['open']['obs'].shape == self.open['obs'].shape)

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output, taken from a replay of the same sizes."""
        if not self.fits(state):
            raise ValueError(f"a replay of {state['chunks']} chunks does not load into one of {self.chunks}")
        self.size, self.cursor = int(state['size']), int(state['cursor'])
        self.position[...] = state['position']
        for name in self.FIELDS:
            self.stored[name][:self.size] = state['stored'][name]
            self.open[name][...] = state['open'][name]
