"""Difference rewards for cameras (`credit='difference'`): the formula, the core's per-camera credit
(`World.camera_reward_parts`), the training env's per-camera rewards, and the learner's per-agent critic."""

import numpy as np
import pytest

from mate.learn import CheckpointError, load_checkpoint
import mate
from mate.learn.envs import TeamEnvConfig, TrainingEnv
from mate.learn.mappo import MAPPOConfig, train
from mate.messages import Team
from mate.spaces import observation_indices_of

from .toy import OwnCueMatching


def _env(num_envs, **options):
    """Training envs of grid-move cameras on MATE-4v8-9 (the camera preset), `options` of `TeamEnvConfig`."""
    config = TeamEnvConfig(team='camera', num_envs=num_envs, **options)
    return config.make_env(config.policy_spec())


def difference_rewards(sees: np.ndarray) -> np.ndarray:
    """The formula, written here apart from the core: `sees` (..., Nc, Nt) bool -> (..., Nc), the share of the
    targets each camera alone tracks."""
    return (sees & (sees.sum(axis=-2, keepdims=True) == 1)).sum(axis=-1) / sees.shape[-1]


@pytest.mark.parametrize('preset', ['MATE-4v8-9', 'MATE-8v8-9', 'MATE-2v4-0'])
def test_the_core_credits_each_camera_the_targets_it_alone_tracks(preset):
    """`World.camera_reward_parts`, written by the core's step and reset, is the formula on the step's view masks."""
    envs = mate.make_vec('MultiAgentTracking-v0', 16, config=preset, max_episode_steps=30)
    envs.reset(seed=1)
    credited = 0
    for step in range(60):
        assert np.array_equal(envs.world.camera_reward_parts, difference_rewards(envs.world.camera_target_view_mask))
        credited += int((envs.world.camera_reward_parts > 0).sum())
        envs.step(envs.sample_actions(step))
    assert credited > 0


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
    env = _env(4, credit='difference', horizon=40, seed=3)
    plain = _env(4, horizon=40, seed=3)
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


def test_the_cores_reward_parts_by_hand():
    """The core's step keeps each target's part of the dense reward (`World.target_reward_parts`): -1 for a tracked
    target with bounty left; a delivery pays its freight and the bounty left after this step's decay."""
    import mate

    env = mate.make('MATE-2v4-0-v0')
    env.reset(seed=0)
    world, b = env._world, 0
    for _ in range(400):                     # until a step has a tracked target with bounty and a delivery, or not
        bounty, freight = world.target_bounty[b].copy(), world.target_freight[b].copy()
        env.step(env.action_space.sample())
        tracked = world.camera_target_view_mask[b].any(axis=0)
        expected = np.where(world.target_done[b], freight + np.maximum(bounty - tracked, 0), 0) \
            - (tracked & (bounty > 0))
        np.testing.assert_array_equal(world.target_reward_parts[b], expected)
        assert world.target_reward_parts[b].sum() == world.target_reward[b]


def test_each_target_is_paid_its_own_part_of_the_team_reward():
    """Same game as the team-reward env (MATE-4v8-0, greedy cameras); each target's reward summed over the targets
    is the team's raw reward of every held decision, deliveries included."""
    config = dict(team='target', config='MATE-4v8-0', num_envs=4, horizon=600, seed=2)
    env = TeamEnvConfig(credit='own', **config).make_env(TeamEnvConfig(**config).policy_spec())
    plain = TeamEnvConfig(**config).make_env(TeamEnvConfig(**config).policy_spec())
    obs, _ = env.reset(seed=2)
    base, _ = plain.reset(seed=2)
    rng = np.random.default_rng(0)
    paid = 0.0
    for _ in range(150):
        actions = rng.integers(0, 25, (4, env.num_agents))
        obs, _, reward, done, _, _ = env.step(actions)
        base, _, team_reward, *_ = plain.step(actions)
        assert np.array_equal(obs, base) and reward.shape == (4, 8)
        np.testing.assert_allclose(reward.sum(-1), team_reward, rtol=0, atol=1e-9)
        paid = max(paid, reward.max())
    assert paid >= 100                              # some target delivered (freight 100 per unit)


def test_learner_with_per_agent_rewards_improves(tmp_path):
    rows = []
    config = MAPPOConfig(actor='mlp', steps=16 * 16 * 12, num_envs=16, rollout_length=16, epochs=4, hidden=(32,),
                         lr_schedule=((0, 3e-3),), entropy_schedule=((0, 0.0),), seed=1, run_dir=str(tmp_path),
                         progress=False)
    train(config, OwnCueMatching(num_envs=16, num_agents=2, num_actions=4), callback=rows.append)
    assert rows[0]['rollout_coverage'] < 0.45
    assert rows[-1]['rollout_coverage'] > 0.8, [round(r['rollout_coverage'], 3) for r in rows]
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['state']['networks']['critic']['head.weight'].shape[0] == 2      # one value per agent


