"""Target velocities for cameras that hold their decisions: the features, the training env's columns,
the actor, and the agents that compute the same columns from their own observations."""

import numpy as np
import pytest
import torch

import mate
from mate.constants import PRESERVED_DIM
from mate.learn import PolicyCameraAgent, load_checkpoint, load_policy
from mate.learn.envs import TeamEnvConfig
from mate.learn.mappo import MAPPOConfig, train
from mate.policies.networks import PerTargetActor
from mate.policies.spec import PolicySpec, SpecError, preprocess_observation
from mate.policies.velocity import VELOCITY_FEATURES, target_displacements
from mate.spaces import observation_indices_of

COUNTS = (2, 3, 0)


def _env(num_envs, **options):
    """Training envs of grid-move cameras on MATE-4v8-9 (the camera preset), `options` of `TeamEnvConfig`."""
    config = TeamEnvConfig(team='camera', num_envs=num_envs, **options)
    return config.make_env(config.policy_spec())


def _camera_obs(targets):
    """Raw camera observations (2, D) of a (2, 3, 0) game; per camera the targets it sees as {slot: (x, y)}."""
    starts = observation_indices_of(mate.Team.CAMERA, *COUNTS)
    obs = np.zeros((COUNTS[0], int(starts[-1])))
    for c, seen in enumerate(targets):
        obs[c, PRESERVED_DIM:PRESERVED_DIM + 2] = 100.0 * c, 0.0
        for t, (x, y) in seen.items():
            obs[c, int(starts[2]) + 5 * t:int(starts[2]) + 5 * t + 5] = x, y, 100.0, 0.0, 1.0
    return obs


def test_displacements_by_hand():
    before = _camera_obs([{0: (10.0, 20.0), 1: (0.0, 0.0)}, {2: (5.0, 5.0)}])
    now = _camera_obs([{0: (14.0, 17.0), 2: (7.0, 7.0)}, {2: (5.0, 25.0)}])
    moved = target_displacements(now, before, COUNTS, steps=5).reshape(2, 3, VELOCITY_FEATURES)
    assert moved.dtype == np.float32
    expected = np.zeros((2, 3, 2))
    expected[0, 0] = np.array([4.0, -3.0]) * 5 / 2000      # seen at both steps: displacement over 5 steps
    expected[1, 2] = np.array([0.0, 20.0]) * 5 / 2000      # slot 1 lost and slot 2 new for camera 0: zero
    assert np.allclose(moved, expected)
    # leading batch axes pass through
    assert target_displacements(now[None], before[None], COUNTS, 1).shape == (1, 2, 3 * VELOCITY_FEATURES)
    with pytest.raises(ValueError, match='cameras only'):
        TeamEnvConfig(team='target', num_envs=2, velocity=True)
    with pytest.raises(SpecError, match='cameras only'):
        PolicySpec.for_game('target', 'MATE-2v4-0-v0', frame_skip=10, velocity=True)


def test_team_env_appends_the_last_raw_step_motion():
    """The columns are the displacement between the last two raw steps of the decision, recorded here
    from the vector env itself, and zero for rows that started an episode at the last raw step."""
    env = _env(4, velocity=True, horizon=40, seed=3)
    plain = _env(4, horizon=40, seed=3)
    nc, nt, _ = env.counts
    raw_steps = []
    vec_step = env.vec.step

    def recording_step(actions):
        result = vec_step(actions)
        raw_steps.append((result[0][0].copy(), (result[2] | result[3]).copy()))
        return result

    env.vec.step = recording_step
    obs, _ = env.reset(seed=3)
    base, _ = plain.reset(seed=3)
    assert obs.shape[-1] == env.obs_dim == plain.obs_dim + VELOCITY_FEATURES * nt
    assert np.all(obs[..., plain.obs_dim:] == 0.0)                   # no motion at the first observation
    rng = np.random.default_rng(0)
    restarted_rows = 0
    for _ in range(12):
        actions = rng.integers(0, 25, (4, nc))
        raw_steps.clear()
        obs, _, _, done, _, _ = env.step(actions)
        base, *_ = plain.step(actions)
        assert np.array_equal(obs[..., :plain.obs_dim], base)       # the same game, velocity columns aside
        (previous, ended_before), (current, _) = raw_steps[-2], raw_steps[-1]
        # rows whose episode ended at the last but one raw step restarted at the last one: no motion yet
        expected = target_displacements(current, previous, env.counts, env.frame_skip)
        expected[ended_before] = 0.0
        restarted_rows += int(ended_before.sum())
        assert np.allclose(obs[..., plain.obs_dim:], expected)
        assert np.array_equal(current, env.raw_observations)
    assert np.abs(obs[..., plain.obs_dim:]).max() > 0                # targets do move
    assert restarted_rows > 0


