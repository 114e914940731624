"""Upper-bound cameras: a centralised camera team that sees the true state and plans its poses ahead.

A reference for how much of the targets a camera team can cover, not a learner. It reads what no
camera of the game reads: every target's true position every step (and every obstacle), and it
decides for the whole team at once, with no messages. The decision rule, `plan`, is written once,
compiled, on arrays with a leading batch axis (B, ...): `UpperBoundTeam` calls it on B games and
`mate.agents.UpperBoundCameraAgent` on its own game (every camera computes the team's plan from its
fully observing observation and plays its own part), so both play the same episodes for the same seeds.

The rule, each step and in each game:

1. Prediction: every target keeps the velocity of its last step (the difference of its last two true
   positions; 0 at the first step), clipped to the terrain, at the look-ahead times of
   `lookahead_times(horizon, discount)`: 1, 2, ..., 8 steps, then about 1.3 x apart up to `horizon`.
2. Candidate aims per camera (orientation, viewing angle in degrees): hold the current pose; the last
   step's aim; for each target within the maximum sight range, its predicted bearing at the time the
   camera has turned there, with the widest viewing angle whose sight range reaches it (distance x
   `RANGE_MARGIN`); for each pair of targets, the middle of their bearings with the widest viewing
   angle that reaches both, when that angle spans both with `ANGLE_MARGIN` to spare on each side.
3. Each aim is followed at full speed within the per-step limits (the rotation and zoom steps of the
   action box, viewing angle clipped to [theta_min, 180], constant sector area theta R^2); at each
   look-ahead time it covers the predicted targets inside the sector (the env's in-sector test) and not
   occluded (the env's exact segment-disc test, with the obstacles closer than max sight range + radius).
4. Assignment: the joint choice (one aim per camera) maximising the sum over look-ahead times of
   weight(time) x the number of distinct targets covered, weight = the steps a time stands for x
   `discount` ** time. Coordinate ascent (each camera in turn takes its best aim given the others, until
   nothing changes, at most `MAX_PASSES` passes) from 1 + Nc starts: the last step's aims, and a greedy
   pass (camera by camera, each adding the most targets not yet covered) from each camera in turn; the
   best is kept (the first on ties).
5. Action: one step towards the chosen aim, clipped to the action box.

Occluded targets count as not covered (an env with obstacle transmittance tau > 0 still sees them with
probability tau: the plan does not count on it). Everything is deterministic.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from ..constants import (
    CAMERA_STATE_DIM_PRIVATE,
    CAMERA_STATE_DIM_PUBLIC,
    MAX_CAMERA_VIEWING_ANGLE,
    OBSTACLE_STATE_DIM,
    PRESERVED_DIM,
    TARGET_STATE_DIM_PRIVATE,
    TARGET_STATE_DIM_PUBLIC,
    TERRAIN_SIZE,
)
from ..core.perception import disc_hides
from ..messages import Team
from ..spaces import camera_observation_indices_of
from .greedy import checked_counts

__all__ = ['UpperBoundTeam', 'UPPER_BOUND_OPTIONS', 'lookahead_times', 'plan', 'camera_records', 'teammate_records',
           'target_records', 'obstacle_records', 'check_full_view']

HORIZON = 40
"""Default look-ahead of the plan (env steps)."""
DISCOUNT = 0.9
"""Default discount per step of the look-ahead's weights."""
RANGE_MARGIN = 1.1
"""An aim at a target keeps its predicted distance within sight range / 1.1."""
ANGLE_MARGIN = 2.5
"""An aim at a pair of targets keeps each this many degrees inside the sector's edges."""
MAX_PASSES = 4
"""Coordinate-ascent passes over the cameras (the ascent stops earlier when nothing changes)."""
MAX_TARGETS = 63
"""The plan keeps the targets a pose covers as the bits of one int64."""
UPPER_BOUND_OPTIONS = ('horizon', 'discount')
"""The keyword options of `UpperBoundTeam` and `mate.agents.UpperBoundCameraAgent`."""

