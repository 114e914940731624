"""Difference rewards for cameras (`credit='difference'`): the formula, the training env's per-camera
rewards, and the learner's per-agent critic."""

import numpy as np
import pytest

from mate.learn import CheckpointError, load_checkpoint
from mate.learn.envs import TeamVecEnv, difference_rewards
from mate.learn.ppo import PPOConfig, train
from mate.spaces import observation_indices_of
from mate.messages import Team

from .toy import OwnCueMatching


def test_difference_rewards_by_hand():
    sees = np.array([[1, 1, 0, 0],      # camera 0: targets 0 and 1; target 1 also seen by camera 1
                     [0, 1, 1, 0],      # camera 1: targets 1 and 2
                     [0, 0, 0, 0]],     # camera 2: nothing
                    dtype=bool)
    assert np.allclose(difference_rewards(sees), [1 / 4, 1 / 4, 0.0])
    # each camera's reward is the coverage rate minus the coverage rate of the team without it
    coverage = lambda s: s.any(axis=0).mean()
    for c in range(3):
        assert np.isclose(difference_rewards(sees)[c], coverage(sees) - coverage(np.delete(sees, c, axis=0)))
    # leading batch axes pass through
    assert difference_rewards(np.stack([sees, ~sees])).shape == (2, 3)
    assert np.allclose(difference_rewards(np.ones((2, 3), dtype=bool)), 0.0)   # everything seen twice


def test_team_env_pays_each_camera_its_own_share():
    """Same game as the team-reward env; each camera's reward is the sum over the held raw steps of its
    difference reward, computed here from the recorded raw observations' flags, whose union is the
    coverage rate the env reports."""
    env = TeamVecEnv('camera', num_envs=4, credit='difference', horizon=40, seed=3)
    plain = TeamVecEnv('camera', num_envs=4, horizon=40, seed=3)
    nc, nt, no = env.counts
    begin = int(observation_indices_of(Team.CAMERA, nc, nt, no)[2])
    raw_steps = []
    vec_step = env.vec.step

    def recording_step(actions):
        result = vec_step(actions)
        raw_steps.append((result[0][0][..., begin + 4:begin + 5 * nt:5] > 0.5, result[4]['coverage_rate'].copy(),
                          (result[2] | result[3]).copy()))
        return result

    env.vec.step = recording_step
    obs, _ = env.reset(seed=3)
    base, _ = plain.reset(seed=3)
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(12):
        actions = rng.integers(0, 25, (4, nc))
        raw_steps.clear()
        obs, _, reward, done, _, info = env.step(actions)
        base, _, team_reward, *_ = plain.step(actions)
        assert np.array_equal(obs, base) and reward.shape == (4, nc)
        expected, live = np.zeros((4, nc)), np.ones(4, dtype=bool)
        for sees, coverage_rate, over in raw_steps[:env.frame_skip]:
            assert np.allclose(sees.any(axis=1).sum(-1) / nt, coverage_rate)   # the flags make the coverage
            expected += np.where(live[:, None], difference_rewards(sees), 0.0)
            live &= ~over
        assert np.allclose(reward, expected)
        assert np.all(reward.sum(-1) <= team_reward + 1e-9)          # shares never exceed the coverage
        ended += int(done.sum())
    assert ended > 0 and reward.max() > 0


def test_learner_with_per_agent_rewards_improves(tmp_path):
    rows = []
    config = PPOConfig(algo='mappo', actor='mlp', total_steps=16 * 16 * 12, num_envs=16, rollout_length=16, epochs=4,
                       hidden=(32,), lr_schedule=((0, 3e-3),), entropy_schedule=((0, 0.0),), seed=1)
    train(config, tmp_path, progress=False, callback=rows.append,
          envs=OwnCueMatching(num_envs=16, num_agents=2, num_actions=4))
    assert rows[0]['rollout_coverage'] < 0.45
    assert rows[-1]['rollout_coverage'] > 0.8, [round(r['rollout_coverage'], 3) for r in rows]
    saved = load_checkpoint(tmp_path / 'final.pt')
    assert saved['meta']['credit'] == 'difference'
    assert saved['critic']['head.weight'].shape[0] == 2               # one value per agent


def test_difference_credit_checkpoint_and_validation(tmp_path):
    config = PPOConfig(algo='mappo', team='camera', env_id='MATE-2v4-0-v0', num_envs=4, rollout_length=4,
                       total_steps=2 * 4 * 4, epochs=1, hidden=(16,), credit='difference', seed=0, actor='mlp')
    row = train(config, tmp_path, progress=False)
    assert row['env_steps'] == 32 and np.isfinite(row['value_loss'])
    saved = load_checkpoint(tmp_path / 'final.pt')
    assert saved['meta']['credit'] == 'difference' and saved['critic']['head.weight'].shape[0] == 2
    with pytest.raises(CheckpointError, match='credit'):   # resuming with the team reward is another experiment
        train(PPOConfig(**{**config.__dict__, 'credit': 'team', 'total_steps': 64}), tmp_path, progress=False)
    # older checkpoints (no 'credit' in their metadata) were trained with the team reward
    del saved['meta']['credit']
    from mate.learn import save_checkpoint
    save_checkpoint(tmp_path / 'old.pt', saved)
    assert load_checkpoint(tmp_path / 'old.pt', expect={'credit': 'team'})
    with pytest.raises(ValueError, match='cameras only'):
        TeamVecEnv('target', num_envs=2, credit='difference')
    with pytest.raises(ValueError, match="credit must be one of"):
        TeamVecEnv('camera', num_envs=2, credit='own')


def test_cli_credit_option():
    from mate.cli import build_parser
    from mate.learn.command import config_from_args
    parse = build_parser().parse_args
    assert config_from_args(parse(['train', 'mappo'])).credit == 'team'
    assert config_from_args(parse(['train', 'mappo', '--credit', 'difference'])).credit == 'difference'
    with pytest.raises(SystemExit, match='cameras only'):
        config_from_args(parse(['train', 'mappo', '--team', 'target', '--credit', 'difference']))
