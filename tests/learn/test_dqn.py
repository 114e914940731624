"""IQL and QMIX (mate.learn.dqn): the formulas by hand, the replays, exploration, the mixer's monotonicity, a
matrix game QMIX solves and IQL does not, checkpoints."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import mate

from mate.learn.agents import PolicyCameraAgent, load_policy
from mate.learn.checkpoint import CheckpointError, load_checkpoint
from mate.learn.dqn import (
    DQNConfig, QMixer, ReplayBuffer, SequenceReplay, double_q_targets, epsilon_greedy, qmix_loss, train_dqn,
)
from mate.learn.evaluate import PolicyTeam, make_team, play_batch
from mate.learn.hrl import joint_allowed, selection_bits, target_records
from mate.learn.networks import DuelingQNetwork, RecurrentQNetwork

from .toy import CueMatching, TwoStepGame


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
    config = DQNConfig(algo='iql', total_steps=16 * 400, num_envs=16, buffer_size=20_000, batch_size=128, update_every=16,
                       learning_starts=500, target_update=200, hidden=(32,), epsilon_schedule=((0, 1.0), (2_000, 0.05)),
                       lr_schedule=((0, 3e-3),), report_every=640, seed=0)
    rows = []
    train_dqn(config, tmp_path, progress=False, envs=CueMatching(num_envs=16, num_agents=2, num_actions=4),
              callback=rows.append)
    assert rows[0]['rollout_coverage'] < 0.5 and rows[-1]['rollout_coverage'] > 0.9     # the reward: cues matched
    assert rows[-1]['epsilon'] == pytest.approx(0.05) and np.isfinite(rows[-1]['loss'])


def test_iql_checkpoints_resume_and_play_in_mate_evaluate(tmp_path):
    config = DQNConfig(algo='iql', team='target', env_id='MATE-2v4-0-v0', total_steps=4 * 60, num_envs=4, update_every=4,
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

    config = DQNConfig(algo='iql', team='camera', env_id='MATE-2v4-0-v0', hrl=True, selection='per-target',
                       total_steps=4 * 30, num_envs=4, update_every=4,
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


# ---------------------------------------------------------------------------------------------------- QMIX

def test_mixer_is_monotonic_in_every_agents_value():
    torch.manual_seed(0)
    mixer = QMixer(state_dim=7, agents=3, embed=16)
    q = torch.randn(200, 3, requires_grad=True)
    state = torch.randn(200, 7) * 3
    mixer(q, state).sum().backward()
    assert (q.grad >= 0).all() and (q.grad > 0).any()
    # and it is not additive: the weights depend on the state
    other = torch.randn(200, 7) * 3
    q2 = q.detach().clone().requires_grad_(True)
    mixer(q2, other).sum().backward()
    assert not torch.allclose(q.grad, q2.grad)


def test_sequence_replay_closes_chunks_at_length_and_episode_ends():
    # 2 rows, chunks of 3 decisions; row 1's episode ends after its 2nd decision
    replay = SequenceReplay(capacity=30, length=3, rows=2, agents=2, obs_dim=1, state_dim=1, heads=1, hidden=1)
    assert replay.chunks == 10
    ended = [np.array([False, False]), np.array([False, True]), np.array([False, False]), np.array([False, False])]
    for t, end in enumerate(ended):
        obs = np.full((2, 2, 1), t, np.float32)
        h = np.full((2, 2, 1), 10 + t, np.float32)
        h[end] = 0.0
        replay.record(obs, np.full((2, 1), t, np.float32), np.full((2, 2, 1), t), np.array([t, -t], np.float32),
                      end.astype(np.float32), end, obs + 0.5, np.full((2, 1), t + 0.5, np.float32), h)
    # closed: row 1 at t=1 (episode end, 2 decisions), row 0 at t=2 (full)
    assert replay.size == 2
    first, second = ({k: v[i] for k, v in replay.stored.items()} for i in range(2))
    assert first['mask'].tolist() == [1, 1, 0] and first['terminal'].tolist() == [0, 1, 0]
    assert first['obs'][:3, 0, 0].tolist() == [0, 1, 1.5] and first['reward'][:2].tolist() == [0, -1]
    assert second['mask'].tolist() == [1, 1, 1] and second['obs'][:, 0, 0].tolist() == [0, 1, 2, 2.5]
    assert second['state'][:, 0].tolist() == [0, 1, 2, 2.5] and second['h0'].max() == 0     # opened at reset
    # row 1's new chunk starts at t=2 with the state handed over at its reset (zero); row 0's at t=3 with h=12
    assert replay.open['h0'][1].max() == 0 and replay.position.tolist() == [1, 2]
    assert replay.open['h0'][0].min() == 12 and replay.open['obs'][0, 0, 0, 0] == 3
    batch = replay.sample(5, np.random.default_rng(0))
    assert batch['obs'].shape == (5, 4, 2, 1) and batch['action'].shape == (5, 3, 2, 1) and batch['mask'].shape == (5, 3)
    assert batch['h0'].shape == (5, 2, 1) and batch['state'].shape == (5, 4, 1)


def test_qmix_loss_by_hand():
    torch.manual_seed(0)
    online, target = RecurrentQNetwork(3, 1, 2, width=4), RecurrentQNetwork(3, 1, 2, width=4)
    mixer, target_mixer = QMixer(5, 2, embed=4), QMixer(5, 2, embed=4)
    K, L = 2, 2
    batch = dict(obs=torch.randn(K, L + 1, 2, 3), state=torch.randn(K, L + 1, 5),
                 action=torch.randint(2, (K, L, 2, 1), dtype=torch.int16), reward=torch.randn(K, L),
                 terminal=torch.tensor([[0.0, 1.0], [0.0, 0.0]]), mask=torch.tensor([[1.0, 1.0], [1.0, 0.0]]),
                 h0=torch.randn(K, 2, 4))
    loss, _ = qmix_loss(online, target, mixer, target_mixer, batch, 0.9, 1, lambda obs: None)
    torch.set_grad_enabled(False)
    errors = []
    for k in range(K):
        h_on, h_tg, previous = batch['h0'][k], batch['h0'][k], None
        for t in range(L + 1):
            q_on, (h_on,) = online.step(batch['obs'][k, t], (h_on,))
            q_tg, (h_tg,) = target.step(batch['obs'][k, t], (h_tg,))
            if t > 0 and batch['mask'][k, t - 1]:
                best = q_on.argmax(-1)                                      # the online network chooses
                next_value = q_tg.gather(-1, best[:, None])[:, 0]
                y = batch['reward'][k, t - 1] + 0.9 * (1 - batch['terminal'][k, t - 1]) * target_mixer(next_value, batch['state'][k, t])
                errors.append((previous - y).item() ** 2)
            if t < L:
                taken = q_on.gather(-1, batch['action'][k, t].long())[:, 0]
                previous = mixer(taken, batch['state'][k, t])
    torch.set_grad_enabled(True)
    assert len(errors) == 3
    assert loss.item() == pytest.approx(np.mean(errors), rel=1e-5)


@pytest.mark.parametrize('seed', [0, 1])
def test_qmix_solves_the_two_step_game_that_iql_does_not(tmp_path, seed):
    """Trained on fully exploratory data (epsilon 1 throughout), as in the QMIX paper: the greedy joint
    policy of QMIX earns the optimum 8, IQL's 7 (it values stage 2B at the average over its partner)."""

    def greedy_return(path):
        policy = load_policy(path)
        memory = policy.initial_memory(2)
        returns = []
        with torch.no_grad():
            stage = 0
            for _ in range(2):
                obs = torch.eye(3)[[stage, stage]]
                if policy.recurrent:
                    q, memory = policy.actor.step(obs, memory)
                else:
                    q = policy.actor(obs)
                action = q.argmax(-1)
                returns.append(0.0 if stage == 0 else 7.0 if stage == 1 else TwoStepGame.PAYOFF_2B[action[0], action[1]])
                stage = 1 + int(action[0])
        return sum(returns)

    for algo, optimum in (('iql', 7.0), ('qmix', 8.0)):
        config = DQNConfig(algo=algo, total_steps=4000, num_envs=16, learning_starts=256, batch_size=128,
                           update_every=16, target_update=64, hidden=(32,), mixer_embed=16, sequence_length=2,
                           epsilon_schedule=((0, 1.0), (10 ** 9, 1.0)), lr_schedule=((0, 5e-3),), report_every=1000,
                           seed=seed)
        train_dqn(config, tmp_path / algo, progress=False, envs=TwoStepGame(16))
        assert greedy_return(tmp_path / algo / 'final.pt') == optimum, algo


