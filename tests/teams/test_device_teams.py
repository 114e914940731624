"""The rule teams and the HRL executor on a CUDA device (`mate.teams.device`), and the device vector env.

Without a GPU: every team kernel compiles to PTX; under numba's CUDA simulator the device env (`make_vec(...,
device='cuda')`) plays the CPU vector env's games (NEXT_STEP and SAME_STEP autoreset) exactly, with the caller's
actions or with device teams against their host twins (the same row functions in a compiled loop), and the HRL
kernel gives `executor_actions`. On the host: the counter streams and the stacks they fill. How the device teams'
play compares with the CPU teams' over 300 seeds is measured by benchmarks/device_teams.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import needs_extra, run_simulated
from mate.teams import device
from mate.teams.streams import AGENT_BLOCK

KINDS = ['greedy-camera', 'greedy-target', 'random-camera']


@pytest.mark.slow
@pytest.mark.parametrize('which', ['reset', 'act'])
@pytest.mark.parametrize('kind', KINDS)
def test_every_team_kernel_compiles_for_a_gpu(kind, which):
    needs_extra('numba_cuda')
    ptx = device.compile_ptx(kind, which, cc=(8, 0))
    assert '.target sm_80' in ptx and '.entry' in ptx


def test_the_hrl_executor_compiles_for_a_gpu():
    needs_extra('numba_cuda')
    ptx = device.compile_hrl_ptx(observation_dtype=np.float32, cc=(8, 0))
    assert '.target sm_80' in ptx and '.entry' in ptx


SIMULATED = """
import json, sys
import numpy as np
import mate
from mate.envs.vector_contract import FINAL_WORLD_KEYS, INFO_KEYS
from mate.policies.hrl import executor_actions
from mate.spaces import observation_indices_of
from mate.messages import Team
from mate.teams.device import DeviceRuleTeam, device_team, host_act, host_reset, hrl_actions
from numba import cuda
import torch

report = {}
B, T = 5, 30
for preset in sys.argv[1:]:
    for mode, agents in (('same_step', (None, None)), ('same_step', ('greedy', 'greedy')),
                         ('next_step', (None, None)), ('next_step', ('greedy', 'greedy')),
                         ('next_step', ('random', 'greedy')), ('next_step', ('greedy', 'random'))):
        dev = mate.make_vec('MultiAgentTracking-v0', B, config=preset, device='cuda', max_episode_steps=12, block=4,
                            autoreset_mode=mode)
        cpu = mate.make_vec('MultiAgentTracking-v0', B, config=preset, autoreset_mode=mode, max_episode_steps=12)
        counts = (cpu.num_cameras, cpu.num_targets, cpu.num_obstacles)
        (dc, dt), _ = dev.reset(seed=7)
        (cc, ct), _ = cpu.reset(seed=7)
        teams = [None if a is None else device_team(a, side, B, counts, seed=7)          # host twins on the CPU
                 for a, side in zip(agents, ('camera', 'target'))]
        played = [None if a is None else DeviceRuleTeam(a, side, B, counts, seed=7, block=4)   # the device's
                  for a, side in zip(agents, ('camera', 'target'))]
        for team, obs in zip(teams, (cc, ct)):
            if team is not None:
                host_reset(team, obs, np.ones(B, bool))
        for team, obs in zip(played, (dc, dt)):
            if team is not None:
                team.reset(obs, torch.ones(B, dtype=torch.bool))
        rng = np.random.default_rng(0)
        differing, ends, pending = [], 0, np.zeros(B, bool)
        for step in range(T):
            ca, ta = rng.uniform(-30, 30, (B, counts[0], 2)), rng.uniform(-3, 3, (B, counts[1], 2))
            ca = ca if teams[0] is None else host_act(teams[0], cc).copy()
            ta = ta if teams[1] is None else host_act(teams[1], ct).copy()
            own = tuple(a if team is None else team.act(obs) for a, team, obs in zip((ca, ta), played, (dc, dt)))
            (dc, dt), (dcr, dtr), dterm, dtrunc, dinfo = dev.step(own)
            (cc, ct), (ccr, ctr), cterm, ctrunc, cinfo = cpu.step((ca, ta))
            done = cterm | ctrunc
            ends += int(done.sum())
            restarted = pending if mode == 'next_step' else done
            for team, obs in zip(teams, (cc, ct)):
                if team is not None:
                    host_reset(team, obs, restarted)
            for team, obs in zip(played, (dc, dt)):
                if team is not None:
                    team.reset(obs, torch.from_numpy(restarted))
            pending = done
            pairs = dict(camera_obs=(dc, cc), target_obs=(dt, ct), camera_reward=(dcr, ccr),
                         target_reward=(dtr, ctr), terminated=(dterm, cterm), truncated=(dtrunc, ctrunc),
                         state=(dev.state(), cpu.state()))
            if sorted(dinfo) != sorted(cinfo):
                differing.append(f'{step}: info keys {sorted(dinfo)} {sorted(cinfo)}')
            for key in INFO_KEYS:                       # the CPU env's infos, every key, and its masks
                pairs[key], pairs[f'_{key}'] = (dinfo[key], cinfo[key]), (dinfo[f'_{key}'], cinfo[f'_{key}'])
            if 'final_info' in cinfo and 'final_info' in dinfo:     # same_step: the ended step's, where it ended
                pairs['_final_info'] = (dinfo['_final_info'], cinfo['_final_info'])
                pairs['_final_obs'] = (dinfo['_final_obs'], cinfo['_final_obs'])
                for key in (*INFO_KEYS, *FINAL_WORLD_KEYS):
                    pairs[f'final {key}'] = (np.asarray(dinfo['final_info'][key])[done], cinfo['final_info'][key][done])
                for i in np.flatnonzero(done):
                    for team in (0, 1):
                        pairs[f'final_obs {i} {team}'] = (dinfo['final_obs'][team][i], cinfo['final_obs'][i][team])
            for name, (a, b) in pairs.items():
                if not np.array_equal(np.asarray(a), b):
                    differing.append(f'{step}: {name}')
        report[f'{preset} {mode} {agents}'] = dict(differing=differing[:5], ends=ends)

