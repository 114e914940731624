"""HRL cameras (spec training.md §3): the policy picks a subset of targets, a rule executor aims at it.

High-level action: one keep/ignore bit per target slot, (..., Nt) in {0, 1}. The executor runs at every
raw step on the camera's fresh raw observation:

* valid = selected and currently visible (the camera's own flags);
* no valid target: the action lower bound (-rotation step, -zooming step), a clockwise sweep that
  narrows the view (and so lengthens the sight range);
* otherwise aim at the centroid of the valid targets: rotation = bearing - orientation wrapped to
  (-180, 180], zoom = the greedy camera's desired viewing angle for the centroid's distance - current
  angle; both clipped to the per-step limits.

The spec's learners pick a selection as one of 2^Nt choices (Discrete(256) for 8 targets); `selection_bits`
maps such an index to its bits (bit t of the index keeps target t) and `joint_allowed` lists the choices
that keep only visible targets.
"""

from __future__ import annotations

import numpy as np

from ..constants import PRESERVED_DIM
from ..messages import Team
from ..spaces import observation_indices_of

__all__ = ['desired_viewing_angles', 'executor_actions', 'joint_allowed', 'masked_selection_logits', 'selection_bits', 'target_records']

_OWN = PRESERVED_DIM


def desired_viewing_angles(distance, viewing_angle, sight_range, max_sight_range, iterations: int = 20):
    """The greedy camera's desired viewing angle (`mate.teams.rules.desired_viewing_angle`) on arrays, in degrees,
    element-wise: the executor's zoom (the same fixed-point iteration, numpy's rounding)."""
    half = 0.5 * np.pi / 180.0
    theta_min = viewing_angle * (sight_range / max_sight_range) ** 2
    area = viewing_angle * sight_range ** 2
    theta = np.full(np.shape(distance), 180.0)
    for _ in range(iterations):
        reach = distance * (1.0 + np.sin(np.minimum(theta * half, 0.5 * np.pi)))
        theta = area / np.maximum(reach * reach, 1e-12)
    theta = np.clip(theta, theta_min, 180.0)
    theta = np.where(distance <= 0.5 * np.sqrt(area / 180.0), 180.0, theta)
    far = distance * (1.0 + np.sin(theta_min * half)) >= max_sight_range
    return np.where(far, theta_min, theta)


def target_records(observation: np.ndarray, num_cameras: int, num_targets: int, num_obstacles: int) -> np.ndarray:
    """The target slots (..., Nt, 5) of raw camera observations (..., D): relative location (2), sight range,
    loaded flag and the visibility flag (index 4)."""
    begin = int(observation_indices_of(Team.CAMERA, num_cameras, num_targets, num_obstacles)[2])
    return observation[..., begin:begin + 5 * num_targets].reshape(observation.shape[:-1] + (num_targets, 5))


def masked_selection_logits(logits: np.ndarray, observation: np.ndarray, num_cameras: int, num_targets: int,
                            num_obstacles: int) -> np.ndarray:
    """Logits (..., 2^Nt) of one-choice (`selection='joint'`) HRL policies with the selections that keep an
    invisible target set to -inf, as in training: such choices were never taken, so their values are untrained."""
    visible = target_records(np.asarray(observation), num_cameras, num_targets, num_obstacles)[..., 4] > 0.5
    return np.where(joint_allowed(visible), logits, -np.inf)


def executor_actions(observation: np.ndarray, selection: np.ndarray, num_cameras: int, num_targets: int,
                     num_obstacles: int) -> np.ndarray:
    """Continuous camera actions (..., 2) in degrees from raw observations (..., D) and selection bits
    (..., Nt). Also returns nothing else: the valid-selection statistics are cheap to recompute."""
    observation = np.asarray(observation, dtype=np.float64)
    records = target_records(observation, num_cameras, num_targets, num_obstacles)
    valid = (np.asarray(selection) > 0.5) & (records[..., 4] > 0.5)                  # (..., Nt)
    count = valid.sum(axis=-1)
    centroid = (records[..., :2] * valid[..., None]).sum(axis=-2) / np.maximum(count, 1)[..., None]
    own = observation[..., _OWN:_OWN + 9]
    x, y, rx, ry, theta, max_range = (own[..., k] for k in (0, 1, 3, 4, 5, 6))
    high = own[..., 7:9]
    orientation = np.degrees(np.arctan2(ry, rx))
    bearing = np.degrees(np.arctan2(centroid[..., 1] - y, centroid[..., 0] - x))
    rotation = (bearing - orientation + 180.0) % 360.0 - 180.0
    distance = np.hypot(centroid[..., 0] - x, centroid[..., 1] - y)
    zoom = desired_viewing_angles(np.where(count > 0, distance, 1.0), theta, np.hypot(rx, ry), max_range) - theta
    aimed = np.clip(np.stack([rotation, zoom], axis=-1), -high, high)
    return np.where((count > 0)[..., None], aimed, -high)


def selection_bits(num_targets: int) -> np.ndarray:
    """(2^Nt, Nt) int64: row k holds the keep bits of selection index k (bit t of k keeps target t)."""
    return (np.arange(2 ** num_targets)[:, None] >> np.arange(num_targets)) & 1


def joint_allowed(visible: np.ndarray) -> np.ndarray:
    """(..., 2^Nt) bool from visibility flags (..., Nt): the selections that keep only visible targets."""
    bits = selection_bits(visible.shape[-1]).astype(bool)
    return ~(bits & ~np.asarray(visible, dtype=bool)[..., None, :]).any(-1)
