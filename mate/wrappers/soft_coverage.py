"""Soft coverage score: how deep inside (or how far outside) a camera's field of view each target is.

Used by AuxiliaryCameraRewards and AuxiliaryTargetRewards (component `soft_coverage_score`).

For camera c and target t, `S[c, t] = +-d / dist_max`, where
* `dist_max` is the inradius of c's current sector: `R / (1 + 1 / sin(theta / 2))` for theta < 180 degrees,
  `R / 2` at 180 (R = current sight range, theta = viewing angle, degrees);
* d is the distance from the target to the nearest point of a polyline that outlines the sector: 16
  points along the left edge ray from the camera, the left end point, the samples of the camera's
  obstacle-aware *outer* boundary strictly inside the sector, the right end point, 16 points along the
  right edge ray;
* the sign is + when c sees t, - otherwise.

Boundaries (angles in degrees, lengths in world units). The *inner* profile `rho(a)` is the distance to
the first opaque disc along the ray at angle a (0 when the camera stands inside a disc), capped at R_max;
the *outer* profile uses the far side of the disc instead, so the obstacle bodies count as inside and
only their shadows are cut away. The original samples the outer boundary at R_max, not at the current
sight range (kept: the arc of the polyline lies at R_max), at every integer degree, densely across each
disc, and along the two shadow edges of each disc; the end points use the inner profile. Here both
profiles are evaluated exactly (ray versus disc) at the same kinds of sample angles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .base import private_states

__all__ = [
    'CameraBoundary',
    'SoftCoverage',
    'camera_boundary',
    'sector_inradius',
    'sight_profile',
    'soft_coverage_matrix',
    'soft_coverage_score',
]

_EDGE_OFFSET = 0.01       # degrees between a shadow edge and the far end of its radial sample line
_EDGE_POINTS = 21         # samples along each shadow edge
_RAY_POINTS = 16          # samples along each edge ray of the sector
_ARC_ANGLES = np.arange(-180.0, 180.0, 1.0)


def _wrap(angle):
    return (np.asarray(angle, dtype=np.float64) + 180.0) % 360.0 - 180.0


def sight_profile(center: np.ndarray, angles: np.ndarray, max_sight_range: float, discs: np.ndarray,
                  outer: bool = False) -> np.ndarray:
    """(A,) distance along each ray (angles (A,) in degrees) to the near (or, `outer`, far) side of the first
    disc it crosses, capped at `max_sight_range`; zeros when `center` lies strictly inside a disc.

    `discs` (K, 3) `[x, y, r]` are the occluding obstacles.
    """
    angles = np.asarray(angles, dtype=np.float64)
    rho = np.full(angles.shape, float(max_sight_range))
    if len(discs) == 0:
        return rho
    rel = discs[:, :2] - center
    dist_sq = np.square(rel).sum(axis=1)
    radius_sq = np.square(discs[:, 2])
    if (dist_sq < radius_sq).any():
        return np.zeros(angles.shape)
    radians = np.radians(angles)
    along = np.cos(radians)[:, None] * rel[:, 0] + np.sin(radians)[:, None] * rel[:, 1]   # (A, K)
    off_sq = dist_sq - np.square(along)
    hit = (along >= 0.0) & (off_sq < radius_sq)
    half_chord = np.sqrt(np.maximum(radius_sq - off_sq, 0.0))
    reach = along + half_chord if outer else np.maximum(along - half_chord, 0.0)
    return np.minimum(rho, np.where(hit, reach, np.inf).min(axis=1))


@dataclass(frozen=True)
class CameraBoundary:
    """The obstacle-aware boundary of one camera at full range (fixed for an episode).

    phis, rhos: sorted outer-boundary samples, angles in [-180, 180) (one sample per angle, the shortest).
    """

    center: np.ndarray
    max_sight_range: float
    discs: np.ndarray
    phis: np.ndarray
    rhos: np.ndarray

    def sight_range_at(self, angles, outer: bool = False) -> np.ndarray:
        """Inner (or outer) profile at `angles` (degrees)."""
        return sight_profile(self.center, _wrap(angles), self.max_sight_range, self.discs, outer=outer)

    def boundary_between(self, angle_left: float, angle_right: float) -> tuple[np.ndarray, np.ndarray]:
        """(phis, rhos): the left end (inner profile), the outer samples strictly between the two angles in
        increasing angle (wrapping through +-180), the right end (inner profile). `angle_left` is wrapped to
        [-180, 180) and `angle_right` keeps its distance from it."""
        span = angle_right - angle_left
        if not 0.0 < span <= 360.0:
            raise ValueError(f'need 0 < angle_right - angle_left <= 360, got {angle_left} and {angle_right}')
        left = float(_wrap(angle_left))
        right = left + span
        shifted = left + (self.phis - left) % 360.0
        inside = (shifted > left) & (shifted < right)
        order = np.argsort(shifted[inside], kind='stable')
        ends = self.sight_range_at(np.array([left, right]))
        phis = np.concatenate([[left], shifted[inside][order], [right]])
        rhos = np.concatenate([[ends[0]], self.rhos[inside][order], [ends[1]]])
        return phis, rhos


def camera_boundary(center, max_sight_range: float, discs) -> CameraBoundary:
    """Sample the outer boundary of a camera at `center` with range `max_sight_range` among opaque `discs` (K, 3)."""
    center = np.asarray(center, dtype=np.float64)
    discs = np.asarray(discs, dtype=np.float64).reshape(-1, 3)
    R = float(max_sight_range)
    if len(discs) and (np.square(discs[:, :2] - center).sum(axis=1) < np.square(discs[:, 2])).any():
        phis = np.array([-180.0, -90.0, 0.0, 90.0])
        return CameraBoundary(center, R, discs, phis, np.zeros(4))

    def profile(angles):
        return sight_profile(center, angles, R, discs, outer=True)

    phis, rhos = [_ARC_ANGLES], [profile(_ARC_ANGLES)]
    for x, y, r in discs:
        dx, dy = x - center[0], y - center[1]
        dist = math.hypot(dx, dy)
        half = math.degrees(math.asin(min(r / dist, 1.0)))
        bearing = math.degrees(math.atan2(dy, dx))
        left, right = bearing - half, bearing + half
        fan = np.linspace(left, right, max(16, int(2 * half)) + 1)
        phis.append(fan)
        rhos.append(np.minimum(min(R, dist + r), profile(fan)))
        near = min(R, math.hypot(dist, r))
        for edge, outward in ((left, left - _EDGE_OFFSET), (right, right + _EDGE_OFFSET)):
            t = np.linspace(0.0, 1.0, _EDGE_POINTS)[:, None]
            start = near * np.array([math.cos(math.radians(edge)), math.sin(math.radians(edge))])
            end = R * np.array([math.cos(math.radians(outward)), math.sin(math.radians(outward))])
            points = (1.0 - t) * start + t * end
            angles = np.degrees(np.arctan2(points[:, 1], points[:, 0]))
            phis.append(angles)
            rhos.append(np.minimum(np.hypot(points[:, 0], points[:, 1]), profile(angles)))
    phis, rhos = _wrap(np.concatenate(phis)), np.concatenate(rhos)
    order = np.lexsort((rhos, phis))                     # by angle, then shortest first
    phis, rhos = phis[order], rhos[order]
    first = np.ones(len(phis), dtype=bool)
    first[1:] = phis[1:] != phis[:-1]
    return CameraBoundary(center, R, discs, phis[first], rhos[first])


def sector_inradius(sight_range, viewing_angle):
    """Radius of the largest disc inside a sector (degrees): R / (1 + 1 / sin(theta / 2)), or R / 2 at 180."""
    sight_range = np.asarray(sight_range, dtype=np.float64)
    viewing_angle = np.asarray(viewing_angle, dtype=np.float64)
    sine = np.sin(np.radians(viewing_angle / 2.0))
    return np.where(viewing_angle < 180.0, sight_range / (1.0 + 1.0 / sine), sight_range / 2.0)


def soft_coverage_score(boundary: CameraBoundary, orientation: float, viewing_angle: float, sight_range: float,
                        relative_positions: np.ndarray, tracked: np.ndarray) -> np.ndarray:
    """(Nt,) soft coverage scores of one camera for targets at `relative_positions` (Nt, 2) (target - camera)."""
    phis, rhos = boundary.boundary_between(orientation - viewing_angle / 2.0, orientation + viewing_angle / 2.0)
    ray = np.linspace(0.0, 1.0, _RAY_POINTS, endpoint=False)
    phis = np.concatenate([np.full(_RAY_POINTS, phis[0]), phis, np.full(_RAY_POINTS, phis[-1])])
    rhos = np.concatenate([ray * rhos[0], rhos, ray * rhos[-1]])
    radians = np.radians(phis)
    points = np.stack([rhos * np.cos(radians), rhos * np.sin(radians)], axis=1)         # (P, 2)
    relative_positions = np.asarray(relative_positions, dtype=np.float64)
    dx = relative_positions[:, 0, None] - points[None, :, 0]                           # (Nt, P)
    dy = relative_positions[:, 1, None] - points[None, :, 1]
    nearest = np.sqrt((dx * dx + dy * dy).min(axis=1))
    signed = np.where(np.asarray(tracked, dtype=bool), nearest, -nearest)
    return signed / sector_inradius(sight_range, viewing_angle)


def soft_coverage_matrix(centers: np.ndarray, orientations: np.ndarray, viewing_angles: np.ndarray,
                         sight_ranges: np.ndarray, max_sight_ranges: np.ndarray, sample_phis: np.ndarray,
                         sample_valid: np.ndarray, sample_points: np.ndarray, discs: np.ndarray, disc_mask: np.ndarray,
                         targets: np.ndarray, view_mask: np.ndarray) -> np.ndarray:
    """(Nc, Nt) soft coverage scores of all cameras at once (the same numbers as `soft_coverage_score`).

    centers (Nc, 2); orientations, viewing_angles, sight_ranges, max_sight_ranges (Nc,) (degrees, world
    units); sample_phis (Nc, S) outer-boundary sample angles in [-180, 180), padded, with sample_valid (Nc, S)
    marking the real ones; sample_points (Nc, S, 2) the same samples relative to the camera; discs (No, 3) with
    disc_mask (Nc, No) the opaque discs each camera considers; targets (Nt, 2) positions; view_mask (Nc, Nt).
    """
    left = _wrap(orientations - viewing_angles / 2.0)                                   # (Nc,)
    offset = sample_phis - left[:, None]                  # in (-360, 360): both angles lie in [-180, 180)
    offset = np.where(offset < 0.0, offset + 360.0, offset)
    inside = (offset > 0.0) & (offset < viewing_angles[:, None]) & sample_valid
    ends = np.stack([left, left + viewing_angles], axis=1)                             # (Nc, 2)
    end_rhos = _inner_profiles(centers, ends, max_sight_ranges, discs, disc_mask)       # (Nc, 2)
    ray = np.arange(_RAY_POINTS + 1) / _RAY_POINTS       # 16 points from the camera plus the end point
    radians = np.radians(ends)
    ray_rhos = end_rhos[:, :, None] * ray                                               # (Nc, 2, 17)
    ray_points = np.stack([ray_rhos * np.cos(radians)[:, :, None], ray_rhos * np.sin(radians)[:, :, None]], axis=-1)
    ray_points = ray_points.reshape(len(centers), -1, 2)                                 # (Nc, 34, 2)
    # every camera's polyline as one flat list of points (its samples inside the sector, then its 34 ray and
    # end points), sorted by camera so that a segmented minimum gives each camera's nearest point
    count = len(centers)
    cams, samples = np.nonzero(inside)
    owners = np.concatenate([cams, np.repeat(np.arange(count), ray_points.shape[1])])
    points = np.concatenate([sample_points[cams, samples], ray_points.reshape(-1, 2)]) + centers[owners]
    order = np.argsort(owners, kind='stable')
    owners, points = owners[order], points[order]
    starts = np.searchsorted(owners, np.arange(count))
    dx = targets[:, 0, None] - points[None, :, 0]                                       # (Nt, M)
    dy = targets[:, 1, None] - points[None, :, 1]
    squared = dx * dx + dy * dy
    gap = np.sqrt(np.minimum.reduceat(squared, starts, axis=1)).T                       # (Nc, Nt)
    signed = np.where(np.asarray(view_mask, dtype=bool), gap, -gap)
    return signed / sector_inradius(sight_ranges, viewing_angles)[:, None]


def _inner_profiles(centers: np.ndarray, angles: np.ndarray, max_sight_ranges: np.ndarray, discs: np.ndarray,
                    disc_mask: np.ndarray) -> np.ndarray:
    """(Nc, A) inner sight profile of every camera at its own angles (Nc, A); see `sight_profile`."""
    rho = np.broadcast_to(np.asarray(max_sight_ranges, dtype=np.float64)[:, None], angles.shape).copy()
    if len(discs) == 0 or not disc_mask.any():
        return rho
    rel = discs[None, :, :2] - centers[:, None, :]                                      # (Nc, K, 2)
    dist_sq = np.square(rel).sum(axis=-1)
    radius_sq = np.square(discs[:, 2])[None, :]
    radians = np.radians(angles)
    along = (np.cos(radians)[:, :, None] * rel[:, None, :, 0] + np.sin(radians)[:, :, None] * rel[:, None, :, 1])
    off_sq = dist_sq[:, None, :] - np.square(along)
    hit = (along >= 0.0) & (off_sq < radius_sq[:, None, :]) & disc_mask[:, None, :]
    near = np.maximum(along - np.sqrt(np.maximum(radius_sq[:, None, :] - off_sq, 0.0)), 0.0)
    rho = np.minimum(rho, np.where(hit, near, np.inf).min(axis=-1))
    blind = ((dist_sq < radius_sq) & disc_mask).any(axis=-1)
    rho[blind] = 0.0
    return rho


class SoftCoverage:
    """Soft coverage score matrix `S` (Nc, Nt) of an env, with the cameras' boundaries cached per episode
    (cameras and obstacles do not move; the cache follows the camera positions and obstacle layout)."""

    def __init__(self) -> None:
        self._key = None
        self._boundaries: list[CameraBoundary] = []
        self._samples = (np.zeros((0, 0)), np.zeros((0, 0), dtype=bool), np.zeros((0, 0, 2)))
        self._disc_mask = np.zeros((0, 0), dtype=bool)

    def boundaries(self, env, camera_states: np.ndarray) -> list[CameraBoundary]:
        """Each camera's `CameraBoundary` (rebuilt when the cameras or obstacles changed)."""
        base = env.unwrapped
        obstacles = base.obstacle_states
        flags = base.camera_obstacle_view_mask
        opaque = base.obstacle_transmittance < 1.0
        key = (camera_states[:, :3].tobytes(), camera_states[:, 6].tobytes(), obstacles.tobytes(),
               flags.tobytes(), opaque)
        if key != self._key:
            self._disc_mask = flags.copy() if opaque else np.zeros_like(flags)
            self._boundaries = [camera_boundary(state[:2], state[6], obstacles[self._disc_mask[c]])
                                for c, state in enumerate(camera_states)]
            size = max((len(b.phis) for b in self._boundaries), default=0)
            phis = np.zeros((len(self._boundaries), size))
            valid = np.zeros((len(self._boundaries), size), dtype=bool)
            points = np.zeros((len(self._boundaries), size, 2))
            for c, b in enumerate(self._boundaries):
                radians = np.radians(b.phis)
                phis[c, :len(b.phis)] = b.phis
                valid[c, :len(b.phis)] = True
                points[c, :len(b.phis)] = np.stack([b.rhos * np.cos(radians), b.rhos * np.sin(radians)], axis=1)
            self._samples = (phis, valid, points)
            self._key = key
        return self._boundaries

    def __call__(self, env) -> np.ndarray:
        """(Nc, Nt) matrix S of the env's current world."""
        cameras, targets = private_states(env)
        base = env.unwrapped
        if len(cameras) == 0 or len(targets) == 0:
            return np.zeros((len(cameras), len(targets)))
        self.boundaries(env, cameras)
        return soft_coverage_matrix(
            cameras[:, :2], np.degrees(np.arctan2(cameras[:, 4], cameras[:, 3])), cameras[:, 5],
            np.hypot(cameras[:, 3], cameras[:, 4]), cameras[:, 6], *self._samples, base.obstacle_states,
            self._disc_mask, targets[:, :2], base.camera_target_view_mask)
