"""The recurrent MAPPO / IPPO trainer (mate.learn.mappo_lstm): the recurrent actor's memory at episode starts and
its fused sequences, a toy task that needs memory, the policy spec, the run's files and the command line. Exact
resumes: test_resume_recurrent.py."""

import pytest
import torch

from mate.policies.checkpoint import CheckpointError, load_checkpoint
from mate.learn.mappo_lstm import RecurrentConfig, policy_spec, train
from mate.policies.networks import Actor, RecurrentActor

from .toy import CueMatching, CueRecall


def test_recurrent_actor_resets_its_memory_at_episode_starts():
    torch.manual_seed(0)
    actor = RecurrentActor(Actor(3, 4, hidden=(8,), context_extra=6), lstm=6)
    obs = torch.randn(4, 2, 3)                                   # T=4 steps, 2 rows
    state = (torch.randn(2, 6), torch.randn(2, 6))
    starts = torch.tensor([[False, False], [False, True], [False, False], [False, False]])
    logits = actor(obs, state, starts)
    fresh = actor(obs[1:, 1:], actor.initial_state(1), torch.zeros(3, 1, dtype=torch.bool))
    assert torch.allclose(logits[1:, 1:], fresh, atol=1e-6)     # row 1 restarted at t=1: old memory gone
    step_by_step, memory = [], state
    for t in range(4):
        keep = (~starts[t]).float()[:, None]
        out, memory = actor.step(obs[t], (memory[0] * keep, memory[1] * keep))
        step_by_step.append(out)
    assert torch.allclose(logits, torch.stack(step_by_step), atol=1e-6)


def test_recurrent_actor_sequences_equal_steps_with_several_episode_starts():
    torch.manual_seed(1)
    actor = RecurrentActor(Actor(5, 3, hidden=(8,), context_extra=4), lstm=4)
    obs = torch.randn(6, 3, 2, 5)                                  # T=6 steps, 3 envs x 2 agents
    state = (torch.randn(3, 2, 4), torch.randn(3, 2, 4))
    starts = torch.zeros(6, 3, dtype=torch.bool)                   # one flag per env, shared by its agents
    starts[0, 1] = True                                            # env 1 starts fresh at t = 0
    starts[2, 2] = starts[4, 2] = True                             # env 2: two short episodes inside the window
    logits = actor(obs, state, starts)
    step_by_step, memory = [], state
    for t in range(6):
        keep = (~starts[t]).float()[:, None, None]
        out, memory = actor.step(obs[t], (memory[0] * keep, memory[1] * keep))
        step_by_step.append(out)
    assert torch.allclose(logits, torch.stack(step_by_step), atol=1e-6)
    logits.sum().backward()                                        # the fused path is differentiable
    assert actor.lstm.weight_hh_l0.grad is not None and actor.lstm.weight_hh_l0.grad.abs().sum() > 0


@pytest.mark.slow
def test_a_recurrent_actor_solves_cue_recall(tmp_path):
    """The cue is shown once per episode: a memoryless actor stays below (1 + 7/4) / 8 = 0.34 (test_mappo.py), the
    recurrent one remembers it."""
    rows = []
    config = RecurrentConfig(actor='mlp', steps=16 * 16 * 30, num_envs=16, rollout_length=16, epochs=4, hidden=(32,),
                             lstm=32, lr_schedule=((0, 3e-3),), entropy_schedule=((0, 0.0),), seed=1, threads=1,
                             run_dir=str(tmp_path), progress=False)
    train(config, callback=rows.append, envs=CueRecall(num_envs=16, num_agents=2, num_actions=4, length=8))
    assert max(r['rollout_coverage'] for r in rows[-5:]) > 0.6, [round(r['rollout_coverage'], 3) for r in rows]


def test_the_update_replays_the_rollout(tmp_path):
    """Learning rate 0: the log-probabilities the update recomputes from each sequence's first memory and start flags
    equal the rollout's (KL 0), with episodes ending inside the rollouts and memories carried between them."""
    rows = []
    config = RecurrentConfig(actor='mlp', critic='local', steps=4 * 6 * 3, num_envs=4, rollout_length=6, epochs=2,
                             minibatches=2, hidden=(8,), lstm=8, lr_schedule=((0, 0.0),), seed=0,
                             run_dir=str(tmp_path), progress=False)
    train(config, callback=rows.append, envs=CueRecall(num_envs=4, num_agents=2, num_actions=4, length=4))
    assert len(rows) == 3 and all(r['approx_kl'] < 1e-9 and r['clip_fraction'] == 0 for r in rows), rows


