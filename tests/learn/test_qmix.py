"""QMIX (mate.learn.qmix): the mixer's monotonicity, the sequence replay, the loss by hand, a matrix game QMIX solves
and IQL does not, checkpoints, HRL selections, `mate train qmix`."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mate.cli.main import main
from mate.learn import iql
from mate.policies.checkpoint import CheckpointError, load_checkpoint
from mate.policies.networks import RecurrentQNetwork
from mate.policies.policy import make_actor
from mate.learn.qmix import QMIXConfig, QMixer, qmix_loss, train
from mate.learn.replay import SequenceReplay
from mate.policies.spec import PolicySpec

from .toy import TwoStepGame



# MATE-2v4-0 HRL cameras (a keep/ignore head per target), 4 envs: 60 decisions of 4 decision steps, a log row every 80
SMALL = dict(team='camera', config='MATE-2v4-0', hrl=True, selection='per-target', steps=4 * 60, num_envs=4,
             buffer_size=2_000, batch_size=40, sequence_length=10, learning_starts=80, update_every=40, hidden=(16,),
             mixer_embed=8, report_every=80, seed=1, progress=False)


def spec_of(path) -> PolicySpec:
    return PolicySpec.from_dict(load_checkpoint(path)['spec'])


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
    assert (batch['obs'].shape == (5, 4, 2, 1) and batch['action'].shape == (5, 3, 2, 1)
            and batch['mask'].shape == (5, 3))
    assert batch['h0'].shape == (5, 2, 1) and batch['state'].shape == (5, 4, 1)
    # its state: the stored chunks and the open ones; a copy samples and records the same
    state = replay.state_dict()
    assert state['stored']['obs'].shape[0] == 2 and state['open']['obs'].shape[0] == 2
    copy = SequenceReplay(capacity=30, length=3, rows=2, agents=2, obs_dim=1, state_dim=1, heads=1, hidden=1)
    copy.load_state_dict(state)
    for r in (replay, copy):
        zeros = np.zeros(2, np.float32)
        r.record(obs, np.zeros((2, 1), np.float32), np.zeros((2, 2, 1)), zeros, zeros, np.array([True, True]), obs,
                 np.zeros((2, 1), np.float32), h)
    a, b = (r.sample(6, np.random.default_rng(1)) for r in (replay, copy))
    assert copy.size == replay.size == 4 and all(torch.equal(a[key], b[key]) for key in a)
    assert not SequenceReplay(capacity=33, length=3, rows=2, agents=2, obs_dim=1, state_dim=1, heads=1,
                              hidden=1).fits(state)


def test_qmix_loss_by_hand():
    torch.manual_seed(0)
    online, target = RecurrentQNetwork(3, 1, 2, width=4), RecurrentQNetwork(3, 1, 2, width=4)
    mixer, target_mixer = QMixer(5, 2, embed=4), QMixer(5, 2, embed=4)
    K, L = 2, 2
    batch = dict(obs=torch.randn(K, L + 1, 2, 3), state=torch.randn(K, L + 1, 5),
                 action=torch.randint(2, (K, L, 2, 1), dtype=torch.int16), reward=torch.randn(K, L),
                 terminal=torch.tensor([[0.0, 1.0], [0.0, 0.0]]), mask=torch.tensor([[1.0, 1.0], [1.0, 0.0]]),
                 h0=torch.randn(K, 2, 4))
    loss, _ = qmix_loss(online, target, mixer, target_mixer, batch, 0.9, 1)
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
                y = (batch['reward'][k, t - 1]
                     + 0.9 * (1 - batch['terminal'][k, t - 1]) * target_mixer(next_value, batch['state'][k, t]))
                errors.append((previous - y).item() ** 2)
            if t < L:
                taken = q_on.gather(-1, batch['action'][k, t].long())[:, 0]
                previous = mixer(taken, batch['state'][k, t])
    torch.set_grad_enabled(True)
    assert len(errors) == 3
    assert loss.item() == pytest.approx(np.mean(errors), rel=1e-5)


def greedy_return(path) -> float:
    """The two-step game's return of the greedy joint policy of a policy file (its network built from its spec)."""
    saved = load_checkpoint(path)
    spec = PolicySpec.from_dict(saved['spec'])
    net = make_actor(spec)
    net.load_state_dict(saved['actor'])
    memory = net.initial_state(2) if spec.recurrent else None
    returns, stage = [], 0
    with torch.no_grad():
        for _ in range(2):
            obs = torch.eye(3)[[stage, stage]]
            if spec.recurrent:
                q, memory = net.step(obs, memory)
            else:
                q = net(obs)
            action = q.argmax(-1)
            returns.append(0.0 if stage == 0 else 7.0 if stage == 1 else TwoStepGame.PAYOFF_2B[action[0], action[1]])
            stage = 1 + int(action[0])
    return sum(returns)


