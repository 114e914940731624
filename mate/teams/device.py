"""The rule teams as data, for games on a CUDA device: greedy and random teams and the HRL executor, one thread a game.

A team here is a `DeviceTeam`: its settings (a named tuple of numbers) and its state (a named tuple of (B, N, ...)
arrays, on the device or on the host), and two row functions, `reset` and `act`, that call the row functions of
`mate.teams.rules` (the rules the CPU teams and the Python agents run) on game b. A CUDA kernel runs them with one
thread per game (`DeviceTeam.reset` / `act` on device arrays); `host_reset` / `host_act` run the very same row
functions in a compiled loop on the host: the reference the device is checked against (tests/teams/test_device_teams.py,
under numba's CUDA simulator), and what measures the teams' play without a GPU.

Random numbers. The CPU teams replay the numpy generators of the Python agents (`TeamStreams`: one PCG64 generator an
agent, refilled from Python), which a GPU thread cannot call. Here every agent has two counter-based streams, its own
and its action space's (`mate.core.rng.uniform`: SplitMix64 over a key and a counter, (B x N, 2) uint64 arrays), that
fill the same stacks the rules take numbers from, topped up before each rule runs: the own stack to at least
`AGENT_BLOCK` numbers (a sender needs at most Nc - 1 for its messages' delays, a target 2), the action-space stack to at
least 2. So no rule is ever short of numbers and the refill loop of the CPU teams is not needed. The keys come from
the row seeds (row b: seed + b) by a SplitMix64 hash of (row seed, agent, stream). These teams play the same game as
the CPU teams with other random numbers: their results agree in distribution, not draw for draw
(benchmarks/gpu.py and the tests compare coverage over many seeds). A row that restarts goes on with its streams.

HRL executor: `hrl_actions(observation, selection, begin, out)` aims every camera at the centroid of the selected
visible targets (`mate.teams.rules.centroid_aim_row`, the rule `mate.policies.hrl` runs on the host).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numba import njit

from ..constants import PRESERVED_DIM
from ..core.device import BLOCK, assumed_compute_capability, cuda_module, launch_arguments
from ..core.rng import mix64, uniform
from ..messages import Team
from ..spaces import observation_indices_of
from . import rules
from .interface import as_team
from .streams import AGENT_BLOCK, SPACE_BLOCK, row_seeds

__all__ = ['CameraSettings', 'CameraState', 'DeviceRuleTeam', 'DeviceTeam', 'HostTeam', 'RandomSettings',
           'RandomState', 'TargetSettings', 'TargetState', 'compile_hrl_ptx', 'compile_ptx', 'device_team', 'host_act',
           'host_reset', 'hrl_actions', 'stream_keys', 'top_up_row']

OWN = PRESERVED_DIM
_GAMMA, _ODD = np.uint64(0x9E3779B97F4A7C15), np.uint64(0xBF58476D1CE4E5B9)
_MASK = (1 << 64) - 1


def stream_keys(seeds: Sequence[int], num_agents: int, stream: int) -> np.ndarray:
    """(B x N, 2) uint64 counter streams (key, counter 0): agent i of row b, stream 0 (its own) or 1 (its action
    space), keyed by a SplitMix64 hash (`mate.core.rng.mix64`) of (seeds[b], i, stream)."""
    seeds = np.asarray([int(s) & _MASK for s in seeds], dtype=np.uint64)
    agents = np.arange(num_agents, dtype=np.uint64)
    with np.errstate(over='ignore'):
        mixed = mix64(seeds[:, None] * _GAMMA + np.uint64(1))
        mixed = mix64(mixed ^ ((agents[None, :] * np.uint64(2) + np.uint64(stream) + np.uint64(1)) * _ODD))
    keys = np.zeros((len(seeds) * num_agents, 2), dtype=np.uint64)
    keys[:, 0] = mixed.reshape(-1)
    return keys


@njit(cache=True)
def top_up_row(b, rng, stack, left, block, least) -> None:
    """Agent (b, i)'s stack (`stack` (B, N, 2 block), `left` (B, N)) gets a block of its counter stream
    (`rng[b N + i]`) under the numbers it holds whenever it holds fewer than `least`."""
    num_agents = left.shape[1]
    for i in range(num_agents):
        held = left[b, i]
        if held >= least:
            continue
        for j in range(held - 1, -1, -1):
            stack[b, i, block + j] = stack[b, i, j]
        for j in range(block):
            stack[b, i, j] = uniform(rng, b * num_agents + i)
        left[b, i] = held + block


@njit(cache=True)
def _start_row(b, state, observation, camera) -> None:
    """What every team does when game b starts: in play, its action boxes from the observation, zero actions."""
    state.active[b] = True
    for i in range(state.high.shape[1]):
        if camera:
            state.high[b, i, 0] = observation[b, i, OWN + 7]
            state.high[b, i, 1] = observation[b, i, OWN + 8]
        else:
            state.high[b, i, 0] = observation[b, i, OWN + 4]
            state.high[b, i, 1] = observation[b, i, OWN + 4]
        state.action[b, i, 0] = 0.0
        state.action[b, i, 1] = 0.0
        state.todo[b, i] = True


@njit(cache=True)
def _idle_row(b, state) -> bool:
    """Zero actions for game b when its team is out of play; whether it is."""
    if state.active[b]:
        return False
    for i in range(state.action.shape[1]):
        state.action[b, i, 0] = 0.0
        state.action[b, i, 1] = 0.0
    return True


# ---------------------------------------------------------------------------- greedy cameras

class CameraSettings(NamedTuple):
    """The greedy cameras' options (`GreedyCameraTeam`'s) and where the target records begin in an observation."""

    begin: int
    memory_period: int
    filterout_unloaded: bool
    filterout_beyond_range: bool


class CameraState(NamedTuple):
    """The greedy cameras of B games: the arrays of `GreedyCameraTeam` and of its streams (B: games, N: cameras,
    Nt: targets)."""

    active: object          # (B,) bool: in play since its last reset
    high: object            # (B, N, 2) the action box (rotation step, zooming step), degrees
    action: object          # (B, N, 2) the last actions
    todo: object            # (B, N) bool, all true: every camera acts
    short: object           # (B, N) bool, never set (the stacks are topped up first)
    team_index: object      # (B, N) int64: each camera's index in its team (a tuple has .index)
    memory: object          # (B, N, Nt, 4)
    time2forget: object     # (B, N, Nt) int64
    never_loaded: object    # (B, N, Nt) bool
    pending: object         # (B, N, Nt) bool
    pending_state: object   # (B, N) bool
    own_state: object       # (B, N, 3)
    prev_action: object     # (B, N, 2)
    delay: object           # (B, N, N) int64
    known: object           # (B, N, N) bool
    neighbour: object       # (B, N, N, 3)
    sent: object            # (B, N, N) bool
    sent_state: object      # (B, N) bool
    sight: object           # (B, N, N, Nt) bool
    draws: object           # (B, N, 2 AGENT_BLOCK) the own stacks
    left: object            # (B, N) int64
    space: object           # (B, N, 2 SPACE_BLOCK) the action-space stacks
    space_left: object      # (B, N) int64
    own_rng: object         # (B N, 2) uint64
    space_rng: object       # (B N, 2) uint64


@njit(cache=True)
def camera_reset_row(b, settings, state, observation, mask) -> None:
    """Game b (if `mask[b]`) starts an episode for the greedy cameras (`GreedyCameraTeam.reset`)."""
    if not mask[b]:
        return
    _start_row(b, state, observation, True)
    rules.camera_reset_row(b, observation, settings.begin, settings.memory_period, state.memory, state.time2forget,
                           state.never_loaded, state.pending, state.pending_state, state.own_state, state.prev_action,
                           state.delay, state.known)


@njit(cache=True)
def camera_act_row(b, settings, state, observation, mask) -> None:
    """The greedy cameras of game b observe, exchange messages and act (`GreedyCameraTeam.act`) into `state.action`."""
    if not mask[b] or _idle_row(b, state):
        return
    s = state
    rules.camera_observe_row(b, observation, settings.begin, settings.memory_period, s.memory, s.time2forget,
                             s.never_loaded, s.pending)
    top_up_row(b, s.own_rng, s.draws, s.left, AGENT_BLOCK, AGENT_BLOCK)
    rules.camera_outbox_row(b, s.todo, s.team_index, settings.memory_period, settings.filterout_beyond_range, s.memory,
                            s.pending, s.pending_state, s.delay, s.known, s.neighbour, s.draws, s.left, s.sent,
                            s.sent_state, s.sight, s.short)
    rules.camera_inbox_row(b, observation, settings.begin, settings.memory_period, s.sent, s.sent_state, s.sight,
                           s.own_state, s.memory, s.time2forget, s.never_loaded, s.known, s.neighbour)
    top_up_row(b, s.own_rng, s.draws, s.left, AGENT_BLOCK, 1)
    top_up_row(b, s.space_rng, s.space, s.space_left, SPACE_BLOCK, 2)
    rules.camera_act_row(b, observation, s.todo, settings.filterout_unloaded, settings.filterout_beyond_range,
                         s.memory, s.time2forget, s.never_loaded, s.high, s.prev_action, s.draws, s.left, s.space,
                         s.space_left, s.action, s.short)


# ---------------------------------------------------------------------------- greedy targets

class TargetSettings(NamedTuple):
    """The greedy targets' option (`GreedyTargetTeam`'s)."""

    noise_scale: float


class TargetState(NamedTuple):
    """The greedy targets of B games: the arrays of `GreedyTargetTeam` and of its streams (N: targets)."""

    active: object              # (B,) bool
    high: object                # (B, N, 2) the action box (step size, step size)
    action: object              # (B, N, 2)
    todo: object                # (B, N) bool, all true
    short: object               # (B, N) bool, never set
    goal_bits: object           # (B, N, 4)
    non_empty: object           # (B, N, 4) bool
    need_communication: object  # (B, N) bool
    prev_location: object       # (B, N, 2)
    noise: object               # (B, N, 2)
    draws: object               # (B, N, 2 AGENT_BLOCK)
    left: object                # (B, N) int64
    space: object               # (B, N, 2 SPACE_BLOCK)
    space_left: object          # (B, N) int64
    own_rng: object             # (B N, 2) uint64
    space_rng: object           # (B N, 2) uint64


@njit(cache=True)
def target_reset_row(b, settings, state, observation, mask) -> None:
    """Game b (if `mask[b]`) starts an episode for the greedy targets (`GreedyTargetTeam.reset`)."""
    if not mask[b]:
        return
    s = state
    _start_row(b, s, observation, False)
    top_up_row(b, s.space_rng, s.space, s.space_left, SPACE_BLOCK, 2)
    rules.walk_start_row(b, observation, s.high, s.prev_location, s.noise, s.space, s.space_left)
    rules.target_reset_row(b, observation, s.goal_bits, s.non_empty, s.need_communication)


@njit(cache=True)
def target_act_row(b, settings, state, observation, mask) -> None:
    """The greedy targets of game b observe, share what they found and move (`GreedyTargetTeam.act`)."""
    if not mask[b] or _idle_row(b, state):
        return
    s = state
    rules.target_observe_row(b, observation, s.non_empty, s.need_communication)
    rules.target_share_row(b, s.non_empty, s.need_communication)
    top_up_row(b, s.own_rng, s.draws, s.left, AGENT_BLOCK, 2)
    top_up_row(b, s.space_rng, s.space, s.space_left, SPACE_BLOCK, 2)
    rules.target_act_row(b, observation, s.todo, settings.noise_scale, s.goal_bits, s.non_empty, s.high,
                         s.prev_location, s.noise, s.draws, s.left, s.space, s.space_left, s.action, s.short)


# ---------------------------------------------------------------------------- random agents

class RandomSettings(NamedTuple):
    """The random agents' option, and whose action boxes they draw from."""

    frame_skip: int
    camera: bool


