"""Tests of mate.config: presets, name resolution, overrides, validation and normalisation."""

import copy
import json
import math
import pathlib

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from mate.config import (
    DEFAULT_CONFIG,
    PRESETS_DIR,
    ConfigError,
    list_presets,
    preset_path,
    read_config,
)

# (N_c, N_t, N_o) per preset, from spec environment.md §2.4.
PRESET_COUNTS = {
    'MATE-1v1-0': (1, 1, 0),
    'MATE-1v1-9': (1, 1, 9),
    'MATE-1v2-0': (1, 2, 0),
    'MATE-1v2-9': (1, 2, 9),
    'MATE-2v2-0': (2, 2, 0),
    'MATE-2v2-9': (2, 2, 9),
    'MATE-2v4-0': (2, 4, 0),
    'MATE-2v4-9': (2, 4, 9),
    'MATE-4v2-0': (4, 2, 0),
    'MATE-4v2-9': (4, 2, 9),
    'MATE-4v4-0': (4, 4, 0),
    'MATE-4v4-9': (4, 4, 9),
    'MATE-4v8-0': (4, 8, 0),
    'MATE-4v8-9': (4, 8, 9),
    'MATE-8v8-0': (8, 8, 0),
    'MATE-8v8-9': (8, 8, 9),
    'MATE-Navigation': (0, 8, 32),
    'MATE': (4, 8, 9),
}

TOP_LEVEL_KEYS = {
    'max_episode_steps', 'reward_type', 'num_cargoes_per_target', 'high_capacity_target_split',
    'targets_start_with_cargoes', 'bounty_factor', 'shuffle_entities', 'target',
}


def count(config, kind):
    """Number of entities of `kind` ('camera', 'target', 'obstacle') in a normalised config."""
    section = config.get(kind)
    if section is None:
        return 0
    return len(section['location']) + len(section['location_random_range'])


def minimal(**extra):
    """The smallest valid configuration mapping, plus `extra` top-level keys."""
    return {'num_cargoes_per_target': 8, 'target': {'location': [[0, 0]]}, **extra}


def raises(match=None, **kwargs):
    """Read `kwargs` over the default preset and return the ConfigError raised."""
    with pytest.raises(ConfigError, match=match) as info:
        read_config('MATE-4v8-9', **kwargs)
    return info.value


# ----------------------------------------------------------------------------- presets


def test_list_presets_names_all_eighteen_files():
    assert list_presets() == sorted(PRESET_COUNTS)
    assert all(preset_path(name).is_file() for name in list_presets())
    assert preset_path('MATE-4v8-9') == PRESETS_DIR / 'MATE-4v8-9.yaml'


@pytest.mark.parametrize('name', sorted(PRESET_COUNTS))
def test_preset_loads_with_expected_counts(name):
    config = read_config(name)
    counts = tuple(count(config, kind) for kind in ('camera', 'target', 'obstacle'))
    assert counts == PRESET_COUNTS[name]
    assert TOP_LEVEL_KEYS <= set(config)
    assert config['max_episode_steps'] == 10000
    assert config['num_cargoes_per_target'] == 8


def test_default_preset_and_alias():
    assert DEFAULT_CONFIG == 'MATE-4v8-9.yaml'
    assert read_config() == read_config('MATE-4v8-9')
    assert read_config('MATE') == read_config('MATE-4v8-9')


def test_preset_values_from_the_spec():
    config = read_config('MATE-4v8-9')
    assert config['camera']['min_viewing_angle'] == 30.0
    assert config['camera']['max_sight_range'] == 1500.0
    assert config['camera']['location_random_range'][1] == [500.0, 800.0, -800.0, -500.0]
    assert config['obstacle']['radius_random_range'] == [25.0, 100.0]
    assert 'radius' not in config['obstacle']
    assert config['obstacle']['transmittance'] == 0.1
    assert config['target']['step_size'] == 20.0
    for name in ('MATE-8v8-0', 'MATE-8v8-9'):
        assert read_config(name)['camera']['max_sight_range'] == 1000.0


def test_missing_preset_keys_get_defaults():
    config = read_config('MATE-1v1-0')  # no shuffle_entities nor high_capacity_target_split
    assert config['shuffle_entities'] is True
    assert config['high_capacity_target_split'] == 0.5
    assert config['camera']['location'] == [[0.0, 0.0]]
    assert config['camera']['location_random_range'] == []
    assert 'obstacle' not in config


def test_navigation_preset():
    config = read_config('MATE-Navigation')
    assert 'camera' not in config
    assert config['reward_type'] == 'sparse'
    assert config['targets_start_with_cargoes'] is False
    assert config['bounty_factor'] == 1.0  # absent in the file


