"""The greedy decision rules, written once on arrays: the Python agents and the batched teams call them.

Every kernel acts for the agents (b, i) of arrays with leading axes (B, N): B games, N agents of one
team. `mate.GreedyCameraAgent` / `mate.GreedyTargetAgent` call them on one row of one agent
(arrays of shape (1, 1, ...)); `GreedyCameraTeam` / `GreedyTargetTeam` on every agent of B games. The
same compiled code runs in both cases, so both give bit-identical results on the same inputs.

Randomness enters as explicit stacks of pre-drawn uniforms (`mate.agents.base.UniformDraws`): `draws`
(B, N, C) float64 with `left` (B, N) int64 numbers on each stack, the next one on top
(`draws[b, i, left[b, i] - 1]`). Each agent has two: its own stream (delays, the idle camera's coin,
warehouse choices, noise refreshes) and its action space's stream (the idle camera's random action,
the targets' noise). A kernel that needs more numbers of an agent's own stream than its stack holds
leaves that agent untouched and flags it in `short` (B, N); the caller refills its stack and calls
again for the flagged agents (`todo`), so the generator is called exactly when the Python agent's
`self._draw()` would call it. Action-space stacks must hold at least 2 numbers before `camera_act`,
`target_act`, `walk_towards` (and `walk_start`); refilling those early changes nothing.

Observations are raw float64 (B, N, D) (the env's layout, docs/environment/observations.md). Angles are in
degrees, lengths in world units. docs/agents.md and docs/differences.md ("kept
quirks") describe the rules. Their constants (the range factor, the idle camera's 0.1, the noise
refresh chances, ...) live with the agents, in `mate.agents.greedy` and `mate.agents.naive`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..constants import NUM_WAREHOUSES, PRESERVED_DIM, TARGET_STATE_DIM_PUBLIC, WAREHOUSES

__all__ = [
    'INITIAL_NOISE_SCALE', 'MAX_VIEWING_ANGLE', 'NOISE_REFRESH_MOVING', 'NOISE_REFRESH_STUCK',
    'RANDOM_ACTION_PROBABILITY', 'RANGE_FACTOR', 'ZOOM_ITERATIONS', 'desired_viewing_angle', 'communication_delay',
    'remember', 'camera_reset', 'camera_observe', 'camera_outbox',
    'camera_inbox', 'camera_act', 'target_reset', 'target_observe', 'target_share', 'target_act', 'walk_start',
    'walk_towards', 'random_act', 'camera_reset_row', 'camera_observe_row', 'camera_outbox_row', 'camera_inbox_row',
    'camera_act_row', 'walk_start_row', 'target_reset_row', 'target_observe_row', 'target_share_row', 'target_act_row',
    'random_act_row', 'centroid_aim_row',
]

RANGE_FACTOR = 1.1
"""Targets count as reachable within 1.1 x a camera's maximum sight range."""
RANDOM_ACTION_PROBABILITY = 0.1
"""Chance per step that an idle camera (no candidate target) draws a fresh random action."""
MAX_VIEWING_ANGLE = 180.0
"""Widest viewing angle the zoom aims for (degrees)."""
ZOOM_ITERATIONS = 20
"""Rounds of the fixed-point iteration of `desired_viewing_angle`."""
NOISE_REFRESH_MOVING = 0.05
"""Chance per step of drawing new noise when the last move was longer than 0.2 step sizes."""
NOISE_REFRESH_STUCK = 0.75
"""Chance per step of drawing new noise after a (nearly) blocked move."""
INITIAL_NOISE_SCALE = 0.5
"""Scale of the noise drawn at reset (fixed, whatever the agent's noise_scale; kept from the original)."""
DEG2RAD, RAD2DEG = math.pi / 180.0, 180.0 / math.pi
OWN = PRESERVED_DIM
"""Offset of the own state in an observation."""
RECORD = TARGET_STATE_DIM_PUBLIC + 1
"""Width of one target record (x, y, sight range, is_loaded, flag) in a camera's observation."""

