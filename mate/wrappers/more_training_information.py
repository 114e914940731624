"""MoreTrainingInformation: add privileged per-agent and global facts to the info dicts (for training only).

Observations and rewards are unchanged. Array helpers (`warehouse_distances`, `goal_distances`) take
any leading batch axes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mate.constants import (
    CAMERA_STATE_DIM_PRIVATE,
    PRESERVED_DIM,
    TARGET_STATE_DIM_PRIVATE,
    TERRAIN_SIZE,
    WAREHOUSE_RADIUS,
)

from .base import MateWrapper, assert_base_environment, forbid_twice

__all__ = ['MoreTrainingInformation', 'goal_distances', 'warehouse_distances']

_CAMERA_PRIVATE = slice(PRESERVED_DIM, PRESERVED_DIM + CAMERA_STATE_DIM_PRIVATE)
_TARGET_PRIVATE = slice(PRESERVED_DIM, PRESERVED_DIM + TARGET_STATE_DIM_PRIVATE)
_MASKS = ('camera_target_view_mask', 'camera_obstacle_view_mask', 'target_camera_view_mask',
          'target_obstacle_view_mask', 'target_target_view_mask')


def warehouse_distances(centre_distances: np.ndarray) -> np.ndarray:
    """(..., Nt, 4) distances to the warehouse squares' inscribed discs: max(centre distance - 75, 0)."""
    return np.maximum(np.asarray(centre_distances, dtype=np.float64) - WAREHOUSE_RADIUS, 0.0)


def goal_distances(distances: np.ndarray, goals: np.ndarray, unloaded: float = TERRAIN_SIZE) -> np.ndarray:
    """(..., Nt): `distances[..., t, goals[t]]` for loaded targets (goal >= 0), `unloaded` (1000) otherwise."""
    goals = np.asarray(goals)
    picked = np.take_along_axis(distances, np.maximum(goals, 0)[..., None], axis=-1)[..., 0]
    return np.where(goals >= 0, picked, unloaded)


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.array(array)
    array.flags.writeable = False
    return array


class MoreTrainingInformation(MateWrapper):
    """Add training facts to every info dict after `reset` and `step`.

    Camera c: `num_tracked` (targets c sees), `is_sensed` (some target sees c).
    Target t: `goal` (-1 unloaded), `warehouse_distances` (4,), `goal_distance` (1000 when unloaded),
    `individual_done` (delivered this step), `is_tracked`, `is_colliding`.
    Everybody: `state`, `camera_states` (Nc, 9), `target_states` (Nt, 14), `obstacle_states` (No, 3), the five
    masks `camera_target_view_mask`, `camera_obstacle_view_mask`, `target_camera_view_mask`,
    `target_obstacle_view_mask`, `target_target_view_mask`, `remaining_cargoes` (4, 4),
    `remaining_cargo_counts` (cargo waiting at each warehouse) and `awaiting_cargo_counts` (cargo still due
    to each warehouse). The shared arrays are one read-only array per step, referenced by every dict.

    Order: before (inside) any single-team wrapper; once only.
    """

    def __init__(self, env) -> None:
        assert_base_environment(env, type(self).__name__)
        forbid_twice(env, MoreTrainingInformation)
        super().__init__(env)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[Any, Any]:
        observation, infos = self.env.reset(seed=seed, options=options)
        return observation, self.add_information(observation, infos)

    def step(self, action):
        observation, reward, terminated, truncated, infos = self.env.step(action)
        return observation, reward, terminated, truncated, self.add_information(observation, infos)

    def add_information(self, observation: tuple[np.ndarray, np.ndarray],
                        infos: tuple[list, list]) -> tuple[list, list]:
        """Update the info dicts in place with the facts of the current world; returns them."""
        base = self.env.unwrapped
        camera_obs, target_obs = observation
        camera_infos, target_infos = infos
        remaining = base.remaining_cargoes
        shared = {
            'state': _frozen(base.state()),
            'camera_states': _frozen(camera_obs[..., _CAMERA_PRIVATE]),
            'target_states': _frozen(target_obs[..., _TARGET_PRIVATE]),
            'obstacle_states': _frozen(base.obstacle_states),
            **{name: _frozen(getattr(base, name)) for name in _MASKS},
            'remaining_cargoes': _frozen(remaining),
            'remaining_cargo_counts': _frozen(remaining.sum(axis=-1)),
            'awaiting_cargo_counts': _frozen(base.awaiting_cargo_counts),
        }
        num_tracked = shared['camera_target_view_mask'].sum(axis=-1).tolist()
        is_sensed = shared['target_camera_view_mask'].any(axis=-2).tolist()
        for c, info in enumerate(camera_infos):
            info.update(num_tracked=num_tracked[c], is_sensed=is_sensed[c], **shared)

        goals = base.target_goals
        distances = warehouse_distances(base.target_warehouse_distances)
        goal_distance = goal_distances(distances, goals).tolist()
        dones = base.target_dones.tolist()
        tracked = base.tracked_bits.tolist()
        colliding = base.target_is_colliding.tolist()
        for t, info in enumerate(target_infos):
            info.update(goal=int(goals[t]), warehouse_distances=distances[t], goal_distance=goal_distance[t],
                        individual_done=dones[t], is_tracked=tracked[t], is_colliding=colliding[t], **shared)
        return infos
