"""Heuristic camera (score table, joint assignment, controller protocol) and heuristic target
(drift away from sector incentres) (spec agents-and-wrappers.md §7.6-7.7)."""

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
from mate.agents.heuristic import (
    _nearest_grid_point,
    _nearest_grid_point_brute_force,
    calculate_scores,
    joint_assignment,
)

MESH, GRID, SCORES = calculate_scores(1500.0, 30.0)


# ---------------------------------------------------------------------------- score table

def test_score_table_layout():
    assert MESH.shape == (756, 3) and GRID.shape == (2952, 2) and SCORES.shape == (2952, 756)
    np.testing.assert_allclose(MESH[0], [-180.0, 30.0, 1500.0])
    np.testing.assert_allclose(MESH[1, :2], [-170.0, 30.0])               # orientation varies fastest
    np.testing.assert_allclose(MESH[36, :2], [-180.0, 30.0 + 7.5])       # then the viewing angle
    np.testing.assert_allclose(MESH[-1], [170.0, 180.0, 1500.0 * math.sqrt(30.0 / 180.0)])
    np.testing.assert_allclose(GRID[1], [-37.5, 0.0], atol=1e-9)          # bearing -180, second distance
    np.testing.assert_allclose(np.hypot(*GRID[41 + 40]), 1500.0)         # bearing -175, last distance
    assert not SCORES.flags.writeable


def test_scores_live_inside_the_sector_and_peak_at_the_incentre():
    assert SCORES.min() == 0.0 and 0.49 < SCORES.max() <= 0.5
    rho = np.hypot(GRID[:, 0], GRID[:, 1])
    phi = np.degrees(np.arctan2(GRID[:, 1], GRID[:, 0]))
    for pose in (0, 100, 400, 755):
        o, theta, reach = MESH[pose]
        delta = np.abs((phi - o + 180.0) % 360.0 - 180.0)
        outside = (rho > reach + 1e-9) | (delta > theta / 2 + 1e-9)
        assert np.all(SCORES[outside, pose] == 0.0)
    pose = int(np.flatnonzero((MESH[:, 0] == 0.0) & (MESH[:, 1] == 180.0))[0])
    best = GRID[np.argmax(SCORES[:, pose])]                               # half-disc facing east
    assert best[0] == pytest.approx(MESH[pose, 2] / 2, abs=40.0) and abs(best[1]) < 1e-6


@settings(max_examples=300, deadline=None)
@given(st.floats(-1700.0, 1700.0), st.floats(-1700.0, 1700.0))
def test_nearest_grid_point_is_exact(dx, dy):
    fast, slow = _nearest_grid_point(GRID, dx, dy), _nearest_grid_point_brute_force(GRID, dx, dy)
    distance = lambda g: (GRID[g, 0] - dx) ** 2 + (GRID[g, 1] - dy) ** 2
    assert fast == slow or distance(fast) == distance(slow)


# ---------------------------------------------------------------------------- joint assignment

def reference_assignment(cameras, targets, permutations, rotation_step, zooming_step):
    """The spec's algorithm written plainly (numpy argmax/argmin, Python tuple comparison)."""
    n, m, poses = len(cameras), len(targets), SCORES.shape[1]
    summed, hits, in_reach = np.zeros((n, poses)), np.zeros((n, poses, m), dtype=bool), np.zeros(n, dtype=bool)
    for c, cam in enumerate(cameras):
        for t, (tx, ty) in enumerate(targets):
            if math.hypot(tx - cam[0], ty - cam[1]) <= cam[6]:
                in_reach[c] = True
                row = np.argmin(((GRID - [tx - cam[0], ty - cam[1]]) ** 2).sum(axis=1))
                summed[c] += SCORES[row]
                hits[c, :, t] = SCORES[row] > 0
    candidates = []
    for order in permutations:
        covered, total, cost, chosen = np.zeros(m, dtype=bool), 0.0, 0.0, []
        for c in order:
            pose = int(np.argmax(summed[c] + (hits[c] & ~covered).sum(axis=1)))
            orientation = math.degrees(math.atan2(cameras[c][4], cameras[c][3]))
            cost += max(abs(MESH[pose, 0] - orientation) / rotation_step,
                        abs(MESH[pose, 1] - cameras[c][5]) / zooming_step)
            covered |= hits[c, pose]
            total += summed[c, pose]
            chosen.append(pose)
        total += covered.sum()
        candidates.append((total, -cost, tuple(order), tuple(chosen)))
    best = max(candidates)
    return list(best[2]), list(best[3]), in_reach