_HALF_DEG2RAD = 0.5 * DEG2RAD
_RIGHT_ANGLE = 90.0 * DEG2RAD
_WAREHOUSES = np.array(WAREHOUSES, dtype=np.float64)


# ---------------------------------------------------------------------------- shared pieces

@njit(cache=True)
def desired_viewing_angle(distance: float, viewing_angle: float, sight_range: float,
                          max_sight_range: float) -> float:
    """The widest viewing angle (degrees) whose sector, at constant area theta R^2, has its inscribed
    circle centred on a target `distance` away; clipped to [min viewing angle, 180].

    Fixed-point iteration theta <- area / (distance (1 + sin(min(theta / 2, 90 deg))))^2, 20 rounds
    from 180 degrees, unless the target is beyond reach (min angle) or very close (180 degrees).
    """
    theta_min = viewing_angle * (sight_range / max_sight_range) ** 2
    if distance * (1.0 + math.sin(theta_min * _HALF_DEG2RAD)) >= max_sight_range:
        return theta_min
    area = viewing_angle * sight_range * sight_range
    if distance <= 0.5 * math.sqrt(area / MAX_VIEWING_ANGLE):
        return MAX_VIEWING_ANGLE
    theta = MAX_VIEWING_ANGLE
    for _ in range(ZOOM_ITERATIONS):
        half = theta * _HALF_DEG2RAD
        reach = distance * (1.0 + math.sin(half if half < _RIGHT_ANGLE else _RIGHT_ANGLE))
        theta = area / (reach * reach)
    if theta < theta_min:
        return theta_min
    return MAX_VIEWING_ANGLE if theta > MAX_VIEWING_ANGLE else theta


@njit(cache=True)
def communication_delay(u: float, period: int) -> int:
    """Steps a camera waits after a message to a teammate before the next one to it:
    U{period // 4, ..., 2 period - 1} from the uniform `u` in [0, 1)."""
    low, high = period // 4, 2 * period
    return low + int(u * (high - low)) if high > low else low


@njit(cache=True)
def _pop(draws, left, b, i) -> float:
    """The next number of agent (b, i)'s stack (the caller checked that there is one)."""
    n = left[b, i] - 1
    left[b, i] = n
    return draws[b, i, n]


@njit(cache=True)
def _in_box(high: float, u: float) -> float:
    """u in [0, 1) mapped onto [-high, high) as an action space sample is: low + (high - low) u."""
    low = -high
    return low + (high - low) * u


@njit(cache=True)
def remember(memory, time2forget, never_loaded, b, i, t, x, y, sight_range, loaded, period) -> None:
    """Camera (b, i) learns target t's public state (x, y, sight range, is_loaded): it becomes a
    candidate for `period` steps; a loaded sighting clears `never_loaded`."""
    memory[b, i, t, 0] = x
    memory[b, i, t, 1] = y
    memory[b, i, t, 2] = sight_range
    memory[b, i, t, 3] = loaded
    time2forget[b, i, t] = period
    if loaded != 0.0:
        never_loaded[b, i, t] = False


# ---------------------------------------------------------------------------- greedy cameras
#
# Each rule is a row function (`*_row(b, ...)`: the agents of game b) and a loop over the games calling it. The
# CPU teams and agents call the loops; the device teams (`mate.teams.device`) call the row functions, one GPU
# thread per game: the same compiled rules on both targets.

@njit(cache=True)
def camera_reset_row(b, observation, begin, period, memory, time2forget, never_loaded, pending, pending_state,
                     own_state, prev_action, delay, known) -> None:
    """`camera_reset` for game b."""
    num_cameras, num_targets = pending.shape[1], pending.shape[2]
    for i in range(num_cameras):
        for t in range(num_targets):
            k = begin + RECORD * t
            for f in range(4):
                memory[b, i, t, f] = observation[b, i, k + f]
            time2forget[b, i, t] = period if observation[b, i, k + 4] != 0.0 else 0
            never_loaded[b, i, t] = True
            pending[b, i, t] = False
        pending_state[b, i] = True
        own_state[b, i, 0] = observation[b, i, OWN]
        own_state[b, i, 1] = observation[b, i, OWN + 1]
        own_state[b, i, 2] = observation[b, i, OWN + 6]
        prev_action[b, i, 0] = 0.0
        prev_action[b, i, 1] = 0.0
        for c in range(delay.shape[2]):
            delay[b, i, c] = 0
            known[b, i, c] = False


