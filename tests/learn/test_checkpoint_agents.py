"""Training runs' files (format 2: run checkpoints and policy files) and the agents that play them: round trips,
resumes, refusals of corrupt, foreign or mismatched files, exports, warm starts, the train command's options, and
the per-target camera actor."""

import csv

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
    save_checkpoint,
)
from mate.learn import mappo, mappo_lstm
from mate.policies.spec import PolicySpec


def _camera_config(run_dir, **changes) -> mappo.MAPPOConfig:
    """A tiny MAPPO run of MLP cameras on MATE-2v4-0 in `run_dir`: 8 envs x 8 decisions per iteration."""
    return mappo.MAPPOConfig(**{**dict(team='camera', config='MATE-2v4-0', num_envs=8, rollout_length=8,
                                       steps=2 * 8 * 8, epochs=1, hidden=(16,), checkpoint_every=1, seed=0,
                                       actor='mlp', run_dir=str(run_dir), progress=False), **changes})


def _tiny_camera_checkpoint(tmp_path, critic='state', total=2 * 8 * 8, **changes):
    rows = []
    mappo.train(_camera_config(tmp_path, critic=critic, steps=total, **changes), callback=rows.append)
    return tmp_path / 'final.pt', rows


def test_round_trip_and_agent_plays(tmp_path):
    path, _ = _tiny_camera_checkpoint(tmp_path)
    data = load_checkpoint(path)
    assert data['spec']['team'] == 'camera' and data['spec']['obs_dim'] == 56
    policy = load_policy(path, 'camera')
    assert policy.spec == PolicySpec.from_dict(data['spec']) and policy.spec.algo == 'mappo'
    x = torch.randn(3, 56)
    from mate.policies.networks import Actor
    actor = Actor(56, 25, (16,))
    actor.load_state_dict(data['actor'])
    assert np.allclose(policy.outputs(x.numpy()), actor(x).detach().numpy())

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
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['run']['wall_seconds'] >= rows[-1]['wall_seconds'] - 0.01
    saved['run']['wall_seconds'] = 1000.0                           # as if trained 1000 s before
    save_checkpoint(tmp_path / 'checkpoint.pt', saved)
    log = tmp_path / 'progress.csv'   # as if written by a version that logged one column less
    log.write_text('\n'.join(','.join(line.split(',')[:-1]) for line in log.read_text().splitlines()) + '\n')
    _, more = _tiny_camera_checkpoint(tmp_path, total=4 * 8 * 8)   # resumes at 128 steps
    with open(log, newline='') as f:
        logged = list(csv.DictReader(f))
    assert len(logged) == 4 and all(None not in row for row in logged)   # no row longer than the header
    assert [int(row['iteration']) for row in logged] == [1, 2, 3, 4]
    assert more[0]['iteration'] == 3 and more[-1]['env_steps'] == 256
    assert 1000.0 < more[0]['wall_seconds'] <= more[-1]['wall_seconds']   # wall time continues over sessions
    with pytest.raises(CheckpointError, match='trained by mappo; this run is ippo'):
        _tiny_camera_checkpoint(tmp_path, critic='local', total=6 * 8 * 8)
    with pytest.raises(CheckpointError, match='trained without --full-observability; this run has it'):
        _tiny_camera_checkpoint(tmp_path, total=6 * 8 * 8, full_observability=True)


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
    # a policy file whose spec is missing or does not fit its weights
    data = load_checkpoint(path)
    save_checkpoint(tmp_path / 'no-spec.pt', {k: v for k, v in data.items() if k != 'spec'})
    with pytest.raises(CheckpointError, match='lacks'):
        load_policy(tmp_path / 'no-spec.pt')
    save_checkpoint(tmp_path / 'wider.pt', dict(data, spec=dict(data['spec'], hidden=[32])))
    with pytest.raises(CheckpointError, match='do not fit its spec'):
        load_policy(tmp_path / 'wider.pt')
    # a camera policy for 2 cameras refuses an env with 4
    agent = PolicyCameraAgent.from_checkpoint(path)
    env = mate.make('MATE-4v8-9-v0')
    (camera_obs, _), _ = env.reset(seed=0)
    with pytest.raises(ValueError, match='trained with'):
        agent.reset(camera_obs[0])


def test_spec_differences_name_the_setting_in_the_words_of_the_command_line():
    from .toy import CueMatching

    spec = mappo.policy_spec(_camera_config('unused'))
    assert spec.differences(spec.replace(algo='ippo', deterministic=True)) == []
    assert spec.differences(spec.replace(action='hrl', levels=0, memory=25)) == [
        'trained with grid moves (no --hrl); this run has per-target HRL selections (--hrl)']   # the cause only
    assert spec.differences(spec.replace(hidden=(32, 32), memory=25)) == [
        'trained with --hidden 16; this run has --hidden 32 32', 'trained without --memory; this run has --memory 25']
    toy = CueMatching().spec
    assert toy.differences(toy.replace(action='continuous', network='independent', levels=0)) == [
        'trained with abstract discrete choices (a toy task); this run has continuous actions (matd3)']