_RAD2DEG = 180.0 / math.pi
_OWN = PRESERVED_DIM
_CAMERA_FIELDS = np.array([0, 1, 3, 4, 5])   # x, y, R_s cos phi, R_s sin phi, theta in a camera state


def lookahead_times(horizon: int = HORIZON, discount: float = DISCOUNT) -> tuple[np.ndarray, np.ndarray]:
    """The look-ahead of a plan: (times (T,) int64, weights (T,) float64).

    Times (env steps): every step up to 8, then about 1.3 x the previous time, up to `horizon` (40: 15 times).
    Each time weighs the steps it stands for (half the gaps to its neighbours) x `discount` ** time, so the
    score is about the discounted sum of the coverage over the next `horizon` steps. ValueError for a horizon
    below 1 or a discount outside (0, 1].
    """
    horizon, discount = _options(horizon, discount)
    times = list(range(1, min(horizon, 8) + 1))
    while times[-1] < horizon:
        times.append(min(horizon, max(times[-1] + 1, int(round(times[-1] * 1.3)))))
    times = np.array(times, dtype=np.int64)
    edges = np.concatenate([[0.5], (times[1:] + times[:-1]) / 2.0, [times[-1] + 0.5]])
    return times, np.diff(edges) * discount ** times.astype(np.float64)


def _options(horizon, discount) -> tuple[int, float]:
    if isinstance(horizon, bool) or not isinstance(horizon, (int, np.integer)) or horizon < 1:
        raise ValueError(f'horizon must be a positive integer (env steps), got {horizon!r}')
    try:
        discount = float(discount)
    except (TypeError, ValueError):
        discount = math.nan
    if not 0.0 < discount <= 1.0:
        raise ValueError(f'discount must be a number in (0, 1], got {discount!r}')
    return int(horizon), discount


# ---------------------------------------------------------------------------- the rule (compiled)

@njit(cache=True)
def _wrap(angle):
    """Degrees into [-180, 180)."""
    return (angle + 180.0) % 360.0 - 180.0


@njit(cache=True)
def _occluded(cx, cy, max_range, obstacles, b, x, y):
    """Whether an obstacle disc hides (x, y) from a camera at (cx, cy): the env's exact test
    (`mate.core.perception.is_occluded`) over the obstacles with flag 1 whose centre is closer than
    max_range + radius (those the env flags for the camera at reset)."""
    dx, dy = x - cx, y - cy
    dist = math.sqrt(dx * dx + dy * dy)
    for o in range(obstacles.shape[1]):
        if obstacles[b, o, 3] == 0.0:
            continue
        r = obstacles[b, o, 2]
        ox, oy = obstacles[b, o, 0] - cx, obstacles[b, o, 1] - cy
        if math.sqrt(ox * ox + oy * oy) < max_range + r and disc_hides(dx, dy, dist, ox, oy, r, max_range):
            return True
    return False


@njit(cache=True)
def _count(bits):
    n = 0
    while bits:
        bits &= bits - 1
        n += 1
    return n


@njit(cache=True)
def _gain(masks, c, k, rest, weights):
    """The weighted coverage with camera c on aim k and the other cameras' union `rest` (T,)."""
    total = 0.0
    for i in range(rest.shape[0]):
        total += weights[i] * _count(rest[i] | masks[c, k, i])
    return total


@njit(cache=True)
def _ascend(masks, count, choice, weights, rest, passes):
    """Coordinate ascent on the cameras' aims `choice` (in place); returns the final score."""
    num_cameras, num_times = masks.shape[0], masks.shape[2]
    score = 0.0
    for _ in range(passes):
        changed = False
        for c in range(num_cameras):
            for i in range(num_times):
                union = 0
                for d in range(num_cameras):
                    if d != c:
                        union |= masks[d, choice[d], i]
                rest[i] = union
            best, score = choice[c], _gain(masks, c, choice[c], rest, weights)
            for k in range(count[c]):
                gain = _gain(masks, c, k, rest, weights)
                if gain > score:
                    best, score = k, gain
            if best != choice[c]:
                choice[c] = best
                changed = True
        if not changed:
            break
    return score


