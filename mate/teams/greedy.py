"""Batched greedy teams: `GreedyCameraAgent` / `GreedyTargetAgent` for every agent of B games at once.

Each team runs the rules of `mate.teams.rules` (the code the Python agents run on their own row) on
(B, N, ...) arrays, messages included: the cameras' responses round (own state once, sightings within
each known teammate's reach, per-(row, sender, recipient) random delays, what cannot be sent dropped)
and the targets' broadcasts of the warehouses they found empty. With the random streams of
`TeamStreams`, row b of a team seeded with s plays draw for draw as `Cls(seed=s + b).spawn(N)`: the
same observations give the same actions, and `play_batch` the same episodes as `mate evaluate`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..messages import Team
from ..spaces import observation_indices_of
from . import rules
from .interface import action_high, as_team
from .streams import TeamStreams, row_seeds

__all__ = ['GreedyCameraTeam', 'GreedyTargetTeam', 'GreedyTeam', 'GREEDY_OPTIONS']

GREEDY_OPTIONS = {
    Team.CAMERA: ('memory_period', 'filterout_unloaded', 'filterout_beyond_range'),
    Team.TARGET: ('noise_scale',),
}
"""The keyword options of each team's greedy agents (and of `GreedyTeam`)."""


def checked_counts(counts) -> tuple[int, int, int]:
    """`counts` as (Nc, Nt, No) ints; ValueError unless three integers, at least one camera and one target."""
    try:
        nc, nt, no = (int(n) for n in counts)
    except (TypeError, ValueError):
        raise ValueError(f'counts must be (num_cameras, num_targets, num_obstacles), got {counts!r}') from None
    if min(nc, nt, no) < 0 or nc < 1 or nt < 1:
        raise ValueError(f'counts must be (num_cameras, num_targets, num_obstacles) with at least one camera '
                         f'and one target, got {(nc, nt, no)}')
    return nc, nt, no


