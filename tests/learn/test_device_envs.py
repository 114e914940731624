"""The training env with its games on a device (`TrainingEnv(..., device='cuda')`): the spec's pipeline gives on torch
tensors the numbers it gives on numpy arrays (one body, `mate.core.arrays`); under numba's CUDA simulator the env on the
device plays the CPU env's games (with the device team's host twin as the CPU env's opponent) number for number, and
a PPO run over it logs the rows of a run over the CPU env and resumes exactly."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import torch
from conftest import needs_extra, run_simulated

from mate.agents.utils import normalize_observation
from mate.learn.envs import TrainingEnv, compress, device_unsupported
from mate.policies.memory import SightingMemory
from mate.learn.mappo import MAPPOConfig, policy_spec
from mate.policies.spec import PolicySpec
from mate.envs.vector import make_vec


def _played(preset: str, steps: int = 12, seed: int = 0):
    """(camera obs, target obs, state) float32 after `steps` random env steps of 6 games, episodes of 5 steps (so
    that some games restart)."""
    vec = make_vec(f'{preset}-v0', 6, observation_dtype=np.float32, max_episode_steps=5)
    vec.reset(seed=seed)
    for _ in range(steps):
        (camera, target), *_ = vec.step(vec.action_space.sample())
    return camera.copy(), target.copy(), vec


def _check_memory_and_velocity(preset, raw, vec):
    """The memory and velocity columns on tensors are those on numpy arrays bit for bit, on a memory (one of each
    kind, fed the same steps) that saw a few steps of the games and lost some targets."""
    spec = PolicySpec.for_game('camera', f'{preset}-v0', frame_skip=5, action='hrl', memory=3, velocity=True)
    memory = SightingMemory(raw.shape[0], spec.counts, spec.memory)
    tensors = SightingMemory(raw.shape[0], spec.counts, spec.memory, like=torch.zeros(0))
    previous = raw
    for step in range(4):
        (now, _), *_ = vec.step(vec.action_space.sample())
        for kept, observation in ((memory, now), (tensors, torch.from_numpy(now))):
            if step == 2:
                kept.forget(np.array([True] + [False] * (raw.shape[0] - 1)) if kept is memory
                            else torch.tensor([True] + [False] * (raw.shape[0] - 1)))
            kept.tick()
            kept.observe_team(observation)
        previous, raw = raw, now.copy()
    assert isinstance(tensors.age, torch.Tensor) and np.array_equal(tensors.age.numpy(), memory.age)
    assert (memory.age == spec.memory).any() and (memory.age == 0).any()   # forgotten targets and fresh ones
    expected = spec.features(raw, memory.features(raw), previous)
    got = spec.features(torch.from_numpy(raw), tensors.features(torch.from_numpy(raw)), torch.from_numpy(previous))
    assert isinstance(got, torch.Tensor) and np.array_equal(got.numpy(), expected)
    assert np.abs(expected[..., -2 * spec.counts[1]:]).max() > 0           # some target moved while seen


@pytest.mark.parametrize('preset', ['MATE-4v8-9', 'MATE-2v4-0', 'MATE-8v8-9'])
def test_the_specs_pipeline_gives_on_tensors_what_it_gives_on_arrays(preset):
    camera, target, vec = _played(preset)
    state = vec.state()
    rng = np.random.default_rng(1)
    for team, raw in (('camera', camera), ('target', target)):
        actions = ('grid', 'continuous') + (('hrl', 'hrl-joint') if team == 'camera' else ())
        for action in actions:
            spec = PolicySpec.for_game(team, f'{preset}-v0', frame_skip=5, action=action)
            features = spec.features(raw)
            got = spec.features(torch.from_numpy(raw))
            assert got.dtype == torch.float32 and np.array_equal(got.numpy(), features), (team, action)
            expected_state = compress(normalize_observation(state, vec.single_state_space))
            got_state = compress(normalize_observation(torch.from_numpy(state), vec.single_state_space))
            assert isinstance(got_state, torch.Tensor) and np.array_equal(got_state.numpy(), expected_state)
            allowed = spec.allowed(features)
            got_allowed = spec.allowed(torch.from_numpy(features))
            if allowed is None:
                assert got_allowed is None
            else:
                assert allowed.any(-1).all() and not allowed.all()           # some choices masked, never all
                assert np.array_equal(got_allowed.numpy(), allowed), (team, action)
            if team == 'camera' and action == 'hrl':      # the sighting memory and velocity columns
                _check_memory_and_velocity(preset, raw, vec)
            if action in ('grid', 'continuous'):
                held = rng.integers(0, spec.choices, raw.shape[:2] + (1,)) if action == 'grid' else \
                    rng.uniform(-1.5, 1.5, raw.shape[:2] + (2,))
            else:
                held = rng.integers(0, spec.choices, raw.shape[:2] + (spec.heads,))
            decoded = spec.decode(torch.from_numpy(held), torch.from_numpy(raw))
            assert isinstance(decoded, torch.Tensor) and np.array_equal(decoded.numpy(), spec.decode(held, raw)), \
                (team, action)


def test_what_the_device_does_not_play_is_named_and_auto_keeps_it_on_the_cpu(tmp_path):
    spec = PolicySpec.for_game('camera', 'MATE-4v8-9-v0', frame_skip=5, action='hrl', memory=25, velocity=True,
                               full_observability=True)
    assert device_unsupported(spec) == []
    assert device_unsupported(spec, camera_reward='mixed', opponent=lambda n, counts, seed: None) == \
        ["the 'mixed' camera reward", 'an opponent other than the greedy rules']
    config = MAPPOConfig(hrl=True, memory=25, device='cpu', run_dir=str(tmp_path), num_envs=2)
    assert config.resolved_game_device(policy_spec(config)) == 'cpu'            # auto: the networks are on the CPU
    assert isinstance(config.make_env(policy_spec(config)), TrainingEnv)
    config = MAPPOConfig(device='cpu', game_device='cuda', run_dir=str(tmp_path))
    with pytest.raises(ValueError, match=r"^--game-device cuda: the 'mixed' camera reward is not played on the device "
                                         r'yet; use --game-device cpu$'):
        config.resolved_game_device(policy_spec(config), camera_reward='mixed')
    with pytest.raises(ValueError, match='--game-device must be auto, cpu or cuda'):
        MAPPOConfig(game_device='gpu')
    envs = MAPPOConfig(num_envs=2, device='cpu', game_device='cpu').make_env(policy_spec(MAPPOConfig()))
    with pytest.raises(ValueError, match='played on a GPU; resume it with --game-device cuda'):
        envs.load_state_dict(dict(device={}, raw=None, returns=None))


SIMULATED = """
import csv, json, sys, tempfile
from pathlib import Path
import numpy as np, torch
sys.path.insert(0, sys.argv[1])
from resume import assert_same_run, stopped_and_resumed
from mate.learn.envs import TrainingEnv
from mate.learn.mappo import MAPPOConfig, policy_spec, train
from mate.learn.run import TIMING_COLUMNS
from mate.policies.spec import PolicySpec
from mate.teams.device import HostTeam

