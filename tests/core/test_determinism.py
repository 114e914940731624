"""Seeding and determinism (decisions.md "Seeding"): same seed, same episode, batched or not."""

from __future__ import annotations

import numpy as np
import pytest

import mate
from mate.core import engine
from mate.core.params import params_from_config
from mate.core.world import empty_world

PRESET = 'MATE-4v8-9'
STEPS = 200


def _actions(seed, steps, rows, num_cameras, num_targets, scale=1.5):
    """Random joint actions (steps, rows, N, 2), somewhat beyond the action bounds."""
    rng = np.random.default_rng(seed)
    cam = rng.uniform(-1, 1, (steps, rows, num_cameras, 2)) * np.array([5.0, 2.5]) * scale
    tgt = rng.uniform(-1, 1, (steps, rows, num_targets, 2)) * 20.0 * scale
    return cam, tgt


def _run_env(env, seed, cam_actions, tgt_actions):
    """Reset with `seed`, play the given actions; return the list of per-step outputs."""
    (cam_obs, tgt_obs), _ = env.reset(seed=seed)
    trace = [(cam_obs, tgt_obs, 0.0, 0.0, False, False)]
    for cam, tgt in zip(cam_actions, tgt_actions):
        (cam_obs, tgt_obs), (cam_r, tgt_r), terminated, truncated, _ = env.step((cam, tgt))
        trace.append((cam_obs, tgt_obs, cam_r, tgt_r, terminated, truncated))
    return trace


def _assert_same_trace(a, b):
    assert len(a) == len(b)
    for k, (x, y) in enumerate(zip(a, b)):
        np.testing.assert_array_equal(x[0], y[0], err_msg=f'camera obs at step {k}')
        np.testing.assert_array_equal(x[1], y[1], err_msg=f'target obs at step {k}')
        assert x[2:] == y[2:], f'rewards/flags at step {k}'


@pytest.fixture(scope='module')
def actions():
    cam, tgt = _actions(11, STEPS, 1, 4, 8)
    return cam[:, 0], tgt[:, 0]


def test_same_seed_same_episode(actions):
    first = _run_env(mate.make(f'{PRESET}-v0'), 7, *actions)
    second = _run_env(mate.make(f'{PRESET}-v0'), 7, *actions)
    _assert_same_trace(first, second)
    # the episode is not trivial: cameras tracked someone and rewards were paid
    assert any(step[3] != 0.0 for step in first)


def test_same_env_reseeded_repeats_itself(actions):
    env = mate.make(f'{PRESET}-v0')
    first = _run_env(env, 21, *actions)
    second = _run_env(env, 21, *actions)
    _assert_same_trace(first, second)


def test_different_seeds_differ(actions):
    env = mate.make(f'{PRESET}-v0')
    (cam_a, tgt_a), _ = env.reset(seed=1)
    (cam_b, tgt_b), _ = env.reset(seed=2)
    assert not np.array_equal(cam_a, cam_b)
    assert not np.array_equal(tgt_a, tgt_b)
    trace_a = _run_env(env, 1, *actions)
    trace_b = _run_env(env, 2, *actions)
    assert any(not np.array_equal(a[1], b[1]) for a, b in zip(trace_a[1:], trace_b[1:]))


def test_two_envs_in_one_process_are_independent(actions):
    """Interleaving the steps of two environments does not change either episode."""
    alone = _run_env(mate.make(f'{PRESET}-v0'), 5, *actions)
    env_a, env_b = mate.make(f'{PRESET}-v0'), mate.make(f'{PRESET}-v0')
    env_a.reset(seed=5)
    env_b.reset(seed=6)
    for k, (cam, tgt) in enumerate(zip(*actions)):
        (cam_obs, tgt_obs), *_ = env_a.step((cam, tgt))
        env_b.step((-cam, -tgt))
        np.testing.assert_array_equal(tgt_obs, alone[k + 1][1])


def test_reset_without_seed_continues_the_stream():
    env = mate.make(f'{PRESET}-v0')
    env.reset(seed=3)
    (cam_1, tgt_1), _ = env.reset()
    (cam_2, tgt_2), _ = env.reset()
    assert not np.array_equal(tgt_1, tgt_2)
    other = mate.make(f'{PRESET}-v0')
    other.reset(seed=3)
    (cam_1b, tgt_1b), _ = other.reset()
    (cam_2b, tgt_2b), _ = other.reset()
    np.testing.assert_array_equal(cam_1, cam_1b)
    np.testing.assert_array_equal(tgt_1, tgt_1b)
    np.testing.assert_array_equal(cam_2, cam_2b)
    np.testing.assert_array_equal(tgt_2, tgt_2b)


def test_steps_consume_the_stream_like_resets_do():
    """reset(seed) -> k random steps -> reset() is reproducible."""
    cam, tgt = _actions(3, 10, 1, 4, 8)
    outcomes = []
    for _ in range(2):
        env = mate.make(f'{PRESET}-v0')
        env.reset(seed=9)
        for c, t in zip(cam[:, 0], tgt[:, 0]):
            env.step((c, t))
        outcomes.append(env.reset()[0][1])
    np.testing.assert_array_equal(outcomes[0], outcomes[1])