class RandomState(NamedTuple):
    """The random agents of B games (`RandomTeam`'s arrays, its action-space streams)."""

    active: object          # (B,) bool
    high: object            # (B, N, 2)
    action: object          # (B, N, 2) held for frame_skip steps
    todo: object            # (B, N) bool, all true
    step: object            # (B,) int64: steps of the episode so far
    space: object           # (B, N, 2 SPACE_BLOCK)
    space_left: object      # (B, N) int64
    space_rng: object       # (B N, 2) uint64


@njit(cache=True)
def random_reset_row(b, settings, state, observation, mask) -> None:
    """Game b (if `mask[b]`) starts an episode for the random agents."""
    if mask[b]:
        _start_row(b, state, observation, settings.camera)
        state.step[b] = 0


@njit(cache=True)
def random_act_row(b, settings, state, observation, mask) -> None:
    """A fresh uniform action for every agent of game b at steps 0, frame_skip, ..., held in between."""
    if not mask[b] or _idle_row(b, state):
        return
    if state.step[b] % settings.frame_skip == 0:
        top_up_row(b, state.space_rng, state.space, state.space_left, SPACE_BLOCK, 2)
        rules.random_act_row(b, state.todo, state.high, state.space, state.space_left, state.action)
    state.step[b] += 1


