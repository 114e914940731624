"""Statistics right after reset compared with the original (spec §11.2, §11.4 protocol B; the original's
ground-truth figures, copied into this file): construct, reset(seed=0), then 1999 more reset() calls."""

from __future__ import annotations

import numpy as np
import pytest

import mate

RESETS = 2000


def _reset_statistics(env_id):
    env = mate.make(env_id)
    env.reset(seed=0)
    coverage, cam_obstacle, tgt_camera, cam_camera, cargo = [], [], [], [], []
    for k in range(RESETS):
        if k:
            env.reset()
        coverage.append(env.coverage_rate)
        cam_obstacle.append(env.camera_obstacle_view_mask.mean() if env.num_obstacles else np.nan)
        tgt_camera.append(env.target_camera_view_mask.mean())
        cam_camera.append(env.camera_camera_view_mask.mean())
        cargo.append(env.awaiting_cargo_counts.sum())
    return {name: np.asarray(values) for name, values in
            dict(coverage=coverage, cam_obstacle=cam_obstacle, tgt_camera=tgt_camera, cam_camera=cam_camera,
                 cargo=cargo).items()}


@pytest.fixture(scope='module')
def stats_4v8_9():
    return _reset_statistics('MATE-4v8-9-v0')


@pytest.fixture(scope='module')
def stats_4v8_0():
    return _reset_statistics('MATE-4v8-0-v0')


def _within_standard_errors(values, reference, k=3.0):
    mean = values.mean()
    sem = values.std(ddof=1) / np.sqrt(len(values))
    assert abs(mean - reference) <= k * sem, f'mean {mean:.4f} (s.e.m. {sem:.4f}) vs original {reference}'


def test_coverage_after_reset_4v8_9(stats_4v8_9):
    _within_standard_errors(stats_4v8_9['coverage'], 0.1883)


def test_coverage_after_reset_4v8_0(stats_4v8_0):
    _within_standard_errors(stats_4v8_0['coverage'], 0.2313)


def test_flag_rates_after_reset_4v8_9(stats_4v8_9):
    assert stats_4v8_9['cam_obstacle'].mean() == pytest.approx(0.7483, abs=0.02)
    assert stats_4v8_9['tgt_camera'].mean() == pytest.approx(0.0019, abs=0.002)
    assert stats_4v8_9['cam_camera'].mean() == pytest.approx(0.2524, abs=0.02)


def test_flag_rates_after_reset_4v8_0(stats_4v8_0):
    assert stats_4v8_0['tgt_camera'].mean() == pytest.approx(0.0021, abs=0.002)
    assert stats_4v8_0['cam_camera'].mean() == pytest.approx(0.2535, abs=0.02)


def test_cargo_total_is_64_for_eight_targets(stats_4v8_9, stats_4v8_0):
    assert np.all(stats_4v8_9['cargo'] == 64)
    assert np.all(stats_4v8_0['cargo'] == 64)


def test_cargo_totals_of_1v1_are_whole_batches():
    """1 target x 8 cargoes: batches repeat until every warehouse has something to send
    (spec Q6): 8 with P = 1 - 4 (3/4)^8 + 6 (1/2)^8 - 4 (1/4)^8 = 0.623 (measured 0.63)."""
    env = mate.make('MATE-1v1-0-v0')
    env.reset(seed=0)
    totals = []
    for k in range(500):
        if k:
            env.reset()
        totals.append(int(env.awaiting_cargo_counts.sum()))
        world = env.get_world()
        # the target's load at reset comes out of the generated total
        assert world['remaining_cargoes'].sum() + world['target_state'][:, 6:10].sum() == totals[-1]
    totals = np.asarray(totals)
    assert np.all(totals % 8 == 0) and np.all(totals >= 8)
    assert np.mean(totals == 8) == pytest.approx(0.63, abs=0.06)
    assert np.mean(totals == 16) == pytest.approx(0.34, abs=0.06)
    assert np.all(totals <= 64)


def test_initial_camera_orientation_and_viewing_angle_distribution():
    """Orientation: a multiple of the 5-degree rotation step; viewing angle uniform in [30, 180)."""
    env = mate.make('MATE-4v8-9-v0')
    env.reset(seed=0)
    phis, thetas = [], []
    for k in range(300):
        if k:
            env.reset()
        world = env.get_world()
        phis.extend(world['camera_orientation'])
        thetas.extend(world['camera_viewing_angle'])
    phis, thetas = np.asarray(phis), np.asarray(thetas)
    np.testing.assert_allclose(phis / 5.0, np.round(phis / 5.0), atol=1e-9)
    assert phis.min() >= -180 and phis.max() < 180
    assert len(np.unique(np.round(phis))) > 60           # most of the 72 values occur in 1200 draws
    assert thetas.min() >= 30 and thetas.max() < 180
    assert thetas.mean() == pytest.approx(105.0, abs=3.0)  # measured 104.6 on the original
