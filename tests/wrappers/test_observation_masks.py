"""EnhancedObservation and SharedFieldOfView on a known world (spec §8.3): exact records, flags and empty bits."""

from __future__ import annotations

import numpy as np
import pytest
from wrapper_scene import D_C, D_T, NC, NT, SCENE, ZERO_ACTION, make_env, set_scene

import mate
from mate.wrappers.enhanced_observation import enhance_observations
from mate.wrappers.shared_field_of_view import share_field_of_view

R0 = np.sqrt(30.0 * 1000.0 ** 2 / 60.0)   # camera 0's sight range at 60 degrees: 707.107
R1 = 1000.0                                  # camera 1 at its minimum viewing angle (30 degrees)
REMAINING = [[0, 0, 0, 0], [1, 0, 1, 0], [0, 0, 0, 0], [2, 1, 0, 0]]   # warehouses 0 and 2 are empty

# camera layout: targets [22, 37), obstacles [37, 45), cameras [45, 59); target layout: cameras [27, 41),
# obstacles [41, 49), targets [49, 64), own empty bits [23, 27)
CAM_T, CAM_O, CAM_C = slice(22, 37), slice(37, 45), slice(45, 59)
TGT_C, TGT_O, TGT_T, EMPTY = slice(27, 41), slice(41, 49), slice(49, 64), slice(23, 27)

ALL_TARGETS = [0, 0, 300, 1, 1, 500, 300, 300, 1, 1, -300, 700, 300, 1, 1]
ALL_OBSTACLES = [0, 800, 50, 1, 0, -800, 50, 1]
ALL_CAMERAS = [-500, 0, 40, R0, 0, 60, 1, 500, 0, 40, 0, R1, 30, 1]


def scene(env, **extra):
    return set_scene(env, goals=[3, 0, 1], remaining=REMAINING, **{**SCENE, **extra})


def test_enhanced_observation_shows_everything():
    env = make_env(wrappers=[mate.EnhancedObservation])
    camera_obs, target_obs = scene(env)
    before = camera_obs.copy(), target_obs.copy()
    camera_obs, target_obs = env.observation((camera_obs, target_obs))
    assert camera_obs.shape == (NC, D_C) and target_obs.shape == (NT, D_T)
    np.testing.assert_array_equal(env.obstacle_states_flagged.ravel(), ALL_OBSTACLES)   # forwarded env property
    for row in camera_obs:
        np.testing.assert_allclose(row[CAM_T], ALL_TARGETS, atol=1e-9)
        np.testing.assert_allclose(row[CAM_O], ALL_OBSTACLES)
        np.testing.assert_allclose(row[CAM_C], ALL_CAMERAS, atol=1e-9)
    for row in target_obs:
        np.testing.assert_allclose(row[TGT_C], [-500, 0, 40, R0, 0, 60, 1, 500, 0, 40, 0, R1, 30, 1], atol=1e-9)
        np.testing.assert_allclose(row[TGT_O], ALL_OBSTACLES)
        np.testing.assert_allclose(row[TGT_T], ALL_TARGETS)
        np.testing.assert_array_equal(row[EMPTY], [1, 0, 1, 0])          # the truth, not the target's belief
    # preserved part and own state (apart from target empty bits) are untouched
    np.testing.assert_array_equal(camera_obs[:, :22], before[0][:, :22])
    np.testing.assert_array_equal(target_obs[:, :23], before[1][:, :23])


def test_enhanced_observation_after_step_and_team_choice():
    env = make_env(wrappers=[mate.WrapperSpec(mate.EnhancedObservation, team='camera')])
    scene(env)
    (camera_obs, target_obs), *_ = env.step(ZERO_ACTION)
    np.testing.assert_allclose(camera_obs[1, CAM_T], ALL_TARGETS, atol=1e-9)
    np.testing.assert_array_equal(target_obs[0, TGT_C], np.zeros(14))     # targets unchanged: they see no camera
    none = make_env(wrappers=[mate.WrapperSpec(mate.EnhancedObservation, team='none')])
    raw = scene(none)
    expected = tuple(a.copy() for a in raw)
    got = none.observation(raw)
    np.testing.assert_array_equal(got[0], expected[0])
    np.testing.assert_array_equal(got[1], expected[1])


