"""IQL (mate.learn.iql) and the double Q-learning pieces it shares with QMIX (mate.learn.qlearning): the formulas by
hand, the replay ring, exploration, learning a cue-matching task, checkpoints, HRL selections, `mate train iql`."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mate.cli.main import main
from mate.policies.checkpoint import CheckpointError, load_checkpoint
from mate.policies.hrl import joint_allowed, selection_bits
from mate.learn.iql import IQLConfig, train
from mate.policies.networks import DuelingQNetwork
from mate.learn.qlearning import double_q_targets, epsilon_greedy
from mate.learn.replay import ReplayBuffer
from mate.policies.spec import PolicySpec

from .toy import CueMatching



# MATE-2v4-0 targets, 4 envs: 60 decisions of 4 decision steps, a log row every 80
SMALL = dict(team='target', config='MATE-2v4-0', steps=4 * 60, num_envs=4, update_every=4, buffer_size=2_000,
             batch_size=32, learning_starts=80, hidden=(16,), report_every=80, seed=1, progress=False)


def spec_of(path) -> PolicySpec:
    return PolicySpec.from_dict(load_checkpoint(path)['spec'])


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
    torch.testing.assert_close(joint,
                               value[:, 0] + (advantage - advantage.mean(-1, keepdim=True)).max(-1).values.sum(-1))


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


def test_replay_state_holds_the_filled_rows_and_samples_the_same():
    replay = ReplayBuffer(8, obs_dim=2, heads=1)
    replay.add(np.arange(6, dtype=np.float32).reshape(3, 2), np.ones((3, 1)), np.ones(3), np.zeros((3, 2)), np.zeros(3))
    state = replay.state_dict()
    assert state['size'] == 3 and state['rows']['obs'].shape == (3, 2)          # the filled rows only
    copy = ReplayBuffer(8, obs_dim=2, heads=1)
    copy.load_state_dict(state)
    assert (copy.size, copy.cursor) == (3, 3)
    a, b = (r.sample(10, np.random.default_rng(4)) for r in (replay, copy))
    assert all(torch.equal(a[key], b[key]) for key in a)
    assert not ReplayBuffer(9, obs_dim=2, heads=1).fits(state) and not copy.fits(None)


def test_epsilon_greedy_explores_only_among_allowed_choices():
    rng = np.random.default_rng(0)
    q = torch.tensor([[0.0, 1.0, 3.0]]).expand(2000, 1, 3)          # (agents, heads, choices)
    assert (epsilon_greedy(q, 0.0, rng) == 2).all()
    uniform = epsilon_greedy(q, 1.0, rng)
    assert set(np.unique(uniform)) == {0, 1, 2} and 0.28 < np.mean(uniform == 0) < 0.39
    allowed = torch.tensor([[True, True, False]]).expand(2000, 1, 3)
    masked = epsilon_greedy(q, 0.5, rng, allowed)
    assert set(np.unique(masked)) == {0, 1} and np.mean(masked == 1) > 0.7      # greedy among the allowed: 1


@pytest.mark.slow
def test_iql_learns_a_cue_matching_task(tmp_path):
    config = IQLConfig(steps=16 * 400, num_envs=16, buffer_size=20_000, batch_size=128, update_every=16,
                       learning_starts=500, target_update=200, hidden=(32,), epsilon_schedule=((0, 1.0), (2_000, 0.05)),
                       lr_schedule=((0, 3e-3),), report_every=640, seed=0, run_dir=str(tmp_path), progress=False)
    rows = []
    train(config, envs=CueMatching(num_envs=16, num_agents=2, num_actions=4), callback=rows.append)
    assert rows[0]['rollout_coverage'] < 0.5 and rows[-1]['rollout_coverage'] > 0.9     # the reward: cues matched
    assert rows[-1]['epsilon'] == pytest.approx(0.05) and np.isfinite(rows[-1]['loss'])


def test_iql_checkpoints_resume_and_refuse_another_experiment(tmp_path):
    first = train(IQLConfig(**SMALL, run_dir=str(tmp_path)))
    assert first.env_steps == 240 and not first.interrupted
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['algo'] == 'iql' and PolicySpec.from_dict(saved['spec']).network == 'dueling'
    assert set(saved['state']['networks']) == {'actor', 'target'} and 'optimizer' in saved['state']
    assert 'replay' in saved['state'] and saved['state']['replay']['size'] == 960     # the session's end: with it
    resumed = train(IQLConfig(**{**SMALL, 'steps': 4 * 100}, run_dir=str(tmp_path)))
    assert resumed.env_steps == 400 and resumed.iteration == 5
    spec = spec_of(tmp_path / 'final.pt')
    assert spec.deterministic and spec.num_actions == 25 and spec.action == 'grid'
    assert set(load_checkpoint(tmp_path / 'final.pt')) >= {'spec', 'actor'}
    with pytest.raises(CheckpointError, match='does not match this experiment'):
        train(IQLConfig(**{**SMALL, 'steps': 4 * 120, 'team': 'camera'}, run_dir=str(tmp_path)))


def test_iql_keeps_snapshots_that_load_as_policies(tmp_path):
    """`--snapshot-every` is the run's (`RunConfig`), not PPO's: every trainer keeps its policy every N iterations."""
    from mate.policies.policy import load_policy

    train(IQLConfig(**SMALL, snapshot_every=2, run_dir=str(tmp_path)))          # 3 iterations of 80 decision steps
    assert sorted(p.name for p in (tmp_path / 'snapshots').iterdir()) == ['policy-0000000160.pt']
    policy = load_policy(tmp_path / 'snapshots' / 'policy-0000000160.pt', 'target')
    assert policy.spec.algo == 'iql' and policy.spec.num_actions == 25


def test_iql_policy_plays_in_mate_evaluate(tmp_path):
    from mate.policies.policy import PolicyTeam, load_policy, make_team
    from mate.teams import play_batch

    train(IQLConfig(**SMALL, run_dir=str(tmp_path)))
    policy = load_policy(tmp_path / 'final.pt', 'target')
    results, _ = play_batch('MATE-2v4-0', lambda b, c: make_team('greedy', 'camera', b, c, seed=0),
                            lambda b, c: PolicyTeam(policy, 'target', b, c), episodes=2, max_episode_steps=50)
    assert [r.episode_length for r in results] == [50, 50]


def test_hrl_iql_selects_only_visible_targets(tmp_path):
    seen = []
    config = IQLConfig(**{**SMALL, 'team': 'camera', 'hrl': True, 'selection': 'per-target', 'steps': 4 * 30,
                          'buffer_size': 1_000, 'batch_size': 16, 'learning_starts': 40, 'report_every': 40,
                          'seed': 0}, run_dir=str(tmp_path))
    train(config, callback=seen.append)
    spec = spec_of(tmp_path / 'final.pt')
    assert spec.action == 'hrl' and spec.heads == 4 and spec.choices == 2
    assert len(seen) == 3 and all(np.isfinite(row['q_mean']) for row in seen[1:])


def test_joint_selection_indices_and_their_allowed_set():
    bits = selection_bits(3)
    assert bits.shape == (8, 3) and bits[5].tolist() == [1, 0, 1] and bits[0].tolist() == [0, 0, 0]
    visible = np.array([[True, False, True], [False, False, False]])
    allowed = joint_allowed(visible)
    assert np.flatnonzero(allowed[0]).tolist() == [0, 1, 4, 5]          # subsets of the visible {0, 2}
    assert np.flatnonzero(allowed[1]).tolist() == [0]                    # nothing visible: keep nothing


HRL_JOINT = dict(SMALL, team='camera', hrl=True, steps=4 * 40, buffer_size=1_000, batch_size=20, learning_starts=40,
                 report_every=40, epsilon_schedule=((0, 0.5), (1, 0.5)), seed=0)


def test_hrl_joint_selection_trains_one_of_2_to_the_nt_choices(tmp_path):
    run = train(IQLConfig(**HRL_JOINT, run_dir=str(tmp_path)))
    assert np.isfinite(run.last_row['loss'])
    spec = spec_of(tmp_path / 'final.pt')
    assert spec.action == 'hrl-joint' and spec.heads == 1 and spec.num_actions == 16
    with pytest.raises(ValueError, match='selection must be one of joint, per-target'):
        IQLConfig(hrl=True, selection='pairs')
    with pytest.raises(ValueError, match='--selection per-target is how HRL cameras select targets; it needs --hrl'):
        IQLConfig(selection='per-target')


def test_hrl_joint_iql_plays_only_selections_of_visible_targets(tmp_path):
    import mate
    from mate.policies.policy import PolicyCameraAgent, PolicyTeam, load_policy, make_team
    from mate.teams import play_batch
    from mate.policies.hrl import target_records

    train(IQLConfig(**HRL_JOINT, run_dir=str(tmp_path)))
    policy = load_policy(tmp_path / 'final.pt', 'camera')
    results, _ = play_batch('MATE-2v4-0', lambda b, c: PolicyTeam(policy, 'camera', b, c),
                            lambda b, c: make_team('greedy', 'target', b, c, seed=0), episodes=2, max_episode_steps=30)
    assert [r.episode_length for r in results] == [30, 30]
    # deployed, a one-choice policy only takes selections of visible targets (as in training), batched and single
    vec = mate.make_vec('MATE-2v4-0-v0', num_envs=3)
    (camera_obs, _), _ = vec.reset(seed=2)
    team = PolicyTeam(policy, 'camera', 3, (2, 4, 0))
    team.reset(camera_obs, np.ones(3, dtype=bool))
    team.act(camera_obs)
    visible = target_records(camera_obs, 2, 4, 0)[..., 4] > 0.5
    assert not (selection_bits(4)[team.held[..., 0]].astype(bool) & ~visible).any()
    env = mate.MultiCamera(mate.make('MATE-2v4-0-v0'), target_agent=mate.GreedyTargetAgent(seed=0))
    observations, _ = env.reset(seed=2)
    agents = [PolicyCameraAgent(policy, seed=0), PolicyCameraAgent(policy, seed=1)]
    mate.group_reset(agents, observations)
    for a, o in zip(agents, observations):
        a.act(o)
        assert not (selection_bits(4)[a._held[0]].astype(bool) & ~(target_records(o, 2, 4, 0)[..., 4] > 0.5)).any()


def test_iql_settings_errors():
    with pytest.raises(ValueError, match='--batch-size must be an integer >= 1'):
        IQLConfig(batch_size=0)
    with pytest.raises(ValueError, match='--update-every must be an integer >= 1'):
        IQLConfig(update_every=0)
    with pytest.raises(ValueError, match='--hrl exists for cameras only'):
        IQLConfig(team='target', hrl=True)
    assert IQLConfig().steps == 2_000_000 and IQLConfig().num_envs == 16 and IQLConfig().buffer_size == 500_000


def test_mate_train_iql_command(tmp_path, capsys):
    run_dir = tmp_path / 'iql'
    args = ['train', 'iql', '--team', 'target', '--config', 'MATE-2v4-0', '--steps', '160', '--num-envs', '4',
            '--learning-starts', '80', '--buffer-size', '1000', '--batch-size', '16', '--run-dir', str(run_dir),
            '--threads', '1', '--no-progress']
    assert main(args) == 0
    assert 'training IQL targets on MATE-2v4-0-v0 (dueling network' in ' '.join(capsys.readouterr().out.split())
    assert load_checkpoint(run_dir / 'final.pt')['config']['buffer_size'] == 1000
    assert main(args) == 0 and 'run already done' in capsys.readouterr().out
    for arguments, message in ((['train', 'iql', '--epochs', '3'], 'unrecognized arguments: --epochs 3'),
                               (['train', 'mappo', '--buffer-size', '10'], 'unrecognized arguments: --buffer-size 10'),
                               (['train', 'iql', '--epsilon-schedule', '[[0, 1], [oops]]'],
                                'argument --epsilon-schedule: expected JSON [[step, value], ...]')):
        with pytest.raises(SystemExit) as stopped:
            main(arguments)
        assert stopped.value.code == 2 and message in capsys.readouterr().err
