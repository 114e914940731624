"""Environment IDs, `mate.make` and the Gymnasium registration (spec §7.2, §7.4; decisions.md)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import mate

PRESETS = ['1v1-0', '1v1-9', '1v2-0', '1v2-9', '2v2-0', '2v2-9', '2v4-0', '2v4-9', '4v2-0', '4v2-9',
           '4v4-0', '4v4-9', '4v8-0', '4v8-9', '8v8-0', '8v8-9', 'Navigation']


def _counts(env):
    return env.num_cameras, env.num_targets, env.num_obstacles


def test_every_preset_has_an_id():
    ids = set(mate.registered_ids())
    expected = {f'MATE-{preset}-v0' for preset in PRESETS} | {'MultiAgentTracking-v0', 'MATE-v0'}
    assert expected <= ids
    for env_id in expected:
        assert env_id in gymnasium.registry, env_id


@pytest.mark.parametrize('preset', PRESETS)
def test_preset_ids_build_their_preset(preset):
    env = mate.make(f'MATE-{preset}-v0')
    assert isinstance(env.unwrapped, mate.MultiAgentTracking)
    expected = mate.read_config(f'MATE-{preset}')
    assert env.config == expected


@pytest.mark.parametrize('env_id', ['MultiAgentTracking-v0', 'MATE-v0'])
def test_default_ids_use_4v8_9(env_id):
    env = mate.make(env_id)
    assert _counts(env) == (4, 8, 9)
    assert env.config == mate.read_config('MATE-4v8-9')


def test_config_argument_replaces_the_preset_of_the_id():
    assert _counts(mate.make('MATE-4v8-9-v0', config='MATE-4v2-9')) == (4, 2, 9)
    assert _counts(mate.make('MATE-4v8-9-v0', config='MATE-8v8-0.yaml')) == (8, 8, 0)
    assert _counts(mate.make('MultiAgentTracking-v0', config='MATE-1v1-0')) == (1, 1, 0)
    custom = mate.read_config('MATE-2v2-9')
    assert _counts(mate.make('MATE-Navigation-v0', config=custom)) == (2, 2, 9)


def test_keyword_overrides_deep_merge():
    env = mate.make('MATE-4v8-9-v0', reward_type='sparse', camera={'rotation_step': 10.0},
                    obstacle={'transmittance': 0.5})
    assert env.config['reward_type'] == 'sparse'
    assert env.camera_rotation_step == 10.0
    assert env.camera_action_space.high.tolist() == [10.0, 2.5]
    # untouched keys of the same section are kept
    assert env.camera_min_viewing_angle == 30 and env.camera_max_sight_range == 1500
    assert _counts(env) == (4, 8, 9)
    assert env.obstacle_transmittance == 0.5
    assert env.config['obstacle']['radius_random_range'] == mate.read_config('MATE-4v8-9')['obstacle'][
        'radius_random_range']


def test_keyword_overrides_on_top_of_a_config_argument():
    env = mate.make('MultiAgentTracking-v0', config='MATE-4v2-9', target={'step_size': 10.0})
    assert _counts(env) == (4, 2, 9)
    assert env.target_step_size == 10.0 and env.target_sight_range == 500
    assert env.freight_scale == 200


def test_overrides_without_any_config_start_empty():
    """Q8 of the spec, kept on purpose: with no config, overrides do not start from the default file."""
    with pytest.raises(ValueError):
        mate.make('MultiAgentTracking-v0', reward_type='sparse')


@pytest.mark.parametrize('bad_id, suggestion', [('MATE-4v8-8-v0', 'MATE-4v8-9-v0'),
                                                ('MultiAgentTracking-v1', 'MultiAgentTracking-v0'),
                                                ('MATE-navigation-v0', 'MATE-Navigation-v0')])
def test_unknown_id_raises_with_a_suggestion(bad_id, suggestion):
    with pytest.raises(ValueError) as error:
        mate.make(bad_id)
    assert bad_id in str(error.value)
    assert suggestion in str(error.value)


def test_gymnasium_make():
    env = gymnasium.make('MATE-4v8-9-v0')
    assert isinstance(env.unwrapped, mate.MultiAgentTracking)
    assert _counts(env.unwrapped) == (4, 8, 9)
    (cam_obs, tgt_obs), _ = env.reset(seed=0)
    assert cam_obs.shape == (4, 126) and tgt_obs.shape == (8, 131)
    (cam_obs, tgt_obs), (cam_r, tgt_r), terminated, truncated, _ = env.step(env.action_space.sample())
    assert cam_r == -tgt_r and not terminated and not truncated
    other = gymnasium.make('MATE-4v8-9-v0', config='MATE-4v2-0')
    assert _counts(other.unwrapped) == (4, 2, 0)
    direct = mate.make('MATE-4v8-9-v0')
    np.testing.assert_array_equal(direct.reset(seed=0)[0][1], env.reset(seed=0)[0][1])


class _Tag(gymnasium.Wrapper):
    def __init__(self, env, label, log):
        super().__init__(env)
        self.label = label
        log.append(label)


def test_wrappers_are_applied_in_order():
    log = []
    env = mate.make('MATE-4v2-0-v0', wrappers=[lambda e: _Tag(e, 'first', log),
                                                mate.WrapperSpec(_Tag, 'second', log),
                                                lambda e: _Tag(e, 'third', log)])
    assert log == ['first', 'second', 'third']
    assert env.label == 'third' and env.env.label == 'second' and env.env.env.label == 'first'
    assert isinstance(env.unwrapped, mate.MultiAgentTracking)
    (cam_obs, _), _ = env.reset(seed=0)
    assert cam_obs.shape == (4, 60)


def test_wrappers_with_gymnasium_make_and_bad_wrappers():
    log = []
    env = gymnasium.make('MATE-4v2-0-v0', wrappers=(mate.WrapperSpec(_Tag, 'only', log),))
    assert log == ['only'] and isinstance(env.unwrapped, mate.MultiAgentTracking)
    with pytest.raises(TypeError):
        mate.make('MATE-4v2-0-v0', wrappers=['not a wrapper'])
    with pytest.raises(TypeError):
        mate.WrapperSpec(42)
