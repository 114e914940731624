"""The upper-bound cameras (mate/teams/upper_bound.py, mate/agents/upper_bound.py): a centralised camera team that
sees the true state. It stays within the action box, covers clearly more than the greedy cameras (with and
without full observability), and its batched and single-env forms play the same games."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import mate
from mate.cli.main import main
from mate.evaluation.evaluate import play_episode
from mate.teams import GreedyTeam, UpperBoundTeam, make_team, play_batch
from mate.teams.upper_bound import lookahead_times
from mate.wrappers.enhanced_observation import empty_warehouses, enhance_observations

PRESET = 'MATE-4v8-9'
COUNTS = (4, 8, 9)


def test_importing_the_upper_bound_needs_no_torch():
    code = ("import sys, mate.teams.upper_bound, mate.agents.upper_bound; "
            "assert 'torch' not in sys.modules, 'torch was imported'")
    subprocess.run([sys.executable, '-c', code], check=True)


def _play_upper_bound(episodes: int, steps: int, seed: int = 0, **options):
    """`play_batch` of the batched upper bound (watching the vector env: play_batch calls its `watch`) against greedy
    targets."""
    return play_batch(PRESET, lambda b, counts: UpperBoundTeam(b, counts, **options),
                      lambda b, counts: GreedyTeam('target', b, counts, seed=seed), episodes, seed, steps)[0]


def _enhanced(vec, camera_obs, target_obs):
    """The cameras' fully observing observations (a copy) of a vector env's raw ones."""
    return enhance_observations(camera_obs.copy(), target_obs.copy(), vec.obstacle_states,
                                empty_warehouses(vec.remaining_cargoes), *COUNTS, target=False)[0]


# ---------------------------------------------------------------------------- what it achieves

def test_it_covers_clearly_more_than_the_greedy_cameras():
    """Seeds 0-7, 200 steps (measured 2026-11-26: upper bound 0.79-0.88 per episode, greedy 0.49-0.72; the smallest
    margin 0.11, the mean 0.26); with full observability greedy covers 0.66-0.77 on seeds 0-3 (margins 0.11-0.16)."""
    upper = np.array([episode.coverage_rate for episode in _play_upper_bound(8, 200)])
    greedy = np.array([episode.coverage_rate for episode in play_batch(
        PRESET, lambda b, counts: GreedyTeam('camera', b, counts, seed=0),
        lambda b, counts: GreedyTeam('target', b, counts, seed=0), 8, 0, 200)[0]])
    assert (upper > greedy + 0.05).all(), (upper, greedy)
    assert (upper - greedy).mean() > 0.2
    env = mate.make(f'{PRESET}-v0', wrappers=[lambda env: mate.EnhancedObservation(env, team='camera')])
    seeing = np.array([play_episode(env, mate.GreedyCameraAgent, mate.GreedyTargetAgent, seed, 200).coverage_rate
                       for seed in range(4)])
    assert (upper[:4] > seeing + 0.05).all(), (upper[:4], seeing)
    assert (upper[:4] - seeing).mean() > 0.1


def test_batched_and_single_env_forms_play_the_same_episodes():
    batch = _play_upper_bound(2, 150, seed=3)
    env = mate.make(f'{PRESET}-v0', wrappers=[lambda env: mate.EnhancedObservation(env, team='camera')])
    for batched in batch:
        single = play_episode(env, mate.UpperBoundCameraAgent, mate.GreedyTargetAgent, batched.seed, 150)
        assert (batched.coverage_rate, batched.camera_return, batched.episode_length) == \
            (single.coverage_rate, single.camera_return, single.episode_length)


# ---------------------------------------------------------------------------- step by step

def _vector_game(seeds, steps: int, restart: int | None = None):
    """Raw and fully observing camera observations of a vector env with random target moves and the batched
    upper bound (watching) playing the cameras; row 1 restarts at step `restart`. Yields (step, raw, enhanced,
    the actions played, the rows that restart now) before each step."""
    vec = mate.make_vec('MultiAgentTracking-v0', num_envs=len(seeds), config=PRESET, autoreset_mode='disabled')
    (camera_obs, target_obs), _ = vec.reset(seed=list(seeds))
    team = UpperBoundTeam(len(seeds), COUNTS)
    team.watch(vec)
    everyone = np.ones(len(seeds), dtype=bool)
    team.reset(camera_obs, everyone)
    rng = np.random.default_rng(0)
    restarting = np.zeros(len(seeds), dtype=bool)
    for step in range(steps):
        if step == restart:
            restarting = np.arange(len(seeds)) == 1
            (camera_obs, target_obs), _ = vec.reset(options={'reset_mask': restarting})
            team.reset(camera_obs, restarting)
        actions = team.act(camera_obs)
        yield step, camera_obs.copy(), _enhanced(vec, camera_obs, target_obs), actions, restarting
        restarting = np.zeros(len(seeds), dtype=bool)
        (camera_obs, target_obs), *_ = vec.step((actions, rng.uniform(-20.0, 20.0, (len(seeds), COUNTS[1], 2))))


def test_actions_stay_in_the_action_box_and_follow_the_aims():
    high = np.array([5.0, 2.5])                        # MATE-4v8-9: rotation step, zooming step
    moved = 0
    for _, _, _, actions, _ in _vector_game((0, 1, 2), 80):
        assert actions.shape == (3, 4, 2) and np.isfinite(actions).all()
        assert (np.abs(actions) <= high + 1e-12).all()
        moved += int((np.abs(actions) > 1e-9).any())
    assert moved > 40


def test_the_forms_agree_step_by_step_and_rows_reset_alone():
    """The watching team, a team given fully observing observations and the per-camera agents give the same
    actions on the same observations; row 1 restarting (the others go on) plays as a fresh team there."""
    seeing = UpperBoundTeam(2, COUNTS)
    fresh = None
    agents = [mate.UpperBoundCameraAgent().spawn(COUNTS[0]) for _ in range(2)]
    for step, raw, enhanced, actions, restarting in _vector_game((5, 6), 60, restart=30):
        if step == 0:
            seeing.reset(enhanced, np.ones(2, dtype=bool))
            mate.group_reset(agents[0], enhanced[0])
            mate.group_reset(agents[1], enhanced[1])
        if restarting.any():
            seeing.reset(enhanced, restarting)
            mate.group_reset(agents[1], enhanced[1])
            fresh = UpperBoundTeam(1, COUNTS)
            fresh.reset(enhanced[1:], np.ones(1, dtype=bool))
        np.testing.assert_array_equal(seeing.act(enhanced), actions)
        for b in range(2):
            np.testing.assert_array_equal(mate.group_act(agents[b], enhanced[b], [{}] * COUNTS[0]), actions[b])
        if fresh is not None:
            np.testing.assert_array_equal(fresh.act(enhanced[1:]), actions[1:])


def test_state_dict_round_trip_continues_the_same_game():
    first = second = None
    for step, _, enhanced, _, _ in _vector_game((7,), 40):
        if step == 0:
            first = UpperBoundTeam(1, COUNTS)
            first.reset(enhanced, np.ones(1, dtype=bool))
        if step == 20:
            state = first.state_dict()
            second = UpperBoundTeam(1, COUNTS)
            second.load_state_dict(state)
            saved = state['arrays']['aim'].copy()
        actions = first.act(enhanced)
        if second is not None:
            np.testing.assert_array_equal(second.act(enhanced), actions)
    np.testing.assert_array_equal(state['arrays']['aim'], saved)      # the state dict holds copies


def test_idle_rows_get_zeros():
    vec = mate.make_vec('MultiAgentTracking-v0', num_envs=2, config=PRESET, autoreset_mode='disabled')
    (camera_obs, _), _ = vec.reset(seed=0)
    team = UpperBoundTeam(2, COUNTS)
    team.watch(vec)
    team.reset(camera_obs, np.ones(2, dtype=bool))
    team.idle(np.array([False, True]))
    actions = team.act(camera_obs)
    assert (actions[1] == 0.0).all() and (actions[0] != 0.0).any()


# ---------------------------------------------------------------------------- what it refuses

def test_it_refuses_partial_observations():
    vec = mate.make_vec('MultiAgentTracking-v0', num_envs=1, config=PRESET)
    (camera_obs, _), _ = vec.reset(seed=0)
    team = UpperBoundTeam(1, COUNTS)
    team.reset(camera_obs, np.ones(1, dtype=bool))
    with pytest.raises(ValueError, match='sees the true state'):
        team.act(camera_obs)                          # raw observations, no vector env watched
    agent = mate.UpperBoundCameraAgent()
    with pytest.raises(ValueError, match="EnhancedObservation"):
        agent.reset(camera_obs[0, 0])
    with pytest.raises(ValueError, match='cannot watch'):
        UpperBoundTeam(2, COUNTS).watch(vec)


@pytest.mark.parametrize('make, message', [
    (lambda: make_team('upper-bound', 'target', 2, COUNTS), 'upper-bound is a camera team'),
    (lambda: make_team('upper-bound', 'camera', 2, COUNTS, memory_period=3), 'unknown option'),
    (lambda: UpperBoundTeam(2, COUNTS, horizon=0), 'horizon must be a positive integer'),
    (lambda: mate.UpperBoundCameraAgent(discount=1.5), r'discount must be a number in \(0, 1\]'),
    (lambda: UpperBoundTeam(1, (4, 64, 0)), 'at most 63 targets'),
])
def test_bad_options_are_explained(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_lookahead_times_cover_the_horizon():
    times, weights = lookahead_times(40, 1.0)
    assert times[0] == 1 and times[-1] == 40 and (np.diff(times) > 0).all()
    assert weights.sum() == pytest.approx(40.0)
    assert isinstance(make_team('upper-bound', 'camera', 2, COUNTS, horizon=8), UpperBoundTeam)


# ---------------------------------------------------------------------------- mate evaluate

def test_mate_evaluate_plays_it_batched_and_in_the_single_env_alike(tmp_path, capsys):
    common = ['evaluate', '--camera-agent', 'upper-bound', '--episodes', '2', '--max-episode-steps', '40',
              '--no-render']
    assert main([*common, '--json', str(tmp_path / 'batched.json')]) == 0
    assert 'batched' in capsys.readouterr().out
    assert main([*common, '--single-env', '--json', str(tmp_path / 'single.json')]) == 0
    out = capsys.readouterr().out       # the single env, with EnhancedObservation on the cameras added for it
    assert 'single env' in out and 'see the true state' in out
    batched, single = (json.loads((tmp_path / f'{name}.json').read_text())['episodes']
                       for name in ('batched', 'single'))
    assert [e['coverage_rate'] for e in batched] == [e['coverage_rate'] for e in single]
    assert main(['evaluate', '--target-agent', 'upper-bound', '--episodes', '1', '--no-render']) == 2
    assert "unknown target agent 'upper-bound'" in capsys.readouterr().err
