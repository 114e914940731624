"""World snapshots: one world row as a dict of plain arrays, and loading such a dict back.

The keys and layouts are the public snapshot contract (`get_world` / `set_world`): private
camera state (Nc, 9) `[x, y, r, R cos phi, R sin phi, theta, R_max, d_phi_max, d_theta_max]`,
private target state (Nt, 14) `[x, y, sight, loaded, speed, capacity, goal_bits(4), empty_bits(4)]`,
obstacle state (No, 3) `[x, y, r]`, and the cargo bookkeeping. Angles are degrees.
"""

from __future__ import annotations

import numpy as np

from ..constants import (
    CAMERA_STATE_DIM_PRIVATE,
    NUM_WAREHOUSES,
    OBSTACLE_STATE_DIM,
    TARGET_STATE_DIM_PRIVATE,
)
from .params import Params
from .world import World, obstacle_states, target_headings

INPUT_KEYS = (
    'camera_state', 'camera_orientation', 'camera_viewing_angle', 'camera_sight_range',
    'target_state', 'target_goal', 'target_freight', 'target_bounty', 'target_steps',
    'target_tracked_steps', 'obstacle_state', 'remaining_cargoes', 'awaiting_cargo_counts',
    'num_delivered_cargoes', 'episode_step',
)
MASK_KEYS = (
    'camera_target_view_mask', 'camera_obstacle_view_mask', 'camera_camera_view_mask',
    'target_camera_view_mask', 'target_obstacle_view_mask', 'target_target_view_mask',
)

DERIVED_KEYS = MASK_KEYS + (
    'target_is_colliding', 'target_heading', 'coverage_rate', 'real_coverage_rate', 'mean_transport_rate',
)
"""Keys `get_snapshot` adds; `set_snapshot` accepts and ignores them (they are recomputed)."""


class SnapshotError(ValueError):
    """A world snapshot with a missing or unknown key, a wrong shape or an inconsistent value."""


def _private_camera_states(p: Params, w: World, b: int) -> np.ndarray:
    phi = np.radians(w.camera_orientation[b])
    rs = w.camera_sight_range[b]
    out = np.empty((p.num_cameras, CAMERA_STATE_DIM_PRIVATE))
    out[:, :2] = w.camera_pos[b]
    out[:, 2] = p.camera_radius
    out[:, 3], out[:, 4], out[:, 5] = rs * np.cos(phi), rs * np.sin(phi), w.camera_viewing_angle[b]
    out[:, 6:] = p.camera_max_sight_range, p.camera_rotation_step, p.camera_zooming_step
    return out


def goal_bits(w: World, b: int) -> np.ndarray:
    """(Nt, 4) units carried per destination warehouse (one non-zero entry per loaded target)."""
    bits = np.zeros((w.target_goal.shape[1], NUM_WAREHOUSES), dtype=np.int64)
    loaded = np.flatnonzero(w.target_goal[b] >= 0)
    bits[loaded, w.target_goal[b, loaded]] = w.target_load[b, loaded]
    return bits


def _private_target_states(p: Params, w: World, b: int) -> np.ndarray:
    out = np.empty((p.num_targets, TARGET_STATE_DIM_PRIVATE))
    out[:, :2] = w.target_pos[b]
    out[:, 2] = p.target_sight_range
    out[:, 3] = w.target_goal[b] >= 0
    out[:, 4] = p.target_step_size / w.target_capacity[b]
    out[:, 5] = w.target_capacity[b]
    out[:, 6:10] = goal_bits(w, b)
    out[:, 10:14] = w.target_empty_bits[b]
    return out


