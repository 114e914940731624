"""The core on a CUDA device: the same row kernels, compiled by numba-cuda, one GPU thread per game.

The CPU core steps its B games in loops over rows (`engine._step_rows`): `advance_row` (cameras act, targets move,
perception with occlusion, cargo, rewards, counters, episode end), then `joint_observation`; a reset runs
`start_row` (spawn from each row's own random stream, then its first observations). Here each of those
loops is a CUDA kernel whose thread b runs the very same functions on row b: the rules of the game are written once,
in `mate.core`, and numba-cuda compiles them as device functions (numba's CPU functions called from a CUDA kernel are
compiled for the device). The world, the parameters and the observation buffers live on the device as named tuples
of device arrays (`DeviceCore`); a step moves nothing to the host.

Without a GPU the kernels still compile to PTX (`compile_ptx`: what CI checks), and numba's CUDA simulator
(`NUMBA_ENABLE_CUDASIM=1`) runs them, each thread calling the CPU-compiled row functions: the launch, the masks and
the buffers are then checked against the CPU core game for game (tests/core/test_device_core.py). On a GPU, the
device's own math library rounds some results differently (float64: to the last bits); `benchmarks/gpu.py` measures
the speed and the transitions' differences there.

Needs the gpu extra (numba-cuda): `pip install -e '.[gpu]'`.

    from mate.config import read_config
    from mate.core.device import DeviceCore
    from mate.core.params import params_from_config

    core = DeviceCore(params_from_config(read_config('MATE-4v8-9')), batch_size=16384, observation_dims=(126, 131))
    core.reset(seeds=range(16384))
    core.step(camera_actions, target_actions)      # device (or host) arrays (B, Nc, 2), (B, Nt, 2)
    core.camera_obs                                # a device array (B, Nc, D_c), torch.as_tensor(..., device='cuda')
"""

from __future__ import annotations

import contextlib
import functools
import types
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

from ..constants import state_dim
from .engine import advance_row, seed_streams, start_row
from .observe import global_state, joint_observation
from .params import Params
from .world import World, empty_world

__all__ = ['BLOCK', 'KERNEL_NAMES', 'DeviceCore', 'Outputs', 'Rows', 'States', 'compile_ptx', 'cuda_module',
           'from_torch', 'kernels', 'launch_arguments', 'to_torch']

BLOCK = 128
"""Threads (games) per CUDA block."""


class Rows(NamedTuple):
    """The per-row arrays a kernel reads and writes beside the world: the actions (B, Nc, 2), (B, Nt, 2), the
    observation buffers (B, Nc, D_c), (B, Nt, D_t) and the reset mask (B,). One named tuple, so that numba's CUDA
    simulator hands the arrays to the row functions as they are."""

    camera_actions: object
    target_actions: object
    camera_obs: object
    target_obs: object
    mask: object


class Outputs(NamedTuple):
    """What a step hands back (B,) each, written by the `finish` kernel before it restarts the games that ended:
    the step's rewards, end flags and coverage rate, and for the games that ended their episode's statistics, as
    `mate.core.world.episode_statistics` gives them (undefined elsewhere)."""

    camera_reward: object
    target_reward: object
    terminated: object
    truncated: object
    coverage_rate: object
    episode_length: object
    episode_coverage_rate: object
    episode_real_coverage_rate: object
    episode_target_return: object       # the target team's return of the config's reward (dense or sparse)
    transport_rate: object              # at the episode's end
    delivered_cargoes: object


def cuda_module():
    """`numba.cuda`, or ImportError naming the extra that installs it."""
    global cuda
    try:
        from numba import cuda as module
    except ImportError:
        raise ImportError("the device core needs numba-cuda, from the gpu extra: pip install -e '.[gpu]'") from None
    cuda = module
    return module


cuda = None
"""numba.cuda once `cuda_module` imported it: the kernels below read `cuda.grid` from this module's globals, where
numba's CUDA simulator finds it too."""


