import numpy as np
import pytest
import torch

import mate
from mate.learn import (
    CheckpointError,
    PolicyCameraAgent,
    PolicyTargetAgent,
    load_agent,
    load_checkpoint,
    load_policy,
)
from mate.learn.ppo import PPOConfig, train


def _tiny_camera_checkpoint(tmp_path, algo='mappo', total=2 * 8 * 8):
    config = PPOConfig(algo=algo, team='camera', env_id='MATE-2v4-0-v0', num_envs=8, rollout_length=8,
                       total_steps=total, epochs=1, hidden=(16,), checkpoint_every=1, seed=0)
    rows = []
    train(config, tmp_path, progress=False, callback=rows.append)
    return tmp_path / 'final.pt', rows


def test_round_trip_and_agent_plays(tmp_path):
    path, _ = _tiny_camera_checkpoint(tmp_path)
    data = load_checkpoint(path)
    assert data['meta']['team'] == 'camera' and data['meta']['obs_dim'] == 56
    policy = load_policy(path, 'camera')
    x = torch.randn(3, 56)
    from mate.learn.ppo import Actor
    actor = Actor(56, 25, (16,))
    actor.load_state_dict(data['actor'])
    assert np.allclose(policy.logits(x.numpy()), actor(x).detach().numpy())

    env = mate.make('MATE-2v4-0-v0')
    factory = load_agent(f'checkpoint:{path}', 'camera')
    cameras = factory(seed=0).spawn(env.num_cameras)
    targets = mate.GreedyTargetAgent(seed=0).spawn(env.num_targets)
    (camera_obs, target_obs), (camera_infos, target_infos) = env.reset(seed=0)
    mate.group_reset(cameras, camera_obs)
    mate.group_reset(targets, target_obs)
    assert cameras[0].policy is cameras[1].policy
    for _ in range(12):
        camera_action = mate.group_step(env, cameras, camera_obs, camera_infos)
        target_action = mate.group_step(env, targets, target_obs, target_infos)
        assert np.all(np.abs(camera_action) <= np.array([5.0, 2.5]) + 1e-9)
        (camera_obs, target_obs), _, _, _, (camera_infos, target_infos) = env.step((camera_action, target_action))
    # decisions are held for frame_skip (5) steps
    agent = PolicyCameraAgent.from_checkpoint(path, seed=1)
    agent.reset(camera_obs[0])
    actions = [agent.act(camera_obs[0]) for _ in range(5)]
    assert all(np.array_equal(a, actions[0]) for a in actions)


def test_resume_continues_and_mismatch_is_refused(tmp_path):
    _, rows = _tiny_camera_checkpoint(tmp_path, total=2 * 8 * 8)
    assert rows[-1]['env_steps'] == 128
    _, more = _tiny_camera_checkpoint(tmp_path, total=4 * 8 * 8)   # resumes at 128 steps
    assert more[0]['iteration'] == 3 and more[-1]['env_steps'] == 256
    with pytest.raises(CheckpointError, match='algo'):
        _tiny_camera_checkpoint(tmp_path, algo='ippo', total=6 * 8 * 8)


def test_corrupt_and_foreign_checkpoints(tmp_path):
    bad = tmp_path / 'bad.pt'
    bad.write_bytes(b'definitely not a checkpoint' * 10)
    with pytest.raises(CheckpointError, match='corrupt'):
        load_checkpoint(bad)
    with pytest.raises(CheckpointError, match='does not exist'):
        load_checkpoint(tmp_path / 'missing.pt')
    foreign = tmp_path / 'foreign.pt'
    torch.save({'weights': torch.zeros(3)}, foreign)
    with pytest.raises(CheckpointError, match='format'):
        load_checkpoint(foreign)
    path, _ = _tiny_camera_checkpoint(tmp_path / 'run')
    truncated = tmp_path / 'truncated.pt'
    truncated.write_bytes(path.read_bytes()[:1000])
    with pytest.raises(CheckpointError, match='corrupt'):
        load_policy(truncated)
    with pytest.raises(CheckpointError, match='team'):
        PolicyTargetAgent.from_checkpoint(path)
    with pytest.raises(CheckpointError, match='team'):
        load_agent(f'checkpoint:{path}', 'target')
    with pytest.raises(ValueError, match='pretrained'):
        load_agent('pretrained:no-such-policy', 'camera')
    # a camera policy for 2 cameras refuses an env with 4
    agent = PolicyCameraAgent.from_checkpoint(path)
    env = mate.make('MATE-4v8-9-v0')
    (camera_obs, _), _ = env.reset(seed=0)
    with pytest.raises(ValueError, match='trained with'):
        agent.reset(camera_obs[0])


