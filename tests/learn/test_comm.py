"""TarMAC (mate.learn.comm): attention over the team's messages, one-decision delay, gradients through the
messages, sequences equal to steps, a toy task that needs communication, checkpoints, batched play, the CLI."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
import torch

from mate.learn.agents import PolicyTargetAgent, load_agent, load_policy
from mate.learn.checkpoint import CheckpointError, load_checkpoint
from mate.learn.comm import TarMACActor
from mate.learn.evaluate import PolicyTeam, make_team, play_batch
from mate.learn.networks import make_actor
from mate.learn.ppo import PPOConfig, train

from .toy import CueExchange


def _actor(obs_dim=5, num_actions=3, seed=0) -> TarMACActor:
    torch.manual_seed(seed)
    return TarMACActor(obs_dim, num_actions, hidden=(16,), lstm=16, key=8, value=8)


def _random_state(actor: TarMACActor, *shape: int):
    h, c, messages = actor.initial_state(*shape)
    return torch.randn_like(h), torch.randn_like(c), torch.rand_like(messages) * 2 - 1


def test_attention_weights_sum_to_one_over_senders_and_equal_keys_are_uniform():
    actor = _actor()
    weights = actor.attention_weights(_random_state(actor, 4, 3))              # (B=4, receivers 3, senders 3)
    assert weights.shape == (4, 3, 3)
    torch.testing.assert_close(weights.sum(-1), torch.ones(4, 3))
    assert weights.std() > 0.01                                                # random keys: not uniform
    h, c, messages = _random_state(actor, 4, 3)
    messages[..., :actor.key_size] = messages[:, :1, :actor.key_size]          # every sender of a row: the same key
    torch.testing.assert_close(actor.attention_weights((h, c, messages)), torch.full((4, 3, 3), 1 / 3))
    # the spec's init: every output row (logits and message units alike) of norm 1
    torch.testing.assert_close(actor.head.weight.norm(dim=1), torch.ones(3 + 16))


def test_a_message_reaches_its_receivers_one_decision_later_and_carries_gradient():
    actor = _actor()
    obs = torch.randn(2, 1, 3, 5, requires_grad=True)                          # T=2 decisions, 1 env, N=3 agents
    logits = actor(obs, actor.initial_state(1, 3), torch.zeros(2, 1, dtype=torch.bool))
    sender, receiver = 0, 2

    def gradient(output, wrt):
        return torch.autograd.grad(output.sum(), wrt, retain_graph=True)[0]

    assert gradient(logits[0, 0, receiver], obs)[0, 0, sender].abs().max() == 0      # same decision: not heard yet
    assert gradient(logits[1, 0, receiver], obs)[0, 0, sender].abs().max() > 0       # heard at the next one
    # the receiver's loss reaches the message units of the head (they feed nothing else at decision 0 -> 1)
    head = gradient(logits[1, 0, receiver], actor.head.weight)
    assert head[actor.num_actions:].abs().sum() > 0
    # an episode start in between: nothing of decision 0 reaches decision 1
    restarted = actor(obs, actor.initial_state(1, 3), torch.tensor([[False], [True]]))
    assert gradient(restarted[1], obs)[0].abs().max() == 0


def test_sequences_equal_steps_with_episode_starts_inside():
    actor = _actor(seed=1)
    obs = torch.randn(6, 3, 2, 5)                                              # T=6, B=3 envs, N=2 agents
    state = _random_state(actor, 3, 2)
    starts = torch.zeros(6, 3, dtype=torch.bool)                               # one flag per env
    starts[0, 1] = True
    starts[2, 2] = starts[4, 2] = True                                         # env 2: two starts in the window
    logits = actor(obs, state, starts)
    stepped, memory = [], state
    for t in range(6):
        keep = (~starts[t]).float()[:, None, None]
        out, memory = actor.step(obs[t], tuple(part * keep for part in memory))
        stepped.append(out)
    torch.testing.assert_close(logits, torch.stack(stepped))
    fresh = actor(obs[4:, 2:], actor.initial_state(1, 2), torch.zeros(2, 1, dtype=torch.bool))
    torch.testing.assert_close(logits[4:, 2:], fresh)                          # env 2 forgot everything at t = 4
    assert len(memory) == 3 and memory[2].shape == (3, 2, 16) and memory[2].abs().max() <= 1


@pytest.mark.parametrize('seed', [0, 1])
def test_only_a_communicating_team_solves_cue_exchange(tmp_path, seed):
    """Each agent's own cue is shown only to its teammate: chance (1/4) without messages, at best
    (1/4 + 7) / 8 = 0.91 with them. A recurrent MAPPO actor without messages and a TarMAC actor, same budget."""
    results = {}
    for comm in ('none', 'tarmac'):
        rows = []
        config = PPOConfig(algo='mappo', actor='mlp', total_steps=16 * 16 * 25, num_envs=16, rollout_length=16,
                           epochs=4, hidden=(32,), lstm=32, comm=comm, lr_schedule=((0, 3e-3),),
                           entropy_schedule=((0, 0.0),), seed=seed, torch_threads=1)
        train(config, tmp_path / comm, progress=False, callback=rows.append,
              envs=CueExchange(num_envs=16, num_agents=2, num_actions=4, length=8, seed=seed))
        results[comm] = [round(r['rollout_coverage'], 3) for r in rows]
    assert np.mean(results['none'][-10:]) < 0.35, results                   # chance: 0.25
    assert np.mean(results['tarmac'][-5:]) > 0.6, results


def test_tarmac_checkpoints_resume_refuse_another_comm_and_play_batched(tmp_path):
    config = PPOConfig(algo='mappo', team='target', env_id='MATE-2v4-0-v0', num_envs=4, rollout_length=4,
                       total_steps=2 * 4 * 4, epochs=1, hidden=(16,), lstm=16, comm='tarmac', seed=0,
                       torch_threads=1)
    assert train(config, tmp_path, progress=False)['env_steps'] == 32
    assert load_checkpoint(tmp_path / 'checkpoint.pt')['meta']['comm'] == 'tarmac'
    longer = PPOConfig(**{**config.__dict__, 'total_steps': 3 * 4 * 4})
    resumed = train(longer, tmp_path, progress=False)
    assert resumed['env_steps'] == 48 and resumed['iteration'] == 3
    with pytest.raises(CheckpointError, match="comm is 'tarmac' in the checkpoint, 'none' here"):
        train(PPOConfig(**{**longer.__dict__, 'comm': 'none', 'total_steps': 4 * 4 * 4}), tmp_path, progress=False)

    policy = load_policy(tmp_path / 'final.pt', 'target')
    assert isinstance(policy.actor, TarMACActor) and policy.recurrent and policy.communicates
    targets = PolicyTeam(policy, 'target', 2, (2, 4, 0), seed=0)
    results, _ = play_batch('MATE-2v4-0', lambda b, c: make_team('greedy', 'camera', b, c, seed=0), targets,
                            episodes=2, max_episode_steps=30)
    assert [r.episode_length for r in results] == [30, 30]
    messages = targets.memory[2]                                   # the whole team of a row decides together
    assert messages.shape == (2, 4, 64) and messages.abs().sum() > 0

    # single agents would need the env's message channel: refused with the reason
    with pytest.raises(CheckpointError, match=r'play batched \(mate evaluate --batched\) until the message exchange'):
        PolicyTargetAgent(policy, seed=0)
    with pytest.raises(CheckpointError, match='TarMAC policies play batched'):
        load_agent(f'checkpoint:{tmp_path / "final.pt"}', 'target')


def test_make_actor_builds_tarmac_from_the_metadata_and_refuses_other_bodies():
    meta = dict(team='camera', comm='tarmac', action_heads=1)
    actor = make_actor('mlp', 10, 25, (16,), 'tanh', meta, lstm=8)
    assert isinstance(actor, TarMACActor) and actor.lstm_size == 8 and actor.key_size + actor.value_size == 64
    with pytest.raises(ValueError, match="actor 'per-target' does not combine"):
        make_actor('per-target', 10, 25, (16,), 'tanh', meta, lstm=8)
    with pytest.raises(ValueError, match="unknown comm 'i2c'"):
        make_actor('mlp', 10, 25, (16,), 'tanh', dict(meta, comm='i2c'), lstm=8)
    resolved = PPOConfig(team='camera', comm='tarmac').resolved()               # cameras' default actor is per-target
    assert (resolved.actor, resolved.lstm) == ('mlp', 256)
    assert PPOConfig(team='camera', comm='tarmac', lstm=64).resolved().lstm == 64
    assert PPOConfig(team='camera').resolved().lstm == 0


@pytest.mark.parametrize('algo', ['iql', 'qmix', 'maddpg'])
def test_comm_is_an_option_of_the_ppo_trainers_only(algo, capsys):
    from mate.cli import main

    assert main(['train', algo, '--comm', 'tarmac']) == 2
    assert f'--comm is not an option of {algo.upper()}' in capsys.readouterr().err


def test_mate_train_comm_arguments(tmp_path, capsys):
    from mate.cli import main
    from mate.learn.command import add_arguments, config_from_args

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    config = config_from_args(parser.parse_args(['ippo', '--team', 'target', '--comm', 'tarmac'])).resolved()
    assert (config.algo, config.comm, config.actor, config.lstm) == ('ippo', 'tarmac', 'mlp', 256)
    assert main(['train', 'mappo', '--comm', 'tarmac', '--actor', 'per-target']) == 2
    assert '--comm tarmac builds its actor on the MLP body; --actor per-target does not' in capsys.readouterr().err
    run_dir = tmp_path / 'run'
    assert main(['train', 'mappo', '--team', 'target', '--config', 'MATE-2v4-0', '--comm', 'tarmac', '--lstm', '8',
                 '--steps', '8', '--num-envs', '2', '--rollout-length', '4', '--epochs', '1', '--threads', '1',
                 '--run-dir', str(run_dir), '--no-progress']) == 0
    assert 'TarMAC actor, LSTM 8' in ' '.join(capsys.readouterr().out.split())
    assert isinstance(load_policy(run_dir / 'final.pt', 'target').actor, TarMACActor)