def _train_options(algo, argv):
    """The config `mate train ALGO ARGV` trains with (the trainer's generated parser)."""
    from mate.learn.command import TRAINERS, trainer_parser
    from mate.cli.options import config_from

    parser, _, config_class = trainer_parser(algo)
    return config_from(parser, config_class, parser.parse_args(argv), **TRAINERS[algo].fixed)


def _refused(algo, argv, capsys) -> str:
    """The first line of the error `mate train ALGO ARGV` exits with (status 2)."""
    with pytest.raises(SystemExit) as exit_info:
        _train_options(algo, argv)
    assert exit_info.value.code == 2
    return capsys.readouterr().err.splitlines()[0]


def test_cli_train_parser():
    from mate.cli.main import build_parser
    args = build_parser().parse_args(['train', 'ippo', '--team', 'target', '--steps', '1e4'])
    assert args.algo == 'ippo' and args.options == ['--team', 'target', '--steps', '1e4']
    config = _train_options(args.algo, args.options)
    assert isinstance(config, mappo.MAPPOConfig) and config.algo == 'ippo' and config.critic == 'local'
    assert config.team == 'target' and config.steps == 10_000


def test_cli_train_defaults_and_paper_settings(capsys):
    from mate.learn.ppo import PAPER_HYPERPARAMETERS
    camera = _train_options('mappo', [])
    assert mappo.policy_spec(camera).network == 'per-target' and camera.entropy_schedule[0] == (0, 0.01)
    assert mappo.policy_spec(_train_options('mappo', ['--team', 'target'])).network == 'mlp'
    paper = _train_options('mappo', ['--paper'])
    assert paper.actor == 'mlp' and paper.lr_schedule == PAPER_HYPERPARAMETERS['lr_schedule']
    assert paper.entropy_schedule == PAPER_HYPERPARAMETERS['entropy_schedule']
    assert camera.kl_coeff == 0.0 and paper.kl_coeff == 0.2 and paper.kl_target == 0.01
    assert not camera.full_observability
    assert _train_options('ippo', ['--team', 'target', '--full-observability']).full_observability
    assert _train_options('mappo', ['--paper', '--kl-coeff', '0']).kl_coeff == 0.0
    tuned = _train_options('mappo', ['--kl-coeff', '0.5', '--kl-target', '0.02'])
    assert (tuned.kl_coeff, tuned.kl_target) == (0.5, 0.02)
    assert '--kl-coeff: expected a number >= 0' in _refused('mappo', ['--kl-coeff', '-1'], capsys)
    assert '--kl-target: expected a number > 0' in _refused('mappo', ['--kl-target', '0'], capsys)
    mixed = _train_options('mappo', ['--paper', '--actor', 'per-target', '--entropy-schedule', '[[0, 0.02]]'])
    assert mixed.actor == 'per-target' and mixed.entropy_schedule == ((0, 0.02),)
    assert 'needs --team camera' in _refused('mappo', ['--team', 'target', '--actor', 'per-target'], capsys)
    assert 'expected JSON' in _refused('mappo', ['--lr-schedule', 'fast'], capsys)


def test_export_policy_is_small_and_loads(tmp_path):
    from mate.learn import export_policy
    path, _ = _tiny_camera_checkpoint(tmp_path / 'run')
    checkpoint = tmp_path / 'run' / 'checkpoint.pt'
    small = export_policy(checkpoint, tmp_path / 'small.pt', note='test')
    assert small.stat().st_size < checkpoint.stat().st_size
    data = load_checkpoint(small)
    assert 'optimizer' not in data and 'state' not in data and data['note'] == 'test' and data['env_steps'] == 128
    agent = PolicyCameraAgent.from_checkpoint(small)
    assert agent.policy.spec.team == 'camera' and not agent.deterministic
    for key, value in load_checkpoint(path)['actor'].items():     # the run's last actor, as in final.pt
        assert torch.equal(data['actor'][key], value)
    # an exported policy can carry the way it was scored (argmax) as its agents' default
    scored = export_policy(path, tmp_path / 'scored.pt', deterministic=True)
    assert PolicyCameraAgent.from_checkpoint(scored).deterministic
    assert not PolicyCameraAgent.from_checkpoint(scored, deterministic=False).deterministic


@pytest.mark.parametrize('variant', [dict(actor='mlp', lstm=16), dict(hrl=True, actor='per-target'),
                                     dict(actor='per-target', lstm=8)])