def host_twin(team):
    other = 'target' if team == 'camera' else 'camera'
    return lambda n, counts, seed: HostTeam('greedy', other, n, counts, seed=seed)

report = {}
for team, preset, action, credit in (('camera', 'MATE-4v8-9', 'hrl', 'difference'),
                                     ('target', 'MATE-2v4-0', 'continuous', 'team')):
    columns = dict(memory=4, velocity=True, full_observability=True) if team == 'camera' else \
        dict(full_observability=True)
    spec = PolicySpec.for_game(team, preset + '-v0', frame_skip=3, action=action, **columns)
    cpu = TrainingEnv(spec, 2, horizon=10, seed=4, credit=credit, opponent=host_twin(team))
    dev = TrainingEnv(spec, 2, horizon=10, seed=4, credit=credit, device='cuda', block=2)
    differing, episodes = [], 0
    def compare(tag, a, b):
        b = b.numpy() if isinstance(b, torch.Tensor) else b
        if not (np.shape(a) == np.shape(b) and np.array_equal(a, b)):
            differing.append(tag)
    for tag, a, b in zip(('obs', 'state'), cpu.reset(seed=11), dev.reset(seed=11)):
        compare(f'reset {tag}', a, b)
    rng = np.random.default_rng(0)
    for t in range(8):
        shape = (2, spec.num_agents, 2 if spec.continuous else spec.heads)
        act = rng.uniform(-1.2, 1.2, shape) if spec.continuous else rng.integers(0, spec.choices, shape)
        expected, got = cpu.step(act), dev.step(torch.as_tensor(act))
        for tag, a, b in zip(('obs', 'state', 'reward', 'done', 'truncated'), expected, got):
            compare(f'{t} {tag}', a, b)
        ended = expected[3]
        for key in ('final_obs', 'final_state'):
            compare(f'{t} {key}', expected[5][key][ended], got[5][key].numpy()[ended])
        compare(f'{t} coverage', expected[5]['coverage'], got[5]['coverage'])
        if expected[5]['episodes'] != got[5]['episodes']:
            differing.append(f'{t} episodes')
        episodes += len(expected[5]['episodes'])
    report[f'env {team} {action} {credit}'] = dict(differing=differing[:5], episodes=episodes)