dev = mate.make_vec('MultiAgentTracking-v0', 3, config='MATE-2v4-0', device='cuda', block=2)
cpu = mate.make_vec('MultiAgentTracking-v0', 3, config='MATE-2v4-0')
differing = []
for seed in (7, None, None):                      # an unseeded reset goes on with every game's stream
    (dc, dt), _ = dev.reset(seed=seed)
    (cc, ct), _ = cpu.reset(seed=seed)
    for _ in range(3):
        actions = (np.full((3, 2, 2), 5.0), np.full((3, 4, 2), 1.0))
        (dc, dt), *_ = dev.step(actions)
        (cc, ct), *_ = cpu.step(actions)
    differing += [] if np.array_equal(np.asarray(dc), cc) and np.array_equal(np.asarray(dt), ct) else [f'{seed}']
report['unseeded resets'] = dict(differing=differing)

differing = []                                    # seed lists and reset masks, as on the CPU
for kwargs in (dict(seed=[4, None, 6]), dict(seed=2, options={'reset_mask': np.array([True, False, True])}),
               dict(options={'reset_mask': np.array([False, True, False])})):
    (dc, dt), dinfo = dev.reset(**kwargs)
    (cc, ct), cinfo = cpu.reset(**kwargs)
    for _ in range(3):
        actions = (np.full((3, 2, 2), -4.0), np.full((3, 4, 2), 2.0))
        (dc, dt), *_, dinfo = dev.step(actions)
        (cc, ct), *_, cinfo = cpu.step(actions)
        same = [np.array_equal(np.asarray(dinfo[key]), cinfo[key]) for key in INFO_KEYS]
        differing += [] if np.array_equal(np.asarray(dc), cc) and np.array_equal(np.asarray(dt), ct) and all(same) \
            else [str(kwargs)]
messages = []                                     # bad input: the CPU env's refusals, word for word
for actions in ((np.zeros((3, 2, 2)), np.full((3, 4, 2), np.nan)), (np.zeros((2, 2, 2)), np.zeros((3, 4, 2))),
                (np.zeros((3, 4)), [[1, 2], [3]]), np.zeros(3), (np.zeros((3, 2, 2)), 'left')):
    found = []
    for env in (dev, cpu):
        try:
            env.step(actions)
            found.append('accepted')
        except ValueError as exc:
            found.append(str(exc))
    differing += [] if found[0] == found[1] and found[0] != 'accepted' else [f'refusal {found}']
    messages.append(found[0])
for call in (lambda: dev.reset(options={'reset_mask': np.ones(2, bool)}), lambda: dev.reset(seed=[1, 2]),
             lambda: mate.make_vec('MultiAgentTracking-v0', 2, device='cuda', autoreset_mode='disabled'),
             lambda: mate.make_vec('MultiAgentTracking-v0', 2, device='cuda', target_agent='greedy'),
             lambda: mate.make_vec('MultiAgentTracking-v0', 2, device='cuda').step(
                 (np.zeros((2, 4, 2)), np.zeros((2, 8, 2))))):
    try:
        call()
        messages.append('accepted')
    except (ValueError, RuntimeError, TypeError) as exc:
        messages.append(str(exc))