# ---------------------------------------------------------------------------- the teams

ROW_FUNCTIONS = {'greedy-camera': (camera_reset_row, camera_act_row),
                 'greedy-target': (target_reset_row, target_act_row),
                 'random-camera': (random_reset_row, random_act_row),
                 'random-target': (random_reset_row, random_act_row)}
"""(reset, act) row functions of each team kind: f(b, settings, state, observation (B, N, D), mask (B,))."""


class DeviceTeam(NamedTuple):
    """A rule team of B games as data: `kind` ('greedy-camera', 'greedy-target', 'random-camera', 'random-target'),
    its settings and its state (host numpy arrays, or device arrays after `to_device`)."""

    kind: str
    settings: tuple
    state: tuple

    @property
    def team(self) -> Team:
        return Team.CAMERA if self.kind.endswith('camera') else Team.TARGET

    @property
    def action(self):
        """(B, N, 2) float64: the actions of the last `act` (zeros in games out of play)."""
        return self.state.action

    def to_device(self) -> DeviceTeam:
        """The same team with its state copied to the current CUDA device."""
        to_device = cuda_module().to_device
        return self._replace(state=type(self.state)(*(to_device(array) for array in self.state)))

    def reset(self, observation, mask, block: int = BLOCK) -> None:
        """Device arrays: the games of `mask` (B,) bool start an episode from `observation` (B, N, D), a kernel
        (`block` threads a block)."""
        _launch(ROW_FUNCTIONS[self.kind][0], self.settings, self.state, observation, mask, block)

    def act(self, observation, mask, block: int = BLOCK) -> None:
        """Device arrays: every game of `mask` (B,) bool decides its actions into `self.action`, a kernel."""
        _launch(ROW_FUNCTIONS[self.kind][1], self.settings, self.state, observation, mask, block)


