"""EnhancedObservation: every agent sees every entity (full observability), targets see the true warehouse stock.

The array function `enhance_observations` does the work on joint observations with any leading batch
axes, `(..., Nc, D_c)` and `(..., Nt, D_t)`, so a vector env can call it on `(B, N, D)` arrays.
"""

from __future__ import annotations

import numpy as np

from mate.constants import (
    CAMERA_STATE_DIM_PUBLIC,
    NUM_WAREHOUSES,
    PRESERVED_DIM,
    TARGET_STATE_DIM_PUBLIC,
)
from mate.arrays import array_namespace, copied, device_of
from mate.spaces import camera_observation_slices_of, target_observation_slices_of

from .base import TeamObservationWrapper

__all__ = ['EnhancedObservation', 'empty_warehouses', 'enhance_observations', 'flagged_records', 'public_records']

TEAMS = TeamObservationWrapper.TEAMS

_CAMERA_PUBLIC = slice(PRESERVED_DIM, PRESERVED_DIM + CAMERA_STATE_DIM_PUBLIC)
_TARGET_PUBLIC = slice(PRESERVED_DIM, PRESERVED_DIM + TARGET_STATE_DIM_PUBLIC)
TARGET_EMPTY_BITS = slice(PRESERVED_DIM + 10, PRESERVED_DIM + 10 + NUM_WAREHOUSES)
"""Own empty_bits inside a target observation (the last 4 entries of its private state)."""


def flagged_records(records):
    """(..., n, d) records -> (..., 1, n * (d + 1)) float64: each record followed by a flag 1, flattened into one
    row block that broadcasts over the agent axis (numpy, or tensors on their device, as every function here)."""
    if not hasattr(records, 'shape'):
        records = np.asarray(records)
    xp = array_namespace(records)
    records = xp.astype(records, xp.float64, copy=False)
    ones = xp.ones((*records.shape[:-1], 1), dtype=xp.float64, device=device_of(records))
    flagged = xp.concat([records, ones], axis=-1)
    return xp.reshape(flagged, (*records.shape[:-2], 1, flagged.shape[-2] * flagged.shape[-1]))


def public_records(camera_obs, target_obs):
    """Public states read from each agent's own private state: cameras (..., Nc, 6), targets (..., Nt, 4) (copies)."""
    return copied(camera_obs[..., _CAMERA_PUBLIC]), copied(target_obs[..., _TARGET_PUBLIC])


def empty_warehouses(remaining_cargoes):
    """(..., 4) float 0/1: warehouse w has no cargo left to send (row w of `remaining_cargoes` (..., 4, 4) is zero)."""
    if not hasattr(remaining_cargoes, 'shape'):
        remaining_cargoes = np.asarray(remaining_cargoes)
    xp = array_namespace(remaining_cargoes)
    return xp.astype(~xp.any(remaining_cargoes != 0, axis=-1), xp.float64)


def all_flagged_records(camera_obs: np.ndarray, target_obs: np.ndarray, obstacle_states: np.ndarray):
    """(cameras (..., Nc, 7), targets (..., Nt, 5), obstacles (..., No, 4)): every entity's public
    state with flag 1, cut from the joint observations' own-state blocks."""
    cameras, targets = public_records(camera_obs, target_obs)
    return flagged_records(cameras), flagged_records(targets), flagged_records(obstacle_states)


def enhance_observations(camera_obs: np.ndarray, target_obs: np.ndarray, obstacle_states: np.ndarray,
                         empty_bits: np.ndarray, num_cameras: int, num_targets: int, num_obstacles: int,
                         camera: bool = True, target: bool = True) -> tuple[np.ndarray, np.ndarray]:
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
        s = camera_observation_slices_of(*counts)
        camera_obs[..., s['opponent_states_with_mask']] = targets
        camera_obs[..., s['obstacle_states_with_mask']] = obstacles
        camera_obs[..., s['teammate_states_with_mask']] = cameras
    if target:
        s = target_observation_slices_of(*counts)
        if not hasattr(empty_bits, 'shape'):
            empty_bits = np.asarray(empty_bits, dtype=np.float64)
        target_obs[..., TARGET_EMPTY_BITS] = empty_bits[..., None, :]
        target_obs[..., s['opponent_states_with_mask']] = cameras
        target_obs[..., s['obstacle_states_with_mask']] = obstacles
        target_obs[..., s['teammate_states_with_mask']] = targets
    return camera_obs, target_obs


class EnhancedObservation(TeamObservationWrapper):
    """Full observability for one or both teams.

    Camera side: every camera sees all targets, all obstacles and all cameras (public states, flag 1).
    Target side: every target sees all cameras, obstacles and targets, and its own `empty_bits` become the
    truth (warehouse w is empty iff it has no cargo left to send). `team='none'` passes through.

    Order: before (inside) any single-team wrapper, RelativeCoordinates and RescaledObservation.
    """

    def observation(self, observation: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The enhanced joint observations (the given arrays, modified in place)."""
        if not (self.for_camera or self.for_target):
            return observation
        camera_obs, target_obs = observation
        base = self.env.unwrapped
        return enhance_observations(camera_obs, target_obs, base.obstacle_states,
                                    empty_warehouses(base.remaining_cargoes), *self._counts,
                                    camera=self.for_camera, target=self.for_target)
