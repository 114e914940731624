"""Tests of mate.spaces: observation/state spaces, part indices, slices and coordinate masks."""

import numpy as np
import pytest
from gymnasium import spaces as gym_spaces

from mate import spaces as S
from mate.constants import camera_observation_dim, state_dim, target_observation_dim
from mate.messages import Team

# (N_c, N_t, N_o, camera obs, target obs, state): spec environment.md §11.1
PRESET_DIMS = [
    (1, 1, 0, 34, 39, 54), (1, 1, 9, 70, 75, 81), (1, 2, 0, 39, 44, 70), (1, 2, 9, 75, 80, 97),
    (2, 2, 0, 46, 51, 79), (2, 2, 9, 82, 87, 106), (2, 4, 0, 56, 61, 111), (2, 4, 9, 92, 97, 138),
    (4, 2, 0, 60, 65, 97), (4, 2, 9, 96, 101, 124), (4, 4, 0, 70, 75, 129), (4, 4, 9, 106, 111, 156),
    (4, 8, 0, 90, 95, 193), (4, 8, 9, 126, 131, 220), (8, 8, 0, 118, 123, 229), (8, 8, 9, 154, 159, 256),
    (0, 8, 32, 190, 195, 253),
]


@pytest.mark.parametrize('nc, nt, no, d_cam, d_tgt, d_state', PRESET_DIMS)
def test_dimensions_match_measured_presets(nc, nt, no, d_cam, d_tgt, d_state):
    assert S.camera_observation_space_of(nc, nt, no).shape == (d_cam,)
    assert S.target_observation_space_of(nc, nt, no).shape == (d_tgt,)
    assert S.state_space_of(nc, nt, no).shape == (d_state,)
    assert (d_cam, d_tgt, d_state) == (camera_observation_dim(nc, nt, no), target_observation_dim(nc, nt, no),
                                       state_dim(nc, nt, no))
    assert S.camera_observation_indices_of(nc, nt, no)[-1] == d_cam
    assert S.target_observation_indices_of(nc, nt, no)[-1] == d_tgt
    assert S.camera_coordinate_mask_of(nc, nt, no).shape == (d_cam,)
    assert S.target_coordinate_mask_of(nc, nt, no).shape == (d_tgt,)


def test_worked_example_4v8_9_indices_and_slices():
    np.testing.assert_array_equal(S.camera_observation_indices_of(4, 8, 9), [0, 13, 22, 62, 98, 126])
    np.testing.assert_array_equal(S.target_observation_indices_of(4, 8, 9), [0, 13, 27, 55, 91, 131])

    cam = S.camera_observation_slices_of(4, 8, 9)
    assert cam == {
        'preserved_data': slice(0, 13), 'self_state': slice(13, 22),
        'opponent_states_with_mask': slice(22, 62), 'opponent_mask': slice(26, 62, 5),
        'obstacle_states_with_mask': slice(62, 98), 'obstacle_mask': slice(65, 98, 4),
        'teammate_states_with_mask': slice(98, 126), 'teammate_mask': slice(104, 126, 7),
    }
    tgt = S.target_observation_slices_of(4, 8, 9)
    assert tgt == {
        'preserved_data': slice(0, 13), 'self_state': slice(13, 27),
        'opponent_states_with_mask': slice(27, 55), 'opponent_mask': slice(33, 55, 7),
        'obstacle_states_with_mask': slice(55, 91), 'obstacle_mask': slice(58, 91, 4),
        'teammate_states_with_mask': slice(91, 131), 'teammate_mask': slice(95, 131, 5),
    }
    # the strided mask slices pick exactly one flag per block
    assert len(range(126)[cam['opponent_mask']]) == 8
    assert len(range(126)[cam['obstacle_mask']]) == 9
    assert len(range(126)[cam['teammate_mask']]) == 4
    assert len(range(131)[tgt['opponent_mask']]) == 4
    assert len(range(131)[tgt['teammate_mask']]) == 8