def test_fresh_envs_without_seed_are_seeded_from_entropy():
    a, b = mate.make(f'{PRESET}-v0'), mate.make(f'{PRESET}-v0')
    (_, tgt_a), _ = a.reset()
    (_, tgt_b), _ = b.reset()
    assert not np.array_equal(tgt_a, tgt_b)


@pytest.mark.parametrize('rows, chunks', [(5, 1), (40, 1), (67, 2)])
def test_batch_equals_single_envs(rows, chunks, monkeypatch):
    """Row i of a batch seeded [s_0 .. s_{B-1}] plays exactly like a single env reset with s_i.

    Small batches run on the calling thread; large ones are split into chunks that run in
    parallel. The 67-row case lowers the split threshold so that it runs as two uneven chunks
    on the thread pool."""
    if chunks > 1:
        monkeypatch.setattr(engine, 'NUM_THREADS', chunks)
        monkeypatch.setattr(engine, 'PARALLEL_MIN_ROWS', rows // chunks)
    assert max(1, engine._num_workers(rows)) == chunks
    steps = 60 if rows > 10 else STEPS
    params = params_from_config(mate.read_config(PRESET))
    counts = (params.num_cameras, params.num_targets, params.num_obstacles)
    seeds = [1000 + 17 * i for i in range(rows)]
    world = empty_world(params, rows)
    cam_obs = np.zeros((rows, params.num_cameras, mate.camera_observation_dim(*counts)))
    tgt_obs = np.zeros((rows, params.num_targets, mate.target_observation_dim(*counts)))
    everything = np.ones(rows, bool)
    engine.seed_rows(world, everything, seeds)
    engine.reset(params, world, everything, cam_obs, tgt_obs)
    cam_actions, tgt_actions = _actions(rows, steps, rows, params.num_cameras, params.num_targets)

    batch_trace = [[(cam_obs[i].copy(), tgt_obs[i].copy(), 0.0) for i in range(rows)]]
    for k in range(steps):
        engine.step(params, world, cam_actions[k], tgt_actions[k], cam_obs, tgt_obs)
        batch_trace.append([(cam_obs[i].copy(), tgt_obs[i].copy(), float(world.target_reward[i]))
                            for i in range(rows)])

    env = mate.make(f'{PRESET}-v0')
    for i, seed in enumerate(seeds):
        (cam, tgt), _ = env.reset(seed=seed)
        np.testing.assert_array_equal(cam, batch_trace[0][i][0], err_msg=f'row {i} after reset')
        np.testing.assert_array_equal(tgt, batch_trace[0][i][1], err_msg=f'row {i} after reset')
        for k in range(steps):
            (cam, tgt), (_, reward), *_ = env.step((cam_actions[k, i], tgt_actions[k, i]))
            np.testing.assert_array_equal(cam, batch_trace[k + 1][i][0], err_msg=f'row {i} step {k}')
            np.testing.assert_array_equal(tgt, batch_trace[k + 1][i][1], err_msg=f'row {i} step {k}')
            assert reward == batch_trace[k + 1][i][2], f'row {i} step {k}'


def test_partial_reset_leaves_other_rows_alone():
    params = params_from_config(mate.read_config(PRESET))
    counts = (params.num_cameras, params.num_targets, params.num_obstacles)
    rows = 4
    world = empty_world(params, rows)
    cam_obs = np.zeros((rows, params.num_cameras, mate.camera_observation_dim(*counts)))
    tgt_obs = np.zeros((rows, params.num_targets, mate.target_observation_dim(*counts)))
    everything = np.ones(rows, bool)
    engine.seed_rows(world, everything, [1, 2, 3, 4])
    engine.reset(params, world, everything, cam_obs, tgt_obs)
    cam_actions, tgt_actions = _actions(0, 5, rows, params.num_cameras, params.num_targets)
    for k in range(5):
        engine.step(params, world, cam_actions[k], tgt_actions[k], cam_obs, tgt_obs)
    before = {name: getattr(world, name).copy() for name in world._fields}
    obs_before = tgt_obs.copy()
    mask = np.array([False, True, False, True])
    engine.seed_rows(world, mask, [2, 40])
    engine.reset(params, world, mask, cam_obs, tgt_obs)
    for name in world._fields:
        np.testing.assert_array_equal(getattr(world, name)[~mask], before[name][~mask], err_msg=name)
    np.testing.assert_array_equal(tgt_obs[~mask], obs_before[~mask])
    assert np.all(world.episode_step[mask] == 0)
    # row 1 re-seeded with its original seed replays its reset
    env = mate.make(f'{PRESET}-v0')
    (_, tgt), _ = env.reset(seed=2)
    np.testing.assert_array_equal(tgt_obs[1], tgt)
