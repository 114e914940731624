"""Full observability (the paper's Fig. 6 ablation), a rule of the game: every agent of a team sees every entity,
and targets see which warehouses are truly empty. One array function for numpy arrays and torch tensors (the CPU
and the device), on joint observations with any leading batch axes, `(..., Nc, D_c)` and `(..., Nt, D_t)`.

The record of an entity is its public state followed by a flag 1, as a perceived entity's block of the
observation (`mate.core.observe`): the public states are cut from each agent's own private state, the obstacles'
from the world. `enhance_observations` fills them in place for the teams asked for; the `EnhancedObservation`
wrapper, `mate evaluate --enhanced-observation`, the batched play and the training envs (`--full-observability`)
all call it.
"""

from __future__ import annotations

import functools

import numpy as np

from ..constants import (CAMERA_STATE_DIM_PRIVATE, CAMERA_STATE_DIM_PUBLIC, NUM_WAREHOUSES, OBSTACLE_STATE_DIM,
                         PRESERVED_DIM, TARGET_STATE_DIM_PRIVATE, TARGET_STATE_DIM_PUBLIC)
from .arrays import array_namespace, copied, device_of

__all__ = ['TARGET_EMPTY_BITS', 'all_flagged_records', 'empty_warehouses', 'enhance_observations', 'flagged_records',
           'public_records', 'record_slices']

CAMERA_PUBLIC = slice(PRESERVED_DIM, PRESERVED_DIM + CAMERA_STATE_DIM_PUBLIC)
"""A camera's public state inside its own observation (the head of its private state)."""
TARGET_PUBLIC = slice(PRESERVED_DIM, PRESERVED_DIM + TARGET_STATE_DIM_PUBLIC)
"""A target's public state inside its own observation."""
TARGET_EMPTY_BITS = slice(PRESERVED_DIM + 10, PRESERVED_DIM + 10 + NUM_WAREHOUSES)
"""Own empty_bits inside a target observation (the last 4 entries of its private state)."""


@functools.cache
def record_slices(camera: bool, num_cameras: int, num_targets: int, num_obstacles: int) -> tuple[slice, slice, slice]:
    """(opponents, obstacles, teammates): the slices of the flagged records in an observation of a camera
    (`camera`) or of a target, each block an entity's public state and its flag."""
    own = CAMERA_STATE_DIM_PRIVATE if camera else TARGET_STATE_DIM_PRIVATE
    opponents = (num_targets, TARGET_STATE_DIM_PUBLIC) if camera else (num_cameras, CAMERA_STATE_DIM_PUBLIC)
    teammates = (num_cameras, CAMERA_STATE_DIM_PUBLIC) if camera else (num_targets, TARGET_STATE_DIM_PUBLIC)
    begin, slices = PRESERVED_DIM + own, []
    for count, dim in (opponents, (num_obstacles, OBSTACLE_STATE_DIM), teammates):
        slices.append(slice(begin, begin + count * (dim + 1)))
        begin += count * (dim + 1)
    return tuple(slices)


def _array(x):
    return x if hasattr(x, 'shape') else np.asarray(x)


def flagged_records(records):
    """(..., n, d) records -> (..., 1, n * (d + 1)) float64: each record followed by a flag 1, flattened into one
    row block that broadcasts over the agent axis."""
    records = _array(records)
    xp = array_namespace(records)
    records = xp.astype(records, xp.float64, copy=False)
    ones = xp.ones((*records.shape[:-1], 1), dtype=xp.float64, device=device_of(records))
    flagged = xp.concat([records, ones], axis=-1)
    return xp.reshape(flagged, (*records.shape[:-2], 1, flagged.shape[-2] * flagged.shape[-1]))


def public_records(camera_obs, target_obs):
    """Public states read from each agent's own private state: cameras (..., Nc, 6), targets (..., Nt, 4) (copies)."""
    return copied(camera_obs[..., CAMERA_PUBLIC]), copied(target_obs[..., TARGET_PUBLIC])


def empty_warehouses(remaining_cargoes):
    """(..., 4) float 0/1: warehouse w has no cargo left to send (row w of `remaining_cargoes` (..., 4, 4) is zero)."""
    remaining_cargoes = _array(remaining_cargoes)
    xp = array_namespace(remaining_cargoes)
    return xp.astype(~xp.any(remaining_cargoes != 0, axis=-1), xp.float64)


def all_flagged_records(camera_obs, target_obs, obstacle_states):
    """(cameras (..., Nc, 7), targets (..., Nt, 5), obstacles (..., No, 4)): every entity's public
    state with flag 1, cut from the joint observations' own-state blocks."""
    cameras, targets = public_records(camera_obs, target_obs)
    return flagged_records(cameras), flagged_records(targets), flagged_records(obstacle_states)


def enhance_observations(camera_obs, target_obs, obstacle_states, empty_bits, num_cameras: int, num_targets: int,
                         num_obstacles: int, camera: bool = True, target: bool = True):
    """Fill every opponent, obstacle and teammate record with the entity's public state and flag 1, in place
    (numpy arrays, or tensors on their device).

    Args:
        camera_obs: (..., Nc, D_c) joint camera observations (modified in place when `camera`).
        target_obs: (..., Nt, D_t) joint target observations (modified in place when `target`).
        obstacle_states: (..., No, 3) obstacle [x, y, r] per slot.
        empty_bits: (..., 4) true emptiness of each warehouse (see `empty_warehouses`), written into each
            target's own empty_bits.
    Returns:
        the two arrays.
    """
    counts = (num_cameras, num_targets, num_obstacles)
    cameras, targets, obstacles = all_flagged_records(camera_obs, target_obs, obstacle_states)
    if camera:
        opponents, obstacle_slots, teammates = record_slices(True, *counts)
        camera_obs[..., opponents] = targets
        camera_obs[..., obstacle_slots] = obstacles
        camera_obs[..., teammates] = cameras
    if target:
        opponents, obstacle_slots, teammates = record_slices(False, *counts)
        target_obs[..., TARGET_EMPTY_BITS] = _array(empty_bits)[..., None, :]
        target_obs[..., opponents] = cameras
        target_obs[..., obstacle_slots] = obstacles
        target_obs[..., teammates] = targets
    return camera_obs, target_obs