@njit(cache=True)
def camera_reset(observation, begin, rows, period, memory, time2forget, never_loaded, pending, pending_state,
                 own_state, prev_action, delay, known) -> None:
    """Start an episode for every camera of the rows `rows` (B,) bool from its first observation.

    Memory: every target record as observed (all zeros if unseen), a candidate for `period` steps if
    seen; `never_loaded` all True (also for targets seen loaded now, as in the original). Messages:
    the own state (x, y, max sight range into `own_state` (B, N, 3)) waits to be sent
    (`pending_state`), no sightings are pending, no delays run, no teammate is known.
    `begin`: where the target records start in the observation.
    """
    for b in range(pending.shape[0]):
        if rows[b]:
            camera_reset_row(b, observation, begin, period, memory, time2forget, never_loaded, pending,
                             pending_state, own_state, prev_action, delay, known)


@njit(cache=True)
def camera_observe_row(b, observation, begin, period, memory, time2forget, never_loaded, pending) -> int:
    """`camera_observe` for game b."""
    num_cameras, num_targets = pending.shape[1], pending.shape[2]
    seen = 0
    for i in range(num_cameras):
        for t in range(num_targets):
            if time2forget[b, i, t] > 0:
                time2forget[b, i, t] -= 1
        for t in range(num_targets):
            k = begin + RECORD * t
            if observation[b, i, k + 4] != 0.0:
                remember(memory, time2forget, never_loaded, b, i, t, observation[b, i, k],
                         observation[b, i, k + 1], observation[b, i, k + 2], observation[b, i, k + 3], period)
                pending[b, i, t] = True
                seen += 1
    return seen


@njit(cache=True)
def camera_observe(observation, begin, rows, period, memory, time2forget, never_loaded, pending) -> int:
    """A step's observation for every camera of the rows `rows`: every candidate ages one step, then
    each target the camera sees enters its memory (for `period` steps) and its pending sightings
    (`pending` (B, N, Nt) bool, sent in the responses round). Returns the number of sightings."""
    seen = 0
    for b in range(pending.shape[0]):
        if rows[b]:
            seen += camera_observe_row(b, observation, begin, period, memory, time2forget, never_loaded, pending)
    return seen


@njit(cache=True)
def camera_outbox_row(b, todo, index, period, filterout_beyond_range, memory, pending, pending_state, delay, known,
                      neighbour, draws, left, sent, sent_state, sight, short) -> None:
    """`camera_outbox` for the senders of game b."""
    num_senders, num_targets = pending.shape[1], pending.shape[2]
    num_cameras = delay.shape[2]
    random_delays = 2 * period > period // 4
    for s in range(num_senders):
        if not todo[b, s]:
            continue
        short[b, s] = False
        has_sightings = False
        for t in range(num_targets):
            has_sightings = has_sightings or pending[b, s, t]
        count = 0
        for c in range(num_cameras):
            sent[b, s, c] = False
            ready = c != index[b, s] and delay[b, s, c] <= 1          # zero after this step's countdown
            if not ready or not (pending_state[b, s] or has_sightings):
                continue
            kept = False
            if has_sightings and known[b, s, c] and filterout_beyond_range:
                nx, ny = neighbour[b, s, c, 0], neighbour[b, s, c, 1]
                reach = RANGE_FACTOR * neighbour[b, s, c, 2]
                for t in range(num_targets):
                    keep = pending[b, s, t] and math.hypot(memory[b, s, t, 0] - nx, memory[b, s, t, 1] - ny) < reach
                    sight[b, s, c, t] = keep
                    kept = kept or keep
            else:
                for t in range(num_targets):
                    sight[b, s, c, t] = False
            if pending_state[b, s] or kept:
                sent[b, s, c] = True
                count += 1
        if random_delays and left[b, s] < count:
            short[b, s] = True
            continue
        for c in range(num_cameras):
            if delay[b, s, c] > 0:
                delay[b, s, c] -= 1
            if sent[b, s, c]:
                delay[b, s, c] = communication_delay(_pop(draws, left, b, s), period) if random_delays \
                    else period // 4
        sent_state[b, s] = pending_state[b, s]
        if pending_state[b, s] or has_sightings:
            pending_state[b, s] = False
            for t in range(num_targets):
                pending[b, s, t] = False


