"""The camera team's shared sighting memory: the memory itself, the training env's columns, the actor,
and the agents that rebuild the same memory through messages."""

import numpy as np
import pytest
import torch

import mate
from mate.constants import PRESERVED_DIM
from mate.learn import PolicyCameraAgent, load_checkpoint, load_policy
from mate.learn.envs import TeamEnvConfig, TrainingEnv
from mate.learn.mappo import MAPPOConfig, train
from mate.policies.memory import MEMORY_FEATURES, SightingMemory
from mate.policies.networks import PerTargetActor
from mate.policies.spec import PolicySpec, SpecError
from mate.spaces import observation_indices_of

COUNTS = (2, 3, 0)


def _env(num_envs, **options):
    """Training envs of grid-move cameras on MATE-4v8-9 (the camera preset), `options` of `TeamEnvConfig`."""
    config = TeamEnvConfig(team='camera', num_envs=num_envs, **options)
    return config.make_env(config.policy_spec())


def _camera_obs(cameras, targets):
    """Raw camera observations (1, Nc, D) of a (2, 3, 0) game: camera locations, and per camera the
    targets it sees as {slot: (x, y)}."""
    nc, nt, no = COUNTS
    starts = observation_indices_of(mate.Team.CAMERA, nc, nt, no)
    obs = np.zeros((1, nc, int(starts[-1])))
    for c, ((x, y), seen) in enumerate(zip(cameras, targets)):
        obs[0, c, PRESERVED_DIM:PRESERVED_DIM + 2] = x, y
        for t, (tx, ty) in seen.items():
            obs[0, c, int(starts[2]) + 5 * t:int(starts[2]) + 5 * t + 5] = tx, ty, 100.0, 0.0, 1.0
    return obs


def test_memory_features_by_hand():
    memory = SightingMemory(1, COUNTS, period=10)
    cameras = [(0.0, 0.0), (400.0, -200.0)]
    obs = _camera_obs(cameras, [{1: (100.0, 50.0)}, {}])
    memory.forget()
    memory.observe_team(obs)
    f = memory.features(obs).reshape(1, 2, 3, MEMORY_FEATURES)
    scale = memory.scale
    assert scale == 2000.0
    # camera 0 sees target 1 itself: offset, fresh, not "seen by a teammate"
    assert np.allclose(f[0, 0, 1], [100.0 / scale, 50.0 / scale, 1.0, 0.0])
    # camera 1 knows it from camera 0: offset from its own location, fresh, seen by a teammate
    assert np.allclose(f[0, 1, 1], [(100.0 - 400.0) / scale, (50.0 + 200.0) / scale, 1.0, 1.0])
    assert np.all(f[0, :, [0, 2]] == 0.0)                  # never seen: all zero
    # four steps without a sighting: 1 - 4 / 10 fresh, the old location, nobody sees it now
    empty = _camera_obs(cameras, [{}, {}])
    for _ in range(4):
        memory.tick()
        memory.observe_team(empty)
    f = memory.features(empty).reshape(1, 2, 3, MEMORY_FEATURES)
    assert np.allclose(f[0, 1, 1], [-300.0 / scale, 250.0 / scale, 0.6, 0.0])
    # forgotten after `period` steps in all
    for _ in range(6):
        memory.tick()
    assert np.all(memory.features(empty) == 0.0)


def test_memory_rejects_a_bad_period():
    with pytest.raises(ValueError, match='at least 1'):
        SightingMemory(1, COUNTS, period=0)
    with pytest.raises(ValueError, match='cameras only'):
        TeamEnvConfig(team='target', num_envs=2, memory=25)
    with pytest.raises(SpecError, match='cameras only'):
        PolicySpec.for_game('target', 'MATE-2v4-0-v0', frame_skip=10, memory=25)