folder = Path(tempfile.mkdtemp())
for hrl in (True, False):
    def config_of(run_dir, fresh, game='cuda'):
        return MAPPOConfig(seed=1, steps=18, num_envs=2, rollout_length=3, epochs=1, minibatches=2, horizon=10,
                           frame_skip=2, threads=1, progress=False, hrl=hrl, device='cpu', game_device=game,
                           run_dir=run_dir, fresh=fresh, checkpoint_every=1,
                           **(dict(memory=4, velocity=True) if hrl else dict(team='target', credit='own')))
    device_config, cpu_config = config_of(str(folder / f'device-{hrl}'), True), config_of(str(folder / f'cpu-{hrl}'),
                                                                                         True, 'cpu')
    made = device_config.make_env(policy_spec(device_config))
    made = f'{type(made).__name__} tensors={made.tensors}'
    train(device_config)
    train(cpu_config, envs=TrainingEnv(policy_spec(cpu_config), 2, horizon=10, seed=1, credit=cpu_config.credit,
                                      opponent=host_twin(cpu_config.team)))
    rows = []
    for run_dir in (device_config.run_dir, cpu_config.run_dir):
        with open(Path(run_dir) / 'progress.csv', newline='') as f:
            rows.append([{k: v for k, v in row.items() if k not in TIMING_COLUMNS} for row in csv.DictReader(f)])
    found = dict(env=made, same=rows[0] == rows[1], rows=len(rows[0]), episodes=int(rows[0][-1]['episodes']))
    if hrl:
        straight, stopped = stopped_and_resumed(train, config_of, 1, folder / 'resume')
        assert_same_run(straight, stopped)
        found['resumed'] = True
    report[f'train hrl={hrl}'] = found
print(json.dumps(report))
"""


@pytest.mark.slow
def test_the_simulated_device_env_trains_as_the_cpu_env():
    """Under numba's CUDA simulator (its own process: the switch is read when numba.cuda loads): two settings'
    envs step for step (with full observability: HRL cameras with difference credit, the sighting memory and
    velocities; continuous targets), then PPO runs (HRL cameras, targets with their own credit) over the device env
    and over the CPU env with the host twin, and a stopped and resumed run on the device."""
    needs_extra('numba_cuda')
    here = str(Path(__file__).parent)
    done = run_simulated(SIMULATED, here, timeout=900)   # (here: where the script imports resume from)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(report) == 4, report
    for name, found in report.items():
        if name.startswith('env'):
            assert found['differing'] == [] and found['episodes'] >= 2, (name, found)
        else:
            assert found['env'] == 'TrainingEnv tensors=True' and found['same'] and found['rows'] == 3, (name, found)
            assert found['episodes'] >= 2, (name, found)
    assert report['train hrl=True']['resumed']


OFF_POLICY = """
import csv, json, sys, tempfile
from pathlib import Path
sys.path.insert(0, sys.argv[1])
from resume import assert_same_run, stopped_and_resumed
from mate.learn import iql, matd3, qmix
from mate.learn.envs import TrainingEnv
from mate.learn.run import TIMING_COLUMNS
from mate.teams.device import HostTeam