@njit(cache=True)
def camera_outbox(todo, index, period, filterout_beyond_range, memory, pending, pending_state, delay, known,
                  neighbour, draws, left, sent, sent_state, sight, short) -> None:
    """The responses round of every sending camera (b, s) with `todo[b, s]`: which teammates get a
    message, with which sightings, and the delays that follow. `index` (B, N) int64: each camera's index
    in its team (s in a batched team; an agent acting alone passes its own index); arrays over teammates
    (`delay`, `known`, `neighbour`, `sent`, `sight`) have the whole team (Nc) on their third axis.

    Every delay `delay[b, s, c]` first counts down one step. If the camera has something pending, each
    teammate c whose delay has run out gets what is pending: the own state (until it was sent once)
    and the pending sightings within c's reach (1.1 x its max sight range, from the state c sent,
    `neighbour[b, s, c]` = (x, y, max sight range) when `known[b, s, c]`). Kept quirks: a teammate not
    known yet gets no sightings, and with `filterout_beyond_range` False nobody does. After each message
    to c, delay[b, s, c] = `communication_delay(u, period)`, one number of the camera's stream per
    message, in teammate order. What could not be sent is dropped: nothing stays pending.

    Outputs: `sent` (B, N, N) bool [sender, recipient], `sent_state` (B, N) (the messages carry the
    own state), `sight` (B, N, N, Nt) bool [sender, recipient, target]. A camera whose stack holds
    fewer numbers than it has messages to send is left untouched with `short[b, s]` set.
    """
    for b in range(pending.shape[0]):
        camera_outbox_row(b, todo, index, period, filterout_beyond_range, memory, pending, pending_state, delay,
                          known, neighbour, draws, left, sent, sent_state, sight, short)


@njit(cache=True)
def camera_inbox_row(b, observation, begin, period, sent, sent_state, sight, own_state, memory, time2forget,
                     never_loaded, known, neighbour) -> None:
    """`camera_inbox` for game b."""
    num_cameras, num_targets = time2forget.shape[1], time2forget.shape[2]
    for r in range(num_cameras):
        for s in range(num_cameras):
            if s == r or not sent[b, s, r]:
                continue
            if sent_state[b, s]:
                known[b, r, s] = True
                for f in range(3):
                    neighbour[b, r, s, f] = own_state[b, s, f]
            for t in range(num_targets):
                if sight[b, s, r, t]:
                    k = begin + RECORD * t
                    remember(memory, time2forget, never_loaded, b, r, t, observation[b, s, k],
                             observation[b, s, k + 1], observation[b, s, k + 2], observation[b, s, k + 3], period)


@njit(cache=True)
def camera_inbox(observation, begin, rows, period, sent, sent_state, sight, own_state, memory, time2forget,
                 never_loaded, known, neighbour) -> None:
    """Deliver the messages of `camera_outbox` within each row of `rows`: every camera takes the messages
    addressed to it in sender order. A message with the sender's state makes the sender a known teammate
    (kept quirk: however far away); its sightings (the values the sender observed this step) enter the
    memory as the camera's own do."""
    for b in range(time2forget.shape[0]):
        if rows[b]:
            camera_inbox_row(b, observation, begin, period, sent, sent_state, sight, own_state, memory, time2forget,
                             never_loaded, known, neighbour)


