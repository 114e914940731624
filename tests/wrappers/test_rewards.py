"""RepeatedRewardIndividualDone, AuxiliaryCameraRewards, AuxiliaryTargetRewards and the soft coverage score
(spec §8.5) on known worlds."""

from __future__ import annotations

import numpy as np
import pytest
from wrapper_scene import NC, NT, SCENE, ZERO_ACTION, make_env, set_scene

import mate
from mate.constants import WAREHOUSES
from mate.wrappers.auxiliary_rewards import weighted_rewards
from mate.wrappers.soft_coverage import SoftCoverage, camera_boundary, sight_profile

R0 = np.sqrt(30.0 * 1000.0 ** 2 / 60.0)
TARGETS = np.array(SCENE['targets'])


def polyline_score(camera_xy, orientation, viewing_angle, sight_range, target_xy, seen, max_range=1000.0):
    """Independent spec recipe for an unobstructed camera: rays of 16 points, end points and the integer-degree
    arc at max_range strictly inside the sector; +-distance / sector inradius."""
    left, right = orientation - viewing_angle / 2, orientation + viewing_angle / 2
    arc = [a for a in range(-180, 540) if left < a < right]
    ray = np.arange(16) / 16 * max_range
    phis = [left] * 16 + [left] + arc + [right] + [right] * 16
    rhos = list(ray) + [max_range] * (len(arc) + 2) + list(ray)
    points = np.array([[r * np.cos(np.radians(p)), r * np.sin(np.radians(p))] for p, r in zip(phis, rhos)])
    d = np.linalg.norm(points - (np.asarray(target_xy) - camera_xy), axis=1).min()
    inradius = sight_range / (1 + 1 / np.sin(np.radians(viewing_angle / 2))) if viewing_angle < 180 else sight_range / 2
    return (d if seen else -d) / inradius


def expected_scene_scores():
    cams = [((-500.0, 0.0), 0.0, 60.0, R0), ((500.0, 0.0), 90.0, 30.0, 1000.0)]
    seen = [[True, False, False], [False, True, False]]
    return np.array([[polyline_score(np.array(xy), o, va, r, TARGETS[t], seen[c][t]) for t in range(NT)]
                     for c, (xy, o, va, r) in enumerate(cams)])


# ---------------------------------------------------------------------------- RepeatedRewardIndividualDone

def test_repeated_reward_two_teams():
    env = make_env(wrappers=[mate.RepeatedRewardIndividualDone])
    set_scene(env, goals=[3, 0, 1], **SCENE)
    _, (camera_rewards, target_rewards), terminated, truncated, _ = env.step(ZERO_ACTION)
    assert len(camera_rewards) == NC and len(target_rewards) == NT
    assert camera_rewards == [-target_rewards[0]] * NC and len(set(target_rewards)) == 1
    assert terminated == ([False] * NC, [False] * NT) and truncated == ([False] * NC, [False] * NT)


def test_repeated_reward_target_done_at_destination():
    env = make_env(wrappers=[mate.WrapperSpec(mate.RepeatedRewardIndividualDone, target_done_at_destination=True)])
    set_scene(env, cameras=SCENE['cameras'], targets=[(925.0, -925.0), (500.0, 300.0), (0.0, 0.0)], goals=[3, 0, -1],
              obstacles=SCENE['obstacles'])
    _, _, terminated, _, _ = env.step(ZERO_ACTION)
    assert terminated == ([False, False], [True, False, False])      # target 0 delivered this step


def test_repeated_reward_single_team_inside_and_outside():
    greedy = mate.GreedyTargetAgent(seed=0)
    outside = make_env(wrappers=[mate.WrapperSpec(mate.MultiCamera, target_agent=greedy),
                                 mate.RepeatedRewardIndividualDone])
    inside = make_env(wrappers=[mate.RepeatedRewardIndividualDone,
                                mate.WrapperSpec(mate.MultiCamera, target_agent=greedy)])
    results = []
    for env in (outside, inside):
        env.reset(seed=3)
        results.append(env.step(np.zeros((NC, 2)))[1:4])
    assert results[0] == results[1]
    rewards, terminated, truncated = results[0]
    assert len(rewards) == NC and terminated == [False] * NC and truncated == [False] * NC
    target_team = make_env(wrappers=[
        mate.WrapperSpec(mate.MultiTarget, camera_agent=mate.GreedyCameraAgent(seed=0)),
        mate.WrapperSpec(mate.RepeatedRewardIndividualDone, target_done_at_destination=True)])
    set_scene(target_team, cameras=SCENE['cameras'], targets=[(925.0, -925.0), (500.0, 300.0), (0.0, 0.0)],
              goals=[3, 0, -1], obstacles=SCENE['obstacles'])
    target_team.opponent_observation = target_team.unwrapped.joint_observation()[0]
    _, rewards, terminated, _, _ = target_team.step(np.zeros((NT, 2)))
    assert len(rewards) == NT and terminated == [True, False, False]


# ---------------------------------------------------------------------------- soft coverage

