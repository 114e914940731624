"""The dynamic world state: a NamedTuple of arrays, every one with a leading batch axis B.

Row b of every field is one environment. Kernels update rows in place. Shapes use
Nc cameras, Nt targets, No obstacles and W = 4 warehouses; angles are degrees.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..constants import NUM_WAREHOUSES
from .arrays import array_namespace
from .params import Params


class World(NamedTuple):
    """Everything that changes during an episode, batched over B environments."""

    rng: np.ndarray                    # (B, 2) uint64: stream key and draw counter (mate.core.rng)
    camera_order: np.ndarray           # (B, Nc) int64: configuration index of the camera in each slot
    target_order: np.ndarray           # (B, Nt) int64
    obstacle_order: np.ndarray         # (B, No) int64
    camera_pos: np.ndarray             # (B, Nc, 2)
    camera_orientation: np.ndarray     # (B, Nc) degrees in [-180, 180)
    camera_direction: np.ndarray       # (B, Nc, 2) unit vector (cos, sin) of the orientation (kept in sync)
    camera_viewing_angle: np.ndarray   # (B, Nc) degrees in [min_viewing_angle, 180]
    camera_sight_range: np.ndarray     # (B, Nc) sqrt(min_viewing_angle * max_sight_range^2 / viewing_angle)
    obstacle_pos: np.ndarray           # (B, No, 2)
    obstacle_radius: np.ndarray        # (B, No)
    target_pos: np.ndarray             # (B, Nt, 2)
    target_capacity: np.ndarray        # (B, Nt) int64: 1 or 2 cargo units
    target_goal: np.ndarray            # (B, Nt) int64: destination warehouse of the cargo, -1 if none
    target_load: np.ndarray            # (B, Nt) int64: units carried (the non-zero goal bit)
    target_empty_bits: np.ndarray      # (B, Nt, W) bool: remembers "warehouse w has nothing left to send"
    target_freight: np.ndarray         # (B, Nt) int64
    target_bounty: np.ndarray          # (B, Nt) int64: remaining bounty, decays 1 per tracked step
    target_steps: np.ndarray           # (B, Nt) int64: steps since the last warehouse visit
    target_tracked_steps: np.ndarray   # (B, Nt) int64: tracked steps in that time
    target_is_colliding: np.ndarray    # (B, Nt) bool: last move altered by a disc or the border
    target_facing: np.ndarray          # (B, Nt, 2) direction the target faces (last move), for rendering
    target_done: np.ndarray            # (B, Nt) bool: delivered cargo this step
    target_reward_parts: np.ndarray    # (B, Nt) each target's part of this step's target team reward
    camera_reward_parts: np.ndarray    # (B, Nc) each camera's difference credit: the share of the Nt targets it
    #                                    alone tracks (the coverage rate minus the coverage without it)
    remaining_cargoes: np.ndarray      # (B, W, W) int64: units waiting at [src] for [dst]
    awaiting_cargo_counts: np.ndarray  # (B, W) int64: units still to be delivered to each warehouse
    num_delivered_cargoes: np.ndarray  # (B,) int64
    episode_step: np.ndarray           # (B,) int64
    camera_target_view_mask: np.ndarray    # (B, Nc, Nt) bool
    camera_obstacle_view_mask: np.ndarray  # (B, Nc, No) bool, fixed at reset
    camera_camera_view_mask: np.ndarray    # (B, Nc, Nc) bool
    target_camera_view_mask: np.ndarray    # (B, Nt, Nc) bool
    target_obstacle_view_mask: np.ndarray  # (B, Nt, No) bool
    target_target_view_mask: np.ndarray    # (B, Nt, Nt) bool
    target_team_episode_reward: np.ndarray          # (B,) sum of dense target rewards
    delayed_target_team_episode_reward: np.ndarray  # (B,) sum of sparse target rewards
    coverage_rate: np.ndarray          # (B,) share of targets tracked by any camera
    real_coverage_rate: np.ndarray     # (B,) share of bounty-carrying targets that are tracked
    coverage_rate_sum: np.ndarray      # (B,) coverage_rate summed over the episode's steps (the reset not counted)
    real_coverage_rate_sum: np.ndarray  # (B,) real_coverage_rate summed likewise
    mean_transport_rate: np.ndarray    # (B,)
    target_reward: np.ndarray          # (B,) target team reward of the last step (dense or sparse)
    terminated: np.ndarray             # (B,) bool: every cargo unit delivered
    truncated: np.ndarray              # (B,) bool: max_episode_steps reached


def empty_world(params: Params, batch_size: int) -> World:
    """A zero-filled world of `batch_size` rows (call `engine.reset` before use)."""
    B, nc, nt, no, nw = batch_size, params.num_cameras, params.num_targets, params.num_obstacles, NUM_WAREHOUSES
    f, i, z = np.float64, np.int64, bool
    shapes = {
        'rng': ((B, 2), np.uint64),
        'camera_order': ((B, nc), i), 'target_order': ((B, nt), i), 'obstacle_order': ((B, no), i),
        'camera_pos': ((B, nc, 2), f), 'camera_orientation': ((B, nc), f), 'camera_direction': ((B, nc, 2), f),
        'camera_viewing_angle': ((B, nc), f), 'camera_sight_range': ((B, nc), f),
        'obstacle_pos': ((B, no, 2), f), 'obstacle_radius': ((B, no), f),
        'target_pos': ((B, nt, 2), f), 'target_capacity': ((B, nt), i), 'target_goal': ((B, nt), i),
        'target_load': ((B, nt), i), 'target_empty_bits': ((B, nt, nw), z),
        'target_freight': ((B, nt), i), 'target_bounty': ((B, nt), i), 'target_steps': ((B, nt), i),
        'target_tracked_steps': ((B, nt), i), 'target_is_colliding': ((B, nt), z),
        'target_facing': ((B, nt, 2), f), 'target_done': ((B, nt), z), 'target_reward_parts': ((B, nt), f),
        'camera_reward_parts': ((B, nc), f),
        'remaining_cargoes': ((B, nw, nw), i), 'awaiting_cargo_counts': ((B, nw), i),
        'num_delivered_cargoes': ((B,), i), 'episode_step': ((B,), i),
        'camera_target_view_mask': ((B, nc, nt), z), 'camera_obstacle_view_mask': ((B, nc, no), z),
        'camera_camera_view_mask': ((B, nc, nc), z), 'target_camera_view_mask': ((B, nt, nc), z),
        'target_obstacle_view_mask': ((B, nt, no), z), 'target_target_view_mask': ((B, nt, nt), z),
        'target_team_episode_reward': ((B,), f), 'delayed_target_team_episode_reward': ((B,), f),
        'coverage_rate': ((B,), f), 'real_coverage_rate': ((B,), f),
        'coverage_rate_sum': ((B,), f), 'real_coverage_rate_sum': ((B,), f), 'mean_transport_rate': ((B,), f),
        'target_reward': ((B,), f), 'terminated': ((B,), z), 'truncated': ((B,), z),
    }
    assert tuple(shapes) == World._fields
    world = World(**{name: np.zeros(shape, dtype) for name, (shape, dtype) in shapes.items()})
    world.target_goal[:] = -1
    world.target_capacity[:] = 1
    return world


EPISODE_STATISTICS = ('episode_coverage_rate', 'episode_real_coverage_rate', 'episode_target_return')
"""What `episode_statistics` gives of every row's episode so far."""


