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
                                                ('MATE-Navigaton-v0', 'MATE-Navigation-v0'),
                                                ('MATE-4v8-8', 'MATE-4v8-9')])
def test_unknown_id_raises_with_a_suggestion(bad_id, suggestion):
    """In the spelling given (an id or a preset name), on one line that lists the valid ids."""
    for make in (mate.make, lambda name: mate.make_vec(name, num_envs=2)):
        with pytest.raises(ValueError) as error:
            make(bad_id)
        message = str(error.value)
        assert bad_id in message and f"'{suggestion}'" in message and '\n' not in message
        assert 'Known ids: MultiAgentTracking-v0, MATE-v0, MATE-1v1-0-v0' in message and 'preset name' in message


# ----------------------------------------------------------------------------- both spellings of a game
# `mate.make` / `make_vec` took env ids ('MATE-2v4-0-v0') where `make_team_vec`, `score_policy`, PettingZoo and the
# command line took preset names ('MATE-2v4-0'); each now takes both (`mate.config.preset_name` resolves them).

@pytest.mark.parametrize('name', ['MATE-2v4-0', 'MATE-2v4-0-v0', 'mate-2v4-0', 'MATE-2v4-0.yaml'])
def test_make_and_make_vec_take_a_preset_name_or_an_id(name):
    expected = mate.read_config('MATE-2v4-0')
    assert mate.make(name).config == expected
    envs = mate.make_vec(name, num_envs=2)
    assert envs.config == expected and (envs.num_cameras, envs.num_targets) == (2, 4)
    assert mate.make(name, config='MATE-1v1-0').config == mate.read_config('MATE-1v1-0')   # config= still wins


def test_the_default_ids_keep_their_meaning_in_both_spellings():
    """'MATE-v0' and 'MultiAgentTracking-v0' have no preset of their own in `mate.make` (overrides start empty, as in
    the original); as a config name they stand for the default game, MATE-4v8-9."""
    for name in ('MATE-v0', 'mate-v0', 'MultiAgentTracking-v0'):
        assert mate.envs.registration.resolve_config(name) is None
        assert mate.read_config(name) == mate.read_config('MATE-4v8-9')
    assert mate.envs.registration.resolve_config('MATE') == 'MATE'
    with pytest.raises(ValueError):
        mate.make('mate-v0', reward_type='sparse')      # the empty start, whatever the case


def test_config_names_take_env_ids_everywhere(capsys):
    from mate.cli.main import main
    from mate.integrations import pettingzoo as mate_pz

    expected = mate.read_config('MATE-2v4-0')
    assert mate.read_config('MATE-2v4-0-v0') == expected
    assert mate.config.preset_path('MATE-2v4-0-v0') == mate.config.preset_path('MATE-2v4-0')
    team = mate.make_team_vec('MATE-2v4-0-v0', team='target', num_envs=2)
    assert team.vec.config == expected and team.single_observation_space.shape[0] == 4
    zoo = mate_pz.parallel_env(config='MATE-2v4-0-v0')
    assert zoo.env.config == expected
    still = lambda observations: np.zeros((*observations.shape[:2], 2))
    by_id = mate.score_policy(still, 'camera', 'MATE-2v4-0-v0', episodes=1, max_episode_steps=5)
    by_name = mate.score_policy(still, 'camera', 'MATE-2v4-0', episodes=1, max_episode_steps=5)
    assert by_id.absolute == by_name.absolute and by_id.reference_means == by_name.reference_means
    assert main(['evaluate', '--config', 'MATE-2v4-0-v0', '--episodes', '1', '--max-episode-steps', '5',
                 '--no-render']) == 0
    assert '(2 cameras, 4 targets, 0 obstacle)' in capsys.readouterr().out


@pytest.mark.parametrize('name, suggestion', [('MATE-4v8-8-v0', 'MATE-4v8-9-v0'), ('MATE-4v8-8', 'MATE-4v8-9')])
def test_an_unknown_config_name_is_one_line_listing_the_presets(name, suggestion):
    with pytest.raises(mate.ConfigError) as error:
        mate.make_team_vec(name, team='camera', num_envs=1)
    message = str(error.value)
    assert '\n' not in message and f"did you mean '{suggestion}'" in message
    assert 'Known presets: MATE, MATE-1v1-0' in message and "'MATE-4v8-9-v0'" in message


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