def _step(p, w, rows, restart_masked):
    b = cuda.grid(1)
    if b < w.episode_step.shape[0]:
        if restart_masked and rows.mask[b]:
            start_row(p, w, b, rows.camera_obs[b], rows.target_obs[b])
        else:
            advance_row(p, w, b, rows.camera_actions[b], rows.target_actions[b])
            joint_observation(p, w, b, rows.camera_obs[b], rows.target_obs[b])


def _reset(p, w, rows):
    b = cuda.grid(1)
    if b < w.episode_step.shape[0] and rows.mask[b]:
        start_row(p, w, b, rows.camera_obs[b], rows.target_obs[b])


def _finish(p, w, rows, out, restart):
    b = cuda.grid(1)
    if b < w.episode_step.shape[0]:
        reward = w.target_reward[b]
        out.target_reward[b] = reward
        out.camera_reward[b] = -reward
        out.terminated[b] = w.terminated[b]
        out.truncated[b] = w.truncated[b]
        out.coverage_rate[b] = w.coverage_rate[b]
        done = w.terminated[b] or w.truncated[b]
        rows.mask[b] = done
        if done:
            steps = w.episode_step[b]
            out.episode_length[b] = steps
            out.episode_coverage_rate[b] = w.coverage_rate_sum[b] / steps
            out.episode_real_coverage_rate[b] = w.real_coverage_rate_sum[b] / steps
            out.episode_target_return[b] = w.delayed_target_team_episode_reward[b] if p.sparse_reward \
                else w.target_team_episode_reward[b]
            out.transport_rate[b] = w.mean_transport_rate[b]
            out.delivered_cargoes[b] = w.num_delivered_cargoes[b]
            if restart:
                start_row(p, w, b, rows.camera_obs[b], rows.target_obs[b])


def _state(p, w, rows, states):
    b = cuda.grid(1)
    if b < w.episode_step.shape[0]:
        global_state(p, w, b, states.out[b])


class States(NamedTuple):
    """The `state` kernel's output: every game's global state (B, S) (a named tuple, as `Rows`)."""

    out: object


def _kernel_functions() -> dict:
    """The kernels' Python functions (thread b: row b), by name."""
    cuda_module()
    return {'step': _step, 'reset': _reset, 'finish': _finish, 'state': _state}


KERNEL_NAMES = ('step', 'reset', 'finish', 'state')
"""The device kernels: `step` advances every game and writes its observations (told to, the games of the mask
start their next episode instead: next-step autoreset), `reset` starts the masked games,
`finish` copies a step's rewards and flags into `Outputs` and sets the mask to the games that ended (restarting
them at once if told: same-step autoreset), `state` writes every game's global state into `States`."""


@functools.cache
def kernels() -> dict:
    """The CUDA kernels by name (`KERNEL_NAMES`), compiled at their first launch (numba.cuda.jit)."""
    return {name: cuda_module().jit(function) for name, function in _kernel_functions().items()}


def compile_ptx(name: str, params: Params, batch_size: int = 2, dtype=np.float64, cc: tuple[int, int] = (9, 0)) -> str:
    """The PTX of the kernel `name` ('step' or 'reset') for compute capability `cc`, for games of `params` and
    observations of `dtype`; needs no GPU (numba-cuda with NVVM, from the gpu extra). What CI checks: every rule of
    the core compiles for the device."""
    from numba import typeof

    functions = _kernel_functions()
    world = empty_world(params, batch_size)
    rows = _host_rows(params, batch_size, (1, 1), dtype)     # (the observations' lengths do not change the code)
    extra = {'step': (True,), 'finish': (_host_outputs(batch_size), True),
             'state': (States(np.zeros((batch_size, 1), dtype)),)}
    arguments = (params, world, rows) + extra.get(name, ())
    signature = tuple(typeof(argument) for argument in arguments)
    with assumed_compute_capability(cc):
        ptx, _ = cuda.compile_ptx(functions[name], signature, cc=cc)
    return ptx


def launch_arguments(*groups: tuple) -> tuple:
    """A kernel's named-tuple arguments as they are; under numba's CUDA simulator with the host arrays its device
    arrays wrap, which the CPU-compiled row functions take (scalar fields pass through)."""
    if not _simulated():
        return groups
    return tuple(type(group)(*(getattr(field, '_ary', field) for field in group)) for group in groups)


