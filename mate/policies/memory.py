"""The camera team's shared memory of target sightings (`--memory PERIOD`), for learners and their agents.

The greedy cameras do two things a memoryless policy cannot: they remember where each target was last
seen (for 25 steps), and they tell their teammates what they see. This module gives a learned camera
the same information as extra observation columns (what it did to learning: docs/training.md).

What a camera knows about target slot t (one memory per team: every camera broadcasts its sightings
every step, as a `Message` between agents, so all teammates hold the same memory):

* where the target was when a camera of the team last saw it, and how many env steps ago (`age`);
  after `period` steps without a sighting it is forgotten.

Features per camera and target slot, appended to the processed observation (4 per slot, slot-major):
`[dx, dy, freshness, seen_by_teammate]` with `(dx, dy)` the remembered location relative to the
camera, scaled like the observation's target records (divided by `scale`), `freshness = 1 - age /
period` (1: seen this step, 0: unknown; dx, dy are 0 then too), and `seen_by_teammate` 1 when some
camera sees the target now but this one does not.
"""

from __future__ import annotations

import numpy as np

from ..core.arrays import array_namespace, as_kind_of
from ..constants import PRESERVED_DIM
from ..messages import Team
from ..spaces import observation_indices_of, observation_space_of

__all__ = ['MEMORY_FEATURES', 'SightingMemory', 'camera_sightings', 'target_record_scale']

MEMORY_FEATURES = 4
"""Columns per target slot: dx, dy, freshness, seen_by_teammate."""


def camera_sightings(observation, num_cameras: int, num_targets: int, num_obstacles: int):
    """From raw camera observations (..., N, D) (numpy, or tensors on any device): each camera's location
    (..., N, 2) float64, which target slots it sees (..., N, Nt) bool, and their locations (..., N, Nt, 2)."""
    xp = array_namespace(observation)
    begin = int(observation_indices_of(Team.CAMERA, num_cameras, num_targets, num_obstacles)[2])
    records = xp.astype(observation[..., begin:begin + 5 * num_targets], xp.float64, copy=False)
    records = xp.reshape(records, (*records.shape[:-1], num_targets, 5))
    own = xp.astype(observation[..., PRESERVED_DIM:PRESERVED_DIM + 2], xp.float64, copy=False)
    return own, records[..., 4] > 0.5, records[..., :2]


def target_record_scale(num_cameras: int, num_targets: int, num_obstacles: int) -> float:
    """What the rescaling of a camera observation divides the target records' coordinates by."""
    begin = int(observation_indices_of(Team.CAMERA, num_cameras, num_targets, num_obstacles)[2])
    return float(observation_space_of(Team.CAMERA, num_cameras, num_targets, num_obstacles).high[begin])


class SightingMemory:
    """Last sighting of every target for B camera teams (or B = 1 for one agent's copy), in numpy arrays or, with
    `like` a tensor, in tensors on its device (the same code: `mate.core.arrays`).

    `age` (B, Nt) int64 env steps since a camera of the team saw the slot's target (`period`: unknown), `location`
    (B, Nt, 2) float64 where it was then.

    Args:
        num_envs: B.
        counts: (Nc, Nt, No) of the game.
        period: env steps a sighting is remembered (the greedy cameras: 25).
        like: an array or tensor whose kind and device the memory takes (None: numpy).
    """

    def __init__(self, num_envs: int, counts, period: int = 25, like=None) -> None:
        if period < 1:
            raise ValueError(f'memory period must be at least 1 step, got {period}')
        self.counts = tuple(int(n) for n in counts)
        nt = self.counts[1]
        self.period = int(period)
        location, age = np.zeros((num_envs, nt, 2)), np.full((num_envs, nt), self.period, dtype=np.int64)
        if like is not None:
            location, age = as_kind_of(location, like), as_kind_of(age, like)
        self.location, self.age = location, age
        self.scale = target_record_scale(*self.counts)

    def forget(self, mask=None) -> None:
        """Forget everything in the rows `mask` ((B,) bool; all rows if None): a new episode."""
        if mask is None:
            self.age[...] = self.period
        else:
            self.age = array_namespace(self.age).where(mask[:, None], self.period, self.age)

    def tick(self) -> None:
        """One env step has passed."""
        self.age = array_namespace(self.age).minimum(self.age + 1, self.period)

    def see(self, seen, location, rows=None) -> None:
        """Record sightings: `seen` (R, Nt) bool and `location` (R, Nt, 2) for the rows `rows` (all if None; a
        subset of rows: numpy only)."""
        if rows is None:
            xp = array_namespace(self.age)
            self.age = xp.where(seen, 0, self.age)
            self.location = xp.where(seen[..., None], location, self.location)
            return
        age, remembered = self.age[rows], self.location[rows]
        age[seen] = 0
        remembered[seen] = location[seen]
        self.age[rows], self.location[rows] = age, remembered

    def observe_team(self, observation, rows=None) -> None:
        """Record what every camera of the rows sees in raw observations (R, Nc, D) (the team's broadcast)."""
        xp = array_namespace(observation)
        _, seen, location = camera_sightings(observation, *self.counts)
        first = xp.argmax(xp.astype(seen, xp.uint8), axis=-2)                          # a camera that sees it
        location = xp.take_along_axis(location, first[..., None, :, None], axis=-3)[..., 0, :, :]
        self.see(xp.any(seen, axis=-2), location, rows)

    def features(self, observation, rows=None):
        """(R, N, Nt * 4) float32 memory features for raw camera observations (R, N, D) of the rows
        `rows` (all if None)."""
        rows = slice(None) if rows is None else rows
        return self.columns(observation, self.age[rows], self.location[rows])

    def columns(self, observation, age, location):
        """(R, N, Nt * 4) float32 memory features of raw camera observations (R, N, D) and a memory's `age` (R, Nt)
        and `location` (R, Nt, 2) (this one's, or a copy of it kept from an earlier step)."""
        xp = array_namespace(observation)
        own, visible, _ = camera_sightings(observation, *self.counts)
        known = age < self.period                                                      # (R, Nt)
        freshness = xp.where(known, 1.0 - xp.astype(age, xp.float64) / self.period, 0.0)
        offset = (location[:, None] - own[..., None, :]) / self.scale * known[:, None, :, None]
        teammate = (age == 0)[:, None] & ~visible
        nb, n, nt = visible.shape
        columns = xp.concat([offset, xp.broadcast_to(freshness[:, None, :, None], (nb, n, nt, 1)),
                             xp.astype(teammate[..., None], xp.float64)], axis=-1)
        return xp.astype(xp.reshape(columns, (nb, n, nt * MEMORY_FEATURES)), xp.float32)
