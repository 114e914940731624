"""Observation and state vectors (layouts in docs/environment/observations.md) and coverage statistics.

Functions act on one world row b and write into caller-provided output rows, so a batch can
fill one (B, N, D) buffer without allocating.
"""

from __future__ import annotations


from ..constants import NUM_WAREHOUSES, WAREHOUSE_RADIUS, WAREHOUSES
from .jit import inline_kernel, ir_inline_kernel, kernel


@ir_inline_kernel
def _preserved(p, out, index):
    """Write the 13 preserved entries: counts, own slot index, warehouse centres, half-width."""
    out[0], out[1], out[2], out[3] = p.num_cameras, p.num_targets, p.num_obstacles, index
    for h in range(NUM_WAREHOUSES):
        out[4 + 2 * h], out[5 + 2 * h] = WAREHOUSES[h, 0], WAREHOUSES[h, 1]
    out[12] = WAREHOUSE_RADIUS
    return 13


@ir_inline_kernel
def _camera_public(p, w, b, c, out, k, f=1.0):
    """Write camera c's public state [x, y, r, R cos phi, R sin phi, theta] at out[k:k+6],
    times f (1.0, or 0.0 to write zeros; see `_flagged_camera`)."""
    rs = w.camera_sight_range[b, c] * f
    out[k], out[k + 1] = w.camera_pos[b, c, 0] * f + 0.0, w.camera_pos[b, c, 1] * f + 0.0
    out[k + 2] = p.camera_radius * f
    out[k + 3], out[k + 4] = rs * w.camera_direction[b, c, 0] + 0.0, rs * w.camera_direction[b, c, 1] + 0.0
    out[k + 5] = w.camera_viewing_angle[b, c] * f
    return k + 6


@ir_inline_kernel
def _camera_private(p, w, b, c, out, k):
    """Camera public state followed by [max_sight_range, rotation_step, zooming_step]."""
    k = _camera_public(p, w, b, c, out, k)
    out[k], out[k + 1], out[k + 2] = p.camera_max_sight_range, p.camera_rotation_step, p.camera_zooming_step
    return k + 3


@ir_inline_kernel
def _target_public(p, w, b, t, out, k, f=1.0):
    """Target public state [x, y, sight_range, is_loaded] at out[k:k+4], times f."""
    out[k], out[k + 1] = w.target_pos[b, t, 0] * f + 0.0, w.target_pos[b, t, 1] * f + 0.0
    out[k + 2], out[k + 3] = p.target_sight_range * f, (w.target_goal[b, t] >= 0) * f
    return k + 4


@ir_inline_kernel
def _target_private(p, w, b, t, out, k):
    """Target public state + [step_size, capacity, goal_bits(4), empty_bits(4)]."""
    k = _target_public(p, w, b, t, out, k)
    out[k], out[k + 1] = p.target_step_size / w.target_capacity[b, t], w.target_capacity[b, t]
    for h in range(NUM_WAREHOUSES):
        out[k + 2 + h] = w.target_load[b, t] if w.target_goal[b, t] == h else 0
        out[k + 6 + h] = w.target_empty_bits[b, t, h]
    return k + 10


@ir_inline_kernel
def _obstacle(w, b, o, out, k, f=1.0):
    """Obstacle o's [x, y, radius] at out[k:k+3], times f."""
    out[k], out[k + 1] = w.obstacle_pos[b, o, 0] * f + 0.0, w.obstacle_pos[b, o, 1] * f + 0.0
    out[k + 2] = w.obstacle_radius[b, o] * f
    return k + 3


# Flagged blocks: an entity's public state followed by a 1.0 flag when it is perceived, and zeros
# in their place when it is not. The values are multiplied by the flag (`+ 0.0` turns the -0.0 of
# a negative value times 0 into 0.0) instead of branching on the view mask: the masks are hard to
# predict, and the branch-free version builds observations ~20% faster (docs/performance.md).

@ir_inline_kernel
def _flagged_camera(p, w, b, c, visible, out, k):
    f = visible * 1.0
    out[_camera_public(p, w, b, c, out, k, f)] = f
    return k + 7


@ir_inline_kernel
def _flagged_target(p, w, b, t, visible, out, k):
    f = visible * 1.0
    out[_target_public(p, w, b, t, out, k, f)] = f
    return k + 5


