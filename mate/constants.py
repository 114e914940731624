"""Fixed numbers of the MATE world: terrain, warehouses and vector dimensions.

Lengths are in world units, angles in degrees. These values are part of the game's
definition (docs/environment/entities.md) and never change with the configuration.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    'TERRAIN_SIZE', 'TERRAIN_WIDTH', 'WAREHOUSE_RADIUS', 'WAREHOUSES', 'NUM_WAREHOUSES',
    'MAX_CAMERA_VIEWING_ANGLE', 'TARGET_RADIUS', 'PRESERVED_DIM', 'OBSERVATION_OFFSET',
    'CAMERA_STATE_DIM_PUBLIC', 'CAMERA_STATE_DIM_PRIVATE', 'TARGET_STATE_DIM_PUBLIC',
    'TARGET_STATE_DIM_PRIVATE', 'OBSTACLE_STATE_DIM', 'CAMERA_ACTION_DIM', 'TARGET_ACTION_DIM',
    'CAMERA_DEFAULT_ACTION', 'TARGET_DEFAULT_ACTION', 'SPAWN_TRIES', 'WAREHOUSE_SPAWN_RADIUS',
    'SPAWN_CLAMP_FACTOR', 'camera_observation_dim', 'target_observation_dim', 'state_dim',
]

TERRAIN_SIZE = 1000.0
"""Half the side of the square terrain [-1000, 1000]^2."""
TERRAIN_WIDTH = 2.0 * TERRAIN_SIZE
"""Side of the terrain (2000); coordinates in observations are bounded by +-TERRAIN_WIDTH."""

NUM_WAREHOUSES = 4
"""Warehouses, one in each corner of the terrain."""
WAREHOUSE_RADIUS = 0.075 * TERRAIN_SIZE
"""Half-width of each (square) warehouse: 75."""
WAREHOUSES = (TERRAIN_SIZE - WAREHOUSE_RADIUS) * np.array(
    [[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]]
)
"""Warehouse centres (4, 2) in the order NE, NW, SW, SE."""
WAREHOUSES.setflags(write=False)

MAX_CAMERA_VIEWING_ANGLE = 180.0
"""Widest field of view of a camera (degrees)."""
TARGET_RADIUS = 0.0
"""Targets are points: they never collide with each other."""

PRESERVED_DIM = 3 + 1 + 2 * NUM_WAREHOUSES + 1
"""Entries at the start of every observation: counts, own index, warehouses, half-width (13)."""
OBSERVATION_OFFSET = PRESERVED_DIM
"""Index where an agent's own state starts in its observation (same as PRESERVED_DIM)."""

CAMERA_STATE_DIM_PUBLIC = 6
"""Entries of a camera's public state: x, y, radius, R_s cos(phi), R_s sin(phi), viewing angle."""
CAMERA_STATE_DIM_PRIVATE = 9
"""Entries of a camera's private state: the public state + max sight range, rotation and zooming steps."""
TARGET_STATE_DIM_PUBLIC = 4
"""Entries of a target's public state: x, y, sight range, is loaded."""
TARGET_STATE_DIM_PRIVATE = 6 + 2 * NUM_WAREHOUSES
"""Entries of a target's private state: the public state + step size, capacity, 4 goal bits, 4 empty bits."""
OBSTACLE_STATE_DIM = 3
"""Entries of an obstacle's state: x, y, radius."""

CAMERA_ACTION_DIM = 2
"""A camera acts with (rotation, zoom), in degrees."""
TARGET_ACTION_DIM = 2
"""A target acts with a displacement (dx, dy)."""
CAMERA_DEFAULT_ACTION = np.zeros(CAMERA_ACTION_DIM)
"""The no-op camera action (read-only zeros)."""
TARGET_DEFAULT_ACTION = np.zeros(TARGET_ACTION_DIM)
"""The no-op target action (read-only zeros)."""
CAMERA_DEFAULT_ACTION.setflags(write=False)
TARGET_DEFAULT_ACTION.setflags(write=False)

SPAWN_TRIES = 500
"""Placement attempts per entity at reset."""
WAREHOUSE_SPAWN_RADIUS = 0.75 * WAREHOUSE_RADIUS
"""Radius of the virtual disc each warehouse occupies during placement (56.25)."""
SPAWN_CLAMP_FACTOR = 1.2
"""Spawned cameras/obstacles keep 1.2 x radius away from the terrain border."""


def camera_observation_dim(num_cameras: int, num_targets: int, num_obstacles: int) -> int:
    """Length of one camera's observation vector: 22 + 5 Nt + 4 No + 7 Nc."""
    return (PRESERVED_DIM + CAMERA_STATE_DIM_PRIVATE + (TARGET_STATE_DIM_PUBLIC + 1) * num_targets
            + (OBSTACLE_STATE_DIM + 1) * num_obstacles + (CAMERA_STATE_DIM_PUBLIC + 1) * num_cameras)


def target_observation_dim(num_cameras: int, num_targets: int, num_obstacles: int) -> int:
    """Length of one target's observation vector: 27 + 7 Nc + 4 No + 5 Nt."""
    return (PRESERVED_DIM + TARGET_STATE_DIM_PRIVATE + (CAMERA_STATE_DIM_PUBLIC + 1) * num_cameras
            + (OBSTACLE_STATE_DIM + 1) * num_obstacles + (TARGET_STATE_DIM_PUBLIC + 1) * num_targets)


def state_dim(num_cameras: int, num_targets: int, num_obstacles: int) -> int:
    """Length of the global state vector: 29 + 9 Nc + 16 Nt + 3 No."""
    return (PRESERVED_DIM + CAMERA_STATE_DIM_PRIVATE * num_cameras + TARGET_STATE_DIM_PRIVATE * num_targets
            + OBSTACLE_STATE_DIM * num_obstacles + 2 * num_targets + NUM_WAREHOUSES * NUM_WAREHOUSES)
