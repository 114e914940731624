"""The step and reset of the game for a whole batch: the compiled entry points of the core.

`reset`, `step`, `observe` and `global_states` take `Params`, a `World` of B rows and output
buffers. Rows are independent: a large batch is cut into contiguous chunks that run on a
thread pool (the compiled loops release the GIL); a small one runs on the calling thread.
A single environment is B = 1 of the same code.

Why threads and not numba's `prange`: with reference counting off (see `jit.py`) the prange
version of the step loop ran no faster than the serial one on our 2-core machines, while two
threads over two halves of the batch ran 1.9x faster (benchmarks/throughput.py).
"""

from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from ..constants import NUM_WAREHOUSES
from .cargo import transport_cargoes
from .jit import NUM_THREADS, entry_kernel, inline_kernel
from .kinematics import move_targets, rotate_and_zoom_cameras
from .observe import global_state, joint_observation, update_coverage
from .params import Params
from .perception import flag_camera_obstacles, is_tracked, perceive
from .rng import key_from_seed
from .spawn import reset_row
from .warmup import compiling_step_aside, wait_for_step_compile
from .world import World

PARALLEL_MIN_ROWS = 256
"""Each thread gets at least this many rows; smaller batches run on the calling thread. Handing
work to the pool costs ~100-250 us per call on our VMs, about what 100-150 rows take: with 32
rows per thread, B = 64 ran 3x slower on two threads than on one (docs/performance.md)."""


@inline_kernel
def advance_row(p, w, b, camera_actions, target_actions):
    """One step of row b's world, observations aside: cameras act, targets move, perception,
    cargo and rewards, counters, episode end."""
    rotate_and_zoom_cameras(p, w, b, camera_actions)
    move_targets(p, w, b, target_actions)
    perceive(p, w, b)
    dense, sparse = transport_cargoes(p, w, b)
    w.target_team_episode_reward[b] += dense
    w.delayed_target_team_episode_reward[b] += sparse
    w.target_reward[b] = sparse if p.sparse_reward else dense
    update_coverage(p, w, b)
    w.coverage_rate_sum[b] += w.coverage_rate[b]
    w.real_coverage_rate_sum[b] += w.real_coverage_rate[b]
    for t in range(p.num_targets):
        w.target_steps[b, t] += 1
        w.target_tracked_steps[b, t] += is_tracked(p, w, b, t)
    w.episode_step[b] += 1
    awaiting = 0
    for h in range(NUM_WAREHOUSES):
        awaiting += w.awaiting_cargo_counts[b, h]
    w.terminated[b] = awaiting <= 0
    w.truncated[b] = w.episode_step[b] >= p.max_episode_steps and not w.terminated[b]


STEP_BLOCK = 64
"""Rows advanced together before their observations are written (see `_step_rows`)."""


def _step_rows(p, w, camera_actions, target_actions, camera_obs, target_obs):
    """Advance every row, then write the observations, a block of rows at a time: the world rows
    of a block are still in cache when their observations are built, and each pass streams
    through fewer arrays at once than one fused loop (faster on large batches)."""
    batch_size = w.episode_step.shape[0]
    for start in range(0, batch_size, STEP_BLOCK):
        stop = min(start + STEP_BLOCK, batch_size)
        for b in range(start, stop):
            advance_row(p, w, b, camera_actions[b], target_actions[b])
        for b in range(start, stop):
            joint_observation(p, w, b, camera_obs[b], target_obs[b])


@inline_kernel
def start_row(p, w, b, camera_out, target_out):
    """Start row b's episode (`reset_row`: spawn from its random stream) and write its first observations
    camera_out (Nc, D_c), target_out (Nt, D_t): the reset of one game, on the CPU and on a device."""
    reset_row(p, w, b)
    update_coverage(p, w, b)
    joint_observation(p, w, b, camera_out, target_out)


def _reset_rows(p, w, mask, camera_obs, target_obs):
    for b in range(w.episode_step.shape[0]):
        if mask[b]:
            start_row(p, w, b, camera_obs[b], target_obs[b])


def _observe_rows(p, w, camera_obs, target_obs):
    for b in range(w.episode_step.shape[0]):
        update_coverage(p, w, b)
        joint_observation(p, w, b, camera_obs[b], target_obs[b])


def _state_rows(p, w, out):
    for b in range(w.episode_step.shape[0]):
        global_state(p, w, b, out[b])


def _refresh_rows(p, w, mask):
    for b in range(w.episode_step.shape[0]):
        if mask[b]:
            flag_camera_obstacles(p, w, b)
            perceive(p, w, b)
            update_coverage(p, w, b)


_step_rows = entry_kernel(_step_rows)
_reset_rows = entry_kernel(_reset_rows)
_observe_rows = entry_kernel(_observe_rows)
_state_rows = entry_kernel(_state_rows)
_refresh_rows = entry_kernel(_refresh_rows)

_POOL: ThreadPoolExecutor | None = None