@njit(cache=True)
def _arrival(turn, rotation, times):
    """Index of the first look-ahead time by which a camera turning `rotation` degrees a step has turned
    `turn` degrees (the last one if none)."""
    for i in range(times.shape[0]):
        if times[i] * rotation >= turn:
            return i
    return times.shape[0] - 1


@njit(cache=True)
def plan(cameras, targets, obstacles, rows, previous, has_previous, aim, has_aim, times, weights, action) -> None:
    """One step of the upper-bound rule (module docstring) for every game b with `rows[b]`: predict where the
    targets will be, list each camera's candidate aims, mark what each aim covers on the way there, choose the
    cameras' aims jointly, and turn the chosen aims into actions.

    Args:
        cameras: (B, Nc, 8) float64 per camera: x, y, R_s cos phi, R_s sin phi, theta (degrees), max sight
            range R_max, rotation step and zooming step (degrees) of its action box.
        targets: (B, Nt, 2) the targets' true positions now.
        obstacles: (B, No, 4) x, y, radius, flag (0: ignored).
        rows: (B,) bool, the games to plan.
        previous: (B, Nt, 2) last step's true positions, valid where `has_previous` (B,) bool; updated.
        aim: (B, Nc, 2) last step's aims (orientation, viewing angle in degrees), valid where `has_aim`
            (B,) bool; updated.
        times, weights: the look-ahead times (T,) int64 and their weights (T,) (`lookahead_times`).
        action: (B, Nc, 2) out: (rotation, zoom) in degrees, within the action box.
    """
    num_rows, num_cameras = cameras.shape[0], cameras.shape[1]
    num_targets, num_times = targets.shape[1], times.shape[0]
    capacity = 2 + num_targets + num_targets * (num_targets - 1) // 2
    px, py = np.empty((num_times, num_targets)), np.empty((num_times, num_targets))
    dist, bearing = np.empty((num_targets, num_times)), np.empty((num_targets, num_times))
    visible = np.empty((num_targets, num_times), dtype=np.bool_)
    aims = np.empty((num_cameras, capacity, 2))
    count = np.zeros(num_cameras, dtype=np.int64)
    masks = np.zeros((num_cameras, capacity, num_times), dtype=np.int64)
    choice, trial = np.zeros(num_cameras, dtype=np.int64), np.zeros(num_cameras, dtype=np.int64)
    rest = np.zeros(num_times, dtype=np.int64)
    for b in range(num_rows):
        if not rows[b]:
            continue
        _predict(targets, previous, has_previous, b, times, px, py)
        for c in range(num_cameras):
            _sight_lines(cameras, obstacles, b, c, px, py, dist, bearing, visible)
            count[c] = _candidate_aims(cameras, b, c, aim, has_aim, times, dist, bearing, aims)
            _coverage_masks(cameras, b, c, count[c], times, dist, bearing, visible, aims, masks)
        _joint_choice(masks, count, has_aim[b], weights, rest, choice, trial)
        for c in range(num_cameras):
            k = choice[c]
            aim[b, c, 0], aim[b, c, 1] = aims[c, k, 0], aims[c, k, 1]
            theta = cameras[b, c, 4]
            phi = math.atan2(cameras[b, c, 3], cameras[b, c, 2]) * _RAD2DEG
            rotation, zooming = cameras[b, c, 6], cameras[b, c, 7]
            action[b, c, 0] = min(max(_wrap(aims[c, k, 0] - phi), -rotation), rotation)
            action[b, c, 1] = min(max(aims[c, k, 1] - theta, -zooming), zooming)
        has_aim[b] = True