def test_sight_profiles_are_exact():
    discs = np.array([[400.0, 0.0, 50.0]])
    center = np.zeros(2)
    np.testing.assert_allclose(sight_profile(center, [0.0, 90.0], 1000.0, discs), [350.0, 1000.0])
    np.testing.assert_allclose(sight_profile(center, [0.0, 90.0], 1000.0, discs, outer=True), [450.0, 1000.0])
    inside = sight_profile(center, [0.0, 45.0], 1000.0, np.array([[10.0, 0.0, 50.0]]))
    np.testing.assert_array_equal(inside, [0.0, 0.0])                 # a camera inside a disc is blind


def test_boundary_between_wraps_and_uses_inner_end_points():
    boundary = camera_boundary([0.0, 0.0], 1000.0, np.array([[-400.0, 0.0, 50.0]]))   # disc straight west
    phis, rhos = boundary.boundary_between(170.0, 190.0)
    assert phis[0] == 170.0 and phis[-1] == 190.0 and np.all(np.diff(phis) >= 0)
    assert 180.0 in phis                                               # the -180 sample, shifted by 360
    assert rhos[list(phis).index(180.0)] == pytest.approx(450.0)       # outer profile: far side of the disc
    boundary = camera_boundary([0.0, 0.0], 1000.0, np.array([[400.0, 0.0, 50.0]]))
    phis, rhos = boundary.boundary_between(-1.0, 1.0)
    along, off = 400 * np.cos(np.radians(1.0)), 400 * np.sin(np.radians(1.0))
    near, far = along - np.sqrt(50 ** 2 - off ** 2), along + np.sqrt(50 ** 2 - off ** 2)
    assert rhos[0] == pytest.approx(near) and rhos[-1] == pytest.approx(near)       # inner profile at the ends
    assert rhos[1:-1].min() >= far - 1e-9 and rhos[1:-1].max() == pytest.approx(450.0)   # outer samples between


def test_soft_coverage_matrix_matches_the_recipe():
    env = make_env()
    set_scene(env, goals=[3, 0, 1], **SCENE)
    np.testing.assert_allclose(SoftCoverage()(env), expected_scene_scores(), rtol=1e-12)


def test_soft_coverage_in_an_obstacle_shadow():
    env = make_env()
    set_scene(env, cameras=SCENE['cameras'], targets=[(-30.0, 0.0), (500.0, 300.0), (-300.0, 700.0)],
              obstacles=[(-100.0, 0.0, 50.0), (0.0, -800.0, 50.0)], goals=[3, 0, 1])
    assert not env.unwrapped.camera_target_view_mask[0, 0]          # hidden behind the disc
    scores = SoftCoverage()(env)
    # the outer boundary at 0 degrees is the far side of the disc, 450 from the camera; the target is at 470
    assert scores[0, 0] == pytest.approx(-20.0 / (R0 / 3.0))


# ---------------------------------------------------------------------------- AuxiliaryCameraRewards

DOCS = {'raw_reward': 1, 'coverage_rate': 1, 'soft_coverage_score': 1, 'baseline': -2}


def camera_env(**kwargs):
    env = make_env(wrappers=[mate.RepeatedRewardIndividualDone,
                             mate.WrapperSpec(mate.AuxiliaryCameraRewards, **kwargs)])
    set_scene(env, goals=[3, 0, 1], episode_step=5, **SCENE)
    return env


def test_auxiliary_camera_rewards_docs_coefficients():
    env = camera_env(coefficients=DOCS)
    _, (camera_rewards, target_rewards), _, _, (camera_infos, _) = env.step(ZERO_ACTION)
    scores = expected_scene_scores()
    soft = [scores[0, 0], scores[1, 1]]                                # each camera sees one target
    raw = camera_infos[0]['raw_reward']
    for c, info in enumerate(camera_infos):
        expected = raw + 2 / 3 + soft[c] - 2
        assert camera_rewards[c] == pytest.approx(expected, rel=1e-12)
        assert info['reward'] == camera_rewards[c]
        assert info['soft_coverage_score'] == pytest.approx(soft[c], rel=1e-12)
        assert info['auxiliary_reward_coverage_rate'] == pytest.approx(2 / 3)
        assert info['reward_coefficient_baseline'] == -2.0
        assert info['auxiliary_reward_baseline'] == 1.0
    assert target_rewards == [-raw] * NT                               # the target side is untouched