def _simulated() -> bool:
    """Whether numba's CUDA simulator stands in for a GPU (`NUMBA_ENABLE_CUDASIM=1`)."""
    from numba import config

    return bool(config.ENABLE_CUDASIM)


@contextlib.contextmanager
def assumed_compute_capability(cc: tuple[int, int]):
    """numba-cuda asks the current device for its compute capability when it compiles a function called from a
    kernel; without a GPU, answer `cc`."""
    import sys

    dispatcher = sys.modules['numba.cuda.dispatcher']
    original = dispatcher.get_current_device
    dispatcher.get_current_device = lambda: types.SimpleNamespace(compute_capability=cc)
    try:
        yield
    finally:
        dispatcher.get_current_device = original


def _host_rows(params: Params, batch_size: int, observation_dims: tuple[int, int], dtype) -> Rows:
    """Zeroed host arrays of `Rows` for B games: actions float64, observations of `dtype`."""
    B, nc, nt = batch_size, params.num_cameras, params.num_targets
    return Rows(np.zeros((B, nc, 2)), np.zeros((B, nt, 2)), np.zeros((B, nc, observation_dims[0]), dtype),
                np.zeros((B, nt, observation_dims[1]), dtype), np.zeros(B, bool))


def _host_outputs(batch_size: int) -> Outputs:
    """Zeroed host arrays of `Outputs` for B games."""
    B = batch_size
    return Outputs(np.zeros(B), np.zeros(B), np.zeros(B, bool), np.zeros(B, bool), np.zeros(B),
                   np.zeros(B, np.int64), np.zeros(B), np.zeros(B), np.zeros(B), np.zeros(B), np.zeros(B, np.int64))


def to_torch(array):
    """A torch tensor viewing the device array `array` without a copy (`__cuda_array_interface__`); under numba's
    CUDA simulator, a CPU tensor viewing its host array."""
    import torch

    if _simulated():
        return torch.from_numpy(array._ary)
    return torch.as_tensor(array, device='cuda')


def from_torch(tensor):
    """A numba device array viewing a CUDA torch tensor without a copy (a CPU tensor under the simulator, and a
    numpy array or anything array-like: returned as numpy)."""
    if getattr(getattr(tensor, 'device', None), 'type', None) == 'cuda':
        return cuda_module().as_cuda_array(tensor.detach())
    if hasattr(tensor, 'detach'):
        return tensor.detach().numpy()
    return tensor