report['resets and refusals'] = dict(differing=differing, messages=messages)


def user_loop(envs, steps=40):                  # a researcher's loop, written once: nothing in it knows the device
    (camera_obs, target_obs), infos = envs.reset(seed=3)
    trace, finished = [sorted(infos)], []
    for _ in range(steps):
        (camera_obs, target_obs), (camera_rewards, _), terminated, truncated, infos = envs.step(envs.sample_actions())
        ended = terminated | truncated
        trace.append([camera_obs.tolist(), target_obs.tolist(), camera_rewards.tolist(), ended.tolist(),
                      infos['coverage_rate'].tolist(), infos['episode_step'].tolist(), sorted(infos)])
        if 'final_info' in infos:
            finished.append(infos['final_info']['episode_coverage_rate'][infos['_final_info']].tolist())
    envs.close()
    return trace, finished


for mode in ('next_step', 'same_step'):
    runs = {where: user_loop(mate.make_vec('MultiAgentTracking-v0', 4, config='MATE-4v8-9', device=where,
                                           autoreset_mode=mode, max_episode_steps=15))
            for where in ('cpu', 'cuda')}
    report[f'user loop {mode}'] = dict(differing=[] if runs['cpu'] == runs['cuda'] else ['the loop'],
                                       ends=sum(sum(row[3]) for row in runs['cpu'][0][1:]),
                                       finished=len(runs['cpu'][1]))

from mate.teams.device import HostTeam
for preset, team, reward, mode in (('MATE-4v8-9', 'camera', 'coverage', 'next_step'),
                                   ('MATE-4v8-9', 'camera', 'difference', 'same_step'),
                                   ('MATE-2v4-0', 'target', 'own', 'next_step'),
                                   ('MATE-2v4-0', 'target', 'team', 'same_step')):
    other = 'target' if team == 'camera' else 'camera'
    dev = mate.make_team_vec(preset, team, 4, device='cuda', reward=reward, autoreset_mode=mode, max_episode_steps=10,
                             block=2)
    cpu = mate.make_team_vec(preset, team, 4, reward=reward, autoreset_mode=mode, max_episode_steps=10,
                             opponent=lambda n, c, seed: HostTeam('greedy', other, n, c, seed=seed))
    do, _ = dev.reset(seed=5)
    co, _ = cpu.reset(seed=5)
    rng = np.random.default_rng(2)
    differing, ends = [], 0
    for step in range(25):
        actions = rng.uniform(-5, 5, (4, cpu.num_agents, 2))
        do, dr, dterm, dtrunc, dinfo = dev.step(torch.from_numpy(actions))
        co, cr, cterm, ctrunc, cinfo = cpu.step(actions)
        pairs = dict(obs=(do, co), reward=(dr, cr), terminated=(dterm, cterm), truncated=(dtrunc, ctrunc))
        if sorted(dinfo) != sorted(cinfo):               # the CPU single-team env's keys, on the same steps
            differing.append(f'{step}: info keys {sorted(dinfo)} {sorted(cinfo)}')
        pairs.update({key: (dinfo[key], cinfo[key]) for key in INFO_KEYS})
        if '_mate_episode' in cinfo and '_mate_episode' in dinfo:
            pairs['ended'] = (dinfo['_mate_episode'], cinfo['_mate_episode'])
        if 'final_info' in cinfo and 'final_info' in dinfo:
            done = cinfo['_final_info']
            pairs['_final_obs'] = (dinfo['_final_obs'], cinfo['_final_obs'])
            pairs.update({f'final {key}': (np.asarray(dinfo['final_info'][key])[done], cinfo['final_info'][key][done])
                          for key in (*INFO_KEYS, *FINAL_WORLD_KEYS)})
            pairs.update({f'final_obs {i}': (dinfo['final_obs'][i], cinfo['final_obs'][i])
                          for i in np.flatnonzero(done)})
        for name, (a, b) in pairs.items():
            if not np.array_equal(np.asarray(a), b):
                differing.append(f'{step}: {name}')
        if '_mate_episode' in cinfo:
            ends += int(cinfo['_mate_episode'].sum())
            for key, value in cinfo['mate_episode'].items():
                if not np.allclose(np.asarray(dinfo['mate_episode'][key]), value, rtol=0, atol=1e-12):
                    differing.append(f'{step}: episode {key}')
    report[f'single {team} {reward} {mode}'] = dict(differing=differing[:5], ends=ends)

