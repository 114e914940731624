"""Throughput benchmark: env-steps per second of the single env, the batched core and the vector env.

Protocol: random actions, uniform over the action boxes, drawn before timing (a bank of 16
joint actions cycled through), observations built every step. The single env is the
Gymnasium-style `MultiAgentTracking` (infos, copies and all); the README loop is the same env
drawing `env.action_space.sample()` every step (the draw timed too); the batched core is
`mate.core.engine.step` on B rows writing into preallocated observation buffers; the vector env
is `mate.make_vec` drawing fresh random actions every step (the draw is timed too). Each
measurement runs for about `seconds` after one warm-up step (compilation is excluded).
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path

import numpy as np

from ..config import read_config
from ..constants import camera_observation_dim, target_observation_dim
from ..core import engine
from ..core.params import params_from_config
from ..core.world import empty_world
from ..envs.multi_agent_tracking import MultiAgentTracking

ORIGINAL_STEPS_PER_SECOND = {'MATE-4v8-9': 731, 'MATE-8v8-9': 503}
"""The original MATE's single-env speed with random actions on our machines (reference/groundtruth.md)."""

_BANK = 16


def _action_bank(rng, batch_size: int, params, count: int = _BANK):
    camera_high = np.array([params.camera_rotation_step, params.camera_zooming_step])
    speed = params.target_step_size
    return [(rng.uniform(-1.0, 1.0, (batch_size, params.num_cameras, 2)) * camera_high,
             rng.uniform(-speed, speed, (batch_size, params.num_targets, 2))) for _ in range(count)]


def _steps_per_second(env: MultiAgentTracking, next_action, seconds: float) -> tuple[int, float]:
    """(steps, seconds) of stepping `env` with `next_action(step)` for about `seconds` (resets included),
    after one warm-up step."""
    env.step(next_action(0))
    steps, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        for _ in range(100):
            _, _, terminated, truncated, _ = env.step(next_action(steps))
            steps += 1
            if terminated or truncated:
                env.reset()
    return steps, elapsed


def measure_single_env(preset: str, seconds: float = 2.0, seed: int = 0) -> dict:
    """Steps/s of one `MultiAgentTracking` env with random actions (resets included)."""
    env = MultiAgentTracking(preset)
    env.reset(seed=seed)
    bank = [(c[0], t[0]) for c, t in _action_bank(np.random.default_rng(seed), 1, env.params)]
    steps, elapsed = _steps_per_second(env, lambda step: bank[step % _BANK], seconds)
    return {'kind': 'single env', 'preset': preset, 'batch_size': 1, 'dtype': 'float64',
            'steps': steps, 'seconds': elapsed, 'env_steps_per_second': steps / elapsed}


def measure_readme_loop(preset: str, seconds: float = 2.0, seed: int = 0) -> dict:
    """Steps/s of the README's loop: one env stepped with `env.action_space.sample()` drawn every step
    (the draw timed too; resets included)."""
    env = MultiAgentTracking(preset)
    env.reset(seed=seed)
    env.action_space.seed(seed)
    steps, elapsed = _steps_per_second(env, lambda step: env.action_space.sample(), seconds)
    return {'kind': 'README loop', 'preset': preset, 'batch_size': 1, 'dtype': 'float64',
            'steps': steps, 'seconds': elapsed, 'env_steps_per_second': steps / elapsed}


def measure_batched_core(preset: str, batch_size: int, seconds: float = 2.0, dtype=np.float64,
                         seed: int = 0) -> dict:
    """Env-steps/s of the batched core at `batch_size` rows with random actions."""
    params = params_from_config(read_config(preset))
    nc, nt, no = params.num_cameras, params.num_targets, params.num_obstacles
    world = empty_world(params, batch_size)
    camera_obs = np.zeros((batch_size, nc, camera_observation_dim(nc, nt, no)), dtype=dtype)
    target_obs = np.zeros((batch_size, nt, target_observation_dim(nc, nt, no)), dtype=dtype)
    everyone = np.ones(batch_size, dtype=bool)
    engine.seed_rows(world, everyone, range(seed, seed + batch_size))
    engine.reset(params, world, everyone, camera_obs, target_obs)
    bank = _action_bank(np.random.default_rng(seed), batch_size, params)
    engine.step(params, world, *bank[0], camera_obs, target_obs)
    calls, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        engine.step(params, world, *bank[calls % _BANK], camera_obs, target_obs)
        calls += 1
    return {'kind': 'batched core', 'preset': preset, 'batch_size': batch_size,
            'dtype': np.dtype(dtype).name, 'steps': calls * batch_size, 'seconds': elapsed,
            'env_steps_per_second': calls * batch_size / elapsed}