@ir_inline_kernel
def _flagged_obstacle(w, b, o, visible, out, k):
    f = visible * 1.0
    out[_obstacle(w, b, o, out, k, f)] = f
    return k + 4


@inline_kernel
def camera_observation(p, w, b, c, out):
    """Camera c's observation (D_c,): preserved, own private state, then flagged blocks of
    targets (tracked), obstacles (flagged at reset) and cameras (self or perceived)."""
    k = _preserved(p, out, c)
    k = _camera_private(p, w, b, c, out, k)
    for t in range(p.num_targets):
        k = _flagged_target(p, w, b, t, w.camera_target_view_mask[b, c, t], out, k)
    for o in range(p.num_obstacles):
        k = _flagged_obstacle(w, b, o, w.camera_obstacle_view_mask[b, c, o], out, k)
    for d in range(p.num_cameras):
        k = _flagged_camera(p, w, b, d, (d == c) | w.camera_camera_view_mask[b, c, d], out, k)


@inline_kernel
def target_observation(p, w, b, t, out):
    """Target t's observation (D_t,): preserved, own private state, then flagged blocks of
    cameras and obstacles within reach and targets in sight (self included)."""
    k = _preserved(p, out, t)
    k = _target_private(p, w, b, t, out, k)
    for c in range(p.num_cameras):
        k = _flagged_camera(p, w, b, c, w.target_camera_view_mask[b, t, c], out, k)
    for o in range(p.num_obstacles):
        k = _flagged_obstacle(w, b, o, w.target_obstacle_view_mask[b, t, o], out, k)
    for s in range(p.num_targets):
        k = _flagged_target(p, w, b, s, (s == t) | w.target_target_view_mask[b, t, s], out, k)


@inline_kernel
def joint_observation(p, w, b, camera_out, target_out):
    """Fill camera_out (Nc, D_c) and target_out (Nt, D_t) for row b."""
    for c in range(p.num_cameras):
        camera_observation(p, w, b, c, camera_out[c])
    for t in range(p.num_targets):
        target_observation(p, w, b, t, target_out[t])


@kernel
def global_state(p, w, b, out):
    """Global state (29 + 9 Nc + 16 Nt + 3 No,): preserved (index 0), every camera's and target's
    private state, obstacles, freights, bounties and the remaining-cargo matrix (row = source)."""
    k = _preserved(p, out, 0)
    for c in range(p.num_cameras):
        k = _camera_private(p, w, b, c, out, k)
    for t in range(p.num_targets):
        k = _target_private(p, w, b, t, out, k)
    for o in range(p.num_obstacles):
        k = _obstacle(w, b, o, out, k)
    for t in range(p.num_targets):
        out[k + t] = w.target_freight[b, t]
        out[k + p.num_targets + t] = w.target_bounty[b, t]
    k += 2 * p.num_targets
    for src in range(NUM_WAREHOUSES):
        for dst in range(NUM_WAREHOUSES):
            out[k + NUM_WAREHOUSES * src + dst] = w.remaining_cargoes[b, src, dst]


@inline_kernel
def update_coverage(p, w, b):
    """coverage_rate, real_coverage_rate (tracked among targets with bounty left),
    mean_transport_rate (sparse episode reward per delivered unit, over reward_scale) and each camera's
    difference credit, `camera_reward_parts` (the share of the targets that it alone tracks: the coverage rate
    minus what the other cameras cover without it)."""
    tracked = tracked_with_bounty = with_bounty = 0
    for c in range(p.num_cameras):
        w.camera_reward_parts[b, c] = 0.0
    for t in range(p.num_targets):
        watchers, watcher = 0, 0
        for c in range(p.num_cameras):
            if w.camera_target_view_mask[b, c, t]:
                watchers += 1
                watcher = c
        if watchers == 1:
            w.camera_reward_parts[b, watcher] += 1.0
        seen = watchers > 0
        tracked += seen
        if w.target_bounty[b, t] > 0:
            with_bounty += 1
            tracked_with_bounty += seen
    for c in range(p.num_cameras):
        w.camera_reward_parts[b, c] /= p.num_targets
    w.coverage_rate[b] = tracked / p.num_targets
    w.real_coverage_rate[b] = tracked_with_bounty / with_bounty if with_bounty > 0 else 0.0
    delivered = w.num_delivered_cargoes[b]
    w.mean_transport_rate[b] = (w.delayed_target_team_episode_reward[b] / (p.reward_scale * delivered)
                                if delivered > 0 else 0.0)