# ----------------------------------------------------------------------------- resolution


def test_name_with_extension_and_case(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    expected = read_config('MATE-4v8-9')
    assert read_config('MATE-4v8-9.yaml') == expected
    assert read_config('mate-4v8-9') == expected
    assert read_config(PRESETS_DIR / 'MATE-4v8-9.yaml') == expected


def test_yaml_file_path(tmp_path, monkeypatch):
    path = tmp_path / 'custom.YML'
    path.write_text(yaml.safe_dump(minimal(max_episode_steps=7)))
    assert read_config(path)['max_episode_steps'] == 7
    assert read_config(str(path))['max_episode_steps'] == 7
    monkeypatch.chdir(tmp_path)
    assert read_config('custom.YML')['max_episode_steps'] == 7


def test_json_file_path(tmp_path):
    path = tmp_path / 'custom.json'
    path.write_text(json.dumps(minimal(reward_type='sparse')))
    config = read_config(str(path))
    assert config['reward_type'] == 'sparse'
    assert config['target']['location'] == [[0.0, 0.0]]


def test_mapping_is_not_mutated():
    mapping = minimal(camera={'location_random_range': [{'low': [0, 1], 'high': [2, 3]}]})
    snapshot = copy.deepcopy(mapping)
    config = read_config(mapping, camera={'radius': 30})
    assert mapping == snapshot
    assert config['camera']['location_random_range'] == [[0.0, 2.0, 1.0, 3.0]]
    config['target']['location'][0][0] = 99.0
    assert mapping == snapshot


def test_unknown_preset_suggests_close_names():
    with pytest.raises(ConfigError, match="did you mean 'MATE-4v8-9'") as info:
        read_config('MATE-4v9-9')
    assert "'MATE-4v9-9'" in str(info.value)
    assert 'Known presets' in str(info.value)
    assert info.value.value == 'MATE-4v9-9'
    with pytest.raises(ConfigError, match='unknown preset'):
        preset_path('MATE-5v5')


def test_bad_files_and_arguments(tmp_path):
    text_file = tmp_path / 'config.txt'
    text_file.write_text('num_cargoes_per_target: 8')
    with pytest.raises(ConfigError, match='extension'):
        read_config(text_file)
    not_a_mapping = tmp_path / 'list.yaml'
    not_a_mapping.write_text('- 1\n- 2\n')
    with pytest.raises(ConfigError, match='mapping'):
        read_config(not_a_mapping)
    broken = tmp_path / 'broken.json'
    broken.write_text('{"num_cargoes_per_target": ')
    with pytest.raises(ConfigError, match='cannot read'):
        read_config(broken)
    with pytest.raises(ConfigError, match='expected None, a preset name'):
        read_config(42)


# ----------------------------------------------------------------------------- overrides


def test_overrides_deep_merge():
    config = read_config('MATE-4v8-9', camera={'radius': 30}, max_episode_steps=100)
    assert config['camera']['radius'] == 30.0
    assert isinstance(config['camera']['radius'], float)
    assert config['camera']['max_sight_range'] == 1500.0
    assert len(config['camera']['location_random_range']) == 4
    assert config['max_episode_steps'] == 100


def test_overrides_replace_non_mapping_values():
    config = read_config('MATE-4v8-9', target={'location_random_range': [[0, 0, 0, 0]]})
    assert config['target']['location_random_range'] == [[0.0, 0.0, 0.0, 0.0]]
    assert config['target']['step_size'] == 20.0


def test_overrides_without_config_start_empty():
    """Quirk Q8 of the original: overrides alone do not start from the default preset."""
    config = read_config(**minimal())
    assert 'camera' not in config and 'obstacle' not in config
    with pytest.raises(ConfigError, match='overrides start from an empty configuration') as info:
        read_config(camera={'radius': 30.0})
    assert "config='MATE-4v8-9'" in str(info.value)
    assert info.value.path == 'num_cargoes_per_target'
    with pytest.raises(ConfigError, match='empty configuration') as info:
        read_config(num_cargoes_per_target=8)
    assert info.value.path == 'target'


def test_missing_key_with_a_config_has_no_hint():
    with pytest.raises(ConfigError) as info:
        read_config({'target': {'location': [[0, 0]]}})
    assert info.value.path == 'num_cargoes_per_target'
    assert 'empty configuration' not in str(info.value)


# ----------------------------------------------------------------------------- validation


def test_unknown_top_level_key_with_did_you_mean():
    error = raises(max_episode_step=5)
    assert error.path == 'max_episode_step'
    assert "did you mean 'max_episode_steps'" in str(error)


def test_unknown_section_key_with_did_you_mean():
    error = raises(camera={'radious': 3})
    assert error.path == 'camera.radious'
    assert "did you mean 'radius'" in str(error)


@pytest.mark.parametrize(
    ('overrides', 'path'),
    [
        ({'max_episode_steps': '100'}, 'max_episode_steps'),
        ({'max_episode_steps': 2.5}, 'max_episode_steps'),
        ({'reward_type': 'Dense'}, 'reward_type'),
        ({'shuffle_entities': 1}, 'shuffle_entities'),
        ({'name': 3}, 'name'),
        ({'camera': None}, 'camera'),
        ({'camera': {'location': [[0, 0, 0]]}}, 'camera.location[0]'),
        ({'camera': {'location': [[0, '1']]}}, 'camera.location[0][1]'),
        ({'target': {'location_random_range': [[0, 1, 0]]}}, 'target.location_random_range[0]'),
        ({'target': {'location_random_range': 5}}, 'target.location_random_range'),
    ],
)
def test_wrong_types(overrides, path):
    error = raises(**overrides)
    assert error.path == path
    assert str(error).startswith(f'{path}: got ')
    assert 'expected' in str(error)


def test_bools_are_not_numbers():
    error = raises(camera={'radius': True})
    assert error.path == 'camera.radius'
    assert 'True' in str(error) and 'bool' in str(error)
    assert raises(num_cargoes_per_target=np.bool_(True)).path == 'num_cargoes_per_target'


@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf, np.float64('nan')])
def test_nan_and_inf_are_rejected(bad):
    assert raises(bounty_factor=bad).path == 'bounty_factor'
    assert raises(obstacle={'transmittance': bad}).path == 'obstacle.transmittance'
    range_error = raises(target={'location_random_range': [[0, bad, 0, 1]]})
    assert range_error.path == 'target.location_random_range[0][1]'


