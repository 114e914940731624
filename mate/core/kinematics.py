"""Motion: cameras rotate and zoom with constant sector area; targets move, slide along discs, stay on the terrain.

All functions act on one world row b. Angles are degrees, lengths world units.
"""

from __future__ import annotations

import math


from ..constants import MAX_CAMERA_VIEWING_ANGLE, TERRAIN_SIZE
from .jit import inline_kernel


@inline_kernel
def wrap_angle(angle):
    """Wrap degrees into [-180, 180)."""
    return (angle + 180.0) % 360.0 - 180.0


@inline_kernel
def sight_range_of(viewing_angle, min_viewing_angle, max_sight_range):
    """Sight range keeping the sector area constant: sqrt(theta_min R_max^2 / theta)."""
    return math.sqrt(min_viewing_angle * max_sight_range * max_sight_range / viewing_angle)


@inline_kernel
def orient_camera(w, b, c, orientation):
    """Set camera c's orientation (degrees, wrapped into [-180, 180)) and its unit direction."""
    orientation = wrap_angle(orientation)
    w.camera_orientation[b, c] = orientation
    w.camera_direction[b, c, 0] = math.cos(math.radians(orientation))
    w.camera_direction[b, c, 1] = math.sin(math.radians(orientation))


@inline_kernel
def rotate_and_zoom_cameras(p, w, b, actions):
    """Apply camera actions (Nc, 2) = (d_orientation, d_viewing_angle) in degrees, box-clipped."""
    for c in range(p.num_cameras):
        d_phi = min(max(actions[c, 0], -p.camera_rotation_step), p.camera_rotation_step)
        d_theta = min(max(actions[c, 1], -p.camera_zooming_step), p.camera_zooming_step)
        orient_camera(w, b, c, w.camera_orientation[b, c] + d_phi)
        theta = min(max(w.camera_viewing_angle[b, c] + d_theta, p.camera_min_viewing_angle),
                    MAX_CAMERA_VIEWING_ANGLE)
        w.camera_viewing_angle[b, c] = theta
        w.camera_sight_range[b, c] = sight_range_of(theta, p.camera_min_viewing_angle, p.camera_max_sight_range)


@inline_kernel
def slide_along_disc(ox, oy, vx, vy, cx, cy, r):
    """Displacement (vx, vy) from (ox, oy) after meeting the disc (c, r): keep the tangential part.

    A target already strictly inside the disc has its move reversed (original behaviour).
    "Strictly" allows a relative 1e-9 of rounding, so that a target that stopped on the
    rim is treated as on the rim (and slides) rather than inside (and backs into the disc).
    """
    length = math.sqrt(vx * vx + vy * vy)
    dx, dy = cx - ox, cy - oy
    dist = math.sqrt(dx * dx + dy * dy)
    if length == 0.0 or dist < r * (1.0 - 1e-9):
        return -vx, -vy
    if dist >= length + r:
        return vx, vy
    dot = dx * vx + dy * vy
    if dot < 0.0:
        return vx, vy
    cos = min(1.0, dot / (dist * length))
    h = dist * math.sqrt(max(0.0, 1.0 - cos * cos))
    if r <= h:
        return vx, vy
    half_chord = math.sqrt(r * r - h * h)
    entry = max(0.0, dist * cos - half_chord)
    if entry >= length:
        return vx, vy
    qx, qy = ox + entry * vx / length, oy + entry * vy / length
    push = (length - entry) * half_chord / (r * r)
    return vx + (qx - cx) * push, vy + (qy - cy) * push


@inline_kernel
def _slide_if_reachable(ox, oy, vx, vy, reach, cx, cy, r):
    """`slide_along_disc`, skipped (same result) for discs farther than reach + r."""
    dx, dy = cx - ox, cy - oy
    if dx * dx + dy * dy >= (reach + r) * (reach + r) and reach > 0.0:
        return vx, vy
    return slide_along_disc(ox, oy, vx, vy, cx, cy, r)


@inline_kernel
def move_targets(p, w, b, actions):
    """Apply target actions (Nt, 2): norm clip to the target's speed, disc slides, terrain clamp."""
    for t in range(p.num_targets):
        ox, oy = w.target_pos[b, t, 0], w.target_pos[b, t, 1]
        vx, vy = actions[t, 0], actions[t, 1]
        speed = p.target_step_size / w.target_capacity[b, t]
        norm = math.sqrt(vx * vx + vy * vy)
        if norm > speed:
            vx, vy = vx * (speed / norm), vy * (speed / norm)
        wanted_x, wanted_y = ox + vx, oy + vy
        reach = min(norm, speed)  # slides never lengthen the move: farther discs cannot be touched
        for o in range(p.num_obstacles):
            vx, vy = _slide_if_reachable(ox, oy, vx, vy, reach, w.obstacle_pos[b, o, 0], w.obstacle_pos[b, o, 1],
                                         w.obstacle_radius[b, o])
        for c in range(p.num_cameras):
            vx, vy = _slide_if_reachable(ox, oy, vx, vy, reach, w.camera_pos[b, c, 0], w.camera_pos[b, c, 1],
                                         p.camera_radius)
        nx = min(max(ox + vx, -TERRAIN_SIZE), TERRAIN_SIZE)
        ny = min(max(oy + vy, -TERRAIN_SIZE), TERRAIN_SIZE)
        w.target_pos[b, t, 0], w.target_pos[b, t, 1] = nx, ny
        w.target_is_colliding[b, t] = abs(nx - wanted_x) > 1e-6 or abs(ny - wanted_y) > 1e-6
        if nx != ox or ny != oy:
            w.target_facing[b, t, 0], w.target_facing[b, t, 1] = nx - ox, ny - oy
