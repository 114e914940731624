"""Static parameters of one environment configuration, as numba-friendly scalars and arrays.

`Params` is built once from a validated configuration (`mate.config.read_config`) and never
changes; it is shared by every row of a batch. Lengths are world units, angles degrees.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..constants import TERRAIN_WIDTH


class Params(NamedTuple):
    """Configuration constants. Entity location boxes are in configuration order."""

    num_cameras: int
    num_targets: int
    num_obstacles: int
    camera_low: np.ndarray            # (Nc, 2) lower corner of each camera's spawn box
    camera_high: np.ndarray           # (Nc, 2) upper corner
    camera_radius: float              # body (collision barrier) radius
    camera_min_viewing_angle: float   # degrees; the sight range is max_sight_range there
    camera_max_sight_range: float
    camera_rotation_step: float       # degrees per step
    camera_zooming_step: float        # degrees per step
    target_low: np.ndarray            # (Nt, 2)
    target_high: np.ndarray           # (Nt, 2)
    target_step_size: float           # speed of a capacity-1 target (per step)
    target_sight_range: float
    obstacle_low: np.ndarray          # (No, 2)
    obstacle_high: np.ndarray         # (No, 2)
    obstacle_radius_low: float
    obstacle_radius_high: float
    transmittance: float              # env-wide obstacle transmittance in [0, 1]
    num_cargoes_per_target: int
    num_high_capacity_targets: int
    shuffle_entities: bool
    targets_start_with_cargoes: bool
    sparse_reward: bool
    freight_scale: int
    bounty_scale: int
    reward_scale: int
    max_target_team_episode_reward: float
    max_episode_steps: int


def _boxes(section: dict | None) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) arrays of shape (N, 2): fixed locations first, then random ranges."""
    if section is None:
        return np.zeros((0, 2)), np.zeros((0, 2))
    fixed = [list(map(float, xy)) for xy in section.get('location', [])]
    ranges = [list(map(float, r)) for r in section.get('location_random_range', [])]
    low = fixed + [[r[0], r[2]] for r in ranges]
    high = fixed + [[r[1], r[3]] for r in ranges]
    return np.array(low, dtype=np.float64).reshape(-1, 2), np.array(high, dtype=np.float64).reshape(-1, 2)


def params_from_config(config: dict) -> Params:
    """Build `Params` from a configuration already normalised by `read_config`."""
    camera = config.get('camera')
    target = config['target']
    obstacle = config.get('obstacle')
    camera_low, camera_high = _boxes(camera)
    target_low, target_high = _boxes(target)
    obstacle_low, obstacle_high = _boxes(obstacle)
    cam = camera or {}
    obs = obstacle or {}
    if 'radius_random_range' in obs:
        radius_low, radius_high = map(float, obs['radius_random_range'])
    else:
        radius_low = radius_high = float(obs.get('radius', 0.0))

    num_targets = len(target_low)
    step_size = float(target['step_size'])
    freight_scale = int(math.ceil(TERRAIN_WIDTH / step_size))
    bounty_scale = int(math.ceil(freight_scale * float(config['bounty_factor'])))
    reward_scale = freight_scale + bounty_scale
    return Params(
        num_cameras=len(camera_low), num_targets=num_targets, num_obstacles=len(obstacle_low),
        camera_low=camera_low, camera_high=camera_high,
        camera_radius=float(cam.get('radius', 40.0)),
        camera_min_viewing_angle=float(cam.get('min_viewing_angle', 90.0)),
        camera_max_sight_range=float(cam.get('max_sight_range', 500.0)),
        camera_rotation_step=float(cam.get('rotation_step', 5.0)),
        camera_zooming_step=float(cam.get('zooming_step', 2.5)),
        target_low=target_low, target_high=target_high,
        target_step_size=step_size, target_sight_range=float(target['sight_range']),
        obstacle_low=obstacle_low, obstacle_high=obstacle_high,
        obstacle_radius_low=radius_low, obstacle_radius_high=radius_high,
        transmittance=min(max(float(obs.get('transmittance', 0.0)), 0.0), 1.0),
        num_cargoes_per_target=int(config['num_cargoes_per_target']),
        num_high_capacity_targets=int(math.floor(num_targets * float(config['high_capacity_target_split']))),
        shuffle_entities=bool(config['shuffle_entities']),
        targets_start_with_cargoes=bool(config['targets_start_with_cargoes']),
        sparse_reward=config['reward_type'] == 'sparse',
        freight_scale=freight_scale, bounty_scale=bounty_scale, reward_scale=reward_scale,
        max_target_team_episode_reward=float(reward_scale * int(config['num_cargoes_per_target']) * num_targets),
        max_episode_steps=int(config['max_episode_steps']),
    )