@pytest.mark.parametrize('seed', range(12))
def test_joint_assignment_matches_the_plain_algorithm(seed):
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 5)), int(rng.integers(0, 9))
    cameras = np.array([camera_private(*rng.uniform(-800, 800, 2), orientation=rng.uniform(-180, 180),
                                       viewing_angle=rng.uniform(30, 180)) for _ in range(n)])
    targets = rng.uniform(-1000, 1000, (m, 2)).reshape(m, 2)
    permutations = np.argsort(rng.random((32, n)), axis=1)
    order, poses, in_reach = joint_assignment(cameras, targets, GRID, SCORES, MESH, permutations, 5.0, 2.5)
    expected_order, expected_poses, expected_reach = reference_assignment(cameras, targets, permutations, 5.0, 2.5)
    assert order.tolist() == expected_order and poses.tolist() == expected_poses
    assert in_reach.tolist() == expected_reach.tolist()


def test_a_single_camera_faces_its_target():
    cameras = np.array([camera_private(0.0, 0.0, orientation=0.0, viewing_angle=90.0)])
    targets = np.array([[250.0, 433.0]])                                 # bearing 60, distance 500
    _, poses, in_reach = joint_assignment(cameras, targets, GRID, SCORES, MESH, np.zeros((32, 1), np.int64), 5., 2.5)
    assert in_reach[0] and MESH[poses[0], 0] == 60.0


def test_two_cameras_split_two_targets():
    cameras = np.array([camera_private(-500.0, 0.0, orientation=0.0), camera_private(500.0, 0.0, orientation=180.0)])
    targets = np.array([[-500.0, 600.0], [500.0, -600.0]])
    rng = np.random.default_rng(0)
    order, poses, _ = joint_assignment(cameras, targets, GRID, SCORES, MESH,
                                       np.argsort(rng.random((32, 2)), axis=1), 5.0, 2.5)
    orientation = {int(c): MESH[p, 0] for c, p in zip(order, poses)}
    assert orientation[0] == 90.0 and orientation[1] == -90.0


# ---------------------------------------------------------------------------- camera agents

def test_controller_protocol_on_the_env():
    env = mate.make('MATE-4v8-9-v0')
    for seed in range(50):                                   # a start where some camera sees a target
        (camera_obs, _), _ = env.reset(seed=seed)
        if env.coverage_rate > 0:
            break
    cameras = mate.HeuristicCameraAgent(seed=0).spawn(4)
    mate.group_reset(cameras, camera_obs)
    mate.group_observe(cameras, camera_obs)
    mate.group_communicate(env, cameras)
    controller = next(c for c in cameras if c.index == 0)
    others = [c for c in cameras if c.index != 0]
    assert controller.is_controller and len(controller.last_requests) == 3
    assert all(np.array_equal(m.content, camera_obs[m.sender]) for m in controller.last_requests)
    goals = controller.joint_goal_state
    assert goals and all(len(goal) == 2 for goal in goals.values())
    for camera in others:
        if camera.index in goals:
            assert [m.content for m in camera.last_responses] == [goals[camera.index]]
        else:
            assert camera.last_responses == ()
    for camera, observation in zip(cameras, camera_obs):
        action = camera.act(observation)
        goal = goals.get(camera.index)
        if goal is not None:
            state = camera.state
            rotation = (goal[0] - state.orientation + 180.0) % 360.0 - 180.0
            np.testing.assert_allclose(action, np.clip([rotation, goal[1] - state.viewing_angle],
                                                       camera.action_space.low, camera.action_space.high))