@njit(cache=True)
def _predict(targets, previous, has_previous, b, times, px, py) -> None:
    """Game b's targets at each look-ahead time, moving on at their last step's velocity (px, py (T, Nt), inside
    the terrain); remembers their positions now for the next step."""
    for t in range(targets.shape[1]):
        x, y = targets[b, t, 0], targets[b, t, 1]
        vx, vy = 0.0, 0.0
        if has_previous[b]:
            vx, vy = x - previous[b, t, 0], y - previous[b, t, 1]
        for i in range(times.shape[0]):
            px[i, t] = min(max(x + times[i] * vx, -TERRAIN_SIZE), TERRAIN_SIZE)
            py[i, t] = min(max(y + times[i] * vy, -TERRAIN_SIZE), TERRAIN_SIZE)
        previous[b, t, 0], previous[b, t, 1] = x, y
    has_previous[b] = True


@njit(cache=True)
def _sight_lines(cameras, obstacles, b, c, px, py, dist, bearing, visible) -> None:
    """From camera c of game b to every predicted target position: distance, bearing (degrees) and whether no
    obstacle hides it, (Nt, T) each."""
    cx, cy, max_range = cameras[b, c, 0], cameras[b, c, 1], cameras[b, c, 5]
    for t in range(px.shape[1]):
        for i in range(px.shape[0]):
            dx, dy = px[i, t] - cx, py[i, t] - cy
            dist[t, i] = math.sqrt(dx * dx + dy * dy)
            bearing[t, i] = math.atan2(dy, dx) * _RAD2DEG
            visible[t, i] = not _occluded(cx, cy, max_range, obstacles, b, px[i, t], py[i, t])


@njit(cache=True)
def _candidate_aims(cameras, b, c, aim, has_aim, times, dist, bearing, aims) -> int:
    """Camera c's candidate aims (orientation, viewing angle) into aims[c]: where it looks now, its last aim,
    each target in range when the camera can first face it, and each pair of targets that fits in one view;
    returns how many."""
    theta, rc, rs = cameras[b, c, 4], cameras[b, c, 2], cameras[b, c, 3]
    max_range, rotation = cameras[b, c, 5], cameras[b, c, 6]
    phi = math.atan2(rs, rc) * _RAD2DEG
    area = theta * (rc * rc + rs * rs)
    theta_min = area / (max_range * max_range)
    num_targets = dist.shape[0]
    n = 0
    aims[c, n, 0], aims[c, n, 1] = phi, theta
    n += 1
    if has_aim[b]:
        aims[c, n, 0], aims[c, n, 1] = aim[b, c, 0], aim[b, c, 1]
        n += 1
    for t in range(num_targets):
        i = _arrival(abs(_wrap(bearing[t, 0] - phi)), rotation, times)
        if dist[t, i] > max_range:
            continue
        reach = dist[t, i] * RANGE_MARGIN
        angle = area / (reach * reach) if reach > 0.0 else MAX_CAMERA_VIEWING_ANGLE
        aims[c, n, 0] = bearing[t, i]
        aims[c, n, 1] = min(max(angle, theta_min), MAX_CAMERA_VIEWING_ANGLE)
        n += 1
    for t in range(num_targets):
        for u in range(t + 1, num_targets):
            middle = bearing[t, 0] + 0.5 * _wrap(bearing[u, 0] - bearing[t, 0])
            i = _arrival(abs(_wrap(middle - phi)), rotation, times)
            far = max(dist[t, i], dist[u, i])
            if far > max_range:
                continue
            gap = _wrap(bearing[u, i] - bearing[t, i])
            reach = far * RANGE_MARGIN
            angle = min(area / (reach * reach), MAX_CAMERA_VIEWING_ANGLE) if reach > 0.0 \
                else MAX_CAMERA_VIEWING_ANGLE
            if abs(gap) + 2.0 * ANGLE_MARGIN > angle:
                continue
            aims[c, n, 0] = _wrap(bearing[t, i] + 0.5 * gap)
            aims[c, n, 1] = max(angle, theta_min)
            n += 1
    return n