def test_qmix_checkpoints_resume_and_play_in_mate_evaluate(tmp_path):
    config = DQNConfig(algo='qmix', team='camera', env_id='MATE-2v4-0-v0', hrl=True, selection='per-target',
                       total_steps=4 * 60, num_envs=4,
                       buffer_size=2_000, batch_size=40, sequence_length=10, learning_starts=80, update_every=40,
                       hidden=(16,), mixer_embed=8, report_every=80, seed=1)
    first = train_dqn(config, tmp_path, progress=False)
    assert first['env_steps'] == 240 and np.isfinite(first['loss'])
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['meta']['actor'] == 'recurrent-q' and set(saved) >= {'actor', 'target', 'mixer', 'target_mixer'}
    longer = DQNConfig(**{**config.__dict__, 'total_steps': 4 * 100})
    resumed = train_dqn(longer, tmp_path, progress=False)
    assert resumed['env_steps'] == 400 and resumed['iteration'] == 5
    policy = load_policy(tmp_path / 'final.pt', 'camera')
    assert policy.recurrent and policy.meta['action_heads'] == 4
    results, _ = play_batch('MATE-2v4-0', lambda b, c: PolicyTeam(policy, 'camera', b, c),
                            lambda b, c: make_team('greedy', 'target', b, c, seed=0), episodes=2, max_episode_steps=50)
    assert [r.episode_length for r in results] == [50, 50]
    with pytest.raises(CheckpointError, match='does not match this experiment'):
        train_dqn(DQNConfig(**{**longer.__dict__, 'algo': 'iql'}), tmp_path, progress=False)