def test_cli_train_parser():
    from mate.cli import build_parser
    args = build_parser().parse_args(['train', 'ippo', '--team', 'target', '--steps', '1e4'])
    assert args.algo == 'ippo' and args.team == 'target' and args.steps == 1e4


def test_export_policy_is_small_and_loads(tmp_path):
    from mate.learn import export_policy
    path, _ = _tiny_camera_checkpoint(tmp_path / 'run')
    small = export_policy(path, tmp_path / 'small.pt', note='test')
    assert small.stat().st_size < path.stat().st_size
    data = load_checkpoint(small)
    assert 'optimizer' not in data and data['note'] == 'test'
    agent = PolicyCameraAgent.from_checkpoint(small)
    assert agent.policy.meta['team'] == 'camera'


@pytest.mark.parametrize('variant', [dict(lstm=16), dict(hrl=True, actor='per-target')])
def test_recurrent_and_per_target_policies_round_trip_as_agents(tmp_path, variant):
    config = PPOConfig(algo='mappo', team='camera', env_id='MATE-2v4-0-v0', num_envs=4, rollout_length=4,
                       total_steps=2 * 4 * 4, epochs=1, hidden=(16,), snapshot_every=1, seed=0, **variant)
    train(config, tmp_path, progress=False)
    snapshots = sorted((tmp_path / 'snapshots').glob('policy-*.pt'))
    assert [p.name for p in snapshots] == ['policy-0000000016.pt', 'policy-0000000032.pt']
    policy = load_policy(snapshots[-1], 'camera')
    assert policy.recurrent == bool(variant.get('lstm'))
    env = mate.make('MATE-2v4-0-v0')
    (camera_obs, _), _ = env.reset(seed=0)
    agent = PolicyCameraAgent(policy, seed=0, deterministic=True)
    agent.reset(camera_obs[0])
    first = [agent.act(camera_obs[0]) for _ in range(6)]
    agent.reset(camera_obs[0])                     # a reset forgets the recurrent memory: same actions again
    assert all(np.array_equal(a, b) for a, b in zip(first, [agent.act(camera_obs[0]) for _ in range(6)]))
    if variant.get('lstm'):                        # the memory changes the logits of the same observation
        from mate.learn.envs import preprocess_observation
        x = preprocess_observation(camera_obs[:1], 'camera', 2, 4, 0)
        logits0, memory = policy.logits(x, policy.initial_memory(1))
        logits1, _ = policy.logits(x, memory)
        assert not np.allclose(logits0, logits1)


def test_per_target_actor_scores_every_slot_with_one_head():
    from mate.learn.ppo import PerTargetActor
    torch.manual_seed(0)
    actor = PerTargetActor(30, (10, 4), hidden=(16,))
    obs = torch.randn(2, 30)
    perm = [2, 0, 3, 1]
    # slot i's logits = head([record_i, context(obs)]); swapping two records swaps their logits
    records = obs[:, 10:30].reshape(2, 4, 5)
    context = actor.body(obs)
    joint = torch.cat([records, context[:, None].expand(2, 4, context.shape[-1])], -1)
    out = actor(obs).reshape(2, 4, 2)
    assert torch.allclose(out, actor.head(joint), atol=1e-6)
    assert torch.allclose(actor.head(joint[:, perm]), out[:, perm], atol=1e-6)
    assert not torch.allclose(out[:, 0], out[:, 1])