@pytest.mark.parametrize(
    ('overrides', 'path', 'value', 'valid'),
    [
        ({'camera': {'min_viewing_angle': 200}}, 'camera.min_viewing_angle', '200', '(0, 180]'),
        ({'camera': {'min_viewing_angle': 0}}, 'camera.min_viewing_angle', '0', '(0, 180]'),
        ({'camera': {'radius': -1}}, 'camera.radius', '-1', '> 0'),
        ({'target': {'step_size': 0.0}}, 'target.step_size', '0.0', '> 0'),
        ({'max_episode_steps': 0}, 'max_episode_steps', '0', '> 0'),
        ({'num_cargoes_per_target': 3}, 'num_cargoes_per_target', '3', '>= 4'),
        ({'high_capacity_target_split': 1.5}, 'high_capacity_target_split', '1.5', '[0, 1]'),
        ({'bounty_factor': -0.5}, 'bounty_factor', '-0.5', '>= 0'),
        ({'obstacle': {'transmittance': 1.1}}, 'obstacle.transmittance', '1.1', '[0, 1]'),
    ],
)
def test_out_of_range_message_names_path_value_and_range(overrides, path, value, valid):
    error = raises(**overrides)
    message = str(error)
    assert error.path == path
    assert message.startswith(f'{path}: got {value}')
    assert valid in message


def test_angles_are_documented_in_degrees():
    assert 'degrees' in str(raises(camera={'min_viewing_angle': 181}))


def test_range_low_above_high():
    ranges = [[0, 1, 0, 1]] * 3 + [[800, 500, 0, 1]]
    error = raises(obstacle={'location_random_range': ranges})
    assert error.path == 'obstacle.location_random_range[3]'
    assert error.value == [800, 500, 0, 1]
    assert 'x_low 800 > x_high 500' in str(error)
    assert 'original MATE' in str(error)  # says the check is our addition
    mapping_range = {'low': [0, 5], 'high': [1, 4]}
    assert 'y_low 5 > y_high 4' in str(raises(camera={'location_random_range': [mapping_range]}))
    radius_error = raises(obstacle={'radius_random_range': {'low': 5, 'high': 2}})
    assert radius_error.path == 'obstacle.radius_random_range'


def test_mapping_range_with_unknown_key():
    error = raises(camera={'location_random_range': [{'low': [0, 0], 'hgh': [1, 1]}]})
    assert error.path == 'camera.location_random_range[0]'
    assert "did you mean 'high'" in str(error)