@njit(cache=True)
def _coverage_masks(cameras, b, c, n, times, dist, bearing, visible, aims, masks) -> None:
    """What each of camera c's n aims covers on the way there: masks[c, k, i], the bits of the targets in view at
    look-ahead time i while the camera turns and zooms towards aim k at its action box's pace."""
    theta, rc, rs = cameras[b, c, 4], cameras[b, c, 2], cameras[b, c, 3]
    max_range, rotation, zooming = cameras[b, c, 5], cameras[b, c, 6], cameras[b, c, 7]
    phi = math.atan2(rs, rc) * _RAD2DEG
    area = theta * (rc * rc + rs * rs)
    theta_min = area / (max_range * max_range)
    for k in range(n):
        turn = _wrap(aims[c, k, 0] - phi)
        widen = aims[c, k, 1] - theta
        for i in range(times.shape[0]):
            limit = times[i] * rotation
            orientation = phi + min(max(turn, -limit), limit)
            limit = times[i] * zooming
            angle = min(max(theta + min(max(widen, -limit), limit), theta_min), MAX_CAMERA_VIEWING_ANGLE)
            sight = math.sqrt(area / angle)
            bits = 0
            for t in range(dist.shape[0]):
                if visible[t, i] and dist[t, i] <= sight and \
                        2.0 * abs(_wrap(bearing[t, i] - orientation)) <= angle:
                    bits |= 1 << t
            masks[c, k, i] = bits


@njit(cache=True)
def _joint_choice(masks, count, had_aim, weights, rest, choice, trial) -> None:
    """The cameras' aims chosen jointly into `choice`: the last aims and a greedy pass from each camera in turn,
    each improved by coordinate ascent; the best kept (the first on ties)."""
    num_cameras, num_times = count.shape[0], rest.shape[0]
    for c in range(num_cameras):
        choice[c] = 1 if had_aim else 0
    best_score = _ascend(masks, count, choice, weights, rest, MAX_PASSES)
    for first in range(num_cameras):
        for i in range(num_times):
            rest[i] = 0
        for j in range(num_cameras):
            c = (first + j) % num_cameras
            best, score = 0, -1.0
            for k in range(count[c]):
                gain = _gain(masks, c, k, rest, weights)
                if gain > score:
                    best, score = k, gain
            trial[c] = best
            for i in range(num_times):
                rest[i] |= masks[c, best, i]
        score = _ascend(masks, count, trial, weights, rest, MAX_PASSES)
        if score > best_score:
            best_score = score
            choice[:] = trial


# ---------------------------------------------------------------------------- reading the observations

def camera_records(observation: np.ndarray, counts) -> np.ndarray:
    """(B, Nc, 8) `plan`'s camera input from B games' cameras' observations (B, Nc, D), each camera's own
    state: x, y, R_s cos phi, R_s sin phi, theta, R_max, rotation step, zooming step."""
    own = observation[..., _OWN:_OWN + CAMERA_STATE_DIM_PRIVATE]
    return np.ascontiguousarray(np.concatenate([own[..., _CAMERA_FIELDS], own[..., 6:9]], axis=-1))


def _blocks(counts) -> tuple[slice, slice, slice]:
    indices = camera_observation_indices_of(*counts)
    return (slice(int(indices[2]), int(indices[3])), slice(int(indices[3]), int(indices[4])),
            slice(int(indices[4]), int(indices[5])))