def test_team_dispatch():
    args = (4, 8, 9)
    assert S.observation_space_of(Team.CAMERA, *args) is S.camera_observation_space_of(*args)
    assert S.observation_space_of(Team.TARGET, *args) is S.target_observation_space_of(*args)
    assert S.observation_indices_of(Team.CAMERA, *args) is S.camera_observation_indices_of(*args)
    assert S.observation_indices_of(Team.TARGET, *args) is S.target_observation_indices_of(*args)
    assert S.observation_slices_of(Team.CAMERA, *args) == S.camera_observation_slices_of(*args)
    assert S.observation_slices_of(Team.TARGET, *args) == S.target_observation_slices_of(*args)
    assert S.coordinate_mask_of(Team.CAMERA, *args) is S.camera_coordinate_mask_of(*args)
    assert S.coordinate_mask_of(Team.TARGET, *args) is S.target_coordinate_mask_of(*args)
    with pytest.raises(ValueError):
        S.observation_space_of(2, *args)


def test_spaces_and_arrays_are_cached():
    assert S.camera_observation_space_of(4, 8, 9) is S.camera_observation_space_of(4, 8, 9)
    assert S.target_observation_space_of(4, 8, 9) is S.target_observation_space_of(4, 8, 9)
    assert S.state_space_of(4, 8, 9) is S.state_space_of(4, 8, 9)
    assert S.camera_state_space(True) is S.camera_state_space(True)
    assert S.obstacle_state_space() is S.obstacle_state_space()
    assert S.camera_observation_indices_of(2, 2, 0) is S.camera_observation_indices_of(2, 2, 0)
    # numpy integers hit the same cache entries
    assert S.camera_observation_space_of(np.int64(4), 8, 9) is S.camera_observation_space_of(4, 8, 9)


def test_cached_arrays_are_read_only_and_slices_are_fresh():
    for array in (S.camera_observation_indices_of(4, 8, 9), S.target_coordinate_mask_of(4, 8, 9)):
        with pytest.raises(ValueError):
            array[0] = 1
    slices = S.camera_observation_slices_of(4, 8, 9)
    slices['preserved_data'] = None
    assert S.camera_observation_slices_of(4, 8, 9)['preserved_data'] == slice(0, 13)


def test_invalid_counts():
    with pytest.raises(ValueError):
        S.camera_observation_space_of(-1, 2, 0)
    with pytest.raises(TypeError):
        S.state_space_of(1.5, 2, 0)


def test_box_types():
    for box in (S.camera_observation_space_of(1, 1, 1), S.target_observation_space_of(1, 1, 1),
                S.state_space_of(1, 1, 1), S.camera_state_space(False), S.target_state_space(True),
                S.obstacle_state_space()):
        assert isinstance(box, gym_spaces.Box)
        assert box.dtype == np.float64
        assert np.all(box.low <= box.high)


def test_preserved_bounds():
    box = S.camera_observation_space_of(4, 8, 9)
    np.testing.assert_array_equal(box.low[:13], [0] * 4 + [-2000] * 8 + [0])
    np.testing.assert_array_equal(box.high[:13], [np.inf] * 4 + [2000] * 8 + [1000])


def test_entity_state_space_bounds():
    cam = S.camera_state_space(private=True)
    np.testing.assert_array_equal(cam.low, [-2000, -2000, 0, -2000, -2000, 0, 0, 0, 0])
    np.testing.assert_array_equal(cam.high, [2000, 2000, 1000, 2000, 2000, 180, 2000, 180, 180])
    assert S.camera_state_space(private=False).shape == (6,)
    tgt = S.target_state_space(private=True)
    np.testing.assert_array_equal(tgt.low, [-2000, -2000, 0, -1, 0, 1, 0, 0, 0, 0, -1, -1, -1, -1])
    np.testing.assert_array_equal(tgt.high, [2000, 2000, 2000, 1, 2000, 2] + [np.inf] * 4 + [1] * 4)
    assert S.target_state_space(private=False).shape == (4,)
    obstacle = S.obstacle_state_space()
    np.testing.assert_array_equal(obstacle.low, [-2000, -2000, 0])
    np.testing.assert_array_equal(obstacle.high, [2000, 2000, 1000])


