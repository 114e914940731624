"""The core on a CUDA device (`mate.core.device`): the same row kernels compiled by numba-cuda, one thread per game.

Without a GPU two things are checked: every kernel compiles to PTX for a GPU (the rules of the game need no change
to run there), and numba's CUDA simulator, running the kernels thread by thread, plays the CPU core's games
exactly: observations and every world array, after resets with seeds, masked resets and steps. The device's own
arithmetic is measured on a GPU by benchmarks/gpu.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import needs_extra, run_simulated
from mate.config import read_config
from mate.core.params import params_from_config

needs_extra('numba_cuda')     # the gpu extra (CI installs it)

from mate.core import device  # noqa: E402


@pytest.mark.slow
@pytest.mark.parametrize('name, dtype', [(name, np.float64) for name in device.KERNEL_NAMES] + [('step', np.float32)])
def test_every_kernel_compiles_for_a_gpu(name, dtype):
    """Every kernel with float64 observations; the step with float32 ones too (what the dtype changes: the
    observation writers, which the other kernels share)."""
    ptx = device.compile_ptx(name, params_from_config(read_config('MATE-4v8-9')), dtype=dtype, cc=(8, 0))
    assert '.target sm_80' in ptx and '.entry' in ptx


GAMES = """
import json, sys
import numpy as np
from mate.config import read_config
from mate.core import engine
from mate.core.device import DeviceCore
from mate.core.params import params_from_config
from mate.core.world import empty_world
from mate.spaces import camera_observation_space_of, target_observation_space_of

report = {}
for preset in sys.argv[1:]:
    p = params_from_config(read_config(preset))
    B, counts = 6, (p.num_cameras, p.num_targets, p.num_obstacles)
    dims = (camera_observation_space_of(*counts).shape[0], target_observation_space_of(*counts).shape[0])
    core = DeviceCore(p, B, dims, block=4)                    # two blocks, the second one half empty
    world, every = empty_world(p, B), np.ones(B, bool)
    camera_obs, target_obs = np.zeros((B, p.num_cameras, dims[0])), np.zeros((B, p.num_targets, dims[1]))
    engine.seed_rows(world, every, range(B))
    engine.reset(p, world, every, camera_obs, target_obs)
    core.reset(seeds=range(B))
    differing = []

    def compare(when):
        host = core.world_to_host()
        names = [name for name, a, b in zip(world._fields, world, host) if not np.array_equal(a, b)]
        if not np.array_equal(camera_obs, core.camera_obs.copy_to_host()):
            names.append('camera_obs')
        if not np.array_equal(target_obs, core.target_obs.copy_to_host()):
            names.append('target_obs')
        if names:
            differing.append(f'{when}: {names}')

    compare('reset')
    rng = np.random.default_rng(1)
    for step in range(40):
        if step == 20:                                        # a masked reset with seeds, halfway
            mask = np.arange(B) % 2 == 0
            engine.seed_rows(world, mask, [100 + b for b in range(0, B, 2)])
            engine.reset(p, world, mask, camera_obs, target_obs)
            core.reset(mask, seeds=[100 + b for b in range(0, B, 2)])
            compare('masked reset')
        camera_actions = rng.uniform(-30, 30, (B, p.num_cameras, 2))
        target_actions = rng.uniform(-30, 30, (B, p.num_targets, 2))
        engine.step(p, world, camera_actions, target_actions, camera_obs, target_obs)
        core.step(camera_actions, target_actions)
        compare(f'step {step}')
    report[preset] = dict(differing=differing, delivered=int(world.num_delivered_cargoes.sum()))
print(json.dumps(report))
"""


@pytest.mark.slow
def test_the_simulated_device_plays_the_cpu_cores_games_exactly():
    """Under numba's CUDA simulator (its own process: the switch is read when numba.cuda loads)."""
    presets = ['MATE-4v8-9', 'MATE-8v8-9', 'MATE-2v4-0']
    done = run_simulated(GAMES, *presets)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(report) == set(presets)
    for preset, found in report.items():
        assert found['differing'] == [], (preset, found['differing'][:3])


def test_wrong_shapes_are_refused_before_a_launch():
    code = """
import numpy as np
from mate.config import read_config
from mate.core.device import DeviceCore
from mate.core.params import params_from_config
core = DeviceCore(params_from_config(read_config('MATE-2v4-0')), 3, (1, 1))
for call in (lambda: core.step(np.zeros((3, 2, 2)), np.zeros((2, 4, 2))), lambda: core.reset(np.ones(4, bool)),
             lambda: core.reset(seeds=[1, 2])):
    try:
        call()
    except ValueError as exc:
        print(exc)
"""
    done = run_simulated(code, timeout=300)
    lines = done.stdout.strip().splitlines()
    assert lines == ['target_actions: expected shape (3, 4, 2), got (2, 4, 2)',
                     'reset mask: expected shape (3,), got (4,)', 'reset: 3 games reset, 2 seeds given'], done.stderr