def test_policy_spec_config_and_files(tmp_path):
    spec = policy_spec(RecurrentConfig())
    assert (spec.network, spec.lstm, spec.algo, spec.action) == ('per-target', 256, 'mappo-lstm', 'grid')
    spec = policy_spec(RecurrentConfig(team='target', critic='local', lstm=16, hrl=False))
    assert (spec.network, spec.lstm, spec.algo) == ('mlp', 16, 'ippo-lstm')
    assert RecurrentConfig.PRESETS['paper'][1]['actor'] == 'mlp'                # --paper: the paper's MLP actor
    with pytest.raises(ValueError, match='--actor per-target reads a camera'):
        RecurrentConfig(team='target', actor='per-target')
    with pytest.raises(ValueError, match='--lstm must be an integer >= 1, got 0'):
        RecurrentConfig(lstm=0)

    config = RecurrentConfig(actor='mlp', steps=2 * 4 * 3, num_envs=2, rollout_length=4, epochs=1, hidden=(8,), lstm=4,
                             run_dir=str(tmp_path), progress=False)
    run = train(config, envs=CueMatching(num_envs=2))
    assert run.iteration == 3 and run.last_row['env_steps'] == 24
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['algo'] == 'mappo-lstm' and saved['spec']['lstm'] == 4
    assert set(saved['state']['networks']) == {'actor', 'critic', 'value_norm'}
    h, c = saved['state']['memory']                                # carried into the next iteration
    assert h.shape == c.shape == (2, 2, 4) and saved['state']['starting'].shape == (2,)
    assert 'lstm.weight_hh_l0' in load_checkpoint(tmp_path / 'final.pt')['actor']
    with pytest.raises(CheckpointError, match='trained by mappo-lstm; this run is ippo-lstm'):
        train(RecurrentConfig(**{**config.__dict__, 'critic': 'local', 'steps': 48}), envs=CueMatching(num_envs=2))
    with pytest.raises(CheckpointError, match='trained by mappo-lstm; this run is mappo-as-lstm'):
        train(RecurrentConfig(**{**config.__dict__, 'critic': 'agent', 'steps': 48}), envs=CueMatching(num_envs=2))


def test_recurrent_mappo_as_critic_reads_state_and_own_observation(tmp_path):
    """critic='agent' (MAPPO-AS): one value per agent from the state with the agent's own observation appended."""
    config = RecurrentConfig(actor='mlp', critic='agent', steps=2 * 4 * 2, num_envs=2, rollout_length=4, epochs=1,
                             hidden=(8,), lstm=4, run_dir=str(tmp_path), progress=False)
    assert config.algo == 'mappo-as-lstm'
    train(config, envs=CueMatching(num_envs=2))
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    spec = saved['spec']
    critic = saved['state']['networks']['critic']
    first, *_, last = (v for k, v in critic.items() if k.endswith('weight'))
    assert first.shape[1] == spec['state_dim'] + spec['obs_dim'] and last.shape[0] == 1
    with pytest.raises(CheckpointError, match='trained with --lstm 4; this run has --lstm 8'):
        train(RecurrentConfig(**{**config.__dict__, 'lstm': 8, 'steps': 48}), envs=CueMatching(num_envs=2))


def test_mate_train_mappo_lstm(tmp_path, capsys):
    from mate.cli.main import main

    run_dir = tmp_path / 'run'
    assert main(['train', 'mappo-lstm', '--team', 'target', '--config', 'MATE-2v4-0', '--lstm', '8', '--steps', '8',
                 '--num-envs', '2', '--rollout-length', '4', '--epochs', '1', '--threads', '1', '--run-dir',
                 str(run_dir), '--no-progress']) == 0
    assert 'mlp network, LSTM 8' in ' '.join(capsys.readouterr().out.split())
    assert load_checkpoint(run_dir / 'final.pt')['spec']['lstm'] == 8
    for arguments, message in ((['--lstm', '0'], 'argument --lstm: expected an integer >= 1'),
                               (['--team', 'target', '--actor', 'per-target'], '--actor per-target reads a camera'),
                               (['--comm', 'tarmac'], 'unrecognized arguments: --comm tarmac')):
        with pytest.raises(SystemExit) as exit_info:
            main(['train', 'mappo-lstm', *arguments])
        assert exit_info.value.code == 2 and message in capsys.readouterr().err.splitlines()[0]
