"""Batched play of two teams (`mate.teams.play_batch`): batched policies (`mate.policies.policy.PolicyTeam`) act as
the deployment agents do."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import mate
from mate.constants import camera_observation_dim, target_observation_dim
from mate.evaluation.evaluate import play_episode
from mate.policies.memory import MEMORY_FEATURES
from mate.policies.policy import AGENT_CLASSES, LoadedPolicy, PolicyTeam, make_actor, make_team
from mate.policies.spec import PolicySpec
from mate.policies.velocity import VELOCITY_FEATURES
from mate.teams import GreedyCameraTeam, GreedyTeam, MixtureTeam, RandomTeam, play_batch

COUNTS = (2, 4, 0)          # MATE-2v4-0


def _policy(team: str, hrl=False, memory=0, velocity=False, lstm=0, frame_skip=3, seed=0, action=None,
            network='mlp', full_observability=False) -> LoadedPolicy:
    """An untrained (randomly initialised) policy of the given kind: varied, deterministic decisions."""
    nc, nt, no = COUNTS
    spec = PolicySpec.for_game(team, 'MATE-2v4-0-v0', frame_skip=frame_skip,
                               action=action or ('hrl' if hrl else 'grid'),
                               memory=memory, velocity=velocity, network=network, hidden=(32,), lstm=lstm,
                               full_observability=full_observability)
    raw_dim = camera_observation_dim(nc, nt, no) if team == 'camera' else target_observation_dim(nc, nt, no)
    assert spec.counts == COUNTS and spec.obs_dim == (raw_dim + MEMORY_FEATURES * nt * bool(memory)
                                                      + VELOCITY_FEATURES * nt * velocity)
    torch.manual_seed(seed)
    actor = make_actor(spec)
    with torch.no_grad():                         # sharper logits than the init's: decisions change with the input
        for parameter in actor.parameters():
            parameter.mul_(4.0)
    return LoadedPolicy(actor, spec, f'untrained-{team}')


class StillTargets:
    """A batched target team that stands still (and its Python agent twin below)."""
    team = mate.Team.TARGET

    def reset(self, observation, rows):
        pass

    def act(self, observation):
        return np.zeros(observation.shape[:-1] + (2,))


class StillTargetAgent(mate.TargetAgentBase):
    def act(self, observation, info=None, deterministic=None):
        return np.zeros(2)


VARIANTS = {
    'flat-cameras': dict(team='camera'),
    'hrl-cameras': dict(team='camera', hrl=True, frame_skip=5),
    'memory-velocity-cameras': dict(team='camera', memory=10, velocity=True),
    'recurrent-cameras': dict(team='camera', lstm=8),
    'flat-targets': dict(team='target', frame_skip=4),
    'recurrent-targets': dict(team='target', lstm=8),
    'per-target-hrl-cameras': dict(team='camera', hrl=True, network='per-target', memory=10, frame_skip=4),
    'joint-hrl-cameras': dict(team='camera', action='hrl-joint', frame_skip=5),
    'q-value-cameras': dict(team='camera', network='dueling'),
    'recurrent-q-targets': dict(team='target', network='recurrent-q', lstm=0),
    'continuous-targets': dict(team='target', action='continuous', network='independent'),
    'tarmac-targets': dict(team='target', network='tarmac', lstm=8),
    'i2c-targets': dict(team='target', network='i2c', lstm=8),
}


@pytest.mark.parametrize('variant', sorted(VARIANTS))
def test_batched_policy_acts_as_the_deployment_agents(variant):
    """Rows of the vector env and single envs with the same seeds, fed the same actions: every row's
    deployment agents (driven by group_step, messages included) choose exactly the batched team's actions,
    through episode ends (a short step limit makes rows restart)."""
    kwargs = VARIANTS[variant]
    team = mate.Team[kwargs['team'].upper()]
    policy = _policy(**kwargs)
    rows, steps, limit = 3, 70, 25
    # Choices from a grid or a selection are exact; continuous actions are float32 network outputs, and a forward
    # pass of 3 rows and of 1 row may run other GEMM kernels (another CPU family: 3e-7 apart): float32's tolerance.
    tolerance = 1e-5 if kwargs.get('action') == 'continuous' else 1e-12
    vec = mate.make_vec('MATE-2v4-0-v0', num_envs=rows, max_episode_steps=limit, autoreset_mode='same_step')
    envs = [mate.make('MATE-2v4-0-v0', max_episode_steps=limit) for _ in range(rows)]
    batched = PolicyTeam(policy, team, rows, COUNTS, deterministic=True)
    opponent = RandomTeam(mate.Team(1 - team), rows, COUNTS, seed=5, frame_skip=3)
    observations, _ = vec.reset(seed=10)
    everyone = np.ones(rows, dtype=bool)
    batched.reset(observations[team], everyone)
    opponent.reset(observations[1 - team], everyone)
    agents, infos = [], [None] * rows
    for i, env in enumerate(envs):
        single, _ = env.reset(seed=10 + i)
        np.testing.assert_array_equal(single[team], observations[team][i])
        agents.append(AGENT_CLASSES[team](policy, seed=0, deterministic=True).spawn(len(single[team])))
        mate.group_reset(agents[i], single[team])
    single_obs = [observations[team][i].copy() for i in range(rows)]
    for step in range(steps):
        own = batched.act(observations[team])
        other = opponent.act(observations[1 - team])
        for i, env in enumerate(envs):
            expected = np.asarray(mate.group_step(env, agents[i], single_obs[i], infos[i]))
            np.testing.assert_allclose(own[i], expected, rtol=tolerance, atol=tolerance, err_msg=f'row {i}, step {step}')
            joint = (own[i], other[i]) if team is mate.Team.CAMERA else (other[i], own[i])
            result, _, terminated, truncated, all_infos = env.step(joint)
            single_obs[i], infos[i] = result[team], all_infos[team]
            if terminated or truncated:
                result, _ = env.reset()
                single_obs[i], infos[i] = result[team], None
                mate.group_reset(agents[i], single_obs[i])
        actions = (own, other) if team is mate.Team.CAMERA else (other, own)
        observations, _, terminated, truncated, _ = vec.step(actions)
        ended = terminated | truncated
        if ended.any():
            batched.reset(observations[team], ended)
            opponent.reset(observations[1 - team], ended)
        for i in range(rows):
            np.testing.assert_array_equal(single_obs[i], observations[team][i])


@pytest.mark.parametrize('opponent', ['still', 'greedy'])
def test_play_batch_rows_equal_single_env_episodes(opponent):
    """Deterministic batched HRL cameras against still targets, or against the batched greedy targets seeded like
    the env (row i plays as `GreedyTargetAgent(seed=4 + i)`, the agents `play_episode` builds for seed 4 + i):
    every row's summary equals `mate.evaluation.evaluate.play_episode` of the deployment agents with the row's seed."""
    policy = _policy('camera', hrl=True, frame_skip=5)
    targets = StillTargets() if opponent == 'still' else GreedyTeam('target', 3, COUNTS, seed=4)
    results, timing = play_batch('MATE-2v4-0', PolicyTeam(policy, 'camera', 3, COUNTS, deterministic=True),
                                 targets, episodes=3, seed=4, max_episode_steps=60)
    assert timing['env_steps'] == 180 and timing['env_steps_per_second'] > 0
    env = mate.make('MATE-2v4-0-v0')
    target_factory = (lambda seed: StillTargetAgent(seed=seed)) if opponent == 'still' else mate.GreedyTargetAgent
    for i, result in enumerate(results):
        single = play_episode(env, lambda seed: AGENT_CLASSES[mate.Team.CAMERA](policy, seed=seed, deterministic=True),
                              target_factory, seed=4 + i, max_steps=60)
        assert result.seed == single.seed == 4 + i
        for field in ('coverage_rate', 'real_coverage_rate', 'transport_rate', 'camera_return', 'target_return',
                      'normalized_target_return', 'delivered_cargoes', 'episode_length'):
            assert getattr(result, field) == pytest.approx(getattr(single, field), abs=1e-12), field


def test_full_observability_policies_play_batched_as_in_the_enhanced_single_env():
    """A policy trained with --full-observability (every entity in its observations) is played batched with its
    observations filled in (`play_batch`) and plays exactly as its deployment agents in a single env under
    `EnhancedObservation` for its team: the held-out evaluation of such a run sees what its training saw."""
    from mate.wrappers import EnhancedObservation

    policy = _policy('target', frame_skip=3, full_observability=True)
    results, _ = play_batch('MATE-2v4-0', GreedyTeam('camera', 2, COUNTS, seed=7),
                            PolicyTeam(policy, 'target', 2, COUNTS, deterministic=True),
                            episodes=2, seed=7, max_episode_steps=60)
    partial = LoadedPolicy(policy.actor, policy.spec.replace(full_observability=False), 'partial')
    raw, _ = play_batch('MATE-2v4-0', GreedyTeam('camera', 2, COUNTS, seed=7),
                        PolicyTeam(partial, 'target', 2, COUNTS, deterministic=True),
                        episodes=2, seed=7, max_episode_steps=60)
    assert [r.target_return for r in raw] != [r.target_return for r in results]     # what it sees matters
    env = EnhancedObservation(mate.make('MATE-2v4-0-v0'), team='target')
    for i, result in enumerate(results):
        single = play_episode(env, mate.GreedyCameraAgent,
                              lambda seed: AGENT_CLASSES[mate.Team.TARGET](policy, seed=seed, deterministic=True),
                              seed=7 + i, max_steps=60)
        for field in ('coverage_rate', 'target_return', 'delivered_cargoes', 'episode_length'):
            assert getattr(result, field) == pytest.approx(getattr(single, field), abs=1e-12), field


def test_play_batch_plays_each_row_to_its_own_end():
    results, timing = play_batch('MATE-2v4-0', lambda b, c: RandomTeam('camera', b, c, seed=0),
                                 lambda b, c: make_team('greedy', 'target', b, c, seed=1),
                                 episodes=4, seed=0, max_episode_steps=300)
    lengths = [r.episode_length for r in results]
    assert all(1 <= n <= 300 for n in lengths) and timing['env_steps'] == sum(lengths)
    for r in results:
        assert 0.0 <= r.coverage_rate <= 1.0 and 0.0 <= r.real_coverage_rate <= 1.0
        assert r.camera_return == pytest.approx(-r.target_return)
        assert r.normalized_target_return == pytest.approx(r.target_return / 6400.0)
    again, _ = play_batch('MATE-2v4-0', lambda b, c: RandomTeam('camera', b, c, seed=0),
                          lambda b, c: make_team('greedy', 'target', b, c, seed=1),
                          episodes=4, seed=0, max_episode_steps=300)
    assert again == results                                            # same seeds, same episodes


def test_random_team_holds_uniform_actions_within_each_agents_box():
    vec = mate.make_vec('MATE-4v8-9-v0', num_envs=64)
    (camera_obs, target_obs), _ = vec.reset(seed=0)
    team = RandomTeam('camera', 64, (4, 8, 9), seed=0, frame_skip=20)
    team.reset(camera_obs, np.ones(64, dtype=bool))
    first = team.act(camera_obs)
    high = camera_obs[..., mate.constants.PRESERVED_DIM + 7:mate.constants.PRESERVED_DIM + 9]
    assert np.all(np.abs(first) <= high) and np.abs(first / high).max() > 0.95
    assert all(np.array_equal(team.act(camera_obs), first) for _ in range(19))
    assert not np.array_equal(team.act(camera_obs), first)             # redrawn at step 20


def test_mixture_team_plays_one_member_per_row_and_episode():
    class Constant:
        team = mate.Team.TARGET

        def __init__(self, value):
            self.value = value

        def reset(self, observation, rows):
            pass

        def act(self, observation):
            return np.full(observation.shape[:-1] + (2,), self.value)

    mixture = MixtureTeam([Constant(1.0), Constant(2.0), Constant(3.0)], weights=[1, 0, 3], seed=0)
    observation = np.zeros((400, 4, target_observation_dim(*COUNTS)))
    mixture.reset(observation, np.ones(400, dtype=bool))
    actions = mixture.act(observation)
    assert set(np.unique(actions)) == {1.0, 3.0}                        # the zero-weight member never plays
    assert np.all(actions == actions[:, :1, :1])                        # one member per row, all its agents
    assert 0.65 < np.mean(actions[:, 0, 0] == 3.0) < 0.85               # drawn with weights 1 : 3
    kept = mixture.act(observation)
    np.testing.assert_array_equal(kept, actions)                        # kept for the episode
    with pytest.raises(ValueError, match='weights'):
        MixtureTeam([Constant(1.0)], weights=[-1])
    with pytest.raises(ValueError, match='same team'):
        MixtureTeam([Constant(1.0), RandomTeam('camera', 2, COUNTS)])


def test_make_team_names_the_batched_agents():
    assert isinstance(make_team('greedy', 'camera', 2, (4, 8, 9)), GreedyCameraTeam)
    assert make_team('greedy', 'camera', 2, (4, 8, 9), memory_period=10).team is mate.Team.CAMERA  # the agents' options
    with pytest.raises(ValueError, match='unknown option.*deterministic for the greedy cameras'):
        make_team('greedy', 'camera', 2, (4, 8, 9), deterministic=False)
    with pytest.raises(ValueError, match='unknown option.*deterministic for the random agents'):
        make_team('random', 'camera', 2, (4, 8, 9), deterministic=False)
    with pytest.raises(ValueError, match='heuristic.*no batched version.*random, greedy'):
        make_team('heuristic', 'camera', 2, (4, 8, 9))
    with pytest.raises(ValueError, match=r'trained with \(cameras, targets, obstacles\) = \(4, 8, 9\)'):
        make_team('pretrained:hrl-mappo-camera-4v8-9', 'camera', 2, COUNTS)
    assert isinstance(make_team('pretrained:hrl-mappo-camera-4v8-9', 'camera', 2, (4, 8, 9)), PolicyTeam)


def test_make_team_reads_a_checkpoint_path_as_load_agent_does(tmp_path, monkeypatch):
    import shutil

    from mate.policies.policy import load_agent, pretrained_path
    shutil.copy(pretrained_path('mappo-target-2v4-0'), tmp_path / 'targets.pt')
    monkeypatch.setenv('HOME', str(tmp_path))
    team = make_team('checkpoint:~/targets.pt', 'target', 2, COUNTS, frame_skip=4, deterministic=False)
    assert isinstance(team, PolicyTeam) and team.frame_skip == 4 and not team.deterministic
    assert load_agent('checkpoint:~/targets.pt', 'target')(seed=0).policy.spec == team.spec


def test_mate_evaluate_batched(tmp_path, capsys):
    from mate.cli import main as cli
    out = tmp_path / 'batched.json'
    assert cli.main(['evaluate', '--batched', '--camera-agent', 'pretrained:hrl-mappo-camera-4v8-9', '--episodes', '3',
                     '--max-episode-steps', '40', '--no-render', '--json', str(out)]) == 0
    import json
    data = json.loads(out.read_text())
    assert [e['seed'] for e in data['episodes']] == [0, 1, 2]
    assert all(e['episode_length'] == 40 for e in data['episodes'])
    assert 'games at once' in capsys.readouterr().out.replace('\n', ' ')
    assert cli.main(['evaluate', '--batched', '--target-agent', 'naive', '--episodes', '2']) == 2
    assert 'no batched form of naive' in capsys.readouterr().err
    assert cli.main(['evaluate', '--batched', '--shared-field-of-view', '--episodes', '2']) == 2
    assert 'drop --shared-field-of-view' in capsys.readouterr().err