def test_recurrent_and_per_target_policies_round_trip_as_agents(tmp_path, variant):
    trainer = mappo_lstm if variant.get('lstm') else mappo
    config_class = mappo_lstm.RecurrentConfig if variant.get('lstm') else mappo.MAPPOConfig
    config = config_class(team='camera', config='MATE-2v4-0', num_envs=4, rollout_length=4, steps=2 * 4 * 4,
                          epochs=1, hidden=(16,), snapshot_every=1, seed=0, run_dir=str(tmp_path), progress=False,
                          **variant)
    trainer.train(config)
    snapshots = sorted((tmp_path / 'snapshots').glob('policy-*.pt'))
    assert [p.name for p in snapshots] == ['policy-0000000016.pt', 'policy-0000000032.pt']
    policy = load_policy(snapshots[-1], 'camera')
    assert policy.recurrent == bool(variant.get('lstm')) and policy.spec.lstm == variant.get('lstm', 0)
    env = mate.make('MATE-2v4-0-v0')
    (camera_obs, _), _ = env.reset(seed=0)
    agent = PolicyCameraAgent(policy, seed=0, deterministic=True)
    agent.reset(camera_obs[0])
    first = [agent.act(camera_obs[0]) for _ in range(6)]
    agent.reset(camera_obs[0])                     # a reset forgets the recurrent memory: same actions again
    assert all(np.array_equal(a, b) for a, b in zip(first, [agent.act(camera_obs[0]) for _ in range(6)]))
    if variant.get('lstm'):                        # the memory changes the logits of the same observation
        x = policy.features(camera_obs[:1])
        logits0, memory = policy.outputs(x, policy.initial_memory(1))
        logits1, _ = policy.outputs(x, memory)
        assert not np.allclose(logits0, logits1)


def _camera_views(steps: int = 60, seed: int = 0):
    """(processed camera observations (S, Nc, D), world snapshots) of random play on MATE-2v4-0, with
    the cameras' viewing angles opened wide so that they often see each other and the same targets."""
    from mate.policies.spec import preprocess_observation
    env = mate.make('MATE-2v4-0-v0')
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    observations, worlds = [], []
    for _ in range(steps):
        world = env.get_world()
        world['camera_orientation'] = rng.uniform(-180, 180, 2)
        world['camera_viewing_angle'] = rng.uniform(60, 180, 2)
        world['camera_sight_range'] = np.sqrt(30 * 1500 ** 2 / world['camera_viewing_angle'])
        radians = np.radians(world['camera_orientation'])
        world['camera_state'][:, 3] = world['camera_sight_range'] * np.cos(radians)
        world['camera_state'][:, 4] = world['camera_sight_range'] * np.sin(radians)
        world['camera_state'][:, 5] = world['camera_viewing_angle']
        env.set_world(world)
        camera_obs, _ = env.joint_observation()
        observations.append(preprocess_observation(camera_obs, 'camera', 2, 4, 0))
        worlds.append(env.get_world())
        env.step((np.zeros((2, 2)), rng.uniform(-20, 20, (4, 2))))
    return torch.as_tensor(np.array(observations)), worlds


def test_per_target_actor_scores_every_slot_with_one_scorer():
    from mate.policies.networks import PerTargetActor
    torch.manual_seed(0)
    obs, _ = _camera_views(steps=4)
    obs, perm = obs.reshape(-1, obs.shape[-1]), [2, 0, 3, 1]
    hrl = PerTargetActor(obs.shape[-1], (2, 4, 0), hidden=(16,))              # keep/ignore logits per slot
    out = hrl(obs).reshape(-1, 4, 2)
    # the context sees the whole observation, so compare slots through the scorer alone
    embedded = hrl.activation(hrl.slot_in(hrl.slot_features(obs)) + hrl.context_in(hrl.body(obs))[:, None])
    assert torch.allclose(hrl.head(embedded), out, atol=1e-6)
    assert torch.allclose(hrl.head(embedded[:, perm]), out[:, perm], atol=1e-6)
    features = hrl.slot_features(obs)
    differ = (features[:, :, None] != features[:, None, :]).any(-1)           # (rows, slot, slot)
    row, a, b = (int(i) for i in differ.nonzero()[0])
    assert not torch.allclose(out[row, a], out[row, b], rtol=0, atol=1e-9)    # different records, different logits
    flat = PerTargetActor(obs.shape[-1], (2, 4, 0), hidden=(16,), num_actions=25)   # pooled + pointer: 25 logits
    assert flat(obs).shape == (obs.shape[0], 25)