def device_team(name: str, team, num_envs: int, counts, seed: int | Sequence[int] | None = None,
                **options) -> DeviceTeam:
    """The team of the built-in agent `name` ('greedy' or 'random') for `team` of `num_envs` games of `counts`
    = (num_cameras, num_targets, num_obstacles), with host arrays (`.to_device()` moves them); row b seeded with
    seed + b. `options`: the agents' (`GREEDY_OPTIONS`, `frame_skip` for random); ValueError (one line) otherwise."""
    team = as_team(team)
    nc, nt, no = (int(n) for n in counts)
    B = int(num_envs)
    if B < 1:
        raise ValueError(f'num_envs must be at least 1, got {num_envs!r}')
    n = nc if team is Team.CAMERA else nt
    seeds = row_seeds(seed, B)
    side = team.name.lower()
    common = dict(active=np.zeros(B, bool), high=np.zeros((B, n, 2)), action=np.zeros((B, n, 2)),
                  todo=np.ones((B, n), bool))
    space = dict(space=np.zeros((B, n, 2 * SPACE_BLOCK)), space_left=np.zeros((B, n), np.int64),
                 space_rng=stream_keys(seeds, n, 1))
    if name == 'random':
        unknown = sorted(set(options) - {'frame_skip'})
        frame_skip = options.get('frame_skip', 20)
        if unknown:
            raise ValueError(f'unknown option(s) {", ".join(unknown)} for the random agents; they take frame_skip')
        if isinstance(frame_skip, bool) or not isinstance(frame_skip, (int, np.integer)) or frame_skip < 1:
            raise ValueError(f'frame_skip must be a positive integer, got {frame_skip!r}')
        return DeviceTeam(f'random-{side}', RandomSettings(int(frame_skip), team is Team.CAMERA),
                          RandomState(**common, step=np.zeros(B, np.int64), **space))
    if name != 'greedy':
        raise ValueError(f'agent {name!r} has no device team; these have: greedy, random')
    from .greedy import GreedyCameraTeam, GreedyTargetTeam, GreedyTeam

    checked = GreedyTeam(team, 1, counts, seed=0, **options)      # the CPU team's checks of the options
    own = dict(short=np.zeros((B, n), bool), draws=np.zeros((B, n, 2 * AGENT_BLOCK)),
               left=np.zeros((B, n), np.int64), own_rng=stream_keys(seeds, n, 0))
    if isinstance(checked, GreedyTargetTeam):
        return DeviceTeam('greedy-target', TargetSettings(checked.noise_scale), TargetState(
            **common, short=own['short'], goal_bits=np.zeros((B, n, 4)), non_empty=np.ones((B, n, 4), bool),
            need_communication=np.zeros((B, n), bool), prev_location=np.zeros((B, n, 2)), noise=np.zeros((B, n, 2)),
            draws=own['draws'], left=own['left'], space=space['space'], space_left=space['space_left'],
            own_rng=own['own_rng'], space_rng=space['space_rng']))
    assert isinstance(checked, GreedyCameraTeam)
    if nc - 1 > AGENT_BLOCK:
        raise ValueError(f'the greedy device cameras take at most {AGENT_BLOCK + 1} cameras, got {nc}')
    begin = int(observation_indices_of(Team.CAMERA, nc, nt, no)[2])
    settings = CameraSettings(begin, checked.memory_period, checked.filterout_unloaded, checked.filterout_beyond_range)
    return DeviceTeam('greedy-camera', settings, CameraState(
        **{k: common[k] for k in ('active', 'high', 'action', 'todo')}, short=own['short'],
        team_index=np.repeat(np.arange(n)[None], B, axis=0), memory=np.zeros((B, n, nt, 4)),
        time2forget=np.zeros((B, n, nt), np.int64), never_loaded=np.ones((B, n, nt), bool),
        pending=np.zeros((B, n, nt), bool), pending_state=np.zeros((B, n), bool), own_state=np.zeros((B, n, 3)),
        prev_action=np.zeros((B, n, 2)), delay=np.zeros((B, n, n), np.int64), known=np.zeros((B, n, n), bool),
        neighbour=np.zeros((B, n, n, 3)), sent=np.zeros((B, n, n), bool), sent_state=np.zeros((B, n), bool),
        sight=np.zeros((B, n, n, nt), bool), draws=own['draws'], left=own['left'], space=space['space'],
        space_left=space['space_left'], own_rng=own['own_rng'], space_rng=space['space_rng']))