def _difference_config(tmp_path, **changes):
    return MAPPOConfig(**{**dict(team='camera', config='MATE-2v4-0', num_envs=4, rollout_length=4, steps=2 * 4 * 4,
                                 epochs=1, hidden=(16,), credit='difference', seed=0, actor='mlp',
                                 run_dir=str(tmp_path), progress=False), **changes})


def test_difference_credit_checkpoint_and_validation(tmp_path):
    run = train(_difference_config(tmp_path))
    row = run.last_row
    assert row['env_steps'] == 32 and np.isfinite(row['value_loss'])
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['config']['credit'] == 'difference'
    assert saved['state']['networks']['critic']['head.weight'].shape[0] == 2
    assert load_checkpoint(tmp_path / 'final.pt')['config']['credit'] == 'difference'
    with pytest.raises(ValueError, match='cameras only'):
        TeamEnvConfig(team='target', num_envs=2, credit='difference')
    target_spec = TeamEnvConfig(team='target').policy_spec()
    with pytest.raises(ValueError, match='cameras only'):
        TrainingEnv(target_spec, num_envs=2, credit='difference')
    with pytest.raises(ValueError, match='targets only'):
        TrainingEnv(TeamEnvConfig(team='camera').policy_spec(), num_envs=2, credit='own')
    with pytest.raises(ValueError, match='targets only'):
        TeamEnvConfig(team='camera', credit='own')
    with pytest.raises(ValueError, match="credit must be one of"):
        TrainingEnv(target_spec, num_envs=2, credit='mine')


def test_resuming_with_another_credit_is_refused(tmp_path):
    train(_difference_config(tmp_path))
    with pytest.raises(CheckpointError, match='trained with --credit difference; this run has --credit team'):
        train(_difference_config(tmp_path, credit='team', steps=64))


def test_warm_start_keeps_the_critic_only_for_the_same_credit(tmp_path):
    """--init-from: the critic (and its value normaliser) come along from a run checkpoint of the same algorithm and
    credit; a checkpoint of another credit gives the actor only."""
    import torch

    train(_difference_config(tmp_path / 'first'))
    first = load_checkpoint(tmp_path / 'first' / 'checkpoint.pt')['state']['networks']
    frozen = dict(lr_schedule=((0, 0.0),), steps=16, rollout_length=4)         # learning rate 0: loaded weights stay
    train(_difference_config(tmp_path / 'same', init_from=str(tmp_path / 'first' / 'checkpoint.pt'), **frozen))
    same = load_checkpoint(tmp_path / 'same' / 'checkpoint.pt')['state']['networks']
    for name in ('actor', 'critic'):
        assert all(torch.equal(same[name][k], v) for k, v in first[name].items()), name
    train(_difference_config(tmp_path / 'team', credit='team', init_from=str(tmp_path / 'first' / 'checkpoint.pt'),
                             **frozen))
    team = load_checkpoint(tmp_path / 'team' / 'checkpoint.pt')['state']['networks']
    assert all(torch.equal(team['actor'][k], v) for k, v in first['actor'].items())
    assert team['critic']['head.weight'].shape[0] == 1                      # a fresh team-reward critic


def test_a_first_format_checkpoint_is_refused_in_one_line(tmp_path):
    """Files of the first format (mate.learn/1, before policy specs) are no longer read; the error says so."""
    import torch

    old = tmp_path / 'old.pt'
    torch.save({'format': 'mate.learn/1', 'meta': {'team': 'camera'}, 'config': {}, 'actor': {}}, old)
    with pytest.raises(CheckpointError, match=r"format 'mate.learn/1'; expected one of \('mate.learn/2',\) \(the first "
                                              r'format, written before policy specs, is no longer read\)'):
        load_checkpoint(old)


def test_cli_credit_option(capsys):
    from mate.learn.command import trainer_parser
    from mate.cli.options import config_from

    parser, _, config_class = trainer_parser('mappo')

    def config_of(argv):
        return config_from(parser, config_class, parser.parse_args(argv))

    assert config_of([]).credit == 'team'
    assert config_of(['--credit', 'difference']).credit == 'difference'
    with pytest.raises(SystemExit) as exit_info:
        config_of(['--team', 'target', '--credit', 'difference'])
    assert exit_info.value.code == 2 and 'cameras only' in capsys.readouterr().err.splitlines()[0]
