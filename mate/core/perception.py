"""Perception: camera sectors, exact occlusion by obstacle discs, the transmittance coin, view masks.

All functions act on one world row b. Angles are degrees, lengths world units.
"""

from __future__ import annotations

import math

from .jit import inline_kernel, kernel
from .rng import uniform


@inline_kernel
def sector_of(w, b, c):
    """Camera c's sector as (x, y, heading unit vector, cos of half the viewing angle, range^2)."""
    cos_half = math.cos(math.radians(0.5 * w.camera_viewing_angle[b, c]))
    return (w.camera_pos[b, c, 0], w.camera_pos[b, c, 1], w.camera_direction[b, c, 0], w.camera_direction[b, c, 1],
            cos_half, w.camera_sight_range[b, c] ** 2)


@inline_kernel
def in_sector(sector, x, y):
    """Whether point (x, y) lies in the sector (radius and angle inclusive).

    The angle test compares the projection on the heading with |d| cos(theta / 2), which is
    the same as 2 * |deviation| <= theta for viewing angles up to 180 degrees.
    """
    cx, cy, ux, uy, cos_half, range_sq = sector
    dx, dy = x - cx, y - cy
    dist_sq = dx * dx + dy * dy
    if dist_sq > range_sq:
        return False
    return dx * ux + dy * uy >= math.sqrt(dist_sq) * cos_half


@inline_kernel
def is_occluded(p, w, b, c, x, y):
    """Whether an opaque obstacle disc hides point (x, y) from camera c.

    Exact ray-versus-disc test against the obstacles flagged for this camera at reset
    (centre closer than max_sight_range + radius). The point is hidden when the first disc
    the ray enters starts before it (relative tolerance 1e-6). With transmittance 1 no
    obstacle occludes.
    """
    if p.transmittance >= 1.0:
        return False
    cx, cy = w.camera_pos[b, c, 0], w.camera_pos[b, c, 1]
    dx, dy = x - cx, y - cy
    dist = math.sqrt(dx * dx + dy * dy)
    for o in range(p.num_obstacles):
        if not w.camera_obstacle_view_mask[b, c, o]:
            continue
        if disc_hides(dx, dy, dist, w.obstacle_pos[b, o, 0] - cx, w.obstacle_pos[b, o, 1] - cy,
                      w.obstacle_radius[b, o], p.camera_max_sight_range):
            return True
    return False


@inline_kernel
def disc_hides(dx, dy, dist, ox, oy, r, max_range):
    """Whether the disc of radius r centred at (ox, oy) hides the point (dx, dy) at distance `dist` (> 0 or 0),
    all relative to the camera: the ray from the camera enters the disc before the point (relative tolerance
    1e-6; entries beyond `max_range` count at `max_range`). A camera inside the disc sees nothing beyond its own
    centre."""
    centre_sq = ox * ox + oy * oy
    if centre_sq < r * r:
        return dist > 0.0
    if dist == 0.0:
        return False
    along = (ox * dx + oy * dy) / dist
    if along < 0.0:
        return False
    h_sq = centre_sq - along * along
    if h_sq >= r * r:
        return False
    entry = along - math.sqrt(r * r - h_sq)
    return dist > min(entry, max_range) * (1.0 + 1e-6)


@inline_kernel
def is_tracked(p, w, b, t):
    """Whether any camera tracks target t in row b (current masks)."""
    for c in range(p.num_cameras):
        if w.camera_target_view_mask[b, c, t]:
            return True
    return False


@kernel
def flag_camera_obstacles(p, w, b):
    """Camera->obstacle flags, fixed per episode: centre distance < max_sight_range + radius."""
    for c in range(p.num_cameras):
        for o in range(p.num_obstacles):
            dx = w.obstacle_pos[b, o, 0] - w.camera_pos[b, c, 0]
            dy = w.obstacle_pos[b, o, 1] - w.camera_pos[b, c, 1]
            w.camera_obstacle_view_mask[b, c, o] = (
                math.sqrt(dx * dx + dy * dy) < p.camera_max_sight_range + w.obstacle_radius[b, o])


@inline_kernel
def _within(ax, ay, bx, by, reach):
    dx, dy = ax - bx, ay - by
    return dx * dx + dy * dy <= reach * reach


@inline_kernel
def perceive(p, w, b):
    """Recompute the five per-step view masks of row b (camera->obstacle stays as set at reset).

    A camera tracks a target in its sector when the target is unoccluded, or, when occluded,
    with probability `transmittance` (one coin per camera, target and step). Cameras see
    other cameras' centres in their sector unless occluded (no coin); cameras never occlude.
    """
    for c in range(p.num_cameras):
        sector = sector_of(w, b, c)
        for t in range(p.num_targets):
            tx, ty = w.target_pos[b, t, 0], w.target_pos[b, t, 1]
            seen = in_sector(sector, tx, ty)
            if seen and is_occluded(p, w, b, c, tx, ty):
                seen = p.transmittance > 0.0 and uniform(w.rng, b) < p.transmittance
            w.camera_target_view_mask[b, c, t] = seen
        for d in range(p.num_cameras):
            x, y = w.camera_pos[b, d, 0], w.camera_pos[b, d, 1]
            w.camera_camera_view_mask[b, c, d] = c == d or (
                in_sector(sector, x, y) and not is_occluded(p, w, b, c, x, y))
    for t in range(p.num_targets):
        tx, ty = w.target_pos[b, t, 0], w.target_pos[b, t, 1]
        for c in range(p.num_cameras):
            w.target_camera_view_mask[b, t, c] = _within(
                tx, ty, w.camera_pos[b, c, 0], w.camera_pos[b, c, 1], p.target_sight_range + p.camera_radius)
        for o in range(p.num_obstacles):
            w.target_obstacle_view_mask[b, t, o] = _within(
                tx, ty, w.obstacle_pos[b, o, 0], w.obstacle_pos[b, o, 1],
                p.target_sight_range + w.obstacle_radius[b, o])
        w.target_target_view_mask[b, t, t] = True
        for s in range(t):  # every target has the same sight range: the mask is symmetric
            seen = _within(tx, ty, w.target_pos[b, s, 0], w.target_pos[b, s, 1], p.target_sight_range)
            w.target_target_view_mask[b, t, s] = w.target_target_view_mask[b, s, t] = seen