def test_camera_observation_block_bounds():
    box, sl = S.camera_observation_space_of(4, 8, 9), S.camera_observation_slices_of(4, 8, 9)
    np.testing.assert_array_equal(box.high[sl['self_state']], S.camera_state_space(True).high)
    # first target block: target public state + flag
    np.testing.assert_array_equal(box.low[22:27], [-2000, -2000, 0, -1, -1])
    np.testing.assert_array_equal(box.high[22:27], [2000, 2000, 2000, 1, 1])
    # last obstacle block and last camera block
    np.testing.assert_array_equal(box.high[94:98], [2000, 2000, 1000, 1])
    np.testing.assert_array_equal(box.high[119:126], [2000, 2000, 1000, 2000, 2000, 180, 1])
    for key in ('opponent_mask', 'obstacle_mask', 'teammate_mask'):
        assert np.all(box.low[sl[key]] == -1) and np.all(box.high[sl[key]] == 1)


def test_target_observation_block_bounds():
    box, sl = S.target_observation_space_of(4, 8, 9), S.target_observation_slices_of(4, 8, 9)
    np.testing.assert_array_equal(box.low[sl['self_state']], S.target_state_space(True).low)
    np.testing.assert_array_equal(box.high[27:34], [2000, 2000, 1000, 2000, 2000, 180, 1])
    np.testing.assert_array_equal(box.high[126:131], [2000, 2000, 2000, 1, 1])
    for key in ('opponent_mask', 'obstacle_mask', 'teammate_mask'):
        assert np.all(box.low[sl[key]] == -1) and np.all(box.high[sl[key]] == 1)


def test_state_space_bounds():
    nc, nt, no = 4, 8, 9
    box = S.state_space_of(nc, nt, no)
    cam_end = 13 + 9 * nc
    tgt_end = cam_end + 14 * nt
    obs_end = tgt_end + 3 * no
    np.testing.assert_array_equal(box.high[13:22], S.camera_state_space(True).high)
    np.testing.assert_array_equal(box.low[cam_end:cam_end + 14], S.target_state_space(True).low)
    np.testing.assert_array_equal(box.high[tgt_end:tgt_end + 3], S.obstacle_state_space().high)
    assert box.shape[0] - obs_end == 2 * nt + 16
    assert np.all(box.low[obs_end:] == 0) and np.all(np.isinf(box.high[obs_end:]))


def _expected_mask(length, block_starts):
    mask = np.zeros(length, dtype=bool)
    mask[4:12] = True
    for start in block_starts:
        mask[start:start + 2] = True
    return mask


def test_coordinate_masks():
    cam = S.camera_coordinate_mask_of(4, 8, 9)
    starts = list(range(22, 62, 5)) + list(range(62, 98, 4)) + list(range(98, 126, 7))
    np.testing.assert_array_equal(cam, _expected_mask(126, starts))
    assert cam.dtype == bool and not cam[13] and not cam[14]
    assert cam.sum() == 8 + 2 * (8 + 9 + 4)

    tgt = S.target_coordinate_mask_of(4, 8, 9)
    starts = list(range(27, 55, 7)) + list(range(55, 91, 4)) + list(range(91, 131, 5))
    np.testing.assert_array_equal(tgt, _expected_mask(131, starts))
    assert not tgt[13] and not tgt[14]


def test_empty_teams():
    np.testing.assert_array_equal(S.camera_observation_indices_of(0, 8, 32), [0, 13, 22, 62, 190, 190])
    sl = S.camera_observation_slices_of(0, 8, 32)
    assert len(range(190)[sl['teammate_mask']]) == 0
    assert S.camera_coordinate_mask_of(0, 0, 0).sum() == 8
    assert S.target_observation_space_of(0, 0, 0).shape == (27,)


# ---------------------------------------------------------------------------- team (joint) spaces

def _box():
    return gym_spaces.Box(np.array([-5.0, -2.0]), np.array([5.0, 2.0]), dtype=np.float64)


def _same(a, b) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))


def test_team_space_samples_every_agent_within_bounds_in_one_draw():
    space = S.TeamSpace(_box(), 6)
    space.seed(0)
    samples = np.array([np.stack(space.sample()) for _ in range(2000)])     # (2000, 6, 2)
    assert samples.shape == (2000, 6, 2) and samples.dtype == np.float64
    assert all(space.sample() in space for _ in range(10))
    assert samples[..., 0].min() < -4.9 and samples[..., 0].max() > 4.9       # uniform over the box,
    assert samples[..., 1].min() < -1.95 and samples[..., 1].max() > 1.95     # each axis its own bounds
    assert np.all(np.abs(samples[..., 0]) <= 5) and np.all(np.abs(samples[..., 1]) <= 2)
    assert not np.array_equal(samples[:, 0], samples[:, 1])                  # agents drawn independently