def test_qmix_settings_errors():
    with pytest.raises(ValueError, match="credit must be 'team'"):
        DQNConfig(algo='qmix', credit='difference').resolved()
    with pytest.raises(ValueError, match="valid: iql, qmix"):
        DQNConfig(algo='vdn').resolved()
    with pytest.raises(ValueError, match='sequence_length must be >= 1'):
        DQNConfig(algo='qmix', sequence_length=0).resolved()


def test_mate_train_qmix_command(tmp_path, capsys):
    from mate.cli import main

    run_dir = tmp_path / 'qmix'
    args = ['train', 'qmix', '--team', 'target', '--config', 'MATE-2v4-0', '--steps', '160', '--num-envs', '4',
            '--learning-starts', '80', '--buffer-size', '400', '--batch-size', '20', '--sequence-length', '10',
            '--update-every', '40', '--run-dir', str(run_dir), '--no-progress']
    assert main(args) == 0
    assert 'training QMIX targets on MATE-2v4-0-v0 (GRU agent network, mixer' in capsys.readouterr().out
    saved = load_checkpoint(run_dir / 'final.pt')
    assert saved['config']['sequence_length'] == 10 and saved['meta']['actor'] == 'recurrent-q'
    assert main(['train', 'iql', '--sequence-length', '5']) == 2
    assert '--sequence-length is not an option of IQL' in capsys.readouterr().err
    assert main(['train', 'qmix', '--credit', 'difference']) == 2
    assert "credit must be 'team'" in capsys.readouterr().err


def test_joint_selection_indices_and_their_allowed_set():
    bits = selection_bits(3)
    assert bits.shape == (8, 3) and bits[5].tolist() == [1, 0, 1] and bits[0].tolist() == [0, 0, 0]
    visible = np.array([[True, False, True], [False, False, False]])
    allowed = joint_allowed(visible)
    assert np.flatnonzero(allowed[0]).tolist() == [0, 1, 4, 5]          # subsets of the visible {0, 2}
    assert np.flatnonzero(allowed[1]).tolist() == [0]                    # nothing visible: keep nothing


@pytest.mark.parametrize('algo', ['iql', 'qmix'])
def test_hrl_joint_selection_trains_and_plays_one_of_2_to_the_nt_choices(tmp_path, algo):
    config = DQNConfig(algo=algo, team='camera', env_id='MATE-2v4-0-v0', hrl=True,
                       total_steps=4 * 40, num_envs=4, update_every=4, buffer_size=1_000, batch_size=20,
                       sequence_length=5, learning_starts=40, hidden=(16,), mixer_embed=8, report_every=40,
                       epsilon_schedule=((0, 0.5), (1, 0.5)), seed=0)
    row = train_dqn(config, tmp_path, progress=False)
    assert np.isfinite(row['loss'])
    policy = load_policy(tmp_path / 'final.pt', 'camera')
    assert policy.meta['joint_selection'] and policy.meta['action_heads'] == 1 and policy.meta['num_actions'] == 16
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
    agent = PolicyCameraAgent(policy, seed=0)
    env = mate.MultiCamera(mate.make('MATE-2v4-0-v0'), target_agent=mate.GreedyTargetAgent(seed=0))
    observations, _ = env.reset(seed=2)
    agents = [agent] + [PolicyCameraAgent(policy, seed=1)]
    mate.group_reset(agents, observations)
    for a, o in zip(agents, observations):
        a.act(o)
        assert not (selection_bits(4)[a._held[0]].astype(bool) & ~(target_records(o, 2, 4, 0)[..., 4] > 0.5)).any()
    with pytest.raises(ValueError, match="selection must be one of joint, per-target"):
        DQNConfig(selection='pairs').resolved()