def test_obstacle_radius_rules():
    assert 'exactly one' in str(raises(obstacle={'radius': 30}))  # both given
    with pytest.raises(ConfigError, match='neither radius nor radius_random_range') as info:
        read_config(minimal(obstacle={'location': [[0, 0]]}))
    assert info.value.path == 'obstacle'
    empty = read_config(minimal(obstacle={}))
    assert empty['obstacle'] == {'location': [], 'location_random_range': [], 'transmittance': 0.0}
    fixed = read_config(minimal(obstacle={'location': [[0, 0]], 'radius': 50}))
    assert fixed['obstacle']['radius'] == 50.0
    assert 'radius_random_range' not in fixed['obstacle']
    assert raises(obstacle={'radius_random_range': [-1, 5]}).path == 'obstacle.radius_random_range'


def test_target_count_must_be_positive():
    error = raises(target={'location_random_range': []})
    assert error.path == 'target'
    assert 'at least one' in str(error)
    with pytest.raises(ConfigError, match='missing required key') as info:
        read_config({'num_cargoes_per_target': 8})
    assert info.value.path == 'target'


# ----------------------------------------------------------------------------- normalisation


def test_accepted_number_types_are_normalised():
    config = read_config(
        minimal(),
        max_episode_steps=np.int64(50),
        bounty_factor=2,
        camera={'location': np.array([[1, 2]]), 'radius': np.float32(12.5)},
        obstacle={'radius_random_range': {'low': 1, 'high': 2}},
    )
    assert type(config['max_episode_steps']) is int
    assert type(config['bounty_factor']) is float
    assert config['camera']['location'] == [[1.0, 2.0]]
    assert type(config['camera']['location'][0][0]) is float
    assert config['camera']['radius'] == 12.5
    assert config['obstacle']['radius_random_range'] == [1.0, 2.0]


@pytest.mark.parametrize('name', sorted(PRESET_COUNTS))
def test_output_is_idempotent_and_json_serialisable(name):
    config = read_config(name)
    assert read_config(config) == config
    assert json.loads(json.dumps(config)) == config
    assert yaml.safe_load(yaml.safe_dump(config)) == config


def _assert_plain(value):
    """Only dict / list / str / int / float / bool anywhere in `value`."""
    assert type(value) in (dict, list, str, int, float, bool), type(value)
    if isinstance(value, dict):
        for key, item in value.items():
            assert type(key) is str
            _assert_plain(item)
    elif isinstance(value, list):
        for item in value:
            _assert_plain(item)


def test_output_holds_only_plain_python_types():
    _assert_plain(read_config(minimal(camera={'location': np.zeros((2, 2))})))


coordinate = st.floats(-1000, 1000, allow_nan=False)
flat_range = st.tuples(coordinate, coordinate, coordinate, coordinate).map(
    lambda r: [min(r[0], r[1]), max(r[0], r[1]), min(r[2], r[3]), max(r[2], r[3])]
)
mapping_range = flat_range.map(lambda r: {'low': [r[0], r[2]], 'high': [r[1], r[3]]})


@settings(max_examples=50, deadline=None)
@given(
    targets=st.lists(st.one_of(flat_range, mapping_range), min_size=1, max_size=5),
    obstacles=st.lists(flat_range, max_size=5),
    radius=st.floats(0, 200),
    steps=st.integers(1, 10**6),
    split=st.floats(0, 1),
)
def test_valid_configs_normalise_idempotently(targets, obstacles, radius, steps, split):
    mapping = minimal(
        max_episode_steps=steps,
        high_capacity_target_split=split,
        target={'location_random_range': targets},
        obstacle={'location_random_range': obstacles, 'radius': radius},
    )
    config = read_config(mapping)
    assert read_config(config) == config
    assert count(config, 'target') == len(targets)
    for low_x, high_x, low_y, high_y in config['target']['location_random_range']:
        assert low_x <= high_x and low_y <= high_y


def test_presets_dir_ships_with_the_package():
    import mate.config

    assert PRESETS_DIR == pathlib.Path(mate.config.__file__).resolve().parent / 'presets'
    assert sorted(path.stem for path in PRESETS_DIR.glob('*.yaml')) == list_presets()


def test_box_like_ranges_are_flattened():
    class Box:  # anything with `low` and `high`, like gymnasium.spaces.Box
        def __init__(self, low, high):
            self.low, self.high = np.asarray(low), np.asarray(high)

    config = read_config(
        minimal(),
        target={'location_random_range': [Box([0, 1], [2, 3])]},
        obstacle={'location': [[0, 0]], 'radius_random_range': Box(1.0, 4.0)},
    )
    assert config['target']['location_random_range'] == [[0.0, 2.0, 1.0, 3.0]]
    assert config['obstacle']['radius_random_range'] == [1.0, 4.0]