for mode, opponent, options in (('next_step', 'random', {'frame_skip': 4}), ('same_step', 'greedy', {})):
    make = lambda: mate.make_team_vec('MATE-4v8-9', 'camera', 3, device='cuda', reward='difference', block=2,
                                      autoreset_mode=mode, max_episode_steps=6, opponent=opponent,
                                      opponent_options=options)
    first = make()
    first.reset(seed=9)
    actions = torch.from_numpy(np.random.default_rng(3).uniform(-5, 5, (20, 3, 4, 2)))
    for step in range(9):
        first.step(actions[step])
    saved = first.state_dict()
    expected, ends = [], 0
    for step in range(9, 20):
        o, r, te, tr, info = first.step_games(actions[step])
        expected.append([x.clone() for x in (o, r, te, tr, info['mate_episode']['r'], first.state())])
        ends += int((te | tr).sum())
    resumed = make()
    resumed.reset(seed=1)
    resumed.load_state_dict(saved)
    differing = []
    for step in range(9, 20):
        o, r, te, tr, info = resumed.step_games(actions[step])
        if not all(torch.equal(x, y) for x, y in zip(expected[step - 9], (o, r, te, tr, info['mate_episode']['r'],
                                                                           resumed.state()))):
            differing.append(f'{step}: resumed')
    report[f'resume {mode} {opponent}'] = dict(differing=differing[:5], ends=ends)

nc, nt, no = 4, 8, 9
vec = mate.make_vec('MultiAgentTracking-v0', 6, config='MATE-4v8-9')
(camera_obs, _), _ = vec.reset(seed=0)
for _ in range(5):
    (camera_obs, _), *_ = vec.step(vec.action_space.sample())
observation = camera_obs.reshape(-1, camera_obs.shape[-1])
keep = np.random.default_rng(1).random((observation.shape[0], nt)) < 0.7
begin = int(observation_indices_of(Team.CAMERA, nc, nt, no)[2])
out = cuda.to_device(np.zeros((observation.shape[0], 2)))
hrl_actions(cuda.to_device(observation), cuda.to_device(keep), begin, out, block=8)
report['hrl'] = dict(equal=bool(np.array_equal(out.copy_to_host(), executor_actions(observation, keep, nc, nt, no))),
                     aimed=int((keep & (observation[:, begin + 4:begin + 5 * nt:5] > 0.5)).any(1).sum()))
