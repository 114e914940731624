"""Agent-side helpers (spec agents-and-wrappers.md §3-4): relative coordinates, rescaling, splitting,
state views and Vector2D, on hand-made observations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from handmade import (
    camera_observation,
    camera_private,
    camera_public,
    target_observation,
    target_private,
)
from hypothesis import given, settings
from hypothesis import strategies as st

import mate
from mate import Team
from mate.agents.geometry import Vector2D, normalize_angle
from mate.spaces import camera_observation_indices_of, target_observation_indices_of


@pytest.fixture()
def cam_obs():
    own = camera_private(300.0, -200.0, orientation=30.0, viewing_angle=60.0)
    return camera_observation(own, index=1, targets={2: [500.0, 100.0, 500.0, 1.0]},
                              obstacles={0: [250.0, -150.0, 50.0]},
                              cameras={3: camera_public(-700.0, 600.0, orientation=-90.0)})


def test_convert_coordinates_of_a_camera_observation(cam_obs):
    out = mate.convert_coordinates(cam_obs, Team.CAMERA, 4, 8, 9)
    idx = camera_observation_indices_of(4, 8, 9)
    np.testing.assert_array_equal(out[:4], cam_obs[:4])
    np.testing.assert_allclose(out[4:12].reshape(4, 2), mate.WAREHOUSES - [300.0, -200.0])
    np.testing.assert_array_equal(out[13:22], cam_obs[13:22])          # own state untouched
    t2 = idx[2] + 5 * 2
    np.testing.assert_allclose(out[t2:t2 + 5], [200.0, 300.0, 500.0, 1.0, 1.0])
    t0 = idx[2]
    np.testing.assert_array_equal(out[t0:t0 + 5], 0.0)                   # invisible stays zero
    np.testing.assert_allclose(out[idx[3]:idx[3] + 4], [-50.0, 50.0, 50.0, 1.0])
    own_record = idx[4] + 7 * 1
    np.testing.assert_allclose(out[own_record:own_record + 2], [0.0, 0.0])
    other = idx[4] + 7 * 3
    np.testing.assert_allclose(out[other:other + 2], [-1000.0, 800.0])
    np.testing.assert_array_equal(out[other + 2:other + 7], cam_obs[other + 2:other + 7])
    assert out is not cam_obs and cam_obs[4] == 925.0                      # input not modified


def test_convert_coordinates_batches_and_extra_columns(cam_obs):
    other = camera_observation(camera_private(-500.0, 500.0), index=2)
    batch = np.stack([cam_obs, other])
    extra = np.concatenate([batch, np.full((2, 3), 7.0)], axis=1)
    out = mate.convert_coordinates(extra, Team.CAMERA, 4, 8, 9)
    assert out.shape == (2, batch.shape[1] + 3)
    np.testing.assert_array_equal(out[:, -3:], 7.0)
    for row in range(2):
        np.testing.assert_allclose(out[row, :-3], mate.convert_coordinates(batch[row], Team.CAMERA, 4, 8, 9))


def test_convert_coordinates_of_a_target_observation():
    own = target_private(100.0, 50.0)
    obs = target_observation(own, index=3, cameras={1: camera_public(600.0, 650.0)}, targets={5: [0.0, 0.0, 500, 0]})
    out = mate.convert_coordinates(obs, Team.TARGET, 4, 8, 9)
    idx = target_observation_indices_of(4, 8, 9)
    np.testing.assert_allclose(out[idx[2] + 7:idx[2] + 9], [500.0, 600.0])
    np.testing.assert_allclose(out[idx[4] + 5 * 5:idx[4] + 5 * 5 + 2], [-100.0, -50.0])
    np.testing.assert_allclose(out[idx[4] + 5 * 3:idx[4] + 5 * 3 + 2], [0.0, 0.0])


def test_rescale_observation_field_maps():
    own = target_private(1000.0, -500.0, step_size=10.0, capacity=2.0, goal_bits=(0, 2, 0, 0), empty_bits=(1, 0, 0, 0))
    obs = target_observation(own, cameras={0: camera_public(400.0, 0.0, viewing_angle=90.0, radius=40.0)},
                             obstacles={2: [0.0, 0.0, 100.0]})
    out = mate.rescale_observation(obs, Team.TARGET, 4, 8, 9)
    idx = target_observation_indices_of(4, 8, 9)
    np.testing.assert_array_equal(out[:4], obs[:4])                       # counts and index unchanged
    assert out[4] == pytest.approx(925.0 / 2000.0)
    assert out[12] == pytest.approx(75.0 / 500.0 - 1.0)
    np.testing.assert_allclose(out[13:15], [0.5, -0.25])
    assert out[15] == pytest.approx(500.0 / 1000.0 - 1.0)                 # sight range
    assert out[16] == 1.0                                                 # is_loaded unchanged
    assert out[17] == pytest.approx(10.0 / 1000.0 - 1.0)                  # step size
    assert out[18] == pytest.approx(2 * 2.0 - 3.0)                        # capacity
    np.testing.assert_array_equal(out[19:23], [0, 2, 0, 0])               # goal bits unchanged
    np.testing.assert_array_equal(out[23:27], [1, 0, 0, 0])
    cam = out[idx[2]:idx[2] + 7]
    np.testing.assert_allclose(cam[[0, 1, 2, 5, 6]], [0.2, 0.0, 40.0 / 500.0 - 1.0, 0.0, 1.0])
    invisible = out[idx[2] + 7:idx[2] + 14]
    np.testing.assert_allclose(invisible, [0.0, 0.0, -1.0, 0.0, 0.0, -1.0, 0.0])
    obstacle = out[idx[3] + 8:idx[3] + 12]
    np.testing.assert_allclose(obstacle, [0.0, 0.0, 100.0 / 500.0 - 1.0, 1.0])


def test_normalize_observation_passes_extra_columns_and_respects_mask():
    space = mate.camera_observation_space_of(4, 8, 9)
    obs = camera_observation(camera_private(0.0, 0.0))
    extra = np.append(obs, [123.0])
    out = mate.normalize_observation(extra, space)
    assert out[-1] == 123.0
    mask = np.zeros(space.shape[0], dtype=bool)
    unscaled = mate.normalize_observation(obs, space, additional_mask=mask)
    np.testing.assert_allclose(unscaled, obs - np.where(space.bounded_below, space.low, 0.0))


def test_split_observation(cam_obs):
    parts = mate.split_observation(cam_obs, Team.CAMERA, 4, 8, 9)
    assert [p.shape[-1] for p in parts] == [13, 9, 40, 36, 28]
    np.testing.assert_array_equal(np.concatenate(parts), cam_obs)
    with pytest.raises(ValueError):
        mate.split_observation(cam_obs[:-1], Team.CAMERA, 4, 8, 9)
    batch = mate.split_observation(np.stack([cam_obs] * 3), Team.CAMERA, 4, 8, 9)
    assert batch[2].shape == (3, 40)


def test_camera_state_views():
    values = camera_private(10.0, 20.0, orientation=-120.0, viewing_angle=120.0, max_sight_range=1200.0,
                            rotation_step=4.0, zooming_step=3.0)
    state = mate.CameraStatePrivate(np.array(values), index=2)
    assert state.index == 2 and state.radius == 40.0
    np.testing.assert_allclose(state.location, [10.0, 20.0])
    assert state.orientation == pytest.approx(-120.0)
    assert state.viewing_angle == 120.0
    assert state.sight_range == pytest.approx(1200.0 * math.sqrt(30.0 / 120.0))
    assert state.min_viewing_angle == pytest.approx(30.0)
    assert (state.max_sight_range, state.rotation_step, state.zooming_step) == (1200.0, 4.0, 3.0)
    np.testing.assert_array_equal(state.action_space.high, [4.0, 3.0])
    np.testing.assert_array_equal(state.action_space.low, [-4.0, -3.0])
    same = mate.CameraStatePrivate.from_values(values, index=2)
    np.testing.assert_array_equal(same.state, state.state)
    assert same.orientation == state.orientation
    copy = state.copy()
    assert copy.state is not state.state and np.array_equal(np.asarray(copy), state.state)
    public = mate.CameraStatePublic(np.array(values[:6]))
    assert public.sight_range == pytest.approx(state.sight_range)
    with pytest.raises(ValueError):
        mate.CameraStatePublic(np.array(values))


def test_target_state_views_and_difference_vector():
    own = mate.TargetStatePrivate(np.array(target_private(3.0, 4.0, step_size=10.0, capacity=2.0,
                                                          goal_bits=(0, 0, 2, 0), empty_bits=(0, 1, 0, 1))))
    assert own.step_size == 10.0 and own.capacity == 2.0 and own.is_loaded and own.sight_range == 500.0
    assert own.goal_bits.dtype == np.int64 and own.goal_bits.tolist() == [0, 0, 2, 0]
    assert own.empty_bits.dtype == bool and own.empty_bits.tolist() == [False, True, False, True]
    np.testing.assert_array_equal(own.action_space.high, [10.0, 10.0])
    other = mate.TargetStatePublic(np.array([0.0, 0.0, 500.0, 0.0]), index=5)
    assert not other.is_loaded and other.sight_range == 500.0
    vector = own - other
    assert vector.norm == pytest.approx(5.0)
    assert vector.angle == pytest.approx(math.degrees(math.atan2(4.0, 3.0)))
    np.testing.assert_allclose(vector.origin, [0.0, 0.0])
    np.testing.assert_allclose(vector.endpoint, [3.0, 4.0])
    assert mate.ObstacleState(np.array([1.0, 2.0, 30.0])).radius == 30.0


def test_vector2d():
    v = Vector2D(norm=2.0, angle=190.0)
    assert v.angle == pytest.approx(-170.0)
    np.testing.assert_allclose(v.vector, 2.0 * np.array([math.cos(math.radians(190)), math.sin(math.radians(190))]))
    w = Vector2D(norm=-1.0, angle=0.0)
    assert w.norm == 1.0 and w.angle == -180.0
    u = Vector2D(vector=[3.0, 4.0], origin=[1.0, 1.0])
    np.testing.assert_allclose(u.endpoint, [4.0, 5.0])
    u.endpoint = [1.0, 3.0]
    np.testing.assert_allclose(u.vector, [0.0, 2.0])
    assert (u * 2).norm == pytest.approx(4.0) and (2 * u).norm == pytest.approx(4.0)
    np.testing.assert_allclose((u + Vector2D(vector=[1.0, 0.0])).vector, [1.0, 2.0])
    np.testing.assert_allclose((-u).vector, [0.0, -2.0])
    u *= 3
    assert isinstance(u, Vector2D) and u.norm == pytest.approx(6.0)
    assert Vector2D(vector=[1.0, 1.0]) == Vector2D(vector=[5.0, 5.0])       # compares angles only
    with pytest.raises(ValueError):
        Vector2D(norm=1.0)


@settings(max_examples=200, deadline=None)
@given(st.floats(-1e4, 1e4, allow_nan=False))
def test_normalize_angle_range(angle):
    wrapped = normalize_angle(angle)
    assert -180.0 <= wrapped < 180.0
    assert math.isclose(math.cos(math.radians(wrapped)), math.cos(math.radians(angle)), abs_tol=1e-9)