@njit(cache=True)
def camera_act_row(b, observation, todo, filterout_unloaded, filterout_beyond_range, memory, time2forget,
                   never_loaded, high, prev_action, draws, left, space, space_left, action, short) -> None:
    """`camera_act` for the cameras of game b."""
    num_cameras, num_targets = time2forget.shape[1], time2forget.shape[2]
    for i in range(num_cameras):
        if not todo[b, i]:
            continue
        short[b, i] = False
        # float64 whatever the observations' dtype (numba's float() of a float32 stays float32)
        x, y = np.float64(observation[b, i, OWN]), np.float64(observation[b, i, OWN + 1])
        rx, ry = np.float64(observation[b, i, OWN + 3]), np.float64(observation[b, i, OWN + 4])
        theta, max_range = np.float64(observation[b, i, OWN + 5]), np.float64(observation[b, i, OWN + 6])
        reach = RANGE_FACTOR * max_range
        best, best_distance = -1, math.inf
        for t in range(num_targets):
            if time2forget[b, i, t] <= 0:
                continue
            distance = math.hypot(memory[b, i, t, 0] - x, memory[b, i, t, 1] - y)
            if filterout_beyond_range and not distance < reach:
                continue
            if filterout_unloaded and not (memory[b, i, t, 3] != 0.0 or never_loaded[b, i, t]):
                continue
            if distance < best_distance:
                best, best_distance = t, distance
        if best < 0:
            if left[b, i] < 1:
                short[b, i] = True
                continue
            if _pop(draws, left, b, i) < RANDOM_ACTION_PROBABILITY:
                prev_action[b, i, 0] = _in_box(high[b, i, 0], _pop(space, space_left, b, i))
                prev_action[b, i, 1] = _in_box(high[b, i, 1], _pop(space, space_left, b, i))
            action[b, i, 0] = prev_action[b, i, 0]
            action[b, i, 1] = prev_action[b, i, 1]
            continue
        orientation = math.atan2(ry, rx) * RAD2DEG
        bearing = math.atan2(memory[b, i, best, 1] - y, memory[b, i, best, 0] - x) * RAD2DEG
        rotation = (bearing - orientation + 180.0) % 360.0 - 180.0
        zoom = desired_viewing_angle(best_distance, theta, math.hypot(rx, ry), max_range) - theta
        h0, h1 = high[b, i, 0], high[b, i, 1]
        prev_action[b, i, 0] = min(max(rotation, -h0), h0)
        prev_action[b, i, 1] = min(max(zoom, -h1), h1)
        action[b, i, 0] = prev_action[b, i, 0]
        action[b, i, 1] = prev_action[b, i, 1]


@njit(cache=True)
def camera_act(observation, todo, filterout_unloaded, filterout_beyond_range, memory, time2forget, never_loaded,
               high, prev_action, draws, left, space, space_left, action, short) -> None:
    """The action (rotation, zoom) in degrees of every camera (b, i) with `todo[b, i]`, into `action` (B, N, 2).

    Candidates: targets remembered (time2forget > 0) within 1.1 x the max sight range (with
    `filterout_beyond_range`), not seen unloaded after having been seen loaded (with
    `filterout_unloaded`). The nearest (the first on ties) is aimed at: rotate towards it and zoom to
    `desired_viewing_angle`, both clipped to +-`high` (B, N, 2) (the steps of the camera's action box at
    reset). With no candidate the camera keeps its previous action, or, when the next number of its
    stream is below 0.1, draws a uniform one from its action-space stack. A camera whose stream is
    empty when it needs a number is left untouched with `short[b, i]` set.
    """
    for b in range(time2forget.shape[0]):
        camera_act_row(b, observation, todo, filterout_unloaded, filterout_beyond_range, memory, time2forget,
                       never_loaded, high, prev_action, draws, left, space, space_left, action, short)


# ---------------------------------------------------------------------------- noisy walk (greedy and naive targets)