def test_a_camera_without_answer_plans_alone():
    own = camera_private(0.0, 0.0, orientation=0.0, viewing_angle=90.0)
    obs = camera_observation(own, index=2, targets={0: [0.0, 700.0, 500.0, 0.0]})
    agent = mate.HeuristicCameraAgent(seed=0)
    agent.reset(obs)
    agent.observe(obs)
    assert agent.send_requests()[0].recipient == 0
    agent.receive_requests([])
    assert agent.send_responses() == ()
    agent.receive_responses([])
    assert agent.act(obs)[0] == 5.0                                  # turns towards the target (bearing 90)
    empty = camera_observation(own, index=2)
    agent.observe(empty)
    agent.receive_responses([])
    actions = {tuple(agent.act(empty)) for _ in range(100)}
    assert (5.0, agent.prev_action[1]) in actions or len(actions) > 1  # idle: previous or random actions


def test_get_joint_goal_state_takes_state_views():
    agent = mate.HeuristicCameraAgent(seed=0)
    agent.reset(camera_observation(camera_private(0.0, 0.0), index=0))
    cameras = [mate.CameraStatePrivate(np.array(camera_private(0.0, 0.0)), index=0),
               mate.CameraStatePrivate(np.array(camera_private(3000.0, 3000.0)), index=3)]
    targets = [mate.TargetStatePublic(np.array([0.0, -500.0, 500.0, 0.0]), index=1)]
    goals = agent.get_joint_goal_state(cameras, targets)
    assert list(goals) == [0] and goals[0][0] == -90.0


# ---------------------------------------------------------------------------- targets

def drifted(camera_values, location=(0.0, 0.0), seed=0):
    """(greedy action, heuristic action) of twin targets seeing one camera."""
    own = target_private(*location, goal_bits=(1, 0, 0, 0))
    obs = target_observation(own, cameras={1: camera_values})
    greedy, heuristic = mate.GreedyTargetAgent(seed=seed), mate.HeuristicTargetAgent(seed=seed)
    greedy.reset(obs)
    heuristic.reset(obs)
    return greedy.act(obs), heuristic.act(obs)


def expected_drift(camera_values, location, step=20.0, noise_scale=0.5):
    x, y, _, rx, ry, theta = camera_values
    reach = math.hypot(rx, ry)
    centre = reach / (1.0 + math.sin(math.radians(min(theta / 2, 90.0))))
    incentre = np.array([x, y]) + centre * np.array([rx, ry]) / reach
    drift = np.asarray(location) - incentre
    length = np.linalg.norm(drift)
    return drift * min(1.0, step * noise_scale / length)


def test_target_inside_a_sector_drifts_away_from_its_incentre():
    camera_values = camera_public(-600.0, -600.0, orientation=45.0, viewing_angle=60.0)
    greedy, heuristic = drifted(camera_values, location=(0.0, 0.0))
    drift = expected_drift(camera_values, (0.0, 0.0))
    assert np.dot(greedy, drift) >= 0
    np.testing.assert_allclose(heuristic, np.clip(greedy + drift, -20.0, 20.0))


def test_target_outside_every_sector_acts_greedily():
    camera_values = camera_public(-600.0, -600.0, orientation=45.0 - 60.0, viewing_angle=60.0)  # target 60 deg ccw
    greedy, heuristic = drifted(camera_values)
    np.testing.assert_array_equal(greedy, heuristic)


def test_signed_angle_test_lets_clockwise_targets_pass():
    camera_values = camera_public(-600.0, -600.0, orientation=45.0 + 100.0, viewing_angle=60.0)  # target 100 deg cw
    greedy, heuristic = drifted(camera_values)
    drift = expected_drift(camera_values, (0.0, 0.0))
    assert np.dot(greedy, drift) >= 0
    np.testing.assert_allclose(heuristic, np.clip(greedy + drift, -20.0, 20.0))