def test_shared_field_of_view_ors_masks():
    env = make_env(wrappers=[mate.SharedFieldOfView])
    # obstacle 1 at (900, -900): flagged for camera 1 only (985 < 1000 + 50), not for camera 0 (1664)
    empty_bits = [[1, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]
    camera_obs, target_obs = scene(env, obstacles=[(0.0, 800.0, 50.0), (900.0, -900.0, 50.0)], empty_bits=empty_bits)
    np.testing.assert_array_equal(camera_obs[:, 37 + 7], [0, 1])            # obstacle 1 flag before sharing
    camera_obs, target_obs = env.observation((camera_obs, target_obs))
    targets_seen = [0, 0, 300, 1, 1, 500, 300, 300, 1, 1, 0, 0, 0, 0, 0]     # t0 (camera 0) and t1 (camera 1)
    for row in camera_obs:
        np.testing.assert_allclose(row[CAM_T], targets_seen)
        np.testing.assert_allclose(row[CAM_O], [0, 800, 50, 1, 900, -900, 50, 1])
        np.testing.assert_allclose(row[CAM_C], ALL_CAMERAS, atol=1e-9)        # every teammate, flagged
    for row in target_obs:
        np.testing.assert_allclose(row[TGT_C], [0] * 7 + [500, 0, 40, 0, R1, 30, 1], atol=1e-9)   # t1 sees camera 1
        np.testing.assert_allclose(row[TGT_O], [0, 800, 50, 1, 0, 0, 0, 0])                      # t2 sees obstacle 0
        np.testing.assert_allclose(row[TGT_T], ALL_TARGETS)
        np.testing.assert_array_equal(row[EMPTY], [1, 0, 0, 1])                                  # OR of beliefs


def test_shared_field_of_view_target_only():
    env = make_env(wrappers=[mate.WrapperSpec(mate.SharedFieldOfView, team='target')])
    camera_obs, target_obs = scene(env)
    cameras_before = camera_obs.copy()
    camera_obs, target_obs = env.observation((camera_obs, target_obs))
    np.testing.assert_array_equal(camera_obs, cameras_before)
    np.testing.assert_allclose(target_obs[0, TGT_C][7:], [500, 0, 40, 0, R1, 30, 1], atol=1e-9)


@pytest.mark.parametrize('function', [enhance_observations, share_field_of_view])
def test_array_functions_work_on_batches(function):
    """The array functions act row by row on (B, N, D) arrays with per-row obstacles and empty bits."""
    env = make_env()
    first = scene(env)
    obstacles_first = env.unwrapped.obstacle_states
    second = scene(env, targets=[(100.0, 0.0), (500.0, 500.0), (-900.0, -900.0)],
                   obstacles=[(0.0, 700.0, 60.0), (0.0, -700.0, 40.0)], empty_bits=[[0, 1, 0, 0]] * 3)
    obstacles_second = env.unwrapped.obstacle_states
    camera_batch = np.stack([first[0], second[0]])
    target_batch = np.stack([first[1], second[1]])
    obstacles = np.stack([obstacles_first, obstacles_second])
    extra = (np.array([[1.0, 0, 1, 0], [0, 0, 0, 1]]),) if function is enhance_observations else ()
    batched = function(camera_batch.copy(), target_batch.copy(), obstacles, *extra, NC, NT, 2)
    for b, (cam, tgt) in enumerate((first, second)):
        single_extra = (extra[0][b],) if extra else ()
        one = function(cam.copy(), tgt.copy(), obstacles[b], *single_extra, NC, NT, 2)
        np.testing.assert_array_equal(batched[0][b], one[0])
        np.testing.assert_array_equal(batched[1][b], one[1])
