"""The configuration generator: camera placement quality and the files it writes."""

import numpy as np
import pytest

import mate
from mate.tools.generator import generate_config, place_cameras, write_config


def test_one_camera_sits_in_the_centre():
    placement = place_cameras(1, restarts=1)
    np.testing.assert_allclose(placement.points, [[0.0, 0.0]], atol=5.0)
    assert placement.covering_distance == pytest.approx(1000 * np.sqrt(2), rel=0.005)


@pytest.mark.slow
def test_four_cameras_cover_the_quadrants():
    placement = place_cameras(4, restarts=1)
    # the optimum puts one camera at the centre of each quadrant: covering distance 500 sqrt(2)
    assert placement.covering_distance == pytest.approx(500 * np.sqrt(2), rel=0.02)
    assert sorted(np.sign(placement.points).tolist()) == [[-1, -1], [-1, 1], [1, -1], [1, 1]]


@pytest.mark.slow
def test_generated_config_follows_the_rules_and_runs(tmp_path):
    config = generate_config(num_cameras=2, num_targets=3, num_obstacles=2, obstacle_transmittance=1.7, restarts=1)
    assert config['name'] == 'MultiAgentTracking(2v3, 2)'
    camera = config['camera']
    sight = camera['max_sight_range']
    assert camera['radius'] == pytest.approx(min(40.0, 0.1 * sight))
    for x_low, x_high, y_low, y_high in camera['location_random_range']:
        assert x_high - x_low == pytest.approx(40.0) and y_high - y_low == pytest.approx(40.0)
    assert config['target']['location_random_range'] == [[-500.0, 500.0, -500.0, 500.0]] * 3
    assert config['target']['sight_range'] == pytest.approx(sight / 2, abs=1e-3)
    assert config['obstacle']['transmittance'] == 1.0  # clipped into [0, 1]
    assert config['obstacle']['location_random_range'] == [[-1000.0, 1000.0, -1000.0, 1000.0]] * 2
    path = write_config(config, tmp_path / 'generated.yaml')
    env = mate.make('MultiAgentTracking-v0', config=str(path))
    env.reset(seed=0)
    assert (env.num_cameras, env.num_targets, env.num_obstacles) == (2, 3, 2)
    env.step(env.action_space.sample())


def test_sections_without_entities_are_dropped():
    config = generate_config(num_cameras=0, num_targets=2, num_obstacles=0)
    assert 'camera' not in config and 'obstacle' not in config


@pytest.mark.parametrize('kwargs, message', [
    ({'num_targets': 0}, 'num_targets must be an integer >= 1'),
    ({'num_cargoes_per_target': 3}, 'num_cargoes_per_target must be an integer >= 4'),
    ({'num_cameras': -1}, 'num_cameras must be an integer >= 0'),
])
def test_bad_arguments_are_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        generate_config(**kwargs)


def test_write_config_needs_a_yaml_suffix(tmp_path):
    with pytest.raises(ValueError, match='.yaml or .yml'):
        write_config(generate_config(num_cameras=0, num_targets=1), tmp_path / 'config.txt')
