import numpy as np
import pytest

import mate
from mate.agents.greedy import desired_viewing_angle
from mate.learn import PolicyCameraAgent
from mate.learn.envs import TeamEnvConfig
from mate.policies.hrl import executor_actions
from mate.learn.mappo import MAPPOConfig, train


def _hrl_env(config, num_envs, seed=0):
    """The training envs of HRL cameras (one keep/ignore head per target slot) on preset `config`."""
    team_env = TeamEnvConfig(team='camera', config=config, num_envs=num_envs, hrl=True, seed=seed)
    return team_env.make_env(team_env.policy_spec(action='hrl'))


def _camera_obs(seed=0):
    env = mate.make('MATE-4v8-0-v0')
    for s in range(seed, seed + 50):
        (camera_obs, _), _ = env.reset(seed=s)
        flags = camera_obs[:, 22:22 + 40].reshape(4, 8, 5)[..., 4]
        if flags.any():
            return camera_obs, flags
    raise AssertionError('no camera sees a target')


def test_executor_sweeps_without_a_valid_selection():
    camera_obs, flags = _camera_obs()
    nothing = np.zeros((4, 8))
    assert np.allclose(executor_actions(camera_obs, nothing, 4, 8, 0), [[-5.0, -2.5]] * 4)
    invisible_only = (flags < 0.5).astype(float)
    assert np.allclose(executor_actions(camera_obs, invisible_only, 4, 8, 0), [[-5.0, -2.5]] * 4)


def test_executor_aims_at_a_single_selected_target_like_the_greedy_rule():
    camera_obs, flags = _camera_obs()
    c, t = map(int, np.argwhere(flags)[0])
    selection = np.zeros((4, 8))
    selection[c, t] = 1
    action = executor_actions(camera_obs, selection, 4, 8, 0)[c]
    own = camera_obs[c, 13:22]
    tx, ty = camera_obs[c, 22 + 5 * t:22 + 5 * t + 2]
    bearing = np.degrees(np.arctan2(ty - own[1], tx - own[0]))
    rotation = (bearing - np.degrees(np.arctan2(own[4], own[3])) + 180) % 360 - 180
    distance = np.hypot(tx - own[0], ty - own[1])
    zoom = desired_viewing_angle(distance, own[5], np.hypot(own[3], own[4]), own[6]) - own[5]
    assert np.allclose(action, np.clip([rotation, zoom], [-5, -2.5], [5, 2.5]))


@pytest.mark.parametrize('critic', ['state', 'local'])        # MAPPO, IPPO
def test_hrl_env_and_policy_agent(tmp_path, critic):
    env = _hrl_env('MATE-2v4-0', 4)
    assert (env.action_heads, env.action_choices, env.num_actions) == (4, 2, 8)
    env.reset()
    *_, info = env.step(np.ones((4, 2, 4), dtype=np.int64))
    assert info['coverage'].shape == (4,)
    config = MAPPOConfig(team='camera', config='MATE-2v4-0', hrl=True, critic=critic, num_envs=4, rollout_length=4,
                         steps=16, epochs=1, hidden=(8,), run_dir=str(tmp_path), progress=False)
    train(config)
    agent = PolicyCameraAgent.from_checkpoint(tmp_path / 'final.pt', seed=0)
    assert agent.spec.action == 'hrl' and agent.spec.algo == ('mappo' if critic == 'state' else 'ippo')
    single = mate.make('MATE-2v4-0-v0')
    (camera_obs, _), _ = single.reset(seed=0)
    agent.reset(camera_obs[0])
    action = agent.act(camera_obs[0])
    assert action.shape == (2,) and np.all(np.abs(action) <= [5.0, 2.5])
    assert agent._held.shape == (4,)


def test_masked_selection_never_keeps_an_unseen_target():
    import torch
    from mate.learn.ppo import action_distribution
    env = _hrl_env('MATE-4v8-0', 8)
    obs, _ = env.reset(seed=3)
    allowed = env.allowed_actions(obs)                                        # (B, Nc, Nt, 2)
    flags = obs[..., 22 + 4:22 + 40:5] > 0.5
    assert allowed.shape == (8, 4, 8, 2) and allowed[..., 0].all() and np.array_equal(allowed[..., 1], flags)
    assert flags.any() and not flags.all()
    logits = torch.zeros(8, 4, 16)                                            # uniform before the mask
    dist = action_distribution(logits, 8, 2, torch.from_numpy(allowed))
    samples = dist.sample((200,))
    assert not samples[:, ~torch.from_numpy(flags)].any()                     # never 'keep' an unseen target
    assert samples[:, torch.from_numpy(flags)].float().mean() == pytest.approx(0.5, abs=0.05)
    # a head with one allowed choice adds nothing to the log-probability or the entropy
    entropy = dist.entropy()
    assert torch.allclose(entropy[~torch.from_numpy(flags)], torch.zeros(()))
    assert torch.allclose(entropy[torch.from_numpy(flags)], torch.tensor(np.log(2.0), dtype=torch.float32))
    assert torch.all(dist.log_prob(torch.zeros(8, 4, 8, dtype=torch.long))[~torch.from_numpy(flags)] == 0)


def test_joint_selections_never_keep_an_unseen_target():
    """`PolicySpec.choose` of an 'hrl-joint' policy (one head of 2^Nt subsets): argmax and samples only ever pick a
    subset of the targets the camera sees, however large the masked-out logits; decode aims as the per-target
    selection of the same bits does."""
    from mate.policies.hrl import selection_bits
    from mate.policies.spec import PolicySpec

    joint = PolicySpec.for_game('camera', 'MATE-4v8-0-v0', frame_skip=5, action='hrl-joint', network='mlp')
    per_target = joint.replace(action='hrl')
    assert (joint.heads, joint.choices) == (1, 256)
    camera_obs, flags = _camera_obs()
    features = joint.features(camera_obs)
    visible = joint.visible(features)
    assert np.array_equal(visible, flags > 0.5)
    bits = selection_bits(8)                                                  # (256, 8)
    outside = (bits[None] & ~visible[:, None]).any(-1)                        # (Nc, 256) keeps an unseen target
    logits = np.where(outside, 10.0, 0.0)                                     # the masked choices look best
    rng = np.random.default_rng(0)
    for deterministic in (True, False):
        for _ in range(20 if not deterministic else 1):
            held = joint.choose(logits, features, deterministic, rng)        # (Nc, 1)
            assert held.shape == (4, 1) and not outside[np.arange(4), held[:, 0]].any()
    np.testing.assert_array_equal(joint.decode(held, camera_obs), per_target.decode(bits[held[:, 0]], camera_obs))


@pytest.mark.parametrize('shape', [(25, 41, 4, 8), (16, 8), (3, 5), (1,), (0, 8)])
def test_joint_allowed_is_the_bit_by_bit_subset_test(shape):
    """`joint_allowed` (one integer test per choice against the visibility word) gives what testing every choice's
    Nt bits against the flags one by one gives: the selections whose kept targets are all visible."""
    from mate.policies.hrl import joint_allowed, selection_bits

    visible = np.random.default_rng(len(shape)).random(shape) < 0.4
    bits = selection_bits(shape[-1]).astype(bool)                              # (2^Nt, Nt)
    by_bits = ~(bits & ~visible[..., None, :]).any(-1)
    allowed = joint_allowed(visible)
    assert allowed.dtype == bool and allowed.shape == (*shape[:-1], 2 ** shape[-1])
    np.testing.assert_array_equal(allowed, by_bits)
    assert allowed[..., 0].all()                                               # keeping nothing is always allowed