class RuleTeam:
    """What both greedy teams share: sizes, streams, the rows in play, input checks and the refill loop."""

    TEAM: Team

    def __init__(self, num_envs: int, counts, seed: int | Sequence[int] | None) -> None:
        self.team = self.TEAM
        self.num_envs = int(num_envs)
        if self.num_envs < 1:
            raise ValueError(f'num_envs must be at least 1, got {num_envs!r}')
        self.counts = checked_counts(counts)
        self.num_agents = self.counts[0] if self.team is Team.CAMERA else self.counts[1]
        self.indices = observation_indices_of(self.team, *self.counts)
        self.seeds = row_seeds(seed, self.num_envs)
        self.streams = TeamStreams(self.seeds, self.num_agents)
        shape = (self.num_envs, self.num_agents)
        self.active = np.zeros(self.num_envs, dtype=bool)
        self.high = np.zeros(shape + (2,))
        self.action = np.zeros(shape + (2,))
        self.short = np.zeros(shape, dtype=bool)

    def _observation(self, observation) -> np.ndarray:
        observation = np.ascontiguousarray(observation, dtype=np.float64)
        expected = (self.num_envs, self.num_agents, int(self.indices[-1]))
        if observation.shape != expected:
            raise ValueError(f'{type(self).__name__}: observation has shape {observation.shape}, expected {expected} '
                             f'(rows, {self.team.name.lower()}s, dimension)')
        return observation

    def _rows(self, rows) -> np.ndarray:
        rows = np.asarray(rows, dtype=bool)
        if rows.shape != (self.num_envs,):
            raise ValueError(f'{type(self).__name__}: rows must be a ({self.num_envs},) bool mask, '
                             f'got shape {rows.shape}')
        return rows

    def _start(self, observation: np.ndarray, rows: np.ndarray) -> None:
        """The part of `reset` every team does: the agents' action spaces reseeded, the action boxes."""
        self.streams.reset(rows)
        self.high[rows] = action_high(observation[rows], self.team)
        self.action[rows] = 0.0
        self.active |= rows

    def _run(self, kernel, *arguments) -> None:
        """`kernel(todo, *arguments, short)` for every agent of the rows in play, then again for the agents
        whose stream ran out, after refilling exactly those (where their `_draw()` would have refilled)."""
        todo = np.repeat(self.active[:, None], self.num_agents, axis=1)
        self.short[...] = False
        kernel(todo, *arguments, self.short)
        if self.short.any():
            todo = self.short.copy()
            self.streams.refill(todo)
            self.short[...] = False
            kernel(todo, *arguments, self.short)

    def idle(self, rows) -> None:
        """The rows `rows` (B,) bool are out of play until their next reset: no decisions, no draws there."""
        self.active &= ~self._rows(rows)

    def _actions(self) -> np.ndarray:
        return np.where(self.active[:, None, None], self.action, 0.0)

    def state_dict(self) -> dict:
        """Everything the team's future depends on, as plain data: its arrays and its agents' random streams (a
        training run's opponent: exact resumes)."""
        return dict(arrays={name: value.copy() for name, value in vars(self).items()
                            if isinstance(value, np.ndarray) and value.flags.writeable},    # (not the constants)
                    streams=self.streams.state_dict())

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (taken from a team of the same kind, sizes and options)."""
        for name, value in state['arrays'].items():
            getattr(self, name)[...] = value
        self.streams.load_state_dict(state['streams'])


class GreedyCameraTeam(RuleTeam):
    """`GreedyCameraAgent` for every camera of B games (see the module docstring).

    Args:
        num_envs: B.
        counts: (num_cameras, num_targets, num_obstacles) of the game.
        seed: row b plays as `GreedyCameraAgent(seed=s_b).spawn(Nc)`: s_b = seed + b for an integer,
            seed[b] for a sequence of B integers, fresh entropy for None.
        memory_period: steps a sighting stays a candidate (25), as `GreedyCameraAgent`'s.
        filterout_unloaded: ignore targets seen unloaded, unless never seen loaded (False).
        filterout_beyond_range: ignore targets beyond 1.1 x the maximum sight range, and send only
            sightings within a teammate's reach (True; with False no sightings are shared at all).
    """

    TEAM = Team.CAMERA

    def __init__(self, num_envs: int, counts, seed: int | Sequence[int] | None = None, memory_period: int = 25,
                 filterout_unloaded: bool = False, filterout_beyond_range: bool = True) -> None:
        if isinstance(memory_period, bool) or not isinstance(memory_period, (int, np.integer)) or memory_period < 1:
            raise ValueError(f'memory_period must be a positive integer, got {memory_period!r}')
        self.memory_period = int(memory_period)
        self.filterout_unloaded = bool(filterout_unloaded)
        self.filterout_beyond_range = bool(filterout_beyond_range)
        super().__init__(num_envs, counts, seed)
        b, nc, nt = self.num_envs, self.num_agents, self.counts[1]
        self.begin = int(self.indices[2])
        self.memory = np.zeros((b, nc, nt, 4))
        self.time2forget = np.zeros((b, nc, nt), dtype=np.int64)
        self.never_loaded = np.ones((b, nc, nt), dtype=bool)
        self.pending = np.zeros((b, nc, nt), dtype=bool)
        self.pending_state = np.zeros((b, nc), dtype=bool)
        self.own_state = np.zeros((b, nc, 3))
        self.prev_action = np.zeros((b, nc, 2))
        self.delay = np.zeros((b, nc, nc), dtype=np.int64)
        self.known = np.zeros((b, nc, nc), dtype=bool)
        self.neighbour = np.zeros((b, nc, nc, 3))
        self.sent = np.zeros((b, nc, nc), dtype=bool)
        self.sent_state = np.zeros((b, nc), dtype=bool)
        self.sight = np.zeros((b, nc, nc, nt), dtype=bool)
        self.index = np.repeat(np.arange(nc)[None], b, axis=0)

    def reset(self, observation, rows) -> None:
        """Start an episode in the rows `rows` (B,) bool from the cameras' raw observations (B, Nc, D)."""
        observation, rows = self._observation(observation), self._rows(rows)
        self._start(observation, rows)
        rules.camera_reset(observation, self.begin, rows, self.memory_period, self.memory, self.time2forget,
                           self.never_loaded, self.pending, self.pending_state, self.own_state, self.prev_action,
                           self.delay, self.known)

    def act(self, observation) -> np.ndarray:
        """(B, Nc, 2) (rotation, zoom) in degrees: observe, the responses round, act (zeros in rows out of play)."""
        observation, rows, streams = self._observation(observation), self.active, self.streams
        rules.camera_observe(observation, self.begin, rows, self.memory_period, self.memory, self.time2forget,
                             self.never_loaded, self.pending)
        self._run(rules.camera_outbox, self.index, self.memory_period, self.filterout_beyond_range, self.memory,
                  self.pending, self.pending_state, self.delay, self.known, self.neighbour, streams.draws, streams.left,
                  self.sent, self.sent_state, self.sight)
        rules.camera_inbox(observation, self.begin, rows, self.memory_period, self.sent, self.sent_state, self.sight,
                           self.own_state, self.memory, self.time2forget, self.never_loaded, self.known,
                           self.neighbour)
        streams.top_up_space(rows)
        self._run(lambda todo, *rest: rules.camera_act(observation, todo, *rest), self.filterout_unloaded,
                  self.filterout_beyond_range, self.memory, self.time2forget, self.never_loaded, self.high,
                  self.prev_action, streams.draws, streams.left, streams.space, streams.space_left, self.action)
        return self._actions()