def test_team_env_appends_memory_and_forgets_at_new_episodes():
    env = _env(4, memory=25, horizon=40, seed=3)
    plain = _env(4, horizon=40, seed=3)
    nc, nt, no = env.counts
    begin = int(observation_indices_of(mate.Team.CAMERA, nc, nt, no)[2])
    obs, _ = env.reset(seed=3)
    base, _ = plain.reset(seed=3)
    assert obs.shape[-1] == env.obs_dim == plain.obs_dim + MEMORY_FEATURES * nt
    forgotten = []
    forget = env.memory.forget
    env.memory.forget = lambda mask=None: (forgotten.append(np.ones(4, bool) if mask is None else mask.copy()),
                                           forget(mask))
    rng = np.random.default_rng(0)
    ended = False
    for _ in range(12):
        actions = rng.integers(0, 25, (4, nc))
        assert np.array_equal(obs[..., :plain.obs_dim], base)       # the same game, memory columns aside
        columns = obs[..., plain.obs_dim:].reshape(4, nc, nt, MEMORY_FEATURES)
        records = obs[..., begin:begin + 5 * nt].reshape(4, nc, nt, 5)
        visible = records[..., 4] > 0.5
        # a target a camera sees now: memory = its record's (rescaled relative) location, fresh, not "teammate"
        assert np.allclose(columns[..., :2][visible], records[..., :2][visible], atol=1e-6)
        assert np.all(columns[..., 2][visible] == 1.0) and np.all(columns[..., 3][visible] == 0.0)
        # freshness is in [0, 1] and locations are zero for forgotten targets
        assert np.all((columns[..., 2] >= 0) & (columns[..., 2] <= 1))
        assert np.all(columns[..., :2][columns[..., 2] == 0] == 0.0)
        forgotten.clear()
        obs, _, _, done, _, info = env.step(actions)
        base, *_ = plain.step(actions)
        if done.any():
            ended = True
            # a row whose episode ended restarts within the decision: its memory is wiped then, no other row's
            wiped = np.any(forgotten, axis=0)
            assert np.array_equal(wiped, done)
    assert ended


@pytest.fixture(scope='module')
def memory_policy(tmp_path_factory):
    run = tmp_path_factory.mktemp('memory-run')
    train(MAPPOConfig(team='camera', config='MATE-4v8-9', num_envs=4, rollout_length=4, steps=2 * 4 * 4, epochs=1,
                      hidden=(16,), memory=25, seed=0, run_dir=str(run), progress=False))
    return run / 'final.pt'


def test_actor_reads_memory_and_checkpoint_keeps_it(memory_policy):
    data = load_checkpoint(memory_policy)
    assert data['spec']['memory'] == 25
    policy = load_policy(memory_policy, 'camera')
    actor = policy.actor
    assert isinstance(actor, PerTargetActor) and actor.slot_features_dim == 15
    # a target known only from memory is a present slot: it changes the logits; a forgotten one does not
    env = _env(1, memory=25, seed=0)
    obs, _ = env.reset(seed=0)
    x = torch.from_numpy(obs[0, :1])
    nt = env.counts[1]
    mem = env.obs_dim - MEMORY_FEATURES * nt
    free = [t for t in range(nt) if x[0, mem + 4 * t + 2] == 0]
    assert free, 'expected a target no camera sees at reset'
    t = free[0]
    remembered = x.clone()
    remembered[0, mem + 4 * t:mem + 4 * t + 4] = torch.tensor([0.1, -0.05, 0.5, 0.0])
    zero_fresh = remembered.clone()
    zero_fresh[0, mem + 4 * t + 2] = 0.0
    # a remembered target beyond this camera's maximum sight range (own state index 6) is not present
    max_reach = 0.5 * (float(x[0, actor.own + 6]) + 1.0)
    far = remembered.clone()
    far[0, mem + 4 * t:mem + 4 * t + 2] = torch.tensor([1.01 * max_reach, 0.0])
    with torch.no_grad():
        slots = actor.slot_features(remembered)
        assert actor.present(slots)[0, t, 0] == 1.0 and slots[0, t, 4] == 0.0
        assert actor.present(actor.slot_features(zero_fresh))[0, t, 0] == 0.0
        assert actor.present(actor.slot_features(far))[0, t, 0] == 0.0
        assert not torch.allclose(actor(remembered), actor(x))