class DeviceCore:
    """B games of one configuration on a CUDA device: the world, the parameters and the observation buffers as
    device arrays; `reset` and `step` launch one thread per game.

    Args:
        params: the game's parameters (`params_from_config`).
        batch_size: B, the games played at once.
        observation_dims: (D_c, D_t), the lengths of a camera's and a target's observation
            (`mate.spaces.camera_observation_space_of(...).shape[0]`, ...).
        dtype: the observations' dtype (float64 or float32; the world is float64).
        block: threads per CUDA block.
    """

    def __init__(self, params: Params, batch_size: int, observation_dims: tuple[int, int], dtype=np.float64,
                 block: int = BLOCK):
        self.cuda = cuda_module()
        self.batch_size = int(batch_size)
        self.block = int(block)
        to_device = self.cuda.to_device
        self.params = Params(*(to_device(field) if isinstance(field, np.ndarray) else field for field in params))
        self.world = World(*(to_device(field) for field in empty_world(params, self.batch_size)))
        host = _host_rows(params, self.batch_size, tuple(observation_dims), dtype)
        self.rows = Rows(*(to_device(array) for array in host))
        self.out = Outputs(*(to_device(array) for array in _host_outputs(self.batch_size)))
        self.host_params, self.dtype, self._states = params, np.dtype(dtype), None

    @property
    def camera_obs(self):
        """(B, Nc, D_c) device array: every camera's observation after the last reset or step."""
        return self.rows.camera_obs

    @property
    def target_obs(self):
        """(B, Nt, D_t) device array: every target's observation after the last reset or step."""
        return self.rows.target_obs

    def _launch(self, name: str, *flags: bool) -> None:
        grid = (self.batch_size + self.block - 1) // self.block
        groups = {'finish': (self.out,), 'state': (self._states,)}.get(name, ())
        kernels()[name][grid, self.block](*launch_arguments(self.params, self.world, self.rows, *groups), *flags)

    def reset(self, mask=None, seeds: Iterable[int | None] | None = None) -> None:
        """Start new episodes in the games where `mask` (B,) is true (None: all); with `seeds` (one int or None per
        game reset), their random streams start anew from them, as `engine.seed_rows` does on the CPU."""
        mask = self._mask(mask, 'reset')
        if seeds is not None:
            seeds = list(seeds)
            if len(seeds) != mask.sum():
                raise ValueError(f'reset: {mask.sum()} games reset, {len(seeds)} seeds given')
            self.seed(mask, seeds)
        self.rows.mask.copy_to_device(mask)
        self._launch('reset')

    def seed(self, mask, seeds: Iterable[int | None]) -> None:
        """Start the random streams of the games where `mask` (B,) is true anew from `seeds` (one int, or None for
        fresh entropy, per game of the mask), as `engine.seed_rows` does on the CPU; nothing else changes (the
        next reset of those games draws from the new streams)."""
        mask = self._mask(mask, 'seed')
        seeds = list(seeds)
        if len(seeds) != mask.sum():
            raise ValueError(f'seed: {mask.sum()} games seeded, {len(seeds)} seeds given')
        rng = self.world.rng.copy_to_host()
        seed_streams(rng, mask, seeds)
        self.world.rng.copy_to_device(rng)

    def _mask(self, mask, what: str) -> np.ndarray:
        mask = np.ones(self.batch_size, bool) if mask is None else np.asarray(mask, bool)
        if mask.shape != (self.batch_size,):
            raise ValueError(f'{what} mask: expected shape ({self.batch_size},), got {mask.shape}')
        return mask

    def step(self, camera_actions=None, target_actions=None, restart_masked: bool = False) -> None:
        """Advance every game one step with the actions (B, Nc, 2) in degrees (rotation, zoom) and (B, Nt, 2)
        displacements, float64, on the device or the host (copied in); None: the team's actions are in
        `self.rows` already (a device team wrote them there). `restart_masked`: the games of `self.rows.mask` (set
        by `finish`) start their next episode instead, their actions ignored (next-step autoreset)."""
        for name, actions, buffer in (('camera_actions', camera_actions, self.rows.camera_actions),
                                      ('target_actions', target_actions, self.rows.target_actions)):
            if actions is None:
                continue
            if getattr(actions, 'shape', None) != buffer.shape:
                raise ValueError(f'{name}: expected shape {buffer.shape}, got {getattr(actions, "shape", None)}')
            buffer.copy_to_device(actions)
        self._launch('step', bool(restart_masked))

    def finish(self, restart: bool = True) -> None:
        """After a step: copy its rewards, flags and coverage into `self.out`, set `self.rows.mask` to the games
        that ended and, with `restart`, start their next episodes now (their random streams go on, as the CPU
        vector env's autoreset does)."""
        self._launch('finish', bool(restart))

    def state(self):
        """(B, S) device array: every game's global state now (`mate.make_vec(...).state()`'s values, in the
        observations' dtype); one buffer, overwritten by the next call."""
        if self._states is None:
            p = self.host_params
            size = state_dim(p.num_cameras, p.num_targets, p.num_obstacles)
            self._states = States(self.cuda.to_device(np.zeros((self.batch_size, size), self.dtype)))
        self._launch('state')
        return self._states.out

    def reset_masked(self) -> None:
        """Start new episodes in the games `self.rows.mask` holds (set by `finish`), their streams going on, without
        a host copy of the mask."""
        self._launch('reset')

    def world_to_host(self) -> World:
        """A host copy of the world (numpy arrays), for checks and snapshots."""
        return World(*(field.copy_to_host() for field in self.world))