@njit(cache=True)
def walk_start_row(b, observation, high, prev_location, noise, space, space_left) -> None:
    """`walk_start` for the targets of game b."""
    for i in range(space_left.shape[1]):
        prev_location[b, i, 0] = observation[b, i, OWN]
        prev_location[b, i, 1] = observation[b, i, OWN + 1]
        noise[b, i, 0] = INITIAL_NOISE_SCALE * _in_box(high[b, i, 0], _pop(space, space_left, b, i))
        noise[b, i, 1] = INITIAL_NOISE_SCALE * _in_box(high[b, i, 1], _pop(space, space_left, b, i))


@njit(cache=True)
def walk_start(observation, rows, high, prev_location, noise, space, space_left) -> None:
    """Start the walk of every target of the rows `rows`: remember the location and draw the first noise,
    `INITIAL_NOISE_SCALE` x a uniform sample of the action box (+-`high` (B, N, 2)), from the
    action-space stacks (kept quirk: the agent's noise scale is not used here)."""
    for b in range(space_left.shape[0]):
        if rows[b]:
            walk_start_row(b, observation, high, prev_location, noise, space, space_left)

@njit(cache=True)
def _walk(b, i, x, y, step, gx, gy, u, noise_scale, high, prev_location, noise, space, space_left):
    """Target (b, i) at (x, y) with step size `step` heads for (gx, gy) at full speed plus sticky noise:
    the noise is redrawn (`noise_scale` x a uniform sample of the box, two action-space numbers) when
    `u` (a number of its stream) is below 0.05 while it moves freely, 0.75 after a blocked step (moved
    <= 0.2 step sizes). The sum is clipped to the box. Returns the action (dx, dy)."""
    ax, ay = gx - x, gy - y
    norm = math.hypot(ax, ay)
    if norm > step:
        ax, ay = ax * step / norm, ay * step / norm
    moving = math.hypot(x - prev_location[b, i, 0], y - prev_location[b, i, 1]) > 0.2 * step
    if u < (NOISE_REFRESH_MOVING if moving else NOISE_REFRESH_STUCK):
        noise[b, i, 0] = noise_scale * _in_box(high[b, i, 0], _pop(space, space_left, b, i))
        noise[b, i, 1] = noise_scale * _in_box(high[b, i, 1], _pop(space, space_left, b, i))
    h0, h1 = high[b, i, 0], high[b, i, 1]
    ax, ay = min(max(ax + noise[b, i, 0], -h0), h0), min(max(ay + noise[b, i, 1], -h1), h1)
    prev_location[b, i, 0] = x
    prev_location[b, i, 1] = y
    return ax, ay


@njit(cache=True)
def walk_towards(b, i, x, y, step, gx, gy, noise_scale, high, prev_location, noise, draws, left, space, space_left,
                 action) -> bool:
    """One step of target (b, i)'s noisy walk towards (gx, gy) (see `_walk`; one number of its stream),
    into `action[b, i]`. Returns True, touching nothing, when its stream is empty."""
    if left[b, i] < 1:
        return True
    ax, ay = _walk(b, i, x, y, step, gx, gy, _pop(draws, left, b, i), noise_scale, high, prev_location, noise,
                   space, space_left)
    action[b, i, 0] = ax
    action[b, i, 1] = ay
    return False


# ---------------------------------------------------------------------------- greedy targets

@njit(cache=True)
def target_reset_row(b, observation, goal_bits, non_empty, need_communication) -> None:
    """`target_reset` for the targets of game b."""
    for i in range(need_communication.shape[1]):
        for w in range(NUM_WAREHOUSES):
            goal_bits[b, i, w] = observation[b, i, OWN + 6 + w]
            non_empty[b, i, w] = True
        need_communication[b, i] = False


@njit(cache=True)
def target_reset(observation, rows, goal_bits, non_empty, need_communication) -> None:
    """Start an episode for every target of the rows `rows`: the goal bits as observed, every warehouse
    believed to have cargo, nothing to tell (the walk starts with `walk_start`)."""
    for b in range(need_communication.shape[0]):
        if rows[b]:
            target_reset_row(b, observation, goal_bits, non_empty, need_communication)