def check_full_view(observation: np.ndarray, counts, who: str) -> None:
    """ValueError (one line) unless every target and every camera is flagged visible in every one of the
    cameras' observations (..., D): what `EnhancedObservation(env, team='camera')` gives them."""
    nc, nt, _ = counts
    targets, _, cameras = _blocks(counts)
    flags = np.concatenate([observation[..., targets].reshape(observation.shape[:-1] + (nt, -1))[..., -1],
                            observation[..., cameras].reshape(observation.shape[:-1] + (nc, -1))[..., -1]], axis=-1)
    if not (flags == 1.0).all():
        raise ValueError(f'{who} sees the true state: it needs camera observations that show every target and camera '
                         "(the EnhancedObservation wrapper on the cameras, EnhancedObservation(env, team='camera'), or "
                         'mate.wrappers.enhanced_observation.enhance_observations); got a partial one')


def target_records(observation: np.ndarray, counts) -> np.ndarray:
    """(..., Nt, 2) true target positions from fully observing camera observations (..., D) (`check_full_view`)."""
    nt = counts[1]
    block = observation[..., _blocks(counts)[0]].reshape(observation.shape[:-1] + (nt, TARGET_STATE_DIM_PUBLIC + 1))
    return np.ascontiguousarray(block[..., :2])


def obstacle_records(observation: np.ndarray, counts) -> np.ndarray:
    """(..., No, 4) obstacle x, y, radius, flag from camera observations (..., D)."""
    no = counts[2]
    block = observation[..., _blocks(counts)[1]].reshape(observation.shape[:-1] + (no, OBSTACLE_STATE_DIM + 1))
    return np.ascontiguousarray(block)


def teammate_records(observation: np.ndarray, counts) -> np.ndarray:
    """(..., Nc, 8) `plan`'s camera input from one fully observing camera observation per game (..., D): the
    teammate records (every camera's public state) with the observer's R_max and action steps (the same for
    every camera of a game)."""
    nc = counts[0]
    block = observation[..., _blocks(counts)[2]].reshape(observation.shape[:-1] + (nc, CAMERA_STATE_DIM_PUBLIC + 1))
    own = observation[..., _OWN + 6:_OWN + 9]
    shared = np.broadcast_to(own[..., None, :], block.shape[:-1] + (3,))
    return np.ascontiguousarray(np.concatenate([block[..., _CAMERA_FIELDS], shared], axis=-1))


# ---------------------------------------------------------------------------- the batched team