print(json.dumps(report))
"""


@pytest.mark.slow
def test_the_simulated_device_env_and_teams_play_the_cpu_games_exactly():
    """Under numba's CUDA simulator (its own process: the switch is read when numba.cuda loads)."""
    needs_extra('numba_cuda')
    needs_extra('torch')
    presets = ['MATE-2v4-0', 'MATE-4v8-9']
    done = run_simulated(SIMULATED, *presets, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    hrl = report.pop('hrl')
    assert hrl['equal'] and hrl['aimed'] > 0, hrl
    assert len(report) == 2 * 6 + 2 + 2 + 4 + 2
    messages = report['resets and refusals']['messages']
    assert 'target actions contain NaN or inf (envs [0, 1, 2])' in messages[0]
    assert 'camera actions must have shape (3, 2, 2)' in messages[1] and 'ragged' in messages[2]
    assert 'actions must be a pair' in messages[3] and 'not numeric' in messages[4]
    assert "reset_mask'] must be a bool array of shape (3,)" in messages[5] and 'got 2 seeds' in messages[6]
    assert "'next_step' or 'same_step'" in messages[7] and 'plays no team inside' in messages[8]
    assert 'call reset() before step()' in messages[9]
    assert report['user loop same_step']['finished'] >= 2, report['user loop same_step']   # final_info seen
    for pairing, found in report.items():
        assert found['differing'] == [], (pairing, found['differing'])
        if 'ends' in found:                         # every game restarted at least once (short episodes)
            assert found['ends'] >= 5, pairing


def test_top_up_puts_a_block_under_the_numbers_held():
    B, N, block = 2, 3, 4
    rng = device.stream_keys([5, 6], N, 0)
    stack, left = np.zeros((B, N, 2 * block)), np.zeros((B, N), np.int64)
    stack[0, 1, :2] = [0.25, 0.75]
    left[0, 1] = 2
    left[0, 2] = 3
    device.top_up_row(0, rng, stack, left, block, 3)
    assert left.tolist() == [[4, 6, 3], [0, 0, 0]]            # (0, 2) held enough; row 1 untouched
    assert stack[0, 1, block:block + 2].tolist() == [0.25, 0.75]   # the numbers held stay on top
    assert ((stack[0, :2, :block] >= 0) & (stack[0, :2, :block] < 1)).all()
    assert len(set(stack[0, :2, :block].ravel().tolist())) == 2 * block
    assert rng[:, 1].tolist() == [block, block, 0, 0, 0, 0]  # counters: one per number drawn


def test_stream_keys_differ_by_row_agent_and_stream():
    keys = np.concatenate([device.stream_keys(range(50), 8, stream)[:, 0] for stream in (0, 1)])
    assert len(set(keys.tolist())) == keys.size
    assert np.array_equal(device.stream_keys([3], 8, 0), device.stream_keys([3], 8, 0))


def _play(seed: int, steps: int = 60):
    import mate

    vec = mate.make_vec('MultiAgentTracking-v0', 3, config='MATE-4v8-9', autoreset_mode='same-step')
    counts = (vec.num_cameras, vec.num_targets, vec.num_obstacles)
    cameras = device.HostTeam('greedy', 'camera', 3, counts, seed=seed)
    targets = device.HostTeam('greedy', 'target', 3, counts, seed=seed)
    (co, to), _ = vec.reset(seed=0)
    cameras.reset(co, np.ones(3, bool))
    targets.reset(to, np.ones(3, bool))
    actions = []
    for _ in range(steps):
        a = (cameras.act(co), targets.act(to))
        actions.append(a)
        (co, to), *_ = vec.step(a)
    return np.array([np.concatenate([c.ravel(), t.ravel()]) for c, t in actions]), cameras, targets


@pytest.mark.slow
def test_host_twins_are_deterministic_and_never_short():
    first, cameras, targets = _play(1)
    again, _, _ = _play(1)
    other, _, _ = _play(2)
    assert np.array_equal(first, again)
    assert not np.array_equal(first, other)
    for team in (cameras, targets):
        state = team.device_team.state
        assert not state.short.any()
        assert (state.left >= 1).all() and (state.left <= 2 * AGENT_BLOCK).all()


def test_a_host_twin_resumes_exactly():
    import mate

    envs = mate.make_team_vec('MATE-2v4-0', 'target', 3, max_episode_steps=8,
                              opponent=lambda n, c, seed: device.HostTeam('greedy', 'camera', n, c, seed=seed))
    envs.reset(seed=2)
    actions = np.random.default_rng(0).uniform(-5, 5, (20, 3, 4, 2))
    for step in range(10):
        envs.step(actions[step])
    saved = envs.state_dict()
    expected = [[np.copy(x) for x in envs.step(actions[step])[:2]] for step in range(10, 20)]
    resumed = mate.make_team_vec('MATE-2v4-0', 'target', 3, max_episode_steps=8,
                                 opponent=lambda n, c, seed: device.HostTeam('greedy', 'camera', n, c, seed=seed))
    resumed.reset(seed=5)
    resumed.load_state_dict(saved)
    for step in range(10, 20):
        observations, rewards = resumed.step(actions[step])[:2]
        assert np.array_equal(observations, expected[step - 10][0]) and np.array_equal(rewards, expected[step - 10][1])


def test_bad_options_are_refused():
    with pytest.raises(ValueError, match='unknown option'):
        device.device_team('random', 'camera', 2, (4, 8, 9), speed=1)
    with pytest.raises(ValueError, match='no device team'):
        device.device_team('heuristic', 'camera', 2, (4, 8, 9))
    with pytest.raises(ValueError, match='memory_period'):
        device.device_team('greedy', 'camera', 2, (4, 8, 9), memory_period=0)


GPU_BENCHMARK = """
import json, sys
sys.path.insert(0, sys.argv[1])
import gpu
found = dict(whole=gpu.whole_game('MATE-2v4-0', 3, 0.05), camera=gpu.rollout('camera', 2, 0.05),
             target=gpu.rollout('target', 2, 0.05))
print(json.dumps({name: {key: value for key, value in record.items() if key != 'seconds'}
                  for name, record in found.items()}))
"""


@pytest.mark.slow
def test_the_gpu_benchmark_plays_on_the_one_api_under_the_simulator():
    """benchmarks/gpu.py, ready for the first GPU at hand: its whole-game loop (both teams DeviceRuleTeams) and its
    rollouts (the single-team env's step_games) run on the simulated device."""
    needs_extra('numba_cuda')
    needs_extra('torch')
    from pathlib import Path

    benchmarks = str(Path(__file__).resolve().parents[2] / 'benchmarks')
    done = run_simulated(GPU_BENCHMARK, benchmarks, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report['whole']['steps'] >= 32 and report['whole']['teams'] == 'greedy vs greedy', report
    assert report['camera']['decisions'] >= 1 and report['target']['decisions'] >= 1, report