# ---------------------------------------------------------------------------- running the rows

class HostTeam:
    """A `DeviceTeam` run on the host (`host_reset` / `host_act`) behind the batched-team protocol of
    `mate.teams` (`reset(observation, rows)`, `act(observation)`, `idle(rows)`): the device's rules and random
    streams where no GPU is, e.g. in `play_batch` (how their play is compared with the CPU teams')."""

    def __init__(self, name: str, team, num_envs: int, counts, seed: int | Sequence[int] | None = None,
                 **options) -> None:
        self.device_team = device_team(name, team, num_envs, counts, seed=seed, **options)
        self.team = self.device_team.team

    def reset(self, observation, rows) -> None:
        host_reset(self.device_team, np.asarray(observation, np.float64), rows)

    def act(self, observation) -> np.ndarray:
        return host_act(self.device_team, np.asarray(observation, np.float64)).copy()

    def idle(self, rows) -> None:
        self.device_team.state.active[np.asarray(rows, bool)] = False

    def state_dict(self) -> dict:
        """The team's arrays, its random streams included (plain data: exact resumes)."""
        state = self.device_team.state
        return {name: array.copy() for name, array in zip(state._fields, state)}

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (a team of the same kind and sizes)."""
        for name, array in zip(self.device_team.state._fields, self.device_team.state):
            array[...] = state[name]


class DeviceRuleTeam:
    """A `DeviceTeam` on the CUDA device behind the batched-team protocol of `mate.teams` (`reset(observation,
    rows)`, `act(observation)`, `idle(rows)`, `state_dict()`), torch tensors in and out: what plays the other team of
    `mate.make_team_vec(..., device='cuda')`, and what a loop of the researcher's plays on the device as it plays a
    `mate.teams` team on the CPU. Its state stays on the device; `act` launches one thread a game and returns the
    team's action buffer (B, N, 2) float64 (a tensor viewing it, overwritten by the next `act`).

    Args:
        name: 'greedy' or 'random'.
        team: 'camera' or 'target'.
        num_envs: B.
        counts: (Nc, Nt, No) of the game.
        seed: row b seeded with seed + b (None: fresh entropy), or one seed per row.
        block: threads per CUDA block.
        **options: the agents' options (`device_team`).
    """

    def __init__(self, name: str, team, num_envs: int, counts, seed: int | Sequence[int] | None = None,
                 block: int = BLOCK, **options) -> None:
        from ..core.device import to_torch

        self.device_team = device_team(name, team, num_envs, counts, seed=seed, **options).to_device()
        self.team, self.block = self.device_team.team, int(block)
        self._every = cuda_module().to_device(np.ones(int(num_envs), bool))
        self._action = to_torch(self.device_team.state.action)

    def reset(self, observation, rows) -> None:
        """The games of `rows` (B,) bool start an episode from `observation` (B, N, D) (tensors on the device)."""
        from ..core.device import from_torch

        self.device_team.reset(from_torch(observation.contiguous()), from_torch(_device_mask(rows, observation)),
                               self.block)

    def act(self, observation):
        """Every game's actions (B, N, 2) float64 from `observation` (B, N, D): the team's buffer, as a tensor."""
        from ..core.device import from_torch

        self.device_team.act(from_torch(observation.contiguous()), self._every, self.block)
        return self._action

    def idle(self, rows) -> None:
        """The games of `rows` (B,) bool are out of play until their next reset."""
        from ..core.device import to_torch

        to_torch(self.device_team.state.active).masked_fill_(_device_mask(rows, self._action), False)

    def state_dict(self) -> dict:
        """The team's arrays, its random streams included, as host numpy arrays (exact resumes)."""
        state = self.device_team.state
        return {name: array.copy_to_host() for name, array in zip(state._fields, state)}

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (a team of the same kind and sizes)."""
        for name, array in zip(self.device_team.state._fields, self.device_team.state):
            array.copy_to_device(np.ascontiguousarray(state[name]))


def _device_mask(rows, like):
    """(B,) bool `rows` (a tensor or a host array) as a contiguous bool tensor on `like`'s device."""
    import torch

    return torch.as_tensor(rows, dtype=torch.bool, device=like.device).contiguous()