@njit(cache=True)
def target_observe_row(b, observation, non_empty, need_communication) -> None:
    """`target_observe` for the targets of game b."""
    for i in range(need_communication.shape[1]):
        for w in range(NUM_WAREHOUSES):
            if observation[b, i, OWN + 6 + NUM_WAREHOUSES + w] != 0.0 and non_empty[b, i, w]:
                non_empty[b, i, w] = False
                need_communication[b, i] = True


@njit(cache=True)
def target_observe(observation, rows, non_empty, need_communication) -> None:
    """Every target of the rows `rows` forgets the warehouses it sees empty (its empty bits); if that
    changed what it believed, it will tell the team (`need_communication`)."""
    for b in range(need_communication.shape[0]):
        if rows[b]:
            target_observe_row(b, observation, non_empty, need_communication)


@njit(cache=True)
def target_share_row(b, non_empty, need_communication) -> None:
    """`target_share` for the targets of game b (what the broadcasts name: bit w of `shared`)."""
    num_targets = need_communication.shape[1]
    shared = (1 << NUM_WAREHOUSES) - 1
    news = False
    for s in range(num_targets):
        if need_communication[b, s]:
            news = True
            need_communication[b, s] = False
            for w in range(NUM_WAREHOUSES):
                if not non_empty[b, s, w]:
                    shared &= ~(1 << w)
    if news:
        for r in range(num_targets):
            for w in range(NUM_WAREHOUSES):
                non_empty[b, r, w] = non_empty[b, r, w] and (shared >> w) & 1 == 1


@njit(cache=True)
def target_share(rows, non_empty, need_communication) -> None:
    """The targets' responses round within each row of `rows`: every target with news broadcasts the
    warehouses it believes non-empty (and has no news any more); every target of the row, the senders
    included, keeps only the warehouses all the broadcasts it receives name."""
    for b in range(need_communication.shape[0]):
        if rows[b]:
            target_share_row(b, non_empty, need_communication)


@njit(cache=True)
def target_act_row(b, observation, todo, noise_scale, goal_bits, non_empty, high, prev_location, noise, draws, left,
                   space, space_left, action, short) -> None:
    """`target_act` for the targets of game b."""
    for i in range(left.shape[1]):
        if not todo[b, i]:
            continue
        short[b, i] = False
        # float64 whatever the observations' dtype (numba's float() of a float32 stays float32)
        x, y = np.float64(observation[b, i, OWN]), np.float64(observation[b, i, OWN + 1])
        loaded, step = np.float64(observation[b, i, OWN + 3]), np.float64(observation[b, i, OWN + 4])
        observed = False
        for w in range(NUM_WAREHOUSES):
            observed = observed or observation[b, i, OWN + 6 + w] != 0.0
        goal = -1
        for w in range(NUM_WAREHOUSES):
            bit = observation[b, i, OWN + 6 + w] if observed else goal_bits[b, i, w]
            if bit != 0.0:
                goal = w
                break
        renew = goal < 0 or (loaded == 0.0 and not non_empty[b, i, goal])
        count = 0
        if renew:
            for w in range(NUM_WAREHOUSES):
                count += non_empty[b, i, w]
        if left[b, i] < (2 if count > 0 else 1):
            short[b, i] = True
            continue
        if observed:
            for w in range(NUM_WAREHOUSES):
                goal_bits[b, i, w] = observation[b, i, OWN + 6 + w]
        if renew:
            for w in range(NUM_WAREHOUSES):
                goal_bits[b, i, w] = 0.0
            goal = -1
            if count > 0:
                k = min(int(_pop(draws, left, b, i) * count), count - 1)
                for w in range(NUM_WAREHOUSES):
                    if non_empty[b, i, w]:
                        if k == 0:
                            goal = w
                            break
                        k -= 1
                goal_bits[b, i, goal] = 1.0
        gx, gy = (x, y) if goal < 0 else (_WAREHOUSES[goal, 0], _WAREHOUSES[goal, 1])
        ax, ay = _walk(b, i, x, y, step, gx, gy, _pop(draws, left, b, i), noise_scale, high, prev_location,
                       noise, space, space_left)
        action[b, i, 0] = ax
        action[b, i, 1] = ay