def get_snapshot(p: Params, w: World, b: int) -> dict:
    """Row b as a dict of fresh arrays (input keys, masks, coverage and derived extras)."""
    snap = {
        'camera_state': _private_camera_states(p, w, b),
        'camera_orientation': w.camera_orientation[b].copy(),
        'camera_viewing_angle': w.camera_viewing_angle[b].copy(),
        'camera_sight_range': w.camera_sight_range[b].copy(),
        'target_state': _private_target_states(p, w, b),
        'target_goal': w.target_goal[b].copy(),
        'target_freight': w.target_freight[b].copy(),
        'target_bounty': w.target_bounty[b].copy(),
        'target_steps': w.target_steps[b].copy(),
        'target_tracked_steps': w.target_tracked_steps[b].copy(),
        'obstacle_state': obstacle_states(w, b),
        'remaining_cargoes': w.remaining_cargoes[b].copy(),
        'awaiting_cargo_counts': w.awaiting_cargo_counts[b].copy(),
        'num_delivered_cargoes': int(w.num_delivered_cargoes[b]),
        'episode_step': int(w.episode_step[b]),
        'target_is_colliding': w.target_is_colliding[b].copy(),
        'target_heading': target_headings(w, b),
        'coverage_rate': float(w.coverage_rate[b]),
        'real_coverage_rate': float(w.real_coverage_rate[b]),
        'mean_transport_rate': float(w.mean_transport_rate[b]),
    }
    for key in MASK_KEYS:
        snap[key] = getattr(w, key)[b].copy()
    assert set(snap) == set(INPUT_KEYS) | set(DERIVED_KEYS)
    return snap


