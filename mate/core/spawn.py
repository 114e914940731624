"""Reset of one world row: slot shuffles, capacities, placement with spacing rules, cargo.

Placement order is cameras, obstacles, targets (slot order). An entity is re-sampled up to
500 times until it keeps clear of every disc placed before it (the four virtual warehouse
discs of radius 56.25 included). Angles are degrees.
"""

from __future__ import annotations

import math

from ..constants import (
    MAX_CAMERA_VIEWING_ANGLE,
    NUM_WAREHOUSES,
    SPAWN_CLAMP_FACTOR,
    SPAWN_TRIES,
    TERRAIN_SIZE,
    WAREHOUSE_SPAWN_RADIUS,
    WAREHOUSES,
)
from .cargo import generate_cargoes, load_all_targets, transport_cargoes
from .jit import inline_kernel, kernel
from .kinematics import orient_camera, sight_range_of
from .perception import flag_camera_obstacles, perceive
from .rng import randint, uniform


@kernel
def _identity(slots):
    """slots (N,) int64 = 0, 1, ..., N - 1."""
    for i in range(slots.shape[0]):
        slots[i] = i


@kernel
def _shuffle(rng, b, slots):
    """Uniform in-place permutation (Fisher-Yates) of slots (N,) int64."""
    _identity(slots)
    for i in range(slots.shape[0] - 1, 0, -1):
        j = randint(rng, b, i + 1)
        slots[i], slots[j] = slots[j], slots[i]


@inline_kernel
def _sample(rng, b, low, high):
    """Uniform draw in [low, high)."""
    return low + (high - low) * uniform(rng, b)


@inline_kernel
def _overlaps(x, y, r, margin, cx, cy, cr):
    """Spawn overlap of a disc (x, y, r) with a placed disc (cx, cy, cr) given a margin."""
    return math.sqrt((x - cx) ** 2 + (y - cy) ** 2) * (1.0 + 1e-6) < r + cr + margin


@kernel
def _clear_of_placed(p, w, b, x, y, r, margin, num_cameras, num_obstacles):
    """Whether (x, y, r) keeps clear of the warehouse discs, the first num_cameras cameras and
    the first num_obstacles obstacles of row b."""
    for h in range(NUM_WAREHOUSES):
        if _overlaps(x, y, r, margin, WAREHOUSES[h, 0], WAREHOUSES[h, 1], WAREHOUSE_SPAWN_RADIUS):
            return False
    for c in range(num_cameras):
        if _overlaps(x, y, r, margin, w.camera_pos[b, c, 0], w.camera_pos[b, c, 1], p.camera_radius):
            return False
    for o in range(num_obstacles):
        if _overlaps(x, y, r, margin, w.obstacle_pos[b, o, 0], w.obstacle_pos[b, o, 1], w.obstacle_radius[b, o]):
            return False
    return True


@inline_kernel
def _clamp(value, bound):
    return min(max(value, -bound), bound)


@kernel
def place_cameras(p, w, b):
    """Cameras: location in the box of their configuration entry (kept 1.2 r from the border),
    orientation a random multiple of rotation_step, viewing angle uniform in [min, 180)."""
    bound = TERRAIN_SIZE - SPAWN_CLAMP_FACTOR * p.camera_radius
    num_orientations = max(int(360.0 / p.camera_rotation_step), 1)
    for c in range(p.num_cameras):
        j = w.camera_order[b, c]
        for _ in range(SPAWN_TRIES):
            x = _clamp(_sample(w.rng, b, p.camera_low[j, 0], p.camera_high[j, 0]), bound)
            y = _clamp(_sample(w.rng, b, p.camera_low[j, 1], p.camera_high[j, 1]), bound)
            orient_camera(w, b, c, p.camera_rotation_step * randint(w.rng, b, num_orientations))
            theta = _sample(w.rng, b, p.camera_min_viewing_angle, MAX_CAMERA_VIEWING_ANGLE)
            w.camera_viewing_angle[b, c] = theta
            w.camera_sight_range[b, c] = sight_range_of(theta, p.camera_min_viewing_angle, p.camera_max_sight_range)
            w.camera_pos[b, c, 0], w.camera_pos[b, c, 1] = x, y
            ok = _clear_of_placed(p, w, b, x, y, p.camera_radius, p.target_step_size, c, 0)
            for d in range(c):  # cameras also keep a tenth of the smaller sight range apart
                gap = math.sqrt((x - w.camera_pos[b, d, 0]) ** 2 + (y - w.camera_pos[b, d, 1]) ** 2)
                ok &= gap >= 0.1 * min(w.camera_sight_range[b, c], w.camera_sight_range[b, d])
            if ok:
                break


