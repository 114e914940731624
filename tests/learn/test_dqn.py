"""IQL (mate.learn.dqn): the formulas by hand, the replay ring, exploration, learning a toy task, checkpoints."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mate.learn.agents import load_policy
from mate.learn.checkpoint import CheckpointError, load_checkpoint
from mate.learn.dqn import DQNConfig, ReplayBuffer, double_q_targets, epsilon_greedy, train_dqn
from mate.learn.evaluate import PolicyTeam, make_team, play_batch
from mate.learn.networks import DuelingQNetwork

from .toy import CueMatching


def test_double_q_targets_by_hand():
    reward = torch.tensor([1.0, 0.5])
    terminal = torch.tensor([0.0, 1.0])
    online = torch.tensor([[[0.1, 0.9], [2.0, 1.0]], [[5.0, 0.0], [0.0, 5.0]]])      # (M=2, H=2, C=2)
    target = torch.tensor([[[10.0, 20.0], [30.0, 40.0]], [[1.0, 1.0], [1.0, 1.0]]])
    # row 0: the online net picks (1, 0) -> the target net values 20 + 30; row 1 is terminal
    expected = torch.tensor([1.0 + 0.9 * 50.0, 0.5])
    torch.testing.assert_close(double_q_targets(reward, terminal, online, target, 0.9), expected)
    allowed = torch.tensor([[[True, False], [True, True]], [[True, True], [True, True]]])
    masked = double_q_targets(reward, terminal, online, target, 0.9, allowed)       # head 0 must take choice 0
    torch.testing.assert_close(masked, torch.tensor([1.0 + 0.9 * (10.0 + 30.0), 0.5]))


def test_dueling_aggregation_by_hand():
    torch.manual_seed(0)
    net = DuelingQNetwork(6, heads=2, choices=3, hidden=(8,))
    obs = torch.randn(5, 6)
    features = net.trunk(obs)
    value = net.value(features)                                   # (5, 1)
    advantage = net.advantage(features).reshape(5, 2, 3)
    expected = value[:, None, :] / 2 + advantage - advantage.mean(-1, keepdim=True)
    torch.testing.assert_close(net(obs), expected.reshape(5, 6))
    joint = net(obs).reshape(5, 2, 3).max(-1).values.sum(-1)      # best joint value: V + sum of best centred A
    torch.testing.assert_close(joint, value[:, 0] + (advantage - advantage.mean(-1, keepdim=True)).max(-1).values.sum(-1))


def test_replay_ring_wraps_and_samples_shapes():
    replay = ReplayBuffer(5, obs_dim=3, heads=2)
    for step in range(3):        # 3 x 2 transitions into 5 slots: the oldest one is overwritten
        obs = np.full((2, 3), step, dtype=np.float32)
        replay.add(obs, np.full((2, 2), step), np.full(2, step), obs + 1, np.zeros(2))
    assert replay.size == 5 and replay.cursor == 1
    assert replay.obs[0, 0] == 2 and replay.obs[1, 0] == 0 and replay.next_obs[0, 0] == 3
    batch = replay.sample(7, np.random.default_rng(0))
    assert batch['obs'].shape == (7, 3) and batch['action'].shape == (7, 2) and batch['reward'].shape == (7,)
    assert batch['action'].dtype == torch.int64 and batch['terminal'].dtype == torch.float32
    assert replay.nbytes == 5 * (2 * 3 * 4 + 2 * 8 + 4 + 4)
    with pytest.raises(ValueError, match='do not fit'):
        replay.add(np.zeros((6, 3)), np.zeros((6, 2)), np.zeros(6), np.zeros((6, 3)), np.zeros(6))


def test_epsilon_greedy_explores_only_among_allowed_choices():
    rng = np.random.default_rng(0)
    q = torch.tensor([[0.0, 1.0, 3.0]]).expand(2000, 1, 3)          # (agents, heads, choices)
    assert (epsilon_greedy(q, 0.0, rng) == 2).all()
    uniform = epsilon_greedy(q, 1.0, rng)
    assert set(np.unique(uniform)) == {0, 1, 2} and 0.28 < np.mean(uniform == 0) < 0.39
    allowed = torch.tensor([[True, True, False]]).expand(2000, 1, 3)
    masked = epsilon_greedy(q, 0.5, rng, allowed)
    assert set(np.unique(masked)) == {0, 1} and np.mean(masked == 1) > 0.7      # greedy among the allowed: 1


def test_iql_learns_a_cue_matching_task(tmp_path):
    config = DQNConfig(algo='iql', total_steps=16 * 400, num_envs=16, buffer_size=20_000, batch_size=128,
                       learning_starts=500, target_update=200, hidden=(32,), epsilon_schedule=((0, 1.0), (2_000, 0.05)),
                       lr_schedule=((0, 3e-3),), report_every=640, seed=0)
    rows = []
    train_dqn(config, tmp_path, progress=False, envs=CueMatching(num_envs=16, num_agents=2, num_actions=4),
              callback=rows.append)
    assert rows[0]['rollout_coverage'] < 0.5 and rows[-1]['rollout_coverage'] > 0.9     # the reward: cues matched
    assert rows[-1]['epsilon'] == pytest.approx(0.05) and np.isfinite(rows[-1]['loss'])


def test_iql_checkpoints_resume_and_play_in_mate_evaluate(tmp_path):
    config = DQNConfig(algo='iql', team='target', env_id='MATE-2v4-0-v0', total_steps=4 * 60, num_envs=4,
                       buffer_size=2_000, batch_size=32, learning_starts=80, hidden=(16,), report_every=80, seed=1)
    first = train_dqn(config, tmp_path, progress=False)
    assert first['env_steps'] == 240
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['meta']['actor'] == 'dueling' and set(saved) >= {'actor', 'target', 'optimizer'}
    longer = DQNConfig(**{**config.__dict__, 'total_steps': 4 * 100})
    resumed = train_dqn(longer, tmp_path, progress=False)
    assert resumed['env_steps'] == 400 and resumed['iteration'] == 5
    policy = load_policy(tmp_path / 'final.pt', 'target')
    assert policy.meta['deterministic'] and policy.meta['num_actions'] == 25
    results, _ = play_batch('MATE-2v4-0', lambda b, c: make_team('greedy', 'camera', b, c, seed=0),
                            lambda b, c: PolicyTeam(policy, 'target', b, c), episodes=2, max_episode_steps=50)
    assert [r.episode_length for r in results] == [50, 50]
    with pytest.raises(CheckpointError, match='does not match this experiment'):
        train_dqn(DQNConfig(**{**longer.__dict__, 'hidden': (16,), 'team': 'camera', 'env_id': 'MATE-2v4-0-v0'}),
                  tmp_path, progress=False)


def test_hrl_iql_selects_only_visible_targets(tmp_path):
    seen = []

    def record(row):
        seen.append(row)

    config = DQNConfig(algo='iql', team='camera', env_id='MATE-2v4-0-v0', hrl=True, total_steps=4 * 30, num_envs=4,
                       buffer_size=1_000, batch_size=16, learning_starts=40, hidden=(16,), report_every=40, seed=0)
    train_dqn(config, tmp_path, progress=False, callback=record)
    policy = load_policy(tmp_path / 'final.pt', 'camera')
    assert policy.meta['hrl'] and policy.meta['action_heads'] == 4 and policy.meta['action_choices'] == 2
    assert len(seen) == 3 and all(np.isfinite(row['q_mean']) for row in seen[1:])


def test_mate_train_iql_command(tmp_path, capsys):
    from mate.cli import main

    run_dir = tmp_path / 'iql'
    args = ['train', 'iql', '--team', 'target', '--config', 'MATE-2v4-0', '--steps', '160', '--num-envs', '4',
            '--learning-starts', '80', '--buffer-size', '1000', '--batch-size', '16', '--run-dir', str(run_dir),
            '--no-progress']
    assert main(args) == 0
    assert 'training IQL targets on MATE-2v4-0-v0 (dueling Q-network' in capsys.readouterr().out
    assert load_checkpoint(run_dir / 'final.pt')['config']['buffer_size'] == 1000
    assert main(args) == 0 and 'run already done' in capsys.readouterr().out
    assert main(['train', 'iql', '--epochs', '3']) == 2
    assert '--epochs is not an option of IQL' in capsys.readouterr().err
    assert main(['train', 'mappo', '--buffer-size', '10']) == 2
    assert '--buffer-size is not an option of MAPPO' in capsys.readouterr().err
    assert main(['train', 'iql', '--epsilon-schedule', '[[0, 1], [oops]]']) == 2
    assert '--epsilon-schedule must be JSON' in capsys.readouterr().err
