"""Invariants of the batched core under random play (hypothesis drives seeds and action scales).

Every few-row batch is reset and stepped with random actions, many far outside the action
bounds; after each step the world must satisfy the invariants of spec §1, §4 and §5.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mate
from mate.constants import TERRAIN_SIZE
from mate.core import engine
from mate.core.params import params_from_config
from mate.core.world import empty_world

PRESETS = ['MATE-4v8-9', 'MATE-2v4-9', 'MATE-8v8-9', 'MATE-1v1-0', 'MATE-Navigation']
ROWS = 3
STEPS = 60
TOL = 1e-6

_PARAMS = {}


def _params(preset):
    if preset not in _PARAMS:
        _PARAMS[preset] = params_from_config(mate.read_config(preset))
    return _PARAMS[preset]


class Batch:
    """A batch of ROWS worlds of one preset with its observation buffers."""

    def __init__(self, preset, seeds):
        self.p = p = _params(preset)
        counts = (p.num_cameras, p.num_targets, p.num_obstacles)
        self.w = empty_world(p, len(seeds))
        self.cam = np.zeros((len(seeds), p.num_cameras, mate.camera_observation_dim(*counts)))
        self.tgt = np.zeros((len(seeds), p.num_targets, mate.target_observation_dim(*counts)))
        everything = np.ones(len(seeds), bool)
        engine.seed_rows(self.w, everything, seeds)
        engine.reset(p, self.w, everything, self.cam, self.tgt)

    def step(self, cam_actions, tgt_actions):
        engine.step(self.p, self.w, cam_actions, tgt_actions, self.cam, self.tgt)


def cargo_units(w):
    """(B,) remaining + carried + delivered units."""
    return w.remaining_cargoes.sum(axis=(1, 2)) + w.target_load.sum(axis=1) + w.num_delivered_cargoes


def check_invariants(p, w, total_cargo):
    tx, ty = w.target_pos[..., 0], w.target_pos[..., 1]
    # on the terrain
    assert np.all(np.abs(w.target_pos) <= TERRAIN_SIZE)
    # outside every obstacle and camera body
    if p.num_obstacles:
        d = np.hypot(tx[:, :, None] - w.obstacle_pos[:, None, :, 0], ty[:, :, None] - w.obstacle_pos[:, None, :, 1])
        depth = w.obstacle_radius[:, None, :] - d
        assert depth.max() <= TOL, f'target inside an obstacle by {depth.max()}'
    if p.num_cameras:
        d = np.hypot(tx[:, :, None] - w.camera_pos[:, None, :, 0], ty[:, :, None] - w.camera_pos[:, None, :, 1])
        depth = p.camera_radius - d
        assert depth.max() <= TOL, f'target inside a camera body by {depth.max()}'
    # bounty, freight, counters
    assert np.all(w.target_bounty >= 0)
    assert np.all(w.target_freight >= 0)
    assert np.all(w.target_bounty <= w.target_load * p.bounty_scale)
    assert np.all(w.remaining_cargoes >= 0)
    assert np.all(w.awaiting_cargo_counts >= 0)
    assert np.all((w.target_goal >= -1) & (w.target_goal < 4))
    assert np.all((w.target_load >= 0) & (w.target_load <= w.target_capacity))
    assert np.all((w.target_goal >= 0) == (w.target_load > 0))
    # coverage statistics
    for rate in (w.coverage_rate, w.real_coverage_rate):
        assert np.all((rate >= 0.0) & (rate <= 1.0))
    np.testing.assert_allclose(w.coverage_rate, w.camera_target_view_mask.any(axis=1).mean(axis=1))
    # cargo conservation
    np.testing.assert_array_equal(cargo_units(w), total_cargo)
    # cameras: constant sector area, angles in range
    if p.num_cameras:
        area = p.camera_min_viewing_angle * p.camera_max_sight_range ** 2
        np.testing.assert_allclose(w.camera_viewing_angle * w.camera_sight_range ** 2, area, rtol=1e-9)
        assert np.all(w.camera_viewing_angle >= p.camera_min_viewing_angle)
        assert np.all(w.camera_viewing_angle <= 180.0)
        assert np.all((w.camera_orientation >= -180.0) & (w.camera_orientation < 180.0))


def random_actions(rng, p, rows, scale):
    """Uniform in the action boxes times `scale` (values far outside the bounds when scale >> 1)."""
    cam_bound = np.array([p.camera_rotation_step, p.camera_zooming_step])
    cam = rng.uniform(-1, 1, (rows, p.num_cameras, 2)) * cam_bound * scale
    tgt = rng.uniform(-1, 1, (rows, p.num_targets, 2)) * p.target_step_size * scale
    return cam, tgt


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(preset=st.sampled_from(PRESETS), seed=st.integers(0, 2**31 - 1),
       scale=st.sampled_from([0.25, 1.0, 2.0, 10.0, 1e6]))
def test_invariants_under_random_play(preset, seed, scale):
    batch = Batch(preset, [seed + i for i in range(ROWS)])
    p, w = batch.p, batch.w
    total = cargo_units(w)
    assert np.all(total % (p.num_cargoes_per_target * p.num_targets) == 0)
    check_invariants(p, w, total)
    rng = np.random.default_rng(seed)
    for _ in range(STEPS):
        batch.step(*random_actions(rng, p, ROWS, scale))
        check_invariants(p, w, total)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_invariants_when_targets_rush_into_the_nearest_obstacle(seed):
    """Targets that mostly drive straight at the centre of their nearest disc (obstacle or
    camera) and sometimes wander in a random direction stop on the rim, slide along it and
    never end up inside (a head-on stop followed by a sideways move is the critical case)."""
    batch = Batch('MATE-4v8-9', [seed + i for i in range(ROWS)])
    p, w = batch.p, batch.w
    total = cargo_units(w)
    cam_actions = np.zeros((ROWS, p.num_cameras, 2))
    rng = np.random.default_rng(seed)
    for _ in range(STEPS):
        centres = np.concatenate([w.obstacle_pos, w.camera_pos], axis=1)       # (B, D, 2)
        rel = centres[:, None, :, :] - w.target_pos[:, :, None, :]             # (B, Nt, D, 2)
        nearest = np.argmin(np.hypot(rel[..., 0], rel[..., 1]), axis=2)       # (B, Nt)
        heading = np.take_along_axis(rel, nearest[:, :, None, None].repeat(2, axis=3), axis=2)[:, :, 0]
        wander = rng.uniform(-20.0, 20.0, heading.shape)
        rush = rng.random((ROWS, p.num_targets, 1)) < 0.7
        batch.step(cam_actions, np.where(rush, heading, wander))
        check_invariants(p, w, total)


@pytest.mark.parametrize('preset', PRESETS)
def test_reset_invariants(preset):
    batch = Batch(preset, list(range(8)))
    p, w = batch.p, batch.w
    check_invariants(p, w, cargo_units(w))
    assert np.all(w.episode_step == 0)
    assert np.all(w.num_delivered_cargoes == 0)
    # pick-ups at reset do not reduce the awaiting counts
    np.testing.assert_array_equal(w.awaiting_cargo_counts.sum(axis=1), cargo_units(w))
    high = np.sum(w.target_capacity == 2, axis=1)
    assert np.all(high == p.num_high_capacity_targets)
    if mate.read_config(preset)['targets_start_with_cargoes']:
        assert np.all(w.target_goal >= 0)
        np.testing.assert_array_equal(w.target_bounty, w.target_load * p.bounty_scale)
        np.testing.assert_array_equal(w.target_freight, w.target_load * p.freight_scale)