@pytest.mark.slow
@pytest.mark.parametrize('seed', [0, 1])
def test_qmix_solves_the_two_step_game_that_iql_does_not(tmp_path, seed):
    """Trained on fully exploratory data (epsilon 1 throughout), as in the QMIX paper: the greedy joint
    policy of QMIX earns the optimum 8, IQL's 7 (it values stage 2B at the average over its partner)."""
    common = dict(steps=4000, num_envs=16, learning_starts=256, batch_size=128, update_every=16, target_update=64,
                  hidden=(32,), epsilon_schedule=((0, 1.0), (10 ** 9, 1.0)), lr_schedule=((0, 5e-3),),
                  report_every=1000, seed=seed, progress=False)
    iql.train(iql.IQLConfig(**common, run_dir=str(tmp_path / 'iql')), envs=TwoStepGame(16))
    train(QMIXConfig(**common, mixer_embed=16, sequence_length=2, run_dir=str(tmp_path / 'qmix')), envs=TwoStepGame(16))
    assert greedy_return(tmp_path / 'iql' / 'final.pt') == 7.0
    assert greedy_return(tmp_path / 'qmix' / 'final.pt') == 8.0


def test_qmix_checkpoints_resume_and_refuse_another_experiment(tmp_path):
    first = train(QMIXConfig(**SMALL, run_dir=str(tmp_path)))
    assert first.env_steps == 240 and np.isfinite(first.last_row['loss'])
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['algo'] == 'qmix' and PolicySpec.from_dict(saved['spec']).network == 'recurrent-q'
    assert list(saved['state']['networks']) == ['actor', 'target', 'mixer', 'target_mixer']
    assert saved['state']['hidden'].shape == (4, 2, 16) and saved['state']['replay']['size'] > 0
    resumed = train(QMIXConfig(**{**SMALL, 'steps': 4 * 100}, run_dir=str(tmp_path)))
    assert resumed.env_steps == 400 and resumed.iteration == 5
    spec = spec_of(tmp_path / 'final.pt')
    assert spec.recurrent and spec.heads == 4 and spec.deterministic
    with pytest.raises(CheckpointError, match='does not match this experiment'):
        iql.train(iql.IQLConfig(team='camera', config='MATE-2v4-0', hrl=True, selection='per-target', steps=4 * 120,
                                num_envs=4, run_dir=str(tmp_path), progress=False))


def test_qmix_policy_plays_in_mate_evaluate(tmp_path):
    from mate.policies.policy import PolicyTeam, load_policy, make_team
    from mate.teams import play_batch

    train(QMIXConfig(**SMALL, run_dir=str(tmp_path)))
    policy = load_policy(tmp_path / 'final.pt', 'camera')
    results, _ = play_batch('MATE-2v4-0', lambda b, c: PolicyTeam(policy, 'camera', b, c),
                            lambda b, c: make_team('greedy', 'target', b, c, seed=0), episodes=2, max_episode_steps=50)
    assert [r.episode_length for r in results] == [50, 50]


def test_hrl_joint_selection_trains_one_of_2_to_the_nt_choices(tmp_path):
    config = QMIXConfig(**{**SMALL, 'selection': 'joint', 'steps': 4 * 40, 'update_every': 4, 'buffer_size': 1_000,
                           'batch_size': 20, 'sequence_length': 5, 'learning_starts': 40, 'report_every': 40,
                           'epsilon_schedule': ((0, 0.5), (1, 0.5)), 'seed': 0}, run_dir=str(tmp_path))
    run = train(config)
    assert np.isfinite(run.last_row['loss'])
    spec = spec_of(tmp_path / 'final.pt')
    assert spec.action == 'hrl-joint' and spec.heads == 1 and spec.num_actions == 16


def test_qmix_settings_errors():
    with pytest.raises(ValueError, match="credit must be 'team'"):
        QMIXConfig(credit='difference')
    with pytest.raises(ValueError, match='--sequence-length must be an integer >= 1'):
        QMIXConfig(sequence_length=0)
    with pytest.raises(ValueError, match='one width'):
        QMIXConfig(hidden=(64, 64))
    assert QMIXConfig().buffer_size == 1_000_000 and QMIXConfig().hidden == (256,) and QMIXConfig().steps == 2_000_000


def test_mate_train_qmix_command(tmp_path, capsys):
    run_dir = tmp_path / 'qmix'
    args = ['train', 'qmix', '--team', 'target', '--config', 'MATE-2v4-0', '--steps', '160', '--num-envs', '4',
            '--learning-starts', '80', '--buffer-size', '400', '--batch-size', '20', '--sequence-length', '10',
            '--update-every', '40', '--run-dir', str(run_dir), '--threads', '1', '--no-progress']
    assert main(args) == 0
    assert 'training QMIX targets on MATE-2v4-0-v0 (recurrent-q network' in ' '.join(capsys.readouterr().out.split())
    saved = load_checkpoint(run_dir / 'final.pt')
    assert saved['config']['sequence_length'] == 10 and PolicySpec.from_dict(saved['spec']).network == 'recurrent-q'
    for arguments, message in ((['train', 'iql', '--sequence-length', '5'],
                                'unrecognized arguments: --sequence-length'),
                               (['train', 'qmix', '--credit', 'difference'], "credit must be 'team'")):
        with pytest.raises(SystemExit) as stopped:
            main(arguments)
        assert stopped.value.code == 2 and message in capsys.readouterr().err
