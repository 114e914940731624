"""The RLlib adapter: MultiAgentEnv conventions, opponents, the policy-spec view (features, grid moves, frame skip,
seeding by rows), and one PPO iteration (slow, local Ray).

Skipped unless `ray[rllib]` is installed (the optional extra `mate[rllib]`)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import needs_extra

needs_extra('ray.rllib')
from ray.rllib.utils.pre_checks.env import check_multiagent_environments  # noqa: E402

from mate.envs.multi_agent_tracking import MultiAgentTracking  # noqa: E402
from mate.integrations import rllib as mate_rllib  # noqa: E402
from mate.policies.spec import PolicySpec, SpecError  # noqa: E402

SMALL = {'config': 'MATE-2v4-9', 'overrides': {'max_episode_steps': 12}}


def test_camera_team_against_an_opponent():
    env = mate_rllib.MateMultiAgentEnv({**SMALL, 'opponent': 'uniform'})
    check_multiagent_environments(env)
    assert env.possible_agents == ['camera_0', 'camera_1']
    observations, infos = env.reset(seed=0)
    assert set(observations) == set(infos) == set(env.agents)
    for agent, obs in observations.items():
        assert obs.dtype == np.float32 and env.observation_spaces[agent].contains(obs)
    steps, done = 0, False
    while not done:
        actions = {agent: env.action_spaces[agent].sample() for agent in env.agents}
        observations, rewards, terminateds, truncateds, infos = env.step(actions)
        done = terminateds['__all__'] or truncateds['__all__']
        steps += 1
        assert rewards['camera_0'] == rewards['camera_1']
        assert 0.0 <= infos['camera_0']['episode_coverage_rate'] <= 1.0
    assert steps == 12 and env.agents == []


def test_observations_are_the_single_env_rescaled():
    env = mate_rllib.MateMultiAgentEnv({**SMALL, 'team': 'both'})
    single = MultiAgentTracking('MATE-2v4-9')
    observations, _ = env.reset(seed=4)
    (camera_obs, target_obs), _ = single.reset(seed=4)
    assert len(observations) == 6
    high = np.abs(single.target_observation_space.high)
    scale = np.where(np.isfinite(high) & (high > 0), np.maximum(high, np.abs(single.target_observation_space.low)), 1)
    np.testing.assert_allclose(observations['target_2'], (target_obs[2] / scale).astype(np.float32))
    _, rewards, _, _, _ = env.step({'camera_0': np.zeros(2, np.float32)})
    assert rewards['camera_0'] == -rewards['target_0']


def _target_positions(env) -> np.ndarray:
    return env.env.get_world()['target_state'][:, :2].copy()


def _still(joint_obs):
    return np.zeros((len(joint_obs), 2))


@pytest.mark.parametrize('opponent', ['greedy', 'naive', 'random', 'uniform', 'mate.agents:GreedyTargetAgent', _still,
                                      'batched-greedy', 'batched-random'],
                         ids=['greedy', 'naive', 'random', 'uniform', 'import-path', 'zeros-callable', 'batched-greedy',
                              'batched-random'])
def test_opponents(opponent):
    """The opponent plays the targets: the rule-based, uniform and imported ones move them at every
    step, the callable returning zeros leaves them where they are; the cameras (absent from the action
    dicts) stay still, and what RLlib gets back is well formed."""
    env = mate_rllib.MateMultiAgentEnv({**SMALL, 'opponent': opponent})
    env.reset(seed=0)
    for step in range(1, 4):
        before = _target_positions(env)
        observations, rewards, terminateds, truncateds, infos = env.step({})
        moved = np.abs(_target_positions(env) - before).max()
        if opponent is _still:
            assert moved == 0.0
        else:
            assert moved > 1.0, f'the targets did not move at step {step}'
        assert env.env.episode_step == step
        assert set(observations) == set(rewards) == set(infos) == {'camera_0', 'camera_1'}
        for agent, obs in observations.items():
            assert obs.dtype == np.float32 and np.isfinite(obs).all()
            assert env.observation_spaces[agent].contains(obs)
        assert np.isfinite(rewards['camera_0']) and rewards['camera_0'] == rewards['camera_1']
        assert terminateds['__all__'] is False and truncateds['__all__'] is False


@pytest.mark.parametrize('other', ['mate.agents:GreedyTargetAgent', 'batched-greedy'])
def test_an_opponent_named_by_its_import_path_or_batched_is_the_named_agent(other):
    """The imported agent is the named one; the batched greedy team plays draw for draw as the Python agents."""
    paths = []
    for opponent in ('greedy', other):
        env = mate_rllib.MateMultiAgentEnv({**SMALL, 'opponent': opponent})
        env.reset(seed=0)
        for _ in range(30):
            env.step({})
        paths.append(_target_positions(env))
    np.testing.assert_array_equal(*paths)


@pytest.mark.parametrize('action, given', [(np.zeros((1, 2)), '(1, 2)'), (np.zeros(4), '(4,)'), (0.0, '()')],
                         ids=['(1, 2)', '(4,)', 'scalar'])
def test_an_action_of_the_wrong_shape_is_refused(action, given):
    env = mate_rllib.MateMultiAgentEnv({**SMALL, 'team': 'both'})
    env.reset(seed=0)
    with pytest.raises(ValueError) as error:
        env.step({'camera_0': np.zeros(2, np.float32), 'target_3': action})
    assert str(error.value) == f'action of target_3 must have shape (2,) [dx, dy]; got {given}'
    assert env.env.episode_step == 0          # the world did not advance
    with pytest.raises(ValueError, match=r"unknown agent 'referee'"):
        env.step({'referee': np.zeros(2)})
    env.step({'camera_0': np.zeros(2, np.float32), 'target_3': [1, 1]})   # (2,), any real dtype
    assert env.env.episode_step == 1


def test_an_opponent_returning_a_flat_vector_is_refused():
    env = mate_rllib.MateMultiAgentEnv({**SMALL, 'opponent': lambda joint_obs: np.zeros(2 * len(joint_obs))})
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r'target joint action must have shape \(4, 2\) .*; got \(8,\)'):
        env.step({})


def test_bad_env_config_is_refused():
    with pytest.raises(ValueError, match='unknown env_config keys'):
        mate_rllib.MateMultiAgentEnv({'preset': 'MATE-2v4-9'})
    with pytest.raises(ValueError, match='team must be'):
        mate_rllib.MateMultiAgentEnv({'team': 'referee'})
    with pytest.raises(ValueError, match='unknown opponent'):
        mate_rllib.MateMultiAgentEnv({**SMALL, 'opponent': 'clever'})


@pytest.mark.slow
def test_one_ppo_iteration_on_a_local_ray_instance(tmp_path):
    """`train` (continuous actions, the camera team against uniform targets): one iteration, then a checkpoint."""
    summaries = mate_rllib.train({**SMALL, 'opponent': 'uniform'}, 1, num_cpus=1, checkpoint_dir=str(tmp_path / 'ppo'),
                                 train_batch_size=120, minibatch_size=60, num_epochs=1, hidden=(32,), seed=0)
    (summary,) = summaries
    assert summary['iteration'] == 1 and summary['env_steps'] >= 120 and summary['episodes'] >= 10
    assert np.isfinite(summary['returns']['camera'])
    assert 0.0 <= summary['coverage_rate'] <= 1.0
    assert summary['checkpoint'] and any((tmp_path / 'ppo').iterdir())


# ----------------------------------------------------------------------------------- the policy-spec view
def _spec(team: str = 'camera', **changes) -> PolicySpec:
    frame_skip = changes.pop('frame_skip', 5 if team == 'camera' else 10)
    return PolicySpec.for_game(team, 'MATE-2v4-0-v0', frame_skip=frame_skip, hidden=(16,), **changes)


def _spec_env(spec: PolicySpec, **config) -> mate_rllib.MateMultiAgentEnv:
    return mate_rllib.MateMultiAgentEnv({'spec': spec.to_dict(), 'opponent': 'batched-greedy',
                                         'overrides': {'max_episode_steps': 40}, **config})


def test_the_spec_view_is_mate_learns_features_grid_moves_and_frame_skip():
    """Observations are the spec's features of the raw observations; a decision is one grid move per agent, decoded
    by the agent's own step limits and held for frame_skip env steps while the opponent acts at each: the same env
    steps as a hand-written loop over MultiAgentTracking and the batched greedy targets, reward the coverage rates
    summed."""
    from mate.teams import make_team

    spec = _spec('camera')
    env = _spec_env(spec, reward='coverage')
    check_multiagent_environments(env)
    assert env.action_spaces['camera_0'].n == 25 and env.observation_spaces['camera_1'].shape == (spec.obs_dim,)
    observations, _ = env.reset(seed=11)
    single = MultiAgentTracking('MATE-2v4-0', max_episode_steps=40)
    (camera_obs, target_obs), _ = single.reset(seed=11)
    targets = make_team('greedy', 'target', 1, (2, 4, 0), seed=11)
    targets.reset(target_obs[None], np.ones(1, dtype=bool))
    for decision, moves in enumerate([(3, 21), (24, 0), (12, 7)]):
        np.testing.assert_array_equal(np.stack([observations['camera_0'], observations['camera_1']]),
                                      spec.features(camera_obs))
        held = np.array(moves)[:, None]
        cameras = spec.decode(held[None], camera_obs[None])[0]
        assert np.abs(cameras).max() > 0
        coverage = 0.0
        for _ in range(spec.frame_skip):
            (camera_obs, target_obs), _, _, _, infos = single.step((cameras, targets.act(target_obs[None])[0]))
            coverage += infos[0][0]['coverage_rate']
        observations, rewards, _, _, infos = env.step({'camera_0': moves[0], 'camera_1': np.int64(moves[1])})
        assert env.env.episode_step == single.episode_step == spec.frame_skip * (decision + 1)
        np.testing.assert_array_equal(env.raw_observations[0], camera_obs)
        assert rewards['camera_0'] == rewards['camera_1'] == pytest.approx(coverage, abs=1e-12)
        assert infos['camera_0']['decision_coverage_rate'] == pytest.approx(coverage / spec.frame_skip, abs=1e-12)


def test_a_decision_stops_where_the_episode_ends_and_targets_learn_the_team_reward():
    spec = _spec('target')                       # frame skip 10, horizon 25 env steps: decisions of 10, 10, 5
    env = _spec_env(spec, overrides={'max_episode_steps': 25})
    env.reset(seed=2)
    steps, total = [], 0.0
    done = False
    while not done:
        _, rewards, terminateds, truncateds, infos = env.step({f'target_{i}': 0 for i in range(4)})
        steps.append(env.env.episode_step)
        total += rewards['target_0']
        done = terminateds['__all__'] or truncateds['__all__']
    info = infos['target_3']
    assert steps == [10, 20, 25] and truncateds['target_0'] and not terminateds['__all__']
    assert info['episode_length'] == 25 and info['episode_return'] == total
    assert info['episode_normalized_target_return'] == pytest.approx(total / 6400)


def test_games_are_seeded_by_rows_as_mate_trains():
    """RLlib seeds sub-env i of runner w with seed + w + i; the env plays seed + row instead (row = (w - 1) E + i on a
    remote runner, i on the local one); other seeds are taken as they are."""
    spec = _spec('camera').to_dict()

    def first_observation(seed: int, worker_index: int = 0, rows: dict | None = None) -> np.ndarray:
        env = mate_rllib.MateMultiAgentEnv({'spec': spec, **(rows or {})}, worker_index=worker_index)
        return env.reset(seed=seed)[0]['camera_0']

    rows = {'seed': 100, 'envs_per_runner': 4}
    assert not np.array_equal(first_observation(105), first_observation(103))
    np.testing.assert_array_equal(first_observation(100 + 2 + 1, 2, rows), first_observation(105))
    np.testing.assert_array_equal(first_observation(100 + 0 + 3, 0, rows), first_observation(103))
    np.testing.assert_array_equal(first_observation(7, 2, rows), first_observation(7))


def test_the_spec_view_refuses_what_it_cannot_play():
    env = _spec_env(_spec('camera'))
    env.reset(seed=0)
    for action, shown in ((25, '25'), (-1, '-1'), (np.zeros(2), 'array([0., 0.])'), (2.5, '2.5')):
        with pytest.raises(ValueError) as error:
            env.step({'camera_1': action})
        assert str(error.value) == f'action of camera_1 must be an integer in [0, 24] (a grid move); got {shown}'
    assert env.env.episode_step == 0
    with pytest.raises(SpecError, match=r'plays specs with grid actions, .*; this one has action \'hrl\''):
        _spec_env(_spec('camera', action='hrl'))
    with pytest.raises(SpecError, match='this one has memory'):
        _spec_env(_spec('camera', memory=25))
    with pytest.raises(ValueError, match="'rescale_observations' does not go with 'spec'"):
        _spec_env(_spec('camera'), rescale_observations=True)
    with pytest.raises(ValueError, match="team 'target' differs from the spec's team 'camera'"):
        _spec_env(_spec('camera'), team='target')
    with pytest.raises(ValueError, match="reward 'coverage' .* is a camera team reward; team is 'target'"):
        _spec_env(_spec('target'), reward='coverage')
    with pytest.raises(SpecError, match=r'trained with \(cameras, targets, obstacles\) = \(2, 4, 0\)'):
        _spec_env(_spec('camera'), config='MATE-4v8-9')