@pytest.fixture(scope='module')
def velocity_policy(tmp_path_factory):
    run = tmp_path_factory.mktemp('velocity-run')
    train(MAPPOConfig(team='camera', config='MATE-4v8-9', num_envs=4, rollout_length=4, steps=2 * 4 * 4, epochs=1,
                      hidden=(16,), velocity=True, seed=0, run_dir=str(run), progress=False))
    return run / 'final.pt'


def test_actor_reads_velocity_and_checkpoint_keeps_it(velocity_policy):
    assert load_checkpoint(velocity_policy)['spec']['velocity'] is True
    actor = load_policy(velocity_policy, 'camera').actor
    assert isinstance(actor, PerTargetActor) and actor.slot_features_dim == 17
    env = _env(1, velocity=True, seed=0)
    obs, _ = env.reset(seed=0)
    nt, first = env.counts[1], env.obs_dim - VELOCITY_FEATURES * env.counts[1]
    for _ in range(20):   # until some camera sees a target
        x = torch.from_numpy(obs[0])
        seen = [(c, t) for c in range(env.num_agents) for t in range(nt) if x[c, actor.begin + 5 * t + 4] > 0.5]
        if seen:
            break
        obs = env.step(np.zeros((1, env.num_agents), dtype=np.int64))[0]
    assert seen, 'expected a camera that sees a target within 20 decisions'
    c, t = seen[0]
    x = x.clone()
    x[:, first:] = 0.0
    with torch.no_grad():
        still = actor.slot_features(x[c])
        # no motion: the predicted bearing (columns 15, 16) is the bearing now (columns 8, 9: cos, sin)
        assert torch.allclose(still[t, 15:17], still[t, 8:10], atol=1e-5)
        moving = x[c].clone()
        moving[first + 2 * t:first + 2 * t + 2] = torch.tensor([0.02, -0.01])
        assert not torch.allclose(actor.slot_features(moving)[t, 13:17], still[t, 13:17])
        assert not torch.allclose(actor(moving), actor(x[c]))
        hidden = [u for u in range(nt) if x[c, actor.begin + 5 * u + 4] < 0.5]
        if hidden:   # a slot the camera does not see has no motion features
            u = hidden[0]
            moving[first + 2 * u:first + 2 * u + 2] = torch.tensor([0.02, -0.01])
            assert torch.all(actor.slot_features(moving)[u, 13:17] == 0.0)
    with pytest.raises(ValueError, match='target velocities'):
        PerTargetActor(env.obs_dim - 1, env.counts, hidden=(16,), num_actions=25, velocity=True)


def test_agents_feed_their_policy_the_training_columns(velocity_policy):
    """A policy camera deciding every step feeds its network the processed observation plus the motion
    between its last two observations, scaled by the training frame skip (5), not its own hold."""
    env = mate.make('MATE-4v8-9-v0')
    policy = load_policy(velocity_policy, 'camera')
    seen_inputs = []
    outputs = policy.outputs
    policy.outputs = lambda features, memory=None: (seen_inputs.append(features[0].copy()), outputs(features))[1]
    cameras = PolicyCameraAgent(policy, seed=0, frame_skip=1).spawn(env.num_cameras)
    targets = mate.GreedyTargetAgent(seed=0).spawn(env.num_targets)
    (camera_obs, target_obs), (camera_infos, target_infos) = env.reset(seed=5)
    mate.group_reset(cameras, camera_obs)
    mate.group_reset(targets, target_obs)
    counts = (env.num_cameras, env.num_targets, env.num_obstacles)
    previous = camera_obs.copy()
    moved_any = False
    for step in range(100):
        seen_inputs.clear()
        camera_action = mate.group_step(env, cameras, camera_obs, camera_infos)
        expected = np.concatenate([preprocess_observation(camera_obs, 'camera', *counts),
                                   target_displacements(camera_obs, previous, counts, 5)], axis=-1)
        assert np.allclose(np.stack(seen_inputs), expected, atol=1e-6), step
        moved_any |= bool(np.abs(expected[:, -VELOCITY_FEATURES * env.num_targets:]).max() > 0)
        previous = camera_obs.copy()
        target_action = mate.group_step(env, targets, target_obs, target_infos)
        (camera_obs, target_obs), _, _, _, (camera_infos, target_infos) = env.step((camera_action, target_action))
    assert moved_any


def test_train_command_validates_velocity(capsys):
    from mate.learn.command import trainer_parser
    from mate.cli.options import config_from

    parser, _, config_class = trainer_parser('mappo')

    def config_of(argv):
        return config_from(parser, config_class, parser.parse_args(argv))

    assert config_of(['--velocity']).velocity is True
    assert config_of([]).velocity is False
    with pytest.raises(SystemExit) as exit_info:
        config_of(['--team', 'target', '--velocity'])
    assert exit_info.value.code == 2 and 'cameras only' in capsys.readouterr().err.splitlines()[0]