@njit(cache=True)
def target_act(observation, todo, noise_scale, goal_bits, non_empty, high, prev_location, noise, draws, left, space,
               space_left, action, short) -> None:
    """The move (dx, dy) of every target (b, i) with `todo[b, i]`, into `action` (B, N, 2).

    Goal: the destination of the carried cargo (the observed goal bits, or the last ones when none are
    observed). Without one, or unloaded with its goal believed empty, the target picks a random
    warehouse among those believed non-empty (one number of its stream: the k-th in index order, k =
    int(u x count)), or none when it believes all empty (then it heads for where it is). Then one step of
    the noisy walk (`_walk`: one more number) towards the goal. A target whose stream holds fewer numbers
    than it needs is left untouched with `short[b, i]` set.
    """
    for b in range(left.shape[0]):
        target_act_row(b, observation, todo, noise_scale, goal_bits, non_empty, high, prev_location, noise, draws,
                       left, space, space_left, action, short)


# ---------------------------------------------------------------------------- random agents

@njit(cache=True)
def random_act_row(b, todo, high, space, space_left, action) -> None:
    """`random_act` for the agents of game b."""
    for i in range(space_left.shape[1]):
        if todo[b, i]:
            action[b, i, 0] = _in_box(high[b, i, 0], _pop(space, space_left, b, i))
            action[b, i, 1] = _in_box(high[b, i, 1], _pop(space, space_left, b, i))


@njit(cache=True)
def random_act(todo, high, space, space_left, action) -> None:
    """A fresh uniform action in the box +-`high` (B, N, 2) for every agent (b, i) with `todo[b, i]`: two
    numbers of its action-space stack, as `AgentBase._sample_action` draws them."""
    for b in range(space_left.shape[0]):
        random_act_row(b, todo, high, space, space_left, action)


# ---------------------------------------------------------------------------- the HRL executor

@njit(cache=True)
def centroid_aim_row(r, observation, keep, begin, num_targets, out) -> None:
    """The HRL cameras' executor for camera row r of (R, D) raw observations and (R, Nt) bool keep bits, into
    `out[r]` (rotation, zoom) in degrees: aim at the centroid of the kept targets the camera sees (rotation
    towards it, zoom to `desired_viewing_angle` of its distance), both clipped to the camera's per-step limits;
    with none, the lower bounds (-rotation step, -zooming step): a clockwise sweep that narrows the view."""
    x, y = float(observation[r, OWN]), float(observation[r, OWN + 1])
    rx, ry = float(observation[r, OWN + 3]), float(observation[r, OWN + 4])
    theta, max_range = float(observation[r, OWN + 5]), float(observation[r, OWN + 6])
    high_rotation, high_zoom = float(observation[r, OWN + 7]), float(observation[r, OWN + 8])
    count, cx, cy = 0, 0.0, 0.0
    for t in range(num_targets):
        slot = begin + RECORD * t
        if keep[r, t] and observation[r, slot + 4] > 0.5:
            count += 1
            cx += float(observation[r, slot])
            cy += float(observation[r, slot + 1])
    if count == 0:
        out[r, 0] = -high_rotation
        out[r, 1] = -high_zoom
        return
    cx, cy = cx / count, cy / count
    orientation = math.degrees(math.atan2(ry, rx))
    bearing = math.degrees(math.atan2(cy - y, cx - x))
    rotation = (bearing - orientation + 180.0) % 360.0 - 180.0
    zoom = desired_viewing_angle(math.hypot(cx - x, cy - y), theta, math.hypot(rx, ry), max_range) - theta
    out[r, 0] = min(max(rotation, -high_rotation), high_rotation)
    out[r, 1] = min(max(zoom, -high_zoom), high_zoom)