def test_team_space_seeding_follows_gymnasium():
    space = S.TeamSpace(_box(), 4)
    space.seed(3)
    first = [space.sample() for _ in range(3)]
    space.seed(3)
    assert all(_same(a, b) for a, b in zip(first, [space.sample() for _ in range(3)]))
    space.seed(4)
    assert not _same(first[0], space.sample())
    space.seed([1, 2, 3, 4])
    listed = space.sample()
    space.seed([1, 2, 3, 4])
    assert _same(listed, space.sample())
    space.seed(None)
    assert space.sample() in space
    joint = gym_spaces.Tuple((S.TeamSpace(_box(), 4), S.TeamSpace(_box(), 8)))    # as env.action_space
    joint.seed(1)
    a = joint.sample()
    joint.seed(1)
    b = joint.sample()
    assert _same(a[0], b[0]) and _same(a[1], b[1]) and len(a[1]) == 8


def test_team_space_is_a_tuple_of_the_agent_space():
    box = _box()
    space = S.TeamSpace(box, 3)
    assert isinstance(space, gym_spaces.Tuple) and space.spaces == (box,) * 3 and space == gym_spaces.Tuple((box,) * 3)
    mask_space = S.TeamSpace(gym_spaces.Discrete(5), 3)
    mask_space.seed(0)
    assert all(0 <= a < 5 for a in mask_space.sample()) and mask_space.sample() in mask_space
    masked = mask_space.sample(mask=tuple(np.array([0, 0, 1, 0, 0], dtype=np.int8) for _ in range(3)))
    assert masked == (2, 2, 2)                                                 # masks fall back to Tuple.sample
    assert S.TeamSpace(box, 0).sample() == ()


def test_env_action_space_samples_reproducibly():
    import mate
    env = mate.make('MATE-4v8-9-v0')
    assert isinstance(env.camera_joint_action_space, S.TeamSpace)
    env.action_space.seed(7)
    a = env.action_space.sample()
    env.action_space.seed(7)
    b = env.action_space.sample()
    assert _same(a[0], b[0]) and _same(a[1], b[1]) and a in env.action_space
    discrete = mate.make('MATE-4v8-9-v0', wrappers=[mate.DiscreteCamera, mate.DiscreteTarget])
    discrete.action_space.seed(7)
    c = discrete.action_space.sample()
    discrete.action_space.seed(7)
    assert c == discrete.action_space.sample() and c in discrete.action_space


def test_team_space_draws_in_blocks_the_numbers_of_one_draw_per_sample():
    """Across a block refill the samples continue the generator's stream exactly as one draw per sample
    would; a sample carries its team array, which the env takes as is."""
    import mate
    box = _box()
    space = S.TeamSpace(box, 3)
    space.seed(11)
    samples = [space.sample() for _ in range(S.TeamSpace.BLOCK + 5)]
    space.seed(11)
    rng = space.np_random
    low, span = box.low.astype(np.float64), (box.high - box.low).astype(np.float64)
    expected = [low + span * rng.random((3, 2)) for _ in range(S.TeamSpace.BLOCK + 5)]
    for sample, wanted in zip(samples, expected):
        assert isinstance(sample, S.TeamSample) and len(sample) == 3
        np.testing.assert_allclose(np.stack(sample), wanted, rtol=0, atol=1e-12)
        assert np.shares_memory(sample.array, sample[0]) and sample.array.shape == (3, 2)
    env = mate.make('MATE-2v4-0-v0')
    env.reset(seed=0)
    env.action_space.seed(2)
    action = env.action_space.sample()
    again = mate.make('MATE-2v4-0-v0')
    again.reset(seed=0)
    plain = (np.stack(action[0]).copy(), np.stack(action[1]).copy())
    assert _same(env.step(action)[0][0], again.step(plain)[0][0])