@functools.cache
def _host_loop(row):
    """A compiled loop over the games calling `row` (the host twin of a kernel)."""
    @njit
    def loop(settings, state, observation, mask):
        for b in range(mask.shape[0]):
            row(b, settings, state, observation, mask)
    return loop


def host_reset(team: DeviceTeam, observation: np.ndarray, mask: np.ndarray) -> None:
    """`DeviceTeam.reset` on host arrays: the same row function in a compiled loop."""
    _host_loop(ROW_FUNCTIONS[team.kind][0])(team.settings, team.state, np.ascontiguousarray(observation),
                                            np.asarray(mask, bool))


def host_act(team: DeviceTeam, observation: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """`DeviceTeam.act` on host arrays; returns the team's actions (B, N, 2) (its own array)."""
    mask = np.ones(team.state.active.shape[0], bool) if mask is None else np.asarray(mask, bool)
    _host_loop(ROW_FUNCTIONS[team.kind][1])(team.settings, team.state, np.ascontiguousarray(observation), mask)
    return team.state.action


cuda = None
"""numba.cuda once a kernel was made: the kernels read `cuda.grid` from this module's globals, where numba's CUDA
simulator finds it too."""


def _cuda():
    global cuda
    cuda = cuda_module()
    return cuda


@functools.cache
def row_kernel(row):
    """A CUDA kernel whose thread b runs `row(b, settings, state, observation, mask)` for b < B."""
    _cuda()

    def kernel(settings, state, inputs):
        b = cuda.grid(1)
        if b < inputs.mask.shape[0]:
            row(b, settings, state, inputs.observation, inputs.mask)
    return cuda.jit(kernel)


class Inputs(NamedTuple):
    """A kernel's observations (B, N, D) and mask (B,) (one named tuple: numba's CUDA simulator hands the arrays of a
    named tuple to the row functions as they are)."""

    observation: object
    mask: object


def _launch(row, settings, state, observation, mask, block: int) -> None:
    count = mask.shape[0]
    row_kernel(row)[(count + block - 1) // block, block](*launch_arguments(settings, state, Inputs(observation, mask)))


def compile_ptx(kind: str, which: str, counts=(4, 8, 9), observation_dtype=np.float64,
                cc: tuple[int, int] = (9, 0)) -> str:
    """The PTX of the `which` ('reset' or 'act') kernel of the team `kind` (a key of `ROW_FUNCTIONS`) for compute
    capability `cc`; needs no GPU (numba-cuda with NVVM): what CI checks."""
    from numba import typeof

    name, side = kind.split('-')
    team = device_team(name, side, 2, counts, seed=0)
    count = counts[0] if side == 'camera' else counts[1]
    inputs = Inputs(np.zeros((2, count, 1), observation_dtype), np.ones(2, bool))
    row = ROW_FUNCTIONS[kind][('reset', 'act').index(which)]
    kernel = row_kernel(row)
    signature = tuple(typeof(argument) for argument in (team.settings, team.state, inputs))
    with assumed_compute_capability(cc):
        ptx, _ = cuda.compile_ptx(kernel.py_func, signature, cc=cc)
    return ptx


# ---------------------------------------------------------------------------- the HRL executor

@functools.cache
def _hrl_kernel():
    _cuda()
    aim_row = rules.centroid_aim_row

    def kernel(arrays, begin):
        r = cuda.grid(1)
        if r < arrays.out.shape[0]:
            aim_row(r, arrays.observation, arrays.keep, begin, arrays.keep.shape[1], arrays.out)
    return cuda.jit(kernel)


class HRLArrays(NamedTuple):
    """The HRL executor kernel's camera observations (R, D), keep bits (R, Nt) bool and actions (R, 2)."""

    observation: object
    keep: object
    out: object


def compile_hrl_ptx(observation_dtype=np.float64, cc: tuple[int, int] = (9, 0)) -> str:
    """The PTX of the HRL executor kernel for compute capability `cc` (no GPU needed)."""
    from numba import typeof

    kernel = _hrl_kernel()
    arrays = HRLArrays(np.zeros((2, 1), observation_dtype), np.zeros((2, 8), bool), np.zeros((2, 2)))
    with assumed_compute_capability(cc):
        ptx, _ = cuda.compile_ptx(kernel.py_func, (typeof(arrays), typeof(0)), cc=cc)
    return ptx


def hrl_actions(observation, keep, begin: int, out, block: int = BLOCK) -> None:
    """Device arrays: the HRL executor's actions (R, 2) into `out` from camera observations (R, D) and keep bits
    (R, Nt) bool (R = B x Nc rows), one thread a camera (`mate.policies.hrl.executor_actions` on the host)."""
    count = out.shape[0]
    _hrl_kernel()[(count + block - 1) // block, block](*launch_arguments(HRLArrays(observation, keep, out)), begin)
