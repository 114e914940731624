"""Kinematics: target collision slides (spec §4.2-4.4) and camera rotation/zoom (spec §4.1)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mate
from mate.core import engine
from mate.core.kinematics import rotate_and_zoom_cameras, slide_along_disc, wrap_angle
from mate.core.params import params_from_config
from mate.core.world import empty_world

# --------------------------------------------------------------------------- slide_along_disc


def _move(ox, oy, vx, vy, cx=0.0, cy=0.0, r=100.0):
    nvx, nvy = slide_along_disc(ox, oy, vx, vy, cx, cy, r)
    return ox + nvx, oy + nvy


def test_slide_worked_example_oblique():
    x, y = _move(30.0, -110.0, 0.0, 20.0)
    assert x == pytest.approx(31.5436, abs=1e-3)
    assert y == pytest.approx(-94.9085, abs=1e-3)
    assert math.hypot(x, y) >= 100.0 - 1e-9  # ends on the tangent line, outside the disc


def test_slide_worked_example_head_on_stops_at_contact():
    x, y = _move(0.0, -110.0, 0.0, 20.0)
    assert (x, y) == pytest.approx((0.0, -100.0), abs=1e-9)


def test_slide_target_inside_disc_is_reversed():
    assert _move(0.0, -50.0, 0.0, 5.0) == pytest.approx((0.0, -55.0), abs=1e-12)


@pytest.mark.parametrize('origin, step', [
    ((0.0, -300.0), (0.0, 20.0)),      # disc out of reach
    ((0.0, -110.0), (0.0, -20.0)),     # moving away
    ((150.0, -110.0), (0.0, 20.0)),    # passes beside the disc
])
def test_slide_leaves_unreachable_moves_alone(origin, step):
    assert slide_along_disc(*origin, *step, 0.0, 0.0, 100.0) == step


@settings(max_examples=200, deadline=None)
@given(angle=st.floats(-180, 180), gap=st.floats(1e-6, 30.0), heading=st.floats(-180, 180),
       length=st.floats(0.0, 20.0), radius=st.floats(1.0, 150.0))
def test_slide_never_ends_inside_the_disc(angle, gap, heading, length, radius):
    ox, oy = (radius + gap) * math.cos(math.radians(angle)), (radius + gap) * math.sin(math.radians(angle))
    vx, vy = length * math.cos(math.radians(heading)), length * math.sin(math.radians(heading))
    nvx, nvy = slide_along_disc(ox, oy, vx, vy, 0.0, 0.0, radius)
    assert math.hypot(ox + nvx, oy + nvy) >= radius * (1 - 1e-9) - 1e-9
    assert math.hypot(nvx, nvy) <= length + 1e-9  # a slide never lengthens the move


# --------------------------------------------------------------------------- through the environment

COLLISION_CONFIG = {
    'max_episode_steps': 100,
    'num_cargoes_per_target': 4,
    'high_capacity_target_split': 0.0,
    'targets_start_with_cargoes': False,
    'shuffle_entities': False,
    'target': {'location_random_range': [[-500, -400, 400, 500]] * 5, 'step_size': 20, 'sight_range': 500},
    'obstacle': {'location': [[0, 0]], 'radius': 100, 'transmittance': 0.0},
}

# (start, action, expected end, expected is_colliding): spec §4.3 worked examples
WORKED = [
    ((30.0, -110.0), (0.0, 20.0), (31.5436, -94.9085), True),
    ((0.0, -110.0), (0.0, 20.0), (0.0, -100.0), True),
    ((0.0, -50.0), (0.0, 5.0), (0.0, -55.0), True),
    ((995.0, 0.0), (20.0, 0.0), (1000.0, 0.0), True),
    ((0.0, -300.0), (300.0, 400.0), (12.0, -284.0), False),
]


def test_worked_collision_examples_through_env_step():
    env = mate.make('MultiAgentTracking-v0', config=COLLISION_CONFIG)
    env.reset(seed=0)
    world = env.get_world()
    assert world['obstacle_state'].tolist() == [[0.0, 0.0, 100.0]]
    world['target_state'][:, :2] = [start for start, *_ in WORKED]
    env.set_world(world)
    actions = np.array([action for _, action, *_ in WORKED])
    env.step((np.zeros((0, 2)), actions))
    after = env.get_world()
    for t, (_, _, end, colliding) in enumerate(WORKED):
        assert after['target_state'][t, :2] == pytest.approx(end, abs=1e-3), f'target {t}'
        assert bool(after['target_is_colliding'][t]) is colliding, f'target {t}'


def test_target_stopped_head_on_is_not_pushed_into_the_disc_next_step():
    """A head-on approach stops on the rim; in floating point the rim point may land a hair
    (1e-14) inside the disc. The next, mostly tangential move must not then be treated as
    "strictly inside -> reverse" (spec Q9), which would carry the target ~2 units into the
    obstacle: targets must stay outside obstacles (up to 1e-6)."""
    env = mate.make('MultiAgentTracking-v0', config=COLLISION_CONFIG)
    env.reset(seed=0)
    world = env.get_world()
    angles = np.radians([-60.0, -50.0, -40.0, -30.0, -20.0])
    radial = np.c_[np.cos(angles), np.sin(angles)]
    world['target_state'][:, :2] = 110.0 * radial
    env.set_world(world)
    env.step((np.zeros((0, 2)), -20.0 * radial))  # head-on: stop on the rim
    rim = env.get_world()['target_state'][:, :2]
    np.testing.assert_allclose(np.hypot(*rim.T), 100.0, atol=1e-9)
    sideways = angles + np.pi / 2 - 0.2             # tangential, slightly outward
    env.step((np.zeros((0, 2)), 20.0 * np.c_[np.cos(sideways), np.sin(sideways)]))
    after = env.get_world()['target_state'][:, :2]
    assert np.all(np.hypot(*after.T) >= 100.0 - 1e-6), np.hypot(*after.T) - 100.0


def test_camera_body_is_a_collision_barrier():
    config = dict(COLLISION_CONFIG, camera={'location': [[0, 0]], 'radius': 40, 'min_viewing_angle': 30,
                                            'max_sight_range': 500, 'rotation_step': 5, 'zooming_step': 2.5})
    del config['obstacle']
    env = mate.make('MultiAgentTracking-v0', config=config)
    env.reset(seed=0)
    world = env.get_world()
    world['target_state'][:, :2] = [(0, -50), (-50, 0), (0, 55), (100, 100), (20, -50)]
    env.set_world(world)
    env.step((np.zeros((1, 2)), [(0, 20), (20, 0), (0, -20), (0, 0), (0, 20)]))
    after = env.get_world()
    xy = after['target_state'][:, :2]
    assert xy[0] == pytest.approx((0, -40), abs=1e-9)
    assert xy[1] == pytest.approx((-40, 0), abs=1e-9)
    assert xy[2] == pytest.approx((0, 40), abs=1e-9)
    assert xy[3] == pytest.approx((100, 100), abs=1e-12)
    assert np.hypot(*xy[4]) >= 40 - 1e-9
    assert after['target_is_colliding'].tolist() == [True, True, True, False, True]


def test_capacity_two_target_is_norm_clipped_to_half_speed():
    env = mate.make('MultiAgentTracking-v0', config=COLLISION_CONFIG)
    env.reset(seed=0)
    world = env.get_world()
    world['target_state'][:, :2] = [(-500, 500 - 30 * t) for t in range(5)]
    world['target_state'][0, 4:6] = (10.0, 2.0)
    env.set_world(world)
    env.step((np.zeros((0, 2)), [(30, 40), (30, 40), (3, 4), (20, 0), (-1000, 0)]))
    xy = env.get_world()['target_state'][:, :2]
    assert xy[0] == pytest.approx((-494, 508))   # |v| clipped to 10 (capacity 2)
    assert xy[1] == pytest.approx((-488, 486))   # clipped to 20
    assert xy[2] == pytest.approx((-497, 444))   # short moves are kept
    assert xy[3] == pytest.approx((-480, 410))
    assert xy[4] == pytest.approx((-520, 380))   # a norm clip, not a box clip


# --------------------------------------------------------------------------- cameras

def _camera_world(config='MATE-4v8-9', rows=1):
    params = params_from_config(mate.read_config(config))
    world = empty_world(params, rows)
    engine.seed_rows(world, np.ones(rows, bool), list(range(rows)))
    cam = np.zeros((rows, params.num_cameras, engine_dim(params, 'camera')))
    tgt = np.zeros((rows, params.num_targets, engine_dim(params, 'target')))
    engine.reset(params, world, np.ones(rows, bool), cam, tgt)
    return params, world


def engine_dim(params, team):
    counts = (params.num_cameras, params.num_targets, params.num_obstacles)
    return (mate.camera_observation_dim if team == 'camera' else mate.target_observation_dim)(*counts)


def test_wrap_angle_range():
    values = np.array([-540.0, -180.0, -179.5, 0.0, 179.999, 180.0, 360.0, 541.0])
    wrapped = np.array([wrap_angle(v) for v in values])
    assert wrapped.tolist() == pytest.approx([-180.0, -180.0, -179.5, 0.0, 179.999, -180.0, 0.0, -179.0])


def test_camera_rotation_and_zoom_are_box_clipped_and_wrapped():
    params, world = _camera_world()
    world.camera_orientation[0] = [178.0, -178.0, 0.0, 10.0]
    world.camera_viewing_angle[0] = [179.0, 31.0, 100.0, 100.0]
    actions = np.array([[100.0, 100.0], [-100.0, -100.0], [2.0, -1.0], [-5.0, 2.5]])
    rotate_and_zoom_cameras(params, world, 0, actions)
    assert world.camera_orientation[0].tolist() == pytest.approx([-177.0, 177.0, 2.0, 5.0])
    assert world.camera_viewing_angle[0].tolist() == pytest.approx([180.0, 30.0, 99.0, 102.5])
    expected_range = 1500.0 * np.sqrt(30.0 / world.camera_viewing_angle[0])
    assert world.camera_sight_range[0] == pytest.approx(expected_range)
    assert world.camera_sight_range[0, 1] == pytest.approx(1500.0)            # at theta_min: R_max
    assert world.camera_sight_range[0, 0] == pytest.approx(612.3724, abs=1e-4)  # at 180 degrees


def test_camera_step_through_env_clips_rotation():
    env = mate.make('MATE-4v8-9-v0')
    env.reset(seed=3)
    before = env.get_world()
    env.step(([[1e6, -1e6]] * 4, np.zeros((8, 2))))
    after = env.get_world()
    expected = (before['camera_orientation'] + 5.0 + 180.0) % 360.0 - 180.0
    assert after['camera_orientation'] == pytest.approx(expected)
    assert after['camera_viewing_angle'] == pytest.approx(np.maximum(before['camera_viewing_angle'] - 2.5, 30.0))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), scale=st.sampled_from([0.5, 1.0, 3.0, 1e3]))
def test_sector_area_is_constant_under_random_actions(seed, scale):
    params, world = _camera_world(rows=2)
    rng = np.random.default_rng(seed)
    area = params.camera_min_viewing_angle * params.camera_max_sight_range ** 2
    bound = np.array([params.camera_rotation_step, params.camera_zooming_step])
    for _ in range(60):
        actions = rng.uniform(-1.0, 1.0, (params.num_cameras, 2)) * bound * scale
        for b in range(2):
            rotate_and_zoom_cameras(params, world, b, actions)
        theta, rs = world.camera_viewing_angle, world.camera_sight_range
        np.testing.assert_allclose(theta * rs ** 2, area, rtol=1e-12)
        assert np.all((theta >= params.camera_min_viewing_angle) & (theta <= 180.0))
        assert np.all((world.camera_orientation >= -180.0) & (world.camera_orientation < 180.0))