@kernel
def place_obstacles(p, w, b):
    """Obstacles: radius uniform in its range, location in its box (kept 1.2 r from the border);
    an obstacle that never fits gets radius 0."""
    for o in range(p.num_obstacles):
        j = w.obstacle_order[b, o]
        fitted = False
        for _ in range(SPAWN_TRIES):
            r = _sample(w.rng, b, p.obstacle_radius_low, p.obstacle_radius_high)
            bound = TERRAIN_SIZE - SPAWN_CLAMP_FACTOR * r
            x = _clamp(_sample(w.rng, b, p.obstacle_low[j, 0], p.obstacle_high[j, 0]), bound)
            y = _clamp(_sample(w.rng, b, p.obstacle_low[j, 1], p.obstacle_high[j, 1]), bound)
            w.obstacle_pos[b, o, 0], w.obstacle_pos[b, o, 1], w.obstacle_radius[b, o] = x, y, r
            if _clear_of_placed(p, w, b, x, y, r, p.target_step_size, p.num_cameras, o):
                fitted = True
                break
        if not fitted:
            w.obstacle_radius[b, o] = 0.0


@kernel
def place_targets(p, w, b):
    """Targets (points): location in their box, clear of warehouses, cameras and obstacles."""
    for t in range(p.num_targets):
        j = w.target_order[b, t]
        for _ in range(SPAWN_TRIES):
            x = _clamp(_sample(w.rng, b, p.target_low[j, 0], p.target_high[j, 0]), TERRAIN_SIZE)
            y = _clamp(_sample(w.rng, b, p.target_low[j, 1], p.target_high[j, 1]), TERRAIN_SIZE)
            w.target_pos[b, t, 0], w.target_pos[b, t, 1] = x, y
            if _clear_of_placed(p, w, b, x, y, 0.0, 0.0, p.num_cameras, p.num_obstacles):
                break


@kernel
def assign_slots(p, w, b):
    """Slot orders (shuffled if configured) and target capacities (k high-capacity slots)."""
    if p.shuffle_entities:
        _shuffle(w.rng, b, w.camera_order[b])
        _shuffle(w.rng, b, w.target_order[b])
        _shuffle(w.rng, b, w.obstacle_order[b])
    else:
        _identity(w.camera_order[b])
        _identity(w.target_order[b])
        _identity(w.obstacle_order[b])
    w.target_capacity[b] = 1
    k = p.num_high_capacity_targets
    if k > 0:
        slots = w.target_goal[b]  # scratch (Nt,) int64, set back to -1 below: kernels allocate nothing
        if p.shuffle_entities:
            _shuffle(w.rng, b, slots)
        else:
            _identity(slots)
        for i in range(k):
            w.target_capacity[b, slots[i]] = 2
        w.target_goal[b] = -1


@kernel
def clear_bookkeeping(p, w, b):
    """Zero every per-episode counter, reward accumulator and per-target cargo record of row b."""
    w.target_goal[b] = -1
    w.target_load[b] = 0
    w.target_empty_bits[b] = False
    w.target_freight[b] = 0
    w.target_bounty[b] = 0
    w.target_steps[b] = 0
    w.target_tracked_steps[b] = 0
    w.target_is_colliding[b] = False
    w.target_done[b] = False
    w.target_reward_parts[b] = 0.0
    w.num_delivered_cargoes[b] = 0
    w.episode_step[b] = 0
    w.target_team_episode_reward[b] = 0.0
    w.delayed_target_team_episode_reward[b] = 0.0
    w.coverage_rate_sum[b] = 0.0
    w.real_coverage_rate_sum[b] = 0.0
    w.target_reward[b] = 0.0
    w.terminated[b] = False
    w.truncated[b] = False


@kernel
def reset_row(p, w, b):
    """A new episode in row b, drawing from its random stream."""
    assign_slots(p, w, b)
    place_cameras(p, w, b)
    place_obstacles(p, w, b)
    place_targets(p, w, b)
    flag_camera_obstacles(p, w, b)
    perceive(p, w, b)
    generate_cargoes(p, w, b)
    clear_bookkeeping(p, w, b)
    transport_cargoes(p, w, b)  # bounties are all zero: only targets spawned in a warehouse load here
    w.target_done[b] = False
    w.target_reward_parts[b] = 0.0
    if p.targets_start_with_cargoes:
        load_all_targets(p, w, b)
    for t in range(p.num_targets):
        g = w.target_goal[b, t]
        if g >= 0:
            dx, dy = WAREHOUSES[g, 0] - w.target_pos[b, t, 0], WAREHOUSES[g, 1] - w.target_pos[b, t, 1]
        else:
            heading = math.radians(_sample(w.rng, b, -180.0, 180.0))
            dx, dy = math.cos(heading), math.sin(heading)
        w.target_facing[b, t, 0], w.target_facing[b, t, 1] = dx, dy
