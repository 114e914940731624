"""Builders of hand-made observations for agent unit tests (layouts of spec environment.md §5).

Entities are given as dicts of Python values; everything not given is an invisible (all-zero)
record. Angles in degrees.
"""

from __future__ import annotations

import math

import numpy as np

from mate.constants import WAREHOUSE_RADIUS, WAREHOUSES
from mate.spaces import camera_observation_indices_of, target_observation_indices_of


def _preserved(nc: int, nt: int, no: int, index: int) -> list[float]:
    return [nc, nt, no, index, *WAREHOUSES.ravel().tolist(), WAREHOUSE_RADIUS]


def camera_public(x, y, orientation=0.0, viewing_angle=90.0, sight_range=None, radius=40.0,
                  max_sight_range=1500.0, min_viewing_angle=30.0) -> list[float]:
    """[x, y, radius, R cos(phi), R sin(phi), theta]; R follows the constant-area rule unless given."""
    if sight_range is None:
        sight_range = max_sight_range * math.sqrt(min_viewing_angle / viewing_angle)
    phi = math.radians(orientation)
    return [x, y, radius, sight_range * math.cos(phi), sight_range * math.sin(phi), viewing_angle]


def camera_private(x, y, orientation=0.0, viewing_angle=90.0, max_sight_range=1500.0, rotation_step=5.0,
                   zooming_step=2.5, min_viewing_angle=30.0, sight_range=None, radius=40.0) -> list[float]:
    public = camera_public(x, y, orientation, viewing_angle, sight_range, radius, max_sight_range, min_viewing_angle)
    return public + [max_sight_range, rotation_step, zooming_step]


def target_private(x, y, step_size=20.0, capacity=1.0, goal_bits=(0, 0, 0, 0), empty_bits=(0, 0, 0, 0),
                   sight_range=500.0) -> list[float]:
    loaded = 1.0 if any(goal_bits) else 0.0
    return [x, y, sight_range, loaded, step_size, capacity, *goal_bits, *empty_bits]


def camera_observation(own: list[float], index: int = 0, nc: int = 4, nt: int = 8, no: int = 9,
                       targets: dict | None = None, obstacles: dict | None = None,
                       cameras: dict | None = None) -> np.ndarray:
    """A camera observation (D_c,). targets: {t: [x, y, sight_range, is_loaded]}; obstacles:
    {o: [x, y, r]}; cameras: {c: 6 public values} (the own record is filled in from `own`)."""
    indices = camera_observation_indices_of(nc, nt, no)
    obs = np.zeros(int(indices[-1]))
    obs[:13] = _preserved(nc, nt, no, index)
    obs[13:22] = own
    for t, values in (targets or {}).items():
        obs[indices[2] + 5 * t:indices[2] + 5 * t + 5] = [*values, 1.0]
    for o, values in (obstacles or {}).items():
        obs[indices[3] + 4 * o:indices[3] + 4 * o + 4] = [*values, 1.0]
    cameras = dict(cameras or {})
    cameras[index] = own[:6]
    for c, values in cameras.items():
        obs[indices[4] + 7 * c:indices[4] + 7 * c + 7] = [*values, 1.0]
    return obs


def target_observation(own: list[float], index: int = 0, nc: int = 4, nt: int = 8, no: int = 9,
                       cameras: dict | None = None, obstacles: dict | None = None,
                       targets: dict | None = None) -> np.ndarray:
    """A target observation (D_t,). cameras: {c: 6 public values}; obstacles: {o: [x, y, r]};
    targets: {t: [x, y, sight_range, is_loaded]} (the own record is filled in from `own`)."""
    indices = target_observation_indices_of(nc, nt, no)
    obs = np.zeros(int(indices[-1]))
    obs[:13] = _preserved(nc, nt, no, index)
    obs[13:27] = own
    for c, values in (cameras or {}).items():
        obs[indices[2] + 7 * c:indices[2] + 7 * c + 7] = [*values, 1.0]
    for o, values in (obstacles or {}).items():
        obs[indices[3] + 4 * o:indices[3] + 4 * o + 4] = [*values, 1.0]
    targets = dict(targets or {})
    targets[index] = own[:4]
    for t, values in targets.items():
        obs[indices[4] + 5 * t:indices[4] + 5 * t + 5] = [*values, 1.0]
    return obs


def bearing(dx: float, dy: float) -> float:
    return math.degrees(math.atan2(dy, dx))
