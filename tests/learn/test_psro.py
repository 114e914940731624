"""Population training (`mate psro`): the opponent mixture in the training env, the jobs, the loop end to
end, its resumption after a kill, the Ray runner and the plots."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch
import pytest

import mate
from mate.cli.main import main
from mate.policies.checkpoint import load_checkpoint
from mate.learn.envs import TeamEnvConfig, mixed_camera_reward
from mate.learn.mappo import MAPPOConfig, train
from mate.policies.policy import PolicyTeam, pretrained_path
from mate.learn.population.jobs import best_response, payoff_entries, policy_from_bytes, rescaled_schedules
from mate.learn.population.psro import (LocalRunner, PSROError, PSROSettings, RayRunner, TrainingWatch, load_state,
                                      run_psro)
from mate.cli.progress import logged_steps
from mate.learn.population.solvers import exploitability
from mate.policies.spec import discrete_to_continuous
from mate.teams import MixtureTeam, RandomTeam, play_batch

from conftest import needs_extra

from .test_batched_evaluation import COUNTS, _policy
from .toy import CueMatching

ENV = dict(env_id='MATE-2v4-0-v0', config=None)
TINY = ['--iterations', '2', '--br-steps', '200', '--num-envs', '4', '--eval-episodes', '3', '--eval-steps', '120']


class StillTargets:
    team = mate.Team.TARGET

    def __init__(self):
        self.resets = []

    def reset(self, observation, rows):
        self.resets.append(np.asarray(rows, dtype=bool).copy())

    def act(self, observation):
        return np.zeros(observation.shape[:-1] + (2,))


# ---------------------------------------------------------------- training env, mixtures, batches

def test_team_env_takes_an_opponent_and_the_mixed_camera_reward():
    """The camera reward 'mixed' is 0.5 coverage + 0.5 real coverage + 0.1 raw camera reward of the raw
    step, as a plain vector env playing the same actions against the same opponent reports them."""
    still = StillTargets()
    config = TeamEnvConfig(config='MATE-2v4-0', frame_skip=1, horizon=50, num_envs=3, seed=3)
    spec = config.policy_spec()
    env = config.make_env(spec, opponent=lambda b, counts, seed: still, camera_reward='mixed')
    vec = mate.make_vec('MATE-2v4-0-v0', num_envs=3, observation_dtype=np.float32, autoreset_mode='next_step',
                        max_episode_steps=50)
    env.reset()
    vec.reset(seed=3)
    assert len(still.resets) == 1 and still.resets[0].all()               # every row starts with an explicit mask
    rng = np.random.default_rng(0)
    for _ in range(30):
        actions = rng.integers(25, size=(3, 2))
        moves = discrete_to_continuous(actions, env.raw_observations, 'camera')
        reward = env.step(actions)[2]
        _, rewards, _, _, infos = vec.step((moves, np.zeros((3, 4, 2))))
        expected = mixed_camera_reward(infos['coverage_rate'], infos['real_coverage_rate'], rewards[0])
        np.testing.assert_allclose(reward, expected, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="camera_reward must be one of"):
        config.make_env(spec, camera_reward='delivery')
    target = TeamEnvConfig(team='target', num_envs=1)
    with pytest.raises(ValueError, match='camera team reward'):
        target.make_env(target.policy_spec(), camera_reward='mixed')


def test_mixture_members_decide_only_in_their_rows_and_assignments_are_fixed():
    members = [PolicyTeam(_policy('camera', seed=s), 'camera', 6, COUNTS, seed=s) for s in range(2)]
    mixture = MixtureTeam(members, assignment=[0, 1, 1, 0, 0, 1])
    vec = mate.make_vec('MATE-2v4-0-v0', num_envs=6)
    (camera_obs, _), _ = vec.reset(seed=0)
    mixture.reset(camera_obs, np.ones(6, dtype=bool))
    np.testing.assert_array_equal(mixture.choice, [0, 1, 1, 0, 0, 1])
    mixture.act(camera_obs)
    for k, member in enumerate(members):             # a member idles in the rows of the other one
        assert (member.countdown[mixture.choice != k] > 10 ** 9).all()
        assert (member.countdown[mixture.choice == k] == member.frame_skip - 1).all()
    with pytest.raises(ValueError, match=r'member indices in \[0, 1\]'):
        MixtureTeam(members, assignment=[0, 2])


def test_play_batch_takes_one_seed_per_row():
    def teams():
        return (lambda b, c: RandomTeam('camera', b, c, seed=0)), (lambda b, c: RandomTeam('target', b, c, seed=1))

    by_start, _ = play_batch('MATE-2v4-0', *teams(), episodes=3, seed=5, max_episode_steps=40)
    by_list, _ = play_batch('MATE-2v4-0', *teams(), episodes=3, seed=[5, 6, 7], max_episode_steps=40)
    assert by_list == by_start and [r.seed for r in by_list] == [5, 6, 7]
    with pytest.raises(ValueError, match='3 integers'):
        play_batch('MATE-2v4-0', *teams(), episodes=3, seed=[5, 6])


# ---------------------------------------------------------------- jobs

def test_train_keeps_the_best_actor(tmp_path):
    class Scored(CueMatching):       # episodes report their real return (the toy reports 0)
        def step(self, actions):
            result = super().step(actions)
            self.score = getattr(self, 'score', 0.0) + float(result[2].mean())
            for episode in result[5]['episodes']:
                episode['return'] = self.score
            if result[5]['episodes']:
                self.score = 0.0
            return result

    config = MAPPOConfig(actor='mlp', hidden=(8,), steps=16 * 8 * 30, num_envs=16, rollout_length=8, seed=0, threads=1,
                         run_dir=str(tmp_path), progress=False)
    train(config, envs=Scored(num_envs=16, length=2))
    rows = [row for row in map(str.split, (tmp_path / 'progress.csv').read_text().splitlines())]
    header = rows[0][0].split(',')
    table = [dict(zip(header, map(float, line[0].split(',')))) for line in rows[1:]]
    eligible = [row['episode_return'] for row in table if row['episodes'] == 25]
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['run']['best_return'] == pytest.approx(max(eligible))
    best = load_checkpoint(tmp_path / 'best.pt')
    assert ('critic' not in best and 'state' not in best
            and set(best['actor']) == set(saved['state']['networks']['actor']))


def test_rescaled_schedules_follow_the_spec():
    schedules = rescaled_schedules(1000)
    assert schedules['lr_schedule'] == ((0, 5e-4), (400, 1e-4), (800, 5e-5))
    assert schedules['entropy_schedule'] == ((0, 0.05), (200, 0.01), (400, 0.001), (1000, 0.0))


def test_best_response_job_returns_a_policy_of_its_team(tmp_path):
    target = Path(pretrained_path('mappo-target-2v4-0')).read_bytes()
    result = best_response('camera', ENV, ['random', target], [0.0, 1.0], steps=200, seed=0,
                           run_dir=str(tmp_path / 'br'), num_envs=4)
    policy = policy_from_bytes(result['policy'], 'camera')
    assert policy.spec.hrl and policy.spec.counts == (2, 4, 0) and result['chosen'] in ('best', 'final')
    assert result['steps'] >= 200 and not result['interrupted']
    config = load_checkpoint(tmp_path / 'br' / 'checkpoint.pt')['config']
    assert config['entropy_schedule'][0] == [0, 0.05]                     # the PSRO schedules
    with pytest.raises(ValueError, match='positive weight'):
        best_response('target', ENV, ['random'], [0.0], steps=100, seed=0, run_dir=str(tmp_path / 'none'))


@pytest.mark.slow
def test_target_best_response_can_be_rewarded_by_each_targets_own_part(tmp_path):
    """`--target-credit own`: the target best response trains with `credit='own'` (per-agent rewards, as the
    benchmark's target learners); the cameras' reward has no such option."""
    result = best_response('target', ENV, ['random'], [1.0], steps=100, seed=0, run_dir=str(tmp_path / 'own'),
                           num_envs=4, credit='own')
    assert policy_from_bytes(result['policy'], 'target').spec.team == 'target'
    assert load_checkpoint(tmp_path / 'own' / 'checkpoint.pt')['config']['credit'] == 'own'
    with pytest.raises(ValueError, match='exists for targets only'):          # MAPPOConfig's own check
        best_response('camera', ENV, ['random'], [1.0], steps=100, seed=0, run_dir=str(tmp_path / 'c'),
                      credit='own')
    settings = PSROSettings(iterations=1, br_steps=200, num_envs=4, eval_episodes=3, eval_steps=120,
                            target_credit='own')
    state = run_psro(settings, tmp_path / 'run', LocalRunner(1), say=lambda line: None)
    assert state['settings']['target_credit'] == 'own'
    for side, credit in (('target', 'own'), ('camera', 'team')):                # the loop hands it to the targets
        assert load_checkpoint(tmp_path / 'run' / 'players' / f'{side}-1' / 'checkpoint.pt')['config'][
            'credit'] == credit


def test_payoff_entries_are_reproducible_and_keep_their_order():
    pairs = [(1, 0), (0, 0)]
    first = payoff_entries(ENV, ['random', 'greedy'], ['random'], pairs, episodes=4, max_episode_steps=400)
    again = payoff_entries(ENV, ['random', 'greedy'], ['random'], pairs, episodes=4, max_episode_steps=400)
    assert [(e['k'], e['l']) for e in first] == pairs
    assert [e['payoff'] for e in first] == [e['payoff'] for e in again]
    for entry in first:
        assert entry['length'] == 400 and 0 <= entry['coverage'] <= 1 and -1 < entry['payoff'] < 1
    assert first[0]['coverage'] > first[1]['coverage']                    # greedy cameras cover more than random


# ---------------------------------------------------------------- the loop

def _state_checks(state: dict, iterations: int) -> None:
    m = iterations + 1
    assert [len(state['pools'][side]) for side in ('camera', 'target')] == [m, m]
    assert len(state['iterations']) == m and state['iterations'][0]['exploitability'] is None
    payoff = np.array(state['payoff'], dtype=float)
    assert payoff.shape == (m, m) and np.isfinite(payoff).all()
    for i, record in enumerate(state['iterations']):
        for side in ('camera', 'target'):
            strategy = np.array(record[f'{side}_strategy'])
            assert strategy.shape == (i + 1,) and strategy.min() >= 0 and strategy.sum() == pytest.approx(1.0)
        if i:   # Eq. 2 over the pools extended by iteration i's best responses, sigma of iteration i - 1
            previous = state['iterations'][i - 1]
            gains = exploitability(-payoff[:i + 1, :i + 1], previous['camera_strategy'], previous['target_strategy'])
            assert record['exploitability'] == pytest.approx(dict(camera=gains['row'], target=gains['column'],
                                                                  mean=gains['mean']))


@pytest.mark.slow
def test_psro_end_to_end_then_plots(tmp_path, capsys):
    out = tmp_path / 'run'
    assert main(['psro', '--solver', 'nash', *TINY, '--out', str(out)]) == 0      # two local worker processes
    state = load_state(out)
    _state_checks(state, 2)
    for side in ('camera', 'target'):
        for i in (1, 2):
            assert policy_from_bytes((out / f'players/{side}-{i}.pt').read_bytes(), side).spec.counts == (2, 4, 0)
    # the second best responses were warm-started from the first ones
    assert load_checkpoint(out / 'players/camera-2/checkpoint.pt')['config']['init_from'].endswith('init.pt')
    printed = capsys.readouterr().out
    assert ('on 2 local processes' in printed and 'iteration 2: exploitability' in printed
            and 'done: 2 iterations' in printed)

    assert main(['psro', '--solver', 'nash', *TINY, '--out', str(out)]) == 0      # done: nothing to redo
    assert load_state(out) == state
    assert main(['psro', '--solver', 'nash', *TINY[:2], '--br-steps', '300', *TINY[4:], '--out', str(out)]) == 2
    assert 'other settings (br_steps 200 there, 300 here)' in capsys.readouterr().err

    assert main(['psro', 'plot', str(out), '--out', str(tmp_path / 'plots')]) == 0
    for name in ('exploitability.png', 'meta-strategies-run.png'):
        image = tmp_path / 'plots' / name
        assert image.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and image.stat().st_size > 10_000


# Runs `mate psro ARGS` in-process (jobs in this process: --workers 1) with the target best response replaced by
# one that says it started (a file) and then waits: the test kills the run at exactly that stage.
STALLING_DRIVER = """
import sys, time
from pathlib import Path
from mate.cli.main import main
from mate.learn.population import jobs
started, train_best_response = Path(sys.argv[1]), jobs.best_response

def best_response(team, **kwargs):
    if team == 'target':
        started.write_text('the target best response started')
        time.sleep(3600)
    return train_best_response(team=team, **kwargs)

jobs.best_response = best_response
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.slow
def test_psro_resumes_after_a_kill(tmp_path):
    """Kill the process while the target best response of iteration 1 trains (the camera one is in the pool),
    start the same command again: the finished stages are kept, the run completes."""
    out, started = tmp_path / 'run', tmp_path / 'target-started'
    arguments = ['psro', '--workers', '1', '--iterations', '2', '--br-steps', '400', '--num-envs', '4',
                 '--eval-episodes', '3', '--eval-steps', '120', '--out', str(out)]
    env = dict(os.environ, MATE_COMPILE_NOTICE='0')
    process = subprocess.Popen([sys.executable, '-c', STALLING_DRIVER, str(started), *arguments],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    deadline = time.time() + 600
    try:
        while time.time() < deadline and process.poll() is None and not started.exists():
            time.sleep(0.05)
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait()
    assert started.exists() and process.returncode == -signal.SIGKILL, process.stderr.read().decode()[-2000:]
    before = load_state(out)
    assert len(before['iterations']) == 1 and len(before['pools']['target']) == 1   # killed mid-iteration 1
    assert before['pools']['camera'] == ['random', 'players/camera-1.pt']
    camera_policy = (out / 'players/camera-1.pt').read_bytes()

    resumed = subprocess.run([sys.executable, '-m', 'mate', *arguments], capture_output=True, text=True, env=env)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert 'resuming' in resumed.stdout and 'training the target best response' in resumed.stdout
    assert 'training the camera and target' not in resumed.stdout.split('iteration 2')[0]   # camera 1 not retrained
    after = load_state(out)
    _state_checks(after, 2)
    assert (out / 'players/camera-1.pt').read_bytes() == camera_policy
    assert after['payoff'][0][0] == before['payoff'][0][0]


@pytest.mark.slow
@pytest.mark.parametrize('signal_number', [signal.SIGINT, signal.SIGTERM])
def test_a_signal_stops_psro_at_an_iteration_of_a_best_response_and_the_run_resumes_exactly(tmp_path, signal_number):
    """SIGINT/SIGTERM while the camera best response trains: it finishes the iteration, writes its checkpoint
    (networks, optimiser, generators, envs with the opponent mixture), the target best response queued behind it
    does not start, and the command exits 130; the same command
    continues and ends with the state of a run never stopped (pools' policies, payoffs, strategies)."""
    arguments = ['psro', '--workers', '1', '--iterations', '1', '--br-steps', '2000', '--num-envs', '4',
                 '--eval-episodes', '2', '--eval-steps', '60', '--device', 'cpu']
    env = dict(os.environ, MATE_COMPILE_NOTICE='0')
    straight = tmp_path / 'straight'
    assert subprocess.run([sys.executable, '-m', 'mate', *arguments, '--out', str(straight)], env=env,
                          capture_output=True).returncode == 0
    stopped = tmp_path / 'stopped'
    process = subprocess.Popen([sys.executable, '-m', 'mate', *arguments, '--out', str(stopped)], env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    log = stopped / 'players' / 'camera-1' / 'progress.csv'
    deadline = time.time() + 600
    while time.time() < deadline and process.poll() is None and not (log.exists() and log.read_text().count('\n') >= 2):
        time.sleep(0.02)                     # the best response has logged an iteration: it is training
    process.send_signal(signal_number)
    out, err = process.communicate(timeout=600)
    assert process.returncode == 130, err[-2000:]
    assert 'Traceback' not in err and 'stopping after this iteration' in out + err
    saved = load_checkpoint(stopped / 'players' / 'camera-1' / 'checkpoint.pt')
    assert 0 < saved['run']['env_steps'] < 2000 and not (stopped / 'players' / 'camera-1.pt').exists()
    # the stage's other job (the target best response, queued behind it with --workers 1) never started
    assert not (stopped / 'players' / 'target-1').exists() and 'training return' not in out
    resumed = subprocess.run([sys.executable, '-m', 'mate', *arguments, '--out', str(stopped)], env=env,
                             capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    a, b = load_state(straight), load_state(stopped)
    for key in ('payoff', 'coverage', 'iterations'):
        a_value, b_value = a[key], b[key]
        if key == 'iterations':
            a_value, b_value = ([{k: v for k, v in r.items() if k != 'seconds'} for r in x] for x in (a_value, b_value))
        assert a_value == b_value, key
    for side in ('camera', 'target'):
        left, right = (load_checkpoint(run / 'players' / f'{side}-1.pt')['actor'] for run in (straight, stopped))
        assert all(torch.equal(left[name], right[name]) for name in left), side


@pytest.mark.slow
def test_psro_on_a_local_ray_instance(tmp_path):
    ray = needs_extra('ray')   # the rllib extra (CI installs it)

    runner = RayRunner(None, num_cpus=2)
    try:
        assert runner.parallel == 2 and ray.is_initialized()
        settings = PSROSettings(solver='uniform', iterations=1, br_steps=200, num_envs=4, eval_episodes=3,
                                eval_steps=120)
        state = run_psro(settings, tmp_path / 'run', runner, say=lambda line: None)
    finally:
        runner.close()
    _state_checks(state, 1)
    assert state['iterations'][1]['camera_strategy'] == [0.5, 0.5]       # FSP: uniform over the pool


def test_psro_settings_are_checked(tmp_path, capsys):
    with pytest.raises(PSROError, match='unknown solver'):
        PSROSettings(solver='minimax').validate()
    with pytest.raises(PSROError, match='br_steps must be an integer >= 1'):
        PSROSettings(br_steps=0).validate()
    with pytest.raises(PSROError, match='target_credit must be one of team, own'):
        PSROSettings(target_credit='difference').validate()
    assert PSROSettings(target_credit='own').same_experiment(PSROSettings()) == ['target_credit']  # no resume
    assert main(['psro', '--address', 'local', '--workers', '2', '--out', str(tmp_path / 'x')]) == 2
    assert '--workers is for local processes' in capsys.readouterr().err
    assert main(['psro', '--initial-cameras', 'heuristic', '--out', str(tmp_path / 'x')]) == 2
    assert '--initial-cameras must be random, greedy or pretrained:NAME' in capsys.readouterr().err
    assert main(['psro', '--config', 'MATE-9v9-9', '--out', str(tmp_path / 'x')]) == 2
    assert main(['psro', 'plot', str(tmp_path / 'nothing')]) == 2
    assert 'holds no population run' in capsys.readouterr().err
    (tmp_path / 'bad').mkdir()
    (tmp_path / 'bad' / 'state.json').write_text('{"format": "other"}')
    with pytest.raises(PSROError, match='not a PSRO state'):
        run_psro(PSROSettings(), tmp_path / 'bad', LocalRunner(1))


def test_exploitability_plot_of_one_iteration_has_integer_ticks(tmp_path, monkeypatch):
    from mate.learn.population import plots

    state = dict(settings=dict(solver='nash'), iterations=[
        dict(iteration=0, exploitability=None, camera_strategy=[1.0], target_strategy=[1.0]),
        dict(iteration=1, exploitability=dict(camera=0.1, target=0.2, mean=0.15), camera_strategy=[0.5, 0.5],
             target_strategy=[1.0, 0.0])])
    figures = []
    saved = plots.save_figure
    monkeypatch.setattr(plots, 'save_figure', lambda figure, path: (figures.append(figure), saved(figure, path))[1])
    plots.plot_exploitability([state], tmp_path / 'exploitability.png')
    ticks = [tick for ax in figures[0].axes for tick in ax.get_xticks() if ax.get_xlim()[0] <= tick <= ax.get_xlim()[1]]
    assert ticks and all(float(tick).is_integer() for tick in ticks), ticks


# ---------------------------------------------------------------- progress lines while best responses train

def _write_rows(run_dir: Path, steps: list[int], partial: str = '') -> None:
    run_dir.mkdir(parents=True, exist_ok=True)
    rows = ''.join(f'{k + 1},{n},{10 * n},0.5\n' for k, n in enumerate(steps))
    (run_dir / 'progress.csv').write_text('iteration,env_steps,raw_steps,wall_seconds\n' + rows + partial)


def test_logged_steps_reads_the_last_complete_row(tmp_path):
    run_dir = tmp_path / 'camera-1'
    assert logged_steps(run_dir) is None                       # no file yet
    _write_rows(run_dir, [])
    assert logged_steps(run_dir) is None                       # the header only
    _write_rows(run_dir, [1600, 3200], partial='3,48')          # a row being written is not read
    assert logged_steps(run_dir) == 3200
    _write_rows(run_dir, list(range(1600, 1600 * 2000, 1600)))  # a long log: read from its end
    assert logged_steps(run_dir) == 1600 * 1999


def test_training_watch_says_a_line_when_a_best_response_advanced(tmp_path):
    runs = {'camera': tmp_path / 'camera-3', 'target': tmp_path / 'target-3'}
    watch = TrainingWatch(3, runs, 10_000, say=print, every=3600)
    assert watch.line() is None                                 # nothing logged yet
    _write_rows(runs['camera'], [1600, 3200])
    assert watch.line() == 'iteration 3: training camera 3,200, target 0 of 10,000 decision steps each (16 %)'
    assert watch.line() is None                                 # no change, no line
    _write_rows(runs['target'], [1600])
    assert watch.line() == 'iteration 3: training camera 3,200, target 1,600 of 10,000 decision steps each (24 %)'
    alone = TrainingWatch(4, {'target': runs['target']}, 1_000, say=print, every=3600)
    assert alone.line() == 'iteration 4: training target 1,600 of 1,000 decision steps (100 %)'


def test_training_watch_speaks_from_its_thread_until_closed(tmp_path):
    lines = []
    run_dir = tmp_path / 'target-1'
    with TrainingWatch(1, {'target': run_dir}, 5_000, say=lines.append, every=0.01):
        _write_rows(run_dir, [1000])
        deadline = time.monotonic() + 30
        while not lines and time.monotonic() < deadline:
            time.sleep(0.01)
    assert lines == ['iteration 1: training target 1,000 of 5,000 decision steps (20 %)']
    _write_rows(run_dir, [1000, 2000])
    time.sleep(0.05)
    assert len(lines) == 1                                       # closed: silent
