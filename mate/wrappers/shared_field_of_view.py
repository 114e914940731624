"""SharedFieldOfView: teammates pool what they see (logical OR of the visibility flags over the team).

The array function `share_field_of_view` works on joint observations with any leading batch axes,
`(..., Nc, D_c)` and `(..., Nt, D_t)`.
"""

from __future__ import annotations

import numpy as np

from mate.spaces import camera_observation_slices_of, target_observation_slices_of

from .base import TeamObservationWrapper
from .enhanced_observation import TARGET_EMPTY_BITS, all_flagged_records

__all__ = ['SharedFieldOfView', 'share_field_of_view']


def _shared_block(joint_obs: np.ndarray, mask_slice: slice, flagged: np.ndarray) -> np.ndarray:
    """(..., 1, n * (d + 1)): record k of `flagged` where any agent's flag k is set, zeros elsewhere."""
    seen = (joint_obs[..., mask_slice] != 0.0).any(axis=-2)               # (..., n)
    n = seen.shape[-1]
    records = flagged.reshape(flagged.shape[:-1] + (n, -1)) if n else flagged.reshape(flagged.shape[:-1] + (0, 1))
    shared = np.where(seen[..., None, :, None], records, 0.0)              # (..., 1, n, d + 1)
    return shared.reshape(flagged.shape)


def share_field_of_view(camera_obs: np.ndarray, target_obs: np.ndarray, obstacle_states: np.ndarray,
                        num_cameras: int, num_targets: int, num_obstacles: int,
                        camera: bool = True, target: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Pool the team's field of view, in place.

    Camera side: target t is shown to every camera iff some camera sees it, likewise each obstacle; the
    teammate block shows every camera (flagged). Target side: the same OR for cameras and obstacles, every
    target's own `empty_bits` become the OR over the team, and the teammate block shows every target.

    Args:
        camera_obs: (..., Nc, D_c); target_obs: (..., Nt, D_t); obstacle_states: (..., No, 3).
    Returns:
        the two arrays.
    """
    counts = (num_cameras, num_targets, num_obstacles)
    cameras, targets, obstacles = all_flagged_records(camera_obs, target_obs, obstacle_states)
    if camera:
        s = camera_observation_slices_of(*counts)
        shared_targets = _shared_block(camera_obs, s['opponent_mask'], targets)
        shared_obstacles = _shared_block(camera_obs, s['obstacle_mask'], obstacles)
        camera_obs[..., s['opponent_states_with_mask']] = shared_targets
        camera_obs[..., s['obstacle_states_with_mask']] = shared_obstacles
        camera_obs[..., s['teammate_states_with_mask']] = cameras
    if target:
        s = target_observation_slices_of(*counts)
        shared_cameras = _shared_block(target_obs, s['opponent_mask'], cameras)
        shared_obstacles = _shared_block(target_obs, s['obstacle_mask'], obstacles)
        empty = (target_obs[..., TARGET_EMPTY_BITS] != 0.0).any(axis=-2, keepdims=True)
        target_obs[..., TARGET_EMPTY_BITS] = empty
        target_obs[..., s['opponent_states_with_mask']] = shared_cameras
        target_obs[..., s['obstacle_states_with_mask']] = shared_obstacles
        target_obs[..., s['teammate_states_with_mask']] = targets
    return camera_obs, target_obs


class SharedFieldOfView(TeamObservationWrapper):
    """Each team shares its field of view: an entity seen by one teammate is seen by all.

    Cameras: OR of the target and obstacle flags over all cameras; every camera sees all cameras.
    Targets: OR of the camera and obstacle flags and of the warehouse `empty_bits` over all targets; every
    target sees all targets. `team` in {'both', 'camera', 'target', 'none'} chooses the teams.

    Order: before (inside) any single-team wrapper, RelativeCoordinates and RescaledObservation.
    """

    def observation(self, observation: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The shared joint observations (the given arrays, modified in place)."""
        if not (self.for_camera or self.for_target):
            return observation
        camera_obs, target_obs = observation
        return share_field_of_view(camera_obs, target_obs, self.env.unwrapped.obstacle_states, *self._counts,
                                   camera=self.for_camera, target=self.for_target)