def test_flat_per_target_head_ignores_slot_order_and_unseen_slots():
    from mate.policies.networks import PerTargetActor
    torch.manual_seed(1)
    obs, _ = _camera_views(steps=4)
    obs = obs.reshape(-1, obs.shape[-1])
    flat = PerTargetActor(obs.shape[-1], (2, 4, 0), hidden=(16,), num_actions=25)
    for layer in (flat.head[-1], flat.aim):                                  # larger than the 0.01 init
        torch.nn.init.normal_(layer.weight, std=1.0)
    context = flat.body(obs)                                                 # the context sees slot order: fix it
    logits = flat.logits_from(obs, context)
    begin, records = flat.begin, obs[:, flat.begin:flat.begin + 20].reshape(-1, 4, 5)
    permuted = obs.clone()
    permuted[:, begin:begin + 20] = records[:, [3, 1, 0, 2]].reshape(-1, 20)
    assert torch.allclose(flat.logits_from(permuted, context), logits, atol=1e-5)
    unseen = records[..., 4] < 0.5
    assert unseen.any() and (~unseen).any()
    changed = obs.clone()
    shift = torch.tensor([0.3, -0.2, 0.1, 0.4, 0.0])                          # the flag stays 0
    changed[:, begin:begin + 20] = torch.where(unseen[..., None], records + shift, records).reshape(-1, 20)
    assert torch.allclose(flat.logits_from(changed, context), logits, atol=1e-5)   # only visible slots count
    moved = obs.clone()
    moved[:, begin:begin + 20] = torch.where(unseen[..., None], records, records + 0.05 * shift).reshape(-1, 20)
    assert not torch.allclose(flat.logits_from(moved, context), logits, atol=1e-3)


def test_per_target_actor_slot_features_match_the_world():
    from mate.policies.networks import PerTargetActor
    obs, worlds = _camera_views()
    actor = PerTargetActor(obs.shape[-1], (2, 4, 0), hidden=(8,))
    features = actor.slot_features(obs).numpy()                              # (S, Nc, Nt, 13)
    visible = np.array([w['camera_target_view_mask'] for w in worlds])       # (S, Nc, Nt)
    sees = np.array([w['camera_camera_view_mask'] for w in worlds])          # (S, Nc, Nc), diagonal true
    other_tracks = np.stack([sees[:, 0, 1, None] & visible[:, 1], sees[:, 1, 0, None] & visible[:, 0]], axis=1)
    assert np.array_equal(features[..., 4] > 0.5, visible)
    assert np.array_equal(features[..., 12] > 0.5, visible & other_tracks)   # a teammate it sees covers it too
    assert 0 < (visible & other_tracks).sum() < visible.sum()                # both cases occur
    inside = features[visible]
    assert np.all(inside[:, 10] >= -1e-6) and np.all(inside[:, 11] >= -1e-6)   # angle and range margins
    assert np.allclose(inside[:, 5] ** 2 + inside[:, 6] ** 2, inside[:, 7] ** 2, atol=1e-5)   # along/across/distance
    assert np.all(features[~visible][:, 5:] == 0)
    assert np.all(np.abs(inside[:, 8]) <= 1 + 1e-6) and np.allclose(inside[:, 8] ** 2 + inside[:, 9] ** 2, 1, atol=1e-5)

def test_warm_start_loads_the_networks_and_rejects_another_setting(tmp_path):
    _tiny_camera_checkpoint(tmp_path / 'first')
    first = load_checkpoint(tmp_path / 'first' / 'checkpoint.pt')['state']['networks']
    frozen = dict(steps=8 * 8, seed=3, lr_schedule=((0, 0.0),))     # learning rate 0: the weights stay the loaded ones
    mappo.train(_camera_config(tmp_path / 'second', init_from=str(tmp_path / 'first' / 'checkpoint.pt'), **frozen))
    assert load_checkpoint(tmp_path / 'second' / 'final.pt')['env_steps'] == 64      # steps count from 0
    warm = load_checkpoint(tmp_path / 'second' / 'checkpoint.pt')['state']['networks']
    for name in ('actor', 'critic'):
        for key, value in first[name].items():
            assert torch.equal(warm[name][key], value), (name, key)
    # a policy file holds the actor only: the critic starts afresh
    mappo.train(_camera_config(tmp_path / 'policy', init_from=str(tmp_path / 'first' / 'final.pt'), **frozen))
    from_policy = load_checkpoint(tmp_path / 'policy' / 'checkpoint.pt')['state']['networks']
    assert all(torch.equal(from_policy['actor'][k], v) for k, v in first['actor'].items())
    assert not all(torch.equal(from_policy['critic'][k], v) for k, v in first['critic'].items())
    with pytest.raises(CheckpointError, match=r'warm start .*grid moves \(no --hrl\); this run has per-target HRL'):
        mappo.train(_camera_config(tmp_path / 'third', hrl=True, steps=8 * 8,
                                   init_from=str(tmp_path / 'first' / 'final.pt')))
