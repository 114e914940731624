"""The feed-forward MAPPO / IPPO trainer (mate.learn.mappo): it learns toy tasks, its critic's views, the adaptive
KL penalty, the time budget, the files of a run, warm starts, devices and exact resumes."""

import pytest
import torch

from mate.policies.checkpoint import CheckpointError, load_checkpoint
from mate.learn.mappo import MAPPOConfig, policy_spec, train
from mate.learn.ppo_loop import critic_input_dim, critic_inputs, critic_outputs, per_agent
from mate.policies.policy import load_policy

from .resume import assert_same_run, stopped_and_resumed
from .toy import CueMatching, CueRecall

TINY = dict(actor='mlp', hidden=(8,), progress=False, seed=0)


def test_critic_inputs():
    obs, state = torch.zeros(3, 4, 10), torch.ones(3, 7)
    assert critic_inputs('state', obs, state) is state      # one value per env: the reward is shared
    assert critic_inputs('local', obs, state) is obs
    values, local = torch.arange(3.0), torch.randn(3, 4)
    assert torch.equal(per_agent('state', values, 4), values[:, None].expand(3, 4))
    assert per_agent('local', local, 4) is local


def test_the_agent_specific_critic_reads_the_state_and_each_agents_observation():
    obs, state = torch.randn(3, 4, 10), torch.randn(3, 7)
    inputs = critic_inputs('agent', obs, state)
    assert inputs.shape == (3, 4, 17) == (3, 4, critic_input_dim('agent', 10, 7))
    for agent in range(4):
        assert torch.equal(inputs[:, agent, :7], state) and torch.equal(inputs[:, agent, 7:], obs[:, agent])
    local = torch.randn(3, 4)
    assert per_agent('agent', local, 4) is local                      # one value per agent row
    assert [critic_outputs(c, 4, True) for c in ('state', 'local', 'agent')] == [4, 1, 1]
    assert MAPPOConfig(critic='agent').algo == 'mappo-as'


@pytest.mark.parametrize('critic', ['state', 'local', 'agent'])
def test_tiny_run_improves_return(tmp_path, critic):
    rows = []
    config = MAPPOConfig(critic=critic, actor='mlp', steps=16 * 16 * 12, num_envs=16, rollout_length=16, epochs=4,
                         hidden=(32,), lr_schedule=((0, 3e-3),), entropy_schedule=((0, 0.0),), seed=1,
                         run_dir=str(tmp_path), progress=False)
    train(config, callback=rows.append, envs=CueMatching(num_envs=16, num_agents=2, num_actions=4))
    first, last = rows[0]['rollout_coverage'], rows[-1]['rollout_coverage']
    assert first < 0.45                  # random: 0.25 of the agents match their cue
    assert last > 0.8, [round(r['rollout_coverage'], 3) for r in rows]
    assert (tmp_path / 'progress.csv').read_text().count('\n') == len(rows) + 1


def test_a_memoryless_actor_cannot_solve_cue_recall(tmp_path):
    rows = []
    config = MAPPOConfig(actor='mlp', steps=16 * 16 * 30, num_envs=16, rollout_length=16, epochs=4, hidden=(32,),
                         lr_schedule=((0, 3e-3),), entropy_schedule=((0, 0.0),), seed=1, run_dir=str(tmp_path),
                         progress=False)
    train(config, callback=rows.append, envs=CueRecall(num_envs=16, num_agents=2, num_actions=4, length=8))
    memoryless_bound = (1 + 7 / 4) / 8                          # 0.34: the cue is shown once per episode
    assert max(r['rollout_coverage'] for r in rows[-5:]) < memoryless_bound + 0.08


def test_kl_penalty_adapts_during_training_and_is_logged(tmp_path):
    """With a tiny target the measured KL stays above it, so the coefficient grows by 1.5 every
    iteration; the row reports the coefficient the iteration used, the checkpoint the next one."""
    rows = []
    config = MAPPOConfig(steps=8 * 8 * 4, num_envs=8, rollout_length=8, epochs=2, lr_schedule=((0, 3e-3),),
                         kl_coeff=0.2, kl_target=1e-9, run_dir=str(tmp_path), **dict(TINY, hidden=(16,)))
    train(config, callback=rows.append, envs=CueMatching(num_envs=8, num_agents=2, num_actions=4))
    assert [round(r['kl_coeff'], 6) for r in rows] == [round(0.2 * 1.5 ** i, 6) for i in range(4)]
    assert all(r['approx_kl'] > 0 for r in rows)
    assert load_checkpoint(tmp_path / 'checkpoint.pt')['state']['kl_coeff'] == pytest.approx(0.2 * 1.5 ** 4)
    off = []
    train(MAPPOConfig(steps=8 * 8, num_envs=8, rollout_length=8, run_dir=str(tmp_path / 'off'), **TINY),
          callback=off.append, envs=CueMatching(num_envs=8, num_agents=2, num_actions=4))
    assert off[0]['kl_coeff'] == 0.0