class GreedyTargetTeam(RuleTeam):
    """`GreedyTargetAgent` for every target of B games (see the module docstring).

    Args:
        num_envs: B.
        counts: (num_cameras, num_targets, num_obstacles) of the game.
        seed: row b plays as `GreedyTargetAgent(seed=s_b).spawn(Nt)`: s_b = seed + b for an integer,
            seed[b] for a sequence of B integers, fresh entropy for None.
        noise_scale: as `GreedyTargetAgent`'s (0.5).
    """

    TEAM = Team.TARGET

    def __init__(self, num_envs: int, counts, seed: int | Sequence[int] | None = None,
                 noise_scale: float = 0.5) -> None:
        try:
            self.noise_scale = float(noise_scale)
        except (TypeError, ValueError):
            raise ValueError(f'noise_scale must be a finite number, got {noise_scale!r}') from None
        if not np.isfinite(self.noise_scale):
            raise ValueError(f'noise_scale must be a finite number, got {noise_scale!r}')
        super().__init__(num_envs, counts, seed)
        shape = (self.num_envs, self.num_agents)
        self.goal_bits = np.zeros(shape + (4,))
        self.non_empty = np.ones(shape + (4,), dtype=bool)
        self.need_communication = np.zeros(shape, dtype=bool)
        self.prev_location = np.zeros(shape + (2,))
        self.noise = np.zeros(shape + (2,))

    def reset(self, observation, rows) -> None:
        """Start an episode in the rows `rows` (B,) bool from the targets' raw observations (B, Nt, D)."""
        observation, rows = self._observation(observation), self._rows(rows)
        self._start(observation, rows)
        self.streams.top_up_space(rows)
        rules.walk_start(observation, rows, self.high, self.prev_location, self.noise, self.streams.space,
                         self.streams.space_left)
        rules.target_reset(observation, rows, self.goal_bits, self.non_empty, self.need_communication)

    def act(self, observation) -> np.ndarray:
        """(B, Nt, 2) moves: observe, the responses round, act (zeros in rows out of play)."""
        observation, rows, streams = self._observation(observation), self.active, self.streams
        rules.target_observe(observation, rows, self.non_empty, self.need_communication)
        rules.target_share(rows, self.non_empty, self.need_communication)
        streams.top_up_space(rows)
        self._run(lambda todo, *rest: rules.target_act(observation, todo, *rest), self.noise_scale, self.goal_bits,
                  self.non_empty, self.high, self.prev_location, self.noise, streams.draws, streams.left,
                  streams.space, streams.space_left, self.action)
        return self._actions()


def GreedyTeam(team, num_envs: int, counts, seed: int | Sequence[int] | None = None, **options):
    """The batched greedy agents of `team` (Team.CAMERA / Team.TARGET or 'camera' / 'target'):
    a `GreedyCameraTeam` or a `GreedyTargetTeam` for `num_envs` games of `counts` =
    (num_cameras, num_targets, num_obstacles), row b seeded as `Cls(seed=seed + b).spawn(N)`.
    `options` are the agents' (`GREEDY_OPTIONS`); ValueError (one line) for any other."""
    team = as_team(team)
    unknown = sorted(set(options) - set(GREEDY_OPTIONS[team]))
    if unknown:
        raise ValueError(f'unknown option(s) {", ".join(unknown)} for the greedy {team.name.lower()}s; '
                         f'they take {", ".join(GREEDY_OPTIONS[team])}')
    cls = GreedyCameraTeam if team is Team.CAMERA else GreedyTargetTeam
    return cls(num_envs, counts, seed=seed, **options)