def episode_statistics(params: Params, world: World, row: int | None = None) -> dict:
    """Every row's episode so far, as the core counted it, (B,) float64 arrays (numpy, or torch tensors where
    `world`'s fields are tensors: a device's world, `mate.envs.device_vector`; or, for one `row`, Python floats:
    the single env's infos at every step, without numpy's per-call cost): the coverage and real coverage rates
    averaged over its steps (the reset not counted; 0 before the first step) and the target team's raw return
    (dense or sparse, as the config pays; the cameras' is its negative). Every consumer (the envs' infos,
    evaluation, training logs, RLlib) reads these: an episode metric is computed in one place."""
    target_return = world.delayed_target_team_episode_reward if params.sparse_reward else \
        world.target_team_episode_reward
    if row is not None:            # the same IEEE divisions on Python floats
        steps = max(int(world.episode_step[row]), 1)
        return dict(episode_coverage_rate=float(world.coverage_rate_sum[row]) / steps,
                    episode_real_coverage_rate=float(world.real_coverage_rate_sum[row]) / steps,
                    episode_target_return=float(target_return[row]))
    steps = array_namespace(world.episode_step).maximum(world.episode_step, 1)   # numpy, or tensors of a device's world
    return dict(episode_coverage_rate=world.coverage_rate_sum / steps,
                episode_real_coverage_rate=world.real_coverage_rate_sum / steps,
                episode_target_return=target_return.clone() if hasattr(target_return, 'clone') else
                target_return.copy())


def obstacle_states(world: World, b: int | slice = slice(None)) -> np.ndarray:
    """Obstacle [x, y, r] per slot of row b, (No, 3), or of every row, (B, No, 3) (a fresh array; a tensor for a
    world of tensors)."""
    xp = array_namespace(world.obstacle_pos)
    return xp.concat([world.obstacle_pos[b], world.obstacle_radius[b][..., None]], axis=-1)


def target_headings(world: World, b: int) -> np.ndarray:
    """Row b's target headings in degrees, in [-180, 180]: the direction of `target_facing`
    (stored as a vector so that the step never pays for an atan2)."""
    facing = world.target_facing[b]
    return np.degrees(np.arctan2(facing[:, 1], facing[:, 0]))