def test_agents_rebuild_the_training_memory_through_messages(memory_policy):
    """Four policy cameras in a single env, driven by `group_step`, hold exactly the memory that the
    training env computes from the joint observations."""
    env = mate.make('MATE-4v8-9-v0')
    policy = load_policy(memory_policy, 'camera')
    cameras = PolicyCameraAgent(policy, seed=0).spawn(env.num_cameras)
    targets = mate.GreedyTargetAgent(seed=0).spawn(env.num_targets)
    (camera_obs, target_obs), (camera_infos, target_infos) = env.reset(seed=5)
    mate.group_reset(cameras, camera_obs)
    mate.group_reset(targets, target_obs)
    reference = SightingMemory(1, (env.num_cameras, env.num_targets, env.num_obstacles), 25)
    reference.forget()
    reference.observe_team(camera_obs[None])
    rng = np.random.default_rng(1)
    told = 0
    for step in range(60):
        mate.group_step(env, cameras, camera_obs, camera_infos)
        if step > 0:
            reference.tick()
            reference.observe_team(camera_obs[None])
        expected = reference.features(camera_obs[None])[0]
        for c, agent in enumerate(cameras):
            got = agent._sightings.features(camera_obs[c][None, None])[0, 0]
            assert np.allclose(got, expected[c]), (step, c)
        told += sum(1 for a in cameras for m in a.last_requests if 'sightings' in m.content)
        camera_action = rng.uniform(-1, 1, (env.num_cameras, 2)) * np.array([5.0, 2.5])   # explore
        target_action = mate.group_step(env, targets, target_obs, target_infos)
        (camera_obs, target_obs), _, _, _, (camera_infos, target_infos) = env.step((camera_action, target_action))
    assert told > 0


def test_train_command_validates_memory(capsys):
    from mate.learn.command import trainer_parser
    from mate.cli.options import config_from

    parser, _, config_class = trainer_parser('mappo')

    def config_of(argv):
        return config_from(parser, config_class, parser.parse_args(argv))

    def refused(argv) -> str:   # the parser's one-line error (status 2)
        with pytest.raises(SystemExit) as exit_info:
            config_of(argv)
        assert exit_info.value.code == 2
        return capsys.readouterr().err.splitlines()[0]

    assert config_of(['--memory', '25']).memory == 25
    assert config_of([]).memory == 0
    assert '>= 0' in refused(['--memory', '-1'])
    assert 'cameras only' in refused(['--team', 'target', '--memory', '25'])


def test_a_training_env_checkpoint_of_the_earlier_layout_resumes_exactly():
    """A CPU training env's state as the version before the one training env saved it (the games' vec, opponent
    and pending at the top level) continues as the state of today's layout does: the checkpoints of runs in
    progress resume."""
    spec = PolicySpec.for_game('camera', 'MATE-4v8-9-v0', frame_skip=2, action='hrl', memory=5, velocity=True)
    rng = np.random.default_rng(0)
    actions = rng.integers(0, 2, size=(12, 3, spec.num_agents, spec.heads))
    envs = TrainingEnv(spec, 3, horizon=8, seed=2)
    envs.reset()
    for step in range(6):
        envs.step(actions[step])
    state = envs.state_dict()
    assert state['games_on'] == 'cpu'
    games = state.pop('games')
    old = dict(state, vec=games['vec'], opponent=games['opponent'], pending=games['pending'])
    del old['games_on']
    expected = [envs.step(actions[step]) for step in range(6, 12)]
    for saved in (dict(state, games=games), old):
        again = TrainingEnv(spec, 3, horizon=8, seed=2)
        again.load_state_dict(saved)
        for step, (features, world_state, reward, done, truncated, info) in zip(range(6, 12), expected):
            found = again.step(actions[step])
            for a, b in zip((features, world_state, reward, done, truncated), found[:5]):
                np.testing.assert_array_equal(a, b)
            assert found[5]['episodes'] == info['episodes']
            np.testing.assert_array_equal(found[5]['final_obs'], info['final_obs'])
    assert sum(len(info['episodes']) for *_, info in expected) >= 3