def _num_workers(batch_size: int) -> int:
    """Threads a batch of `batch_size` rows is split over (1: run on the calling thread)."""
    return min(NUM_THREADS, batch_size // PARALLEL_MIN_ROWS)


def _run(kernel, params: Params, world: World, *row_arrays) -> None:
    """Run `kernel(params, world, *row_arrays)` over all rows, split into contiguous chunks
    on a thread pool when the batch is large (the kernels release the GIL)."""
    global _POOL
    batch_size = len(world.episode_step)
    workers = _num_workers(batch_size)
    if workers <= 1:
        kernel(params, world, *row_arrays)
        return
    if _POOL is None:
        _POOL = ThreadPoolExecutor(NUM_THREADS, thread_name_prefix='mate-core')
    bounds = np.linspace(0, batch_size, workers + 1).astype(int)
    chunks = [slice(lo, hi) for lo, hi in zip(bounds[:-1], bounds[1:])]
    futures = [_POOL.submit(kernel, params, World(*(field[rows] for field in world)),
                            *(array[rows] for array in row_arrays)) for rows in chunks]
    for future in futures:
        future.result()


def seed_rows(world: World, mask: np.ndarray, seeds) -> None:
    """Give the rows where mask (B,) is true fresh random streams derived from `seeds`
    (one int or None per selected row; None draws OS entropy)."""
    seed_streams(world.rng, mask, seeds)


def seed_streams(rng: np.ndarray, mask: np.ndarray, seeds) -> None:
    """`seed_rows` on a world's stream array `rng` (B, 2) alone (a host copy of a device world's, say)."""
    rows = np.flatnonzero(mask)
    for b, seed in zip(rows, seeds, strict=True):
        rng[b, 0] = key_from_seed(seed)
        rng[b, 1] = 0


def reset(params: Params, world: World, mask: np.ndarray, camera_obs: np.ndarray, target_obs: np.ndarray) -> None:
    """Start new episodes in the rows where mask (B,) is true; fill their observations
    camera_obs (B, Nc, D_c) and target_obs (B, Nt, D_t). Other rows are untouched.
    A process's first reset on a cold compile cache has the step compiled meanwhile (`warmup`)."""
    with compiling_step_aside(camera_obs, target_obs):
        _run(_reset_rows, params, world, mask, camera_obs, target_obs)


def step(params: Params, world: World, camera_actions: np.ndarray, target_actions: np.ndarray,
         camera_obs: np.ndarray, target_obs: np.ndarray) -> None:
    """Advance every row by one step. Actions are float64 (B, Nc, 2) in degrees
    (rotation, zoom) and (B, Nt, 2) displacements; they must be finite (callers check)."""
    wait_for_step_compile()
    _run(_step_rows, params, world, camera_actions, target_actions, camera_obs, target_obs)


def bind_step(params: Params, world: World, camera_actions: np.ndarray, target_actions: np.ndarray,
              camera_obs: np.ndarray, target_obs: np.ndarray):
    """`step` on these exact arrays as a call without arguments, for a world stepped over and
    over with its actions written in place (the single env). The compiled kernel is looked up
    once here, which skips numba's per-call typing of the ~40 world arrays (about 7 of the
    10 us a B = 1 call costs). Batches large enough for the thread pool get plain `step`."""
    args = (params, world, camera_actions, target_actions, camera_obs, target_obs)
    wait_for_step_compile()
    if _num_workers(len(world.episode_step)) > 1:
        return functools.partial(step, *args)
    compiled = _step_rows.compile(tuple(numba.typeof(arg) for arg in args))
    return functools.partial(compiled, *args)


def observe(params: Params, world: World, camera_obs: np.ndarray, target_obs: np.ndarray) -> None:
    """Rebuild every row's joint observations (and coverage statistics) from the current masks."""
    _run(_observe_rows, params, world, camera_obs, target_obs)


def global_states(params: Params, world: World, out: np.ndarray) -> None:
    """Fill out (B, 29 + 9 Nc + 16 Nt + 3 No) with every row's global state vector."""
    _run(_state_rows, params, world, out)


def refresh(params: Params, world: World, mask: np.ndarray) -> None:
    """Recompute everything derived from positions (camera->obstacle flags, view masks,
    coverage) for the rows where mask is true; used after loading a snapshot."""
    _run(_refresh_rows, params, world, mask)


def compile_step(camera_dtype: str, target_dtype: str) -> None:
    """(In the helper process) compile `_step_rows` for the argument types a step of an env with
    observations of these dtypes passes, and write it to the cache. The types of `Params` and `World`
    do not depend on the configuration."""
    import numba

    from ..config.loader import read_config
    from .params import params_from_config
    from .world import empty_world

    params = params_from_config(read_config('MATE-4v8-9'))
    world = empty_world(params, 1)
    actions = np.zeros((1, 1, 2))
    observations = (np.zeros((1, 1, 1), dtype=camera_dtype), np.zeros((1, 1, 1), dtype=target_dtype))
    _step_rows.compile(tuple(numba.typeof(a) for a in (params, world, actions, actions, *observations)))
