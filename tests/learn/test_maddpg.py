"""MADDPG as MA-TD3 (mate.learn.matd3): the critic target by hand, really two critics, per-agent networks, the actor
update's inputs, learning a continuous toy task, continuous TrainingEnv actions, checkpoints that resume,
`mate train maddpg`."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mate.cli.main import main
from mate.policies.checkpoint import CheckpointError, load_checkpoint
from mate.learn.matd3 import (
    MATD3Config, TwinCritics, actor_inputs, critic_inputs, critic_targets, policy_spec, smoothed_actions, train,
)
from mate.policies.networks import AgentwiseMLP
from mate.policies.spec import PolicySpec, SpecError, action_high

from .toy import ContinuousCue



# MATE-2v4-0 targets, 4 envs: 60 decisions of 4 decision steps, a log row every 80
SMALL = dict(team='target', config='MATE-2v4-0', steps=4 * 60, num_envs=4, buffer_size=2_000, batch_size=32,
             update_every=8, learning_starts=80, random_steps=80, hidden=(16,), report_every=80, seed=1, progress=False)


def test_critic_target_with_smoothing_and_clipped_double_q_by_hand():
    # target-policy smoothing: noise clipped at +-0.5, then the action clipped to [-1, 1]
    actions = torch.tensor([[[0.9, -0.2], [0.0, 0.3]]])
    noise = torch.tensor([[[0.7, 0.1], [-0.2, -2.0]]])
    expected = torch.tensor([[[1.0, -0.1], [-0.2, -0.2]]])                    # 0.9 + 0.5 -> 1; 0.3 - 0.5
    torch.testing.assert_close(smoothed_actions(actions, noise, 0.5), expected)
    # clipped double-Q: the smaller of the two target critics, per agent; no bootstrap after a terminal
    reward = torch.tensor([[1.0, 2.0], [0.5, 0.5]])
    terminal = torch.tensor([0.0, 1.0])
    q1 = torch.tensor([[10.0, 3.0], [7.0, 7.0]])
    q2 = torch.tensor([[4.0, 8.0], [9.0, 9.0]])
    torch.testing.assert_close(critic_targets(reward, terminal, q1, q2, 0.9),
                               torch.tensor([[1.0 + 0.9 * 4.0, 2.0 + 0.9 * 3.0], [0.5, 0.5]]))


def test_twin_critics_are_two_networks_and_agents_have_their_own_weights():
    torch.manual_seed(0)
    critics = TwinCritics(agents=3, inputs=6, hidden=(8,))
    x = torch.randn(5, 3, 6)
    q1, q2 = critics(x)
    assert q1.shape == q2.shape == (5, 3) and not torch.allclose(q1, q2)
    assert not set(map(id, critics.q1.parameters())) & set(map(id, critics.q2.parameters()))
    # agent 1's critic on agent 0's input differs from agent 0's critic: independent weights
    same = x[:, :1].expand(5, 3, 6)
    values = critics.q1(same).squeeze(-1)
    assert not torch.allclose(values[:, 0], values[:, 1])
    mlp = AgentwiseMLP(2, 4, (8,), 3)
    y = torch.randn(2, 4)
    by_hand = torch.tanh(y[1] @ mlp.weights[0][1] + mlp.biases[0][1]) @ mlp.weights[1][1] + mlp.biases[1][1]
    torch.testing.assert_close(mlp(y)[1], by_hand)


@pytest.mark.parametrize('activation', ['tanh', 'relu'])
def test_agentwise_layers_in_place_give_the_values_and_gradients_of_fresh_tensors(activation):
    """`AgentwiseMLP` adds its biases and activates in place on each product: bitwise the outputs and gradients of
    `bmm(x, W) + b` and the activation module on fresh tensors (the formula it replaced)."""
    torch.manual_seed(0)
    mlp = AgentwiseMLP(3, 6, (8, 5), 2, activation)
    x = torch.randn(7, 3, 6, requires_grad=True)

    def fresh():
        h = x.transpose(0, 1)
        for layer, (w, b) in enumerate(zip(mlp.weights, mlp.biases)):
            h = torch.bmm(h, w) + b.unsqueeze(1)
            h = mlp.activation(h) if layer < len(mlp.weights) - 1 else h
        return h.transpose(0, 1)

    results = []
    for run in (lambda: mlp(x), fresh):
        mlp.zero_grad()
        x.grad = None
        out = run()
        (out * torch.arange(out.numel()).reshape(out.shape)).sum().backward()
        results.append([out.detach(), x.grad.clone(), *(p.grad.clone() for p in mlp.parameters())])
    assert all(torch.equal(a, b) for a, b in zip(*results))


def test_critic_and_actor_inputs():
    state = torch.tensor([[1.0, 2.0]])                                        # (K=1, S=2)
    joint = torch.tensor([[[0.1, 0.2], [0.3, 0.4]]])                          # (K, N=2, A=2)
    own = torch.tensor([[[-1.0, -2.0], [-3.0, -4.0]]], requires_grad=True)
    shared = critic_inputs(state, joint)
    assert (shared.shape == (1, 2, 6)
            and shared[0, 0].tolist() == shared[0, 1].tolist() == pytest.approx([1, 2, .1, .2, .3, .4]))
    mixed = actor_inputs(state, joint, own)
    assert mixed[0, 0].tolist() == pytest.approx([1, 2, -1, -2, 0.3, 0.4])    # agent 0's own action replaced
    assert mixed[0, 1].tolist() == pytest.approx([1, 2, 0.1, 0.2, -3, -4])
    mixed[0, 0].sum().backward()                                              # agent 0's critic input ...
    assert own.grad[0, 0].tolist() == [1, 1] and own.grad[0, 1].tolist() == [0, 0]   # ... reaches only agent 0


@pytest.mark.slow
def test_maddpg_learns_a_continuous_cue_task(tmp_path):
    # a one-step task (gamma 0): the critics learn the reward of a joint action, the actors its argmax; with the
    # exploration noise (0.1 of the bounds) the best expected team reward is ~0.94, uniform actions earn ~0.6
    config = MATD3Config(steps=16 * 300, num_envs=16, buffer_size=20_000, batch_size=128, update_every=4,
                         learning_starts=400, random_steps=400, hidden=(32, 32), actor_lr=3e-3, critic_lr=3e-3,
                         tau=0.05, gamma=0.0, report_every=800, seed=0, run_dir=str(tmp_path), progress=False)
    rows = []
    train(config, envs=ContinuousCue(num_envs=16), callback=rows.append)
    assert rows[0]['rollout_coverage'] < 0.7 and rows[-1]['rollout_coverage'] > 0.85     # the reward
    assert np.isfinite(rows[-1]['critic_loss']) and np.isfinite(rows[-1]['actor_loss'])


def test_team_env_takes_continuous_actions_as_shares_of_the_bounds():
    config = MATD3Config(team='target', config='MATE-2v4-0', frame_skip=1, num_envs=2, seed=0)
    spec = policy_spec(config)
    env = config.make_env(spec)
    assert spec.continuous and env.num_actions == 2 and env.action_heads == 1
    env.reset(seed=3)
    high = action_high(env.raw_observations, 'target')
    with pytest.raises(SpecError, match='levels >= 2'):
        spec.replace(action='grid', network='mlp', levels=1)
    with pytest.raises(SpecError, match="'independent'.*continuous actions"):
        spec.replace(action='grid', levels=5)
    share = np.array([[[0.5, -1.0]] * 4, [[-0.25, 0.75]] * 4], dtype=np.float32)
    np.testing.assert_allclose(spec.decode(share, env.raw_observations), share * high)   # shares of each one's bounds
    obs, *_ = env.step(share)
    assert high.shape == (2, 4, 2) and np.isfinite(obs).all()


def test_maddpg_checkpoints_resume_and_refuse_another_experiment(tmp_path):
    first = train(MATD3Config(**SMALL, run_dir=str(tmp_path)))
    assert first.env_steps == 240 and np.isfinite(first.last_row['critic_loss'])
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['algo'] == 'matd3' and PolicySpec.from_dict(saved['spec']).continuous
    assert list(saved['state']['networks']) == ['actor', 'critics', 'target_actor', 'target_critics']
    assert set(saved['state']['optimizers']) == {'actor', 'critic'} and saved['state']['replay']['size'] == 240
    resumed = train(MATD3Config(**{**SMALL, 'steps': 4 * 100}, run_dir=str(tmp_path)))
    assert resumed.env_steps == 400 and resumed.iteration == 5
    spec = PolicySpec.from_dict(load_checkpoint(tmp_path / 'final.pt')['spec'])
    assert spec.num_actions == 2 and spec.network == 'independent' and spec.deterministic
    with pytest.raises(CheckpointError, match='does not match this experiment'):
        train(MATD3Config(**{**SMALL, 'steps': 4 * 120, 'hidden': (8,)}, run_dir=str(tmp_path)))


def test_maddpg_policy_plays_in_mate_evaluate(tmp_path):
    import mate
    from mate.policies.policy import PolicyTargetAgent, PolicyTeam, load_policy, make_team
    from mate.teams import play_batch

    train(MATD3Config(**SMALL, run_dir=str(tmp_path)))
    policy = load_policy(tmp_path / 'final.pt', 'target')
    results, _ = play_batch('MATE-2v4-0', lambda b, c: make_team('greedy', 'camera', b, c, seed=0),
                            lambda b, c: PolicyTeam(policy, 'target', b, c), episodes=2, max_episode_steps=50)
    assert [r.episode_length for r in results] == [50, 50]
    # a deployed agent acts with its own actor: the batched team's action for its row
    env = mate.make('MATE-2v4-0-v0')
    env = mate.MultiTarget(env, camera_agent=mate.GreedyCameraAgent(seed=0))
    observations, _ = env.reset(seed=5)
    agents = [PolicyTargetAgent(policy, seed=0) for _ in range(4)]
    mate.group_reset(agents, observations)
    actions = np.array([agent.act(o) for agent, o in zip(agents, observations)])
    team = PolicyTeam(policy, 'target', 1, (2, 4, 0))
    team.reset(observations[None], np.ones(1, dtype=bool))
    np.testing.assert_allclose(actions, team.act(observations[None])[0], rtol=1e-5)
    assert len({tuple(a) for a in np.round(actions / action_high(observations, 'target'), 4)}) > 1


def test_maddpg_settings_errors():
    with pytest.raises(ValueError, match=r'--tau must be a number > 0 and <= 1, got 0'):
        MATD3Config(tau=0)
    with pytest.raises(ValueError, match='--policy-delay must be an integer >= 1'):
        MATD3Config(policy_delay=0)
    with pytest.raises(ValueError, match='--hrl is not an option of MA-TD3'):
        MATD3Config(hrl=True)
    assert MATD3Config().steps == 2_000_000 and MATD3Config().num_envs == 16 and MATD3Config().team == 'camera'


def test_mate_train_maddpg_command(tmp_path, capsys):
    run_dir = tmp_path / 'maddpg'
    args = ['train', 'maddpg', '--team', 'target', '--config', 'MATE-2v4-0', '--steps', '160', '--num-envs', '4',
            '--learning-starts', '80', '--buffer-size', '400', '--batch-size', '16', '--update-every', '40',
            '--run-dir', str(run_dir), '--threads', '1', '--no-progress']
    assert main(args) == 0
    assert 'training MADDPG targets on MATE-2v4-0-v0 (independent network, continuous actions' in ' '.join(
        capsys.readouterr().out.split())
    saved = load_checkpoint(run_dir / 'final.pt')
    assert saved['config']['buffer_size'] == 400 and PolicySpec.from_dict(saved['spec']).continuous
    assert main(args) == 0 and 'run already done' in capsys.readouterr().out
    for arguments, message in ((['train', 'maddpg', '--team', 'camera', '--hrl'], 'unrecognized arguments: --hrl'),
                               (['train', 'matd3', '--epochs', '2'], 'unrecognized arguments: --epochs 2')):
        with pytest.raises(SystemExit) as stopped:
            main(arguments)
        assert stopped.value.code == 2 and message in capsys.readouterr().err