class UpperBoundTeam:
    """The upper-bound camera rule (module docstring) for every camera of B games: a reference, not a learner.

    What it reads beyond a camera's observation: every target's true position every step, and every
    obstacle. Two ways to give it the truth:

    * watching the vector env it plays in (`play_batch` calls `watch` for a team that has it), and `act`
      reads the true positions with `vec.state()` and the obstacles with
      `vec.obstacle_states`; the observations passed to `act` may be the raw ones (only each camera's
      own state is read from them);
    * or fully observing observations: `act(observation)` with every target and camera flagged visible, as
      `mate.wrappers.enhanced_observation.enhance_observations` (the `EnhancedObservation` wrapper on the
      cameras) makes them; anything less is a ValueError.

    Deterministic (no random numbers): `seed` is accepted for the common team signature and unused.

    Args:
        num_envs: B.
        counts: (num_cameras, num_targets, num_obstacles) of the game (at most 63 targets).
        seed: unused.
        horizon: the plan's look-ahead in env steps (40).
        discount: discount per step of the look-ahead's weights (0.9).
    """

    team = Team.CAMERA

    def __init__(self, num_envs: int, counts, seed: int | Sequence[int] | None = None, horizon: int = HORIZON,
                 discount: float = DISCOUNT) -> None:
        self.num_envs = int(num_envs)
        if self.num_envs < 1:
            raise ValueError(f'num_envs must be at least 1, got {num_envs!r}')
        self.counts = checked_counts(counts)
        nc, nt, no = self.counts
        if nt > MAX_TARGETS:
            raise ValueError(f'UpperBoundTeam plans for at most {MAX_TARGETS} targets, got {nt}')
        self.times, self.weights = lookahead_times(horizon, discount)     # checks them
        self.horizon, self.discount = int(horizon), float(discount)
        self.num_agents = nc
        self.dim = int(camera_observation_indices_of(*self.counts)[-1])
        self.vec = None
        b = self.num_envs
        self.active = np.zeros(b, dtype=bool)
        self.previous = np.zeros((b, nt, 2))
        self.has_previous = np.zeros(b, dtype=bool)
        self.aim = np.zeros((b, nc, 2))
        self.has_aim = np.zeros(b, dtype=bool)
        self.action = np.zeros((b, nc, 2))

    def watch(self, vec, step: int = 0) -> None:
        """Read the true state from `vec` (the vector env of the games, row b = game b) from now on (`play_batch`
        calls it after every reset and step)."""
        counts = (vec.num_cameras, vec.num_targets, vec.num_obstacles)
        if vec.num_envs != self.num_envs or counts != self.counts:
            raise ValueError(f'UpperBoundTeam for {self.num_envs} games of {self.counts} cannot watch a vector env of '
                             f'{vec.num_envs} games of {counts}')
        self.vec = vec

    def _observation(self, observation) -> np.ndarray:
        observation = np.ascontiguousarray(observation, dtype=np.float64)
        expected = (self.num_envs, self.num_agents, self.dim)
        if observation.shape != expected:
            raise ValueError(f'UpperBoundTeam: observation has shape {observation.shape}, expected {expected} '
                             '(rows, cameras, dimension)')
        return observation

    def _rows(self, rows) -> np.ndarray:
        rows = np.asarray(rows, dtype=bool)
        if rows.shape != (self.num_envs,):
            raise ValueError(f'UpperBoundTeam: rows must be a ({self.num_envs},) bool mask, got shape {rows.shape}')
        return rows

    def reset(self, observation, rows) -> None:
        """Start an episode in the rows `rows` (B,) bool (the cameras' observations (B, Nc, D) are only checked)."""
        self._observation(observation)
        rows = self._rows(rows)
        self.active |= rows
        self.has_previous[rows] = False
        self.has_aim[rows] = False
        self.action[rows] = 0.0

    def idle(self, rows) -> None:
        """The rows `rows` (B,) bool are out of play until their next reset."""
        self.active &= ~self._rows(rows)

    def _truth(self, observation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(targets (B, Nt, 2), obstacles (B, No, 4)): from the watched vector env, else from the observations."""
        nc, nt, no = self.counts
        if self.vec is not None:
            state = self.vec.state()
            begin = PRESERVED_DIM + CAMERA_STATE_DIM_PRIVATE * nc
            records = state[:, begin:begin + TARGET_STATE_DIM_PRIVATE * nt].reshape(self.num_envs, nt, -1)
            obstacles = np.concatenate([self.vec.obstacle_states, np.ones((self.num_envs, no, 1))], axis=-1)
            return np.ascontiguousarray(records[..., :2], dtype=np.float64), obstacles
        check_full_view(observation[self.active], self.counts, 'UpperBoundTeam (not watching a vector env)')
        return target_records(observation[:, 0], self.counts), obstacle_records(observation[:, 0], self.counts)

    def act(self, observation) -> np.ndarray:
        """(B, Nc, 2) (rotation, zoom) in degrees for the cameras' observations (B, Nc, D) (zeros in rows out of
        play)."""
        observation = self._observation(observation)
        targets, obstacles = self._truth(observation)
        plan(camera_records(observation, self.counts), targets, obstacles, self.active, self.previous,
             self.has_previous, self.aim, self.has_aim, self.times, self.weights, self.action)
        return np.where(self.active[:, None, None], self.action, 0.0)

    def state_dict(self) -> dict:
        """Everything the team's future depends on, as plain data (copies)."""
        return dict(arrays={name: getattr(self, name).copy() for name in self._STATE})

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (taken from a team of the same sizes)."""
        for name, value in state['arrays'].items():
            getattr(self, name)[...] = value

    _STATE = ('active', 'previous', 'has_previous', 'aim', 'has_aim', 'action')