def measure_vector_env(preset: str, batch_size: int, seconds: float = 2.0, dtype=np.float64,
                       seed: int = 0) -> dict:
    """Env-steps/s of `mate.make_vec` with fresh random actions drawn every step (`sample_actions`,
    timed), rewards, flags, infos and autoresets included."""
    from ..envs.vector import make_vec

    envs = make_vec(f'{preset}-v0', num_envs=batch_size, observation_dtype=dtype)
    envs.reset(seed=seed)
    rng = np.random.default_rng(seed)
    envs.step(envs.sample_actions(rng))
    calls, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        envs.step(envs.sample_actions(rng))
        calls += 1
    return {'kind': 'vector env', 'preset': preset, 'batch_size': batch_size,
            'dtype': np.dtype(dtype).name, 'steps': calls * batch_size, 'seconds': elapsed,
            'env_steps_per_second': calls * batch_size / elapsed}


_MEASURE = {'single': lambda preset, b, seconds, dtype: measure_single_env(preset, seconds),
            'readme': lambda preset, b, seconds, dtype: measure_readme_loop(preset, seconds),
            'batched': measure_batched_core, 'vector': measure_vector_env}


def run(presets=('MATE-4v8-9', 'MATE-8v8-9'), batch_sizes=(1, 64, 1024, 4096, 16384), seconds: float = 2.0,
        float32: bool = True, progress=None, repeat: int = 1) -> list[dict]:
    """Every measurement of the protocol; `progress(str)` is called before each one.

    With `repeat` > 1 the whole plan runs that many rounds and each result keeps its best round
    (`env_steps_per_second`, as `timeit` reports its fastest run: a shared machine's noise only
    ever slows a run down), the median and every round (`rounds`).
    """
    if repeat < 1:
        raise ValueError(f'repeat must be at least 1, got {repeat}')
    plan = []
    for preset in presets:
        plan.append(('single', preset, 1, np.float64))
        plan.append(('readme', preset, 1, np.float64))
        plan.extend(('batched', preset, b, np.float64) for b in batch_sizes)
        large = [b for b in batch_sizes if b >= 1024]
        if float32:
            plan.extend(('batched', preset, b, np.float32) for b in large)
        plan.extend(('vector', preset, b, dtype) for b in large
                    for dtype in ((np.float64, np.float32) if float32 else (np.float64,)))
    rounds = [[] for _ in plan]
    for round_index in range(repeat):
        for (kind, preset, batch_size, dtype), seen in zip(plan, rounds):
            if progress:
                progress(f'{preset} {kind} B={batch_size} {np.dtype(dtype).name}'
                         + (f' (round {round_index + 1}/{repeat})' if repeat > 1 else ''))
            seen.append(_MEASURE[kind](preset, batch_size, seconds, dtype))
    results = []
    for seen in rounds:
        rates = [r['env_steps_per_second'] for r in seen]
        result = dict(max(seen, key=lambda r: r['env_steps_per_second']))
        if repeat > 1:
            result.update(median_env_steps_per_second=float(np.median(rates)), rounds=rates)
        original = ORIGINAL_STEPS_PER_SECOND.get(result['preset'])
        result['speedup_vs_original'] = result['env_steps_per_second'] / original if original else None
        results.append(result)
    single = {r['preset']: r['env_steps_per_second'] for r in results if r['kind'] == 'single env'}
    for result in results:   # a ratio of two numbers of this run: it holds on any machine, unlike the absolute ones
        result['speedup_vs_single_env'] = result['env_steps_per_second'] / single[result['preset']]
    return results


def cpu_model() -> str:
    """The CPU's model name as the OS reports it (Linux: /proc/cpuinfo), else platform's guess."""
    try:
        with open('/proc/cpuinfo') as info:
            fields = {key.strip(): value.strip() for key, value in
                      (line.split(':', 1) for line in info if ':' in line)}
    except OSError:
        return platform.processor() or platform.machine()
    name = fields.get('model name') or platform.machine()
    family, model = fields.get('cpu family'), fields.get('model')
    return f'{name} (family {family}, model {model})' if family else name


def machine_facts() -> dict:
    """Where the numbers were measured."""
    return {'python': platform.python_version(), 'machine': platform.machine(), 'cpus': engine.NUM_THREADS,
            'processor': cpu_model(), 'numpy': np.__version__, 'numba': __import__('numba').__version__}


def write_json(results: list[dict], path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({'machine': machine_facts(), 'results': results}, indent=2))
    return path