def test_auxiliary_camera_rewards_reductions_and_callables():
    coefficients = {'num_tracked': 1.0, 'baseline': 0.5}
    per_camera = [1.5, 1.5]
    for reduction, shared in (('none', None), ('sum', 3.0), ('mean', 1.5), ('max', 1.5), ('min', 1.5)):
        env = camera_env(coefficients=coefficients, reduction=reduction)
        _, (rewards, _), _, _, (infos, _) = env.step(ZERO_ACTION)
        assert rewards == (per_camera if shared is None else [shared] * NC)
        assert ('shared_reward' in infos[0]) == (shared is not None)
    calls = []

    def coefficient(index, episode_id, episode_step, raw_reward, value):
        calls.append((index, episode_id, episode_step, value))
        return float(index + 1)

    env = camera_env(coefficients={'num_tracked': coefficient, 'coverage_rate': 3})
    # camera 1 sees target 1 only; make camera 0 see two targets by moving target 2 in front of it
    set_scene(env, goals=[3, 0, 1], episode_step=5, cameras=SCENE['cameras'], obstacles=SCENE['obstacles'],
              targets=[(0.0, 0.0), (500.0, 300.0), (0.0, 100.0)])
    _, (rewards, _), _, _, (infos, _) = env.step(ZERO_ACTION)
    assert calls == [(0, 0, 6, 2), (1, 0, 6, 1)]                       # first episode: id 0
    assert rewards == [1 * 2 + 3 * 1.0, 2 * 1 + 3 * 1.0]                 # coverage rate 1: all three targets seen
    assert infos[1]['reward_coefficient_num_tracked'] == 2.0
    env.reset(seed=0)
    assert env.episode_id == 1


def test_camera_soft_score_when_nothing_is_seen():
    env = make_env(wrappers=[mate.RepeatedRewardIndividualDone,
                             mate.WrapperSpec(mate.AuxiliaryCameraRewards, coefficients={'soft_coverage_score': 1})])
    set_scene(env, cameras=SCENE['cameras'], targets=[(-30.0, 0.0), (500.0, 300.0), (-300.0, 700.0)],
              obstacles=[(-100.0, 0.0, 50.0), (0.0, -800.0, 50.0)], goals=[3, 0, 1])
    _, (rewards, _), _, _, _ = env.step(ZERO_ACTION)
    matrix = env.soft_coverage_score_matrix
    assert rewards[0] == pytest.approx(np.tanh(matrix[0].max()))
    assert -1.0 < rewards[0] <= 0.0
    assert rewards[1] == pytest.approx(matrix[1, 1])


# ---------------------------------------------------------------------------- AuxiliaryTargetRewards

def target_env(coefficients, reduction='none'):
    return make_env(wrappers=[mate.RepeatedRewardIndividualDone,
                              mate.WrapperSpec(mate.AuxiliaryTargetRewards, coefficients=coefficients,
                                               reduction=reduction)])


def test_auxiliary_target_rewards_components():
    keys = ('normalized_goal_distance', 'sparse_delivery', 'soft_coverage_score', 'is_tracked', 'is_colliding',
            'baseline', 'coverage_rate', 'raw_reward')
    env = target_env({key: 1.0 for key in keys})
    set_scene(env, goals=[3, -1, -1], empty_bits=[[0, 0, 0, 0], [1, 1, 0, 0], [1, 1, 1, 1]], **SCENE)
    _, (camera_rewards, rewards), _, _, (_, infos) = env.step(ZERO_ACTION)
    wd = np.maximum(np.linalg.norm(TARGETS[:, None] - WAREHOUSES[None], axis=-1) - 75.0, 0.0)
    goal = [wd[0, 3] / 2000, min(wd[1, 2], wd[1, 3]) / 2000, 0.5]
    scores = expected_scene_scores()
    soft = [scores[0, 0], scores[1, 1], np.tanh(scores[:, 2].max())]
    tracked = [True, True, False]
    for t, info in enumerate(infos):
        assert info['normalized_goal_distance'] == pytest.approx(goal[t], rel=1e-12)
        assert info['soft_coverage_score'] == pytest.approx(soft[t], rel=1e-12)
        assert info['is_tracked'] == tracked[t] and info['is_colliding'] is False
        assert info['sparse_delivery'] == 0.0
        expected = goal[t] + soft[t] + tracked[t] + 1.0 + 2 / 3 + info['raw_reward']
        assert rewards[t] == pytest.approx(expected, rel=1e-12)
    assert camera_rewards == [-infos[0]['raw_reward']] * NC


def test_auxiliary_target_rewards_delivery_collision_and_min():
    env = target_env({'sparse_delivery': 100.0, 'is_colliding': -1.0}, reduction='min')
    set_scene(env, cameras=SCENE['cameras'], targets=[(925.0, -925.0), (500.0, 300.0), (995.0, 0.0)],
              goals=[3, 0, -1], obstacles=SCENE['obstacles'])
    action = (ZERO_ACTION[0], np.array([[0.0, 0.0], [0.0, 0.0], [20.0, 0.0]]))
    _, (_, rewards), _, _, (_, infos) = env.step(action)
    assert [info['reward'] for info in infos] == [100.0, 0.0, -1.0]
    assert rewards == [-1.0] * NT and infos[0]['shared_reward'] == -1.0


def test_weighted_rewards_on_batches():
    components = {'a': np.array([[1.0, 2.0], [3.0, 4.0]]), 'b': np.ones((2, 2))}
    np.testing.assert_allclose(weighted_rewards(components, {'a': 2.0, 'b': -1.0}), [[1, 3], [5, 7]])