SMALL = dict(seed=1, steps=48, num_envs=2, horizon=10, frame_skip=2, buffer_size=64, batch_size=8, update_every=4,
             learning_starts=8, report_every=16, hidden=(16,), threads=1, progress=False, device='cpu',
             checkpoint_every=1)
TRAINERS = {'iql': (iql, lambda **kw: iql.IQLConfig(**SMALL, hrl=True, target_update=8, **kw)),
            'qmix': (qmix, lambda **kw: qmix.QMIXConfig(**SMALL, sequence_length=4, mixer_embed=8, target_update=8,
                                                        **kw)),
            'matd3': (matd3, lambda **kw: matd3.MATD3Config(**SMALL, team='target', random_steps=16, **kw))}
folder = Path(tempfile.mkdtemp())
report = {}
for name, (module, config_of) in TRAINERS.items():
    device_config = config_of(run_dir=str(folder / f'{name}-device'), fresh=True, game_device='cuda')
    cpu_config = config_of(run_dir=str(folder / f'{name}-cpu'), fresh=True, game_device='cpu')
    made = device_config.make_env(module.policy_spec(device_config))
    other = 'target' if cpu_config.team == 'camera' else 'camera'
    twin = lambda n, counts, seed: HostTeam('greedy', other, n, counts, seed=seed)
    module.train(device_config)
    module.train(cpu_config, envs=TrainingEnv(module.policy_spec(cpu_config), 2, horizon=10, seed=1,
                                             credit=cpu_config.credit, opponent=twin))
    rows = []
    for run_dir in (device_config.run_dir, cpu_config.run_dir):
        with open(Path(run_dir) / 'progress.csv', newline='') as f:
            rows.append([{k: v for k, v in row.items() if k not in TIMING_COLUMNS} for row in csv.DictReader(f)])
    found = dict(env=f'{type(made).__name__} tensors={made.tensors}', same=rows[0] == rows[1], rows=len(rows[0]),
                 episodes=int(rows[0][-1]['episodes']),
                 loss=rows[0][-1].get('loss', rows[0][-1].get('critic_loss')))
    if name == 'qmix':        # a stopped and resumed run with its games on the device ends as the straight one
        straight, stopped = stopped_and_resumed(module.train, lambda run_dir, fresh: config_of(
            run_dir=run_dir, fresh=fresh, game_device='cuda'), 1, folder / 'resume')
        assert_same_run(straight, stopped)
        found['resumed'] = True
    report[name] = found
print(json.dumps(report))
"""


@pytest.mark.slow
def test_the_off_policy_trainers_play_on_the_simulated_device_as_on_the_cpu():
    """`mate train iql|qmix|matd3 --game-device cuda` under numba's CUDA simulator logs the rows of the same run with
    its games on the CPU (the device team's host twin as the opponent), and QMIX's stops and resumes exactly."""
    needs_extra('numba_cuda')
    here = str(Path(__file__).parent)
    done = run_simulated(OFF_POLICY, here, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert sorted(report) == ['iql', 'matd3', 'qmix'], report
    for name, found in report.items():
        assert found['env'] == 'TrainingEnv tensors=True' and found['same'] and found['rows'] == 3, (name, found)
        assert found['episodes'] >= 2 and float(found['loss']) == float(found['loss']), (name, found)   # updated
    assert report['qmix']['resumed']