def _array(snapshot: dict, key: str, shape: tuple, dtype=np.float64) -> np.ndarray:
    try:
        value = np.asarray(snapshot[key], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SnapshotError(f'snapshot[{key!r}] is not numeric: {exc}') from None
    if value.shape != shape:
        raise SnapshotError(f'snapshot[{key!r}] has shape {value.shape}, expected {shape}')
    if not np.isfinite(value).all():
        raise SnapshotError(f'snapshot[{key!r}] contains NaN or inf')
    if dtype is not np.float64:
        if not np.array_equal(value, np.round(value)):
            raise SnapshotError(f'snapshot[{key!r}] must hold whole numbers, got {value}')
        return value.astype(dtype)
    return value


def _expect(condition, message: str) -> None:
    if not np.all(condition):
        raise SnapshotError(message)


def _read(p: Params, snapshot: dict) -> dict:
    """Validate a snapshot against the configuration; return its arrays, converted."""
    unknown = set(snapshot) - set(INPUT_KEYS) - set(DERIVED_KEYS)
    missing = [k for k in INPUT_KEYS if k not in snapshot]
    _expect(not missing, f'snapshot is missing keys {missing}; required keys: {list(INPUT_KEYS)}')
    _expect(not unknown, f'snapshot has unknown keys {sorted(unknown)}; known keys: {list(INPUT_KEYS)}')
    nc, nt, no, nw = p.num_cameras, p.num_targets, p.num_obstacles, NUM_WAREHOUSES
    s = {
        'camera_state': _array(snapshot, 'camera_state', (nc, CAMERA_STATE_DIM_PRIVATE)),
        'camera_orientation': _array(snapshot, 'camera_orientation', (nc,)),
        'camera_viewing_angle': _array(snapshot, 'camera_viewing_angle', (nc,)),
        'camera_sight_range': _array(snapshot, 'camera_sight_range', (nc,)),
        'target_state': _array(snapshot, 'target_state', (nt, TARGET_STATE_DIM_PRIVATE)),
        'obstacle_state': _array(snapshot, 'obstacle_state', (no, OBSTACLE_STATE_DIM)),
    }
    for key, shape in (('target_goal', (nt,)), ('target_freight', (nt,)), ('target_bounty', (nt,)),
                       ('target_steps', (nt,)), ('target_tracked_steps', (nt,)), ('remaining_cargoes', (nw, nw)),
                       ('awaiting_cargo_counts', (nw,)), ('num_delivered_cargoes', ()), ('episode_step', ())):
        s[key] = _array(snapshot, key, shape, np.int64)
    _check_consistency(p, s)
    return s


def _check_consistency(p: Params, s: dict) -> None:
    cam, tgt = s['camera_state'], s['target_state']
    statics = {2: ('radius', p.camera_radius), 6: ('max_sight_range', p.camera_max_sight_range),
               7: ('rotation_step', p.camera_rotation_step), 8: ('zooming_step', p.camera_zooming_step)}
    for col, (name, value) in statics.items():
        _expect(np.isclose(cam[:, col], value), f'snapshot camera_state[:, {col}] ({name}) must equal the '
                f"configuration's {value}, got {cam[:, col]}")
    _expect((s['camera_viewing_angle'] >= p.camera_min_viewing_angle - 1e-9) & (s['camera_viewing_angle'] <= 180.0),
            f'snapshot camera_viewing_angle must lie in [{p.camera_min_viewing_angle}, 180], '
            f"got {s['camera_viewing_angle']}")
    _expect(s['camera_sight_range'] > 0, f"snapshot camera_sight_range must be > 0, got {s['camera_sight_range']}")
    _expect(np.isclose(tgt[:, 2], p.target_sight_range), f'snapshot target_state[:, 2] (sight_range) must equal '
            f"the configuration's {p.target_sight_range}, got {tgt[:, 2]}")
    capacity = tgt[:, 5]
    _expect(np.isin(capacity, (1.0, 2.0)), f'snapshot target_state[:, 5] (capacity) must be 1 or 2, got {capacity}')
    _expect(np.isclose(tgt[:, 4], p.target_step_size / capacity), 'snapshot target_state[:, 4] (step size) must be '
            f'step_size / capacity = {p.target_step_size / capacity}, got {tgt[:, 4]}')
    goal = s['target_goal']
    _expect((goal >= -1) & (goal < NUM_WAREHOUSES), f'snapshot target_goal must be in -1..3, got {goal}')
    bits = tgt[:, 6:10]
    expected_nonzero = np.zeros_like(bits, dtype=bool)
    expected_nonzero[goal >= 0, goal[goal >= 0]] = True
    _expect(((bits != 0) == expected_nonzero) & (bits >= 0) & (bits == np.round(bits)),
            f'snapshot target_state[:, 6:10] (goal bits) must hold the load at column target_goal only; '
            f'got goal bits {bits.tolist()} with target_goal {goal.tolist()}')
    _expect(bits.sum(axis=1) <= capacity, 'snapshot goal bits exceed the target capacity')
    _expect(np.isin(tgt[:, 10:14], (0.0, 1.0)), 'snapshot target_state[:, 10:14] (empty bits) must be 0 or 1')
    _expect(s['obstacle_state'][:, 2] >= 0, 'snapshot obstacle_state[:, 2] (radius) must be >= 0')
    for key in ('target_freight', 'target_bounty', 'target_steps', 'target_tracked_steps', 'remaining_cargoes',
                'awaiting_cargo_counts', 'num_delivered_cargoes', 'episode_step'):
        _expect(s[key] >= 0, f'snapshot {key} must be >= 0, got {s[key]}')


def set_snapshot(p: Params, w: World, b: int, snapshot: dict) -> None:
    """Load a snapshot into row b (validated first: on error nothing changes). Derived quantities
    (view masks, camera->obstacle flags, coverage) must be recomputed by the caller (`engine.refresh`)."""
    s = _read(p, snapshot)
    w.camera_pos[b] = s['camera_state'][:, :2]
    w.camera_orientation[b] = (s['camera_orientation'] + 180.0) % 360.0 - 180.0
    w.camera_direction[b, :, 0] = np.cos(np.radians(w.camera_orientation[b]))
    w.camera_direction[b, :, 1] = np.sin(np.radians(w.camera_orientation[b]))
    w.camera_viewing_angle[b] = s['camera_viewing_angle']
    w.camera_sight_range[b] = s['camera_sight_range']
    tgt = s['target_state']
    w.target_pos[b] = tgt[:, :2]
    w.target_capacity[b] = tgt[:, 5].astype(np.int64)
    w.target_goal[b] = s['target_goal']
    w.target_load[b] = tgt[:, 6:10].sum(axis=1).astype(np.int64)
    w.target_empty_bits[b] = tgt[:, 10:14] != 0
    w.target_is_colliding[b] = False
    w.target_done[b] = False
    w.target_reward_parts[b] = 0.0
    w.obstacle_pos[b] = s['obstacle_state'][:, :2]
    w.obstacle_radius[b] = s['obstacle_state'][:, 2]
    for key in ('target_freight', 'target_bounty', 'target_steps', 'target_tracked_steps', 'remaining_cargoes',
                'awaiting_cargo_counts', 'num_delivered_cargoes', 'episode_step'):
        getattr(w, key)[b] = s[key]