def test_time_limit_stops_training_early(tmp_path):
    rows = []
    config = MAPPOConfig(steps=10 ** 9, num_envs=4, rollout_length=4, epochs=1, minutes=0.5 / 60,
                         run_dir=str(tmp_path), **TINY)
    run = train(config, callback=rows.append, envs=CueMatching(num_envs=4))
    row = run.last_row
    assert row['wall_seconds'] < 30 and row['env_steps'] < config.steps and rows[-1] == row and run.complete
    # the budget is checked before every iteration: every iteration but the last started (and so ended) before it
    # was spent (logged to 0.01 s); on a busy machine the first iteration alone may spend it (one row)
    assert all(earlier['wall_seconds'] <= 0.51 for earlier in rows[:-1])
    # the last row ends after the budget is spent, which the checkpoint records
    assert load_checkpoint(tmp_path / 'checkpoint.pt')['run']['wall_seconds'] >= 0.5
    assert (tmp_path / 'final.pt').exists()
    # resuming a run whose budget is spent trains no further
    again = train(config, envs=CueMatching(num_envs=4))
    assert again.iteration == run.iteration and again.last_row == {}


def test_the_files_of_a_run(tmp_path):
    """checkpoint.pt (spec, config, counters, state), progress.csv, best.pt once 25 episodes are in the window,
    final.pt and snapshots: policy files that load as policies."""
    config = MAPPOConfig(steps=4 * 8 * 20, num_envs=4, rollout_length=8, snapshot_every=10, run_dir=str(tmp_path),
                         **TINY)     # CueMatching reports one episode per 4 decisions: 40 in all
    train(config, envs=CueMatching(num_envs=4, length=4))
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['algo'] == 'mappo' and saved['run']['iteration'] == 20 and saved['run']['env_steps'] == 640
    assert set(saved['state']['networks']) == {'actor', 'critic', 'value_norm'}
    assert saved['spec']['action'] == 'discrete' and saved['spec']['hidden'] == [8]
    for name in ('best.pt', 'final.pt', 'snapshots/policy-0000000320.pt', 'snapshots/policy-0000000640.pt'):
        policy = load_policy(tmp_path / name)
        assert policy.spec.num_actions == 4 and policy.spec.algo == 'mappo'


def test_policy_spec_of_the_game():
    camera = policy_spec(MAPPOConfig(hrl=True))
    assert ((camera.network, camera.action, camera.heads, camera.choices, camera.frame_skip)
            == ('per-target', 'hrl', 8, 2, 5))
    target = policy_spec(MAPPOConfig(team='target', critic='local'))
    assert (target.network, target.env_id, target.algo, target.num_actions) == ('mlp', 'MATE-2v4-0-v0', 'ippo', 25)
    with pytest.raises(ValueError, match='--actor per-target reads a camera'):
        MAPPOConfig(team='target', actor='per-target')
    with pytest.raises(ValueError, match='--hrl exists for cameras only'):
        MAPPOConfig(team='target', hrl=True)


def test_resuming_another_setting_names_it(tmp_path):
    base = dict(steps=40, num_envs=4, rollout_length=10, horizon=40, threads=1, progress=False, run_dir=str(tmp_path))
    train(MAPPOConfig(hrl=True, **base))
    with pytest.raises(CheckpointError,
                       match='trained with per-target HRL selections .--hrl.; this run has grid moves'):
        train(MAPPOConfig(**dict(base, steps=80)))
    with pytest.raises(CheckpointError, match='trained by mappo; this run is ippo'):
        train(MAPPOConfig(critic='local', hrl=True, **dict(base, steps=80)))


def test_warm_start_takes_the_actor_and_critic_of_the_same_setting(tmp_path):
    base = dict(num_envs=4, rollout_length=10, horizon=40, threads=1, progress=False)
    train(MAPPOConfig(steps=40, run_dir=str(tmp_path / 'a'), **base))
    first = load_checkpoint(tmp_path / 'a' / 'checkpoint.pt')['state']['networks']
    warm = MAPPOConfig(steps=1, rollout_length=1, num_envs=1, horizon=40, threads=1, progress=False, epochs=1,
                       lr_schedule=((0, 0.0),), run_dir=str(tmp_path / 'b'), init_from=str(tmp_path / 'a' / 'final.pt'))
    train(warm)
    second = load_checkpoint(tmp_path / 'b' / 'checkpoint.pt')['state']['networks']
    assert all(torch.equal(first['actor'][k], second['actor'][k]) for k in first['actor'])    # lr 0: unchanged
    with pytest.raises(CheckpointError, match='warm start .*trained with grid moves'):
        train(MAPPOConfig(steps=40, hrl=True, run_dir=str(tmp_path / 'c'), init_from=str(tmp_path / 'a' / 'final.pt'),
                          **base))


def test_devices_are_checked():
    with pytest.raises(ValueError, match='device must be auto, cpu, cuda or cuda:N'):
        MAPPOConfig(device='gpu')
    if not torch.cuda.is_available():
        from mate.policies.device import resolve_device

        with pytest.raises(ValueError, match='--device cuda: PyTorch sees no CUDA GPU here'):
            resolve_device('cuda')
        assert str(resolve_device('auto')) == 'cpu'


@pytest.mark.slow
@pytest.mark.parametrize('hrl', [False, True])
def test_a_run_stopped_by_sigint_and_resumed_is_the_same_run(tmp_path, hrl):
    """SIGINT ends the iteration, writes the checkpoint (networks, optimiser, generator, the envs with their
    opponent and random streams) and returns; the same call continues: the same weights, optimiser and log rows as
    a run never stopped."""
    def config_of(run_dir, fresh):
        return MAPPOConfig(seed=1, steps=240, num_envs=4, rollout_length=10, epochs=2, minibatches=2, horizon=40,
                           threads=1, progress=False, hrl=hrl, memory=25 if hrl else 0, velocity=hrl,
                           run_dir=run_dir, fresh=fresh)

    straight, stopped = stopped_and_resumed(train, config_of, 3, tmp_path)
    assert_same_run(straight, stopped)
