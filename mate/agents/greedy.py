"""Greedy agents: cameras track the nearest remembered target; targets run to their destination.

Both share what they learn with teammates: cameras their own state (once) and the targets they
see; targets the warehouses they found empty. Decision rules and their quirks follow the
original MATE (spec agents-and-wrappers.md §7.4-7.5, decisions.md "kept quirks").
"""

from __future__ import annotations

import math

import numpy as np

from ..constants import (
    CAMERA_STATE_DIM_PRIVATE,
    NUM_WAREHOUSES,
    PRESERVED_DIM,
    TARGET_STATE_DIM_PRIVATE,
    TARGET_STATE_DIM_PUBLIC,
    WAREHOUSES,
)
from .base import CameraAgentBase, TargetAgentBase
from .geometry import DEG2RAD, RAD2DEG
from .naive import NoisyWalker
from .utils import CameraStatePrivate, TargetStatePublic

__all__ = ['GreedyCameraAgent', 'GreedyTargetAgent']

_OWN = PRESERVED_DIM
_WAREHOUSES = WAREHOUSES.tolist()
RANGE_FACTOR = 1.1
"""Targets count as reachable within 1.1 x a camera's maximum sight range."""
RANDOM_ACTION_PROBABILITY = 0.1
"""Chance per step that an idle camera (no candidate target) draws a fresh random action."""
MAX_VIEWING_ANGLE = 180.0
ZOOM_ITERATIONS = 20
_HALF_DEG2RAD = 0.5 * DEG2RAD
_RIGHT_ANGLE = 90.0 * DEG2RAD


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
    theta, sin = MAX_VIEWING_ANGLE, math.sin
    for _ in range(ZOOM_ITERATIONS):
        half = theta * _HALF_DEG2RAD
        reach = distance * (1.0 + sin(half if half < _RIGHT_ANGLE else _RIGHT_ANGLE))
        theta = area / (reach * reach)
    return theta_min if theta < theta_min else MAX_VIEWING_ANGLE if theta > MAX_VIEWING_ANGLE else theta


class GreedyCameraAgent(CameraAgentBase):
    """Aim at the nearest target seen (by itself or a teammate) in the last `memory_period` steps
    and zoom so that the target sits at the centre of the sector's inscribed circle. With no such
    target: keep the previous action, or with probability 0.1 draw a random one.

    Communication (responses round, peer to peer): the camera sends its own state to every
    teammate once, then the targets it saw since its last message to that teammate, filtered to
    the teammate's reach (1.1 x its maximum sight range). After each message to a teammate it waits
    a random U{memory_period // 4, ..., 2 memory_period - 1} steps before the next one to it; what
    could not be sent in a step is dropped.

    Args:
        seed: seed of the agent's generator.
        memory_period: steps a sighting stays a candidate (25).
        filterout_unloaded: ignore targets seen unloaded, unless never seen loaded (False).
        filterout_beyond_range: ignore targets beyond 1.1 x the maximum sight range, and send only
            sightings within a teammate's reach (True). As in the original, with False no sightings
            are shared at all.
    """

    def __init__(self, seed: int | None = None, memory_period: int = 25, filterout_unloaded: bool = False,
                 filterout_beyond_range: bool = True) -> None:
        self.memory_period = int(memory_period)
        if self.memory_period < 1:
            raise ValueError(f'memory_period must be a positive integer, got {memory_period!r}')
        self.filterout_unloaded = bool(filterout_unloaded)
        self.filterout_beyond_range = bool(filterout_beyond_range)
        self._memory = []
        self.time2forget = []
        self.never_loaded = []
        self.neighboring_teammate_states = {}
        self.message2send = {}
        self.communication_delay = []
        self._prev_action = [0.0, 0.0]
        super().__init__(seed=seed)

    def reset(self, observation) -> None:
        super().reset(observation)
        observation = np.asarray(observation, dtype=np.float64)
        nt, period = self.num_targets, self.memory_period
        begin = int(self.observation_indices[2])
        records = observation[begin:begin + (TARGET_STATE_DIM_PUBLIC + 1) * nt].tolist()
        self._memory = [records[5 * t:5 * t + 4] for t in range(nt)]
        self.time2forget = [period if records[5 * t + 4] else 0 for t in range(nt)]
        self.never_loaded = [True] * nt
        self._prev_action = [0.0, 0.0]
        self.neighboring_teammate_states = {}
        self.communication_delay = [0] * self.num_cameras
        own = observation[_OWN:_OWN + CAMERA_STATE_DIM_PRIVATE].tolist()
        self.message2send = {'state': CameraStatePrivate.from_values(own, self.index)}

    @property
    def memory(self) -> tuple:
        """Last known public state of every target (all zeros if never seen)."""
        return tuple(TargetStatePublic.from_values(values, t) for t, values in enumerate(self._memory))

    @property
    def prev_action(self) -> np.ndarray:
        return np.array(self._prev_action)

    def observe(self, observation, info: dict | None = None) -> None:
        observation = self._accept(observation)
        self.last_observation, self.last_info = observation, info
        time2forget, memory, period = self.time2forget, self._memory, self.memory_period
        for t, left in enumerate(time2forget):
            if left > 0:
                time2forget[t] = left - 1
        begin = int(self.observation_indices[2])
        records = observation[begin:begin + (TARGET_STATE_DIM_PUBLIC + 1) * self.num_targets].tolist()
        seen = None
        for t in range(self.num_targets):
            if records[5 * t + 4]:
                values = records[5 * t:5 * t + 4]
                memory[t] = values
                time2forget[t] = period
                if values[3]:
                    self.never_loaded[t] = False
                if seen is None:
                    seen = self.message2send.setdefault('target_states', [])
                seen.append(TargetStatePublic.from_values(values, t))

    def send_responses(self):
        delay = self.communication_delay
        for c, left in enumerate(delay):
            if left > 0:
                delay[c] = left - 1
        pending = self.message2send
        if not pending:
            return ()
        messages = []
        period = self.memory_period
        low, high = period // 4, 2 * period
        for c in range(self.num_cameras):
            if c == self.index or delay[c] > 0:
                continue
            content = dict(pending)
            if 'target_states' in content:
                neighbor = self.neighboring_teammate_states.get(c)
                if neighbor is not None and self.filterout_beyond_range:
                    nv = neighbor.values
                    nx, ny, reach = nv[0], nv[1], RANGE_FACTOR * nv[6]
                    kept = [s for s in content['target_states']
                            if math.hypot(s.values[0] - nx, s.values[1] - ny) < reach]
                    if kept:
                        content['target_states'] = kept
                    else:
                        del content['target_states']
                else:
                    del content['target_states']   # kept quirk: unknown neighbours get no sightings
            if content:
                messages.append(self.pack_message(content, recipient=c))
                delay[c] = low + int(self._draw() * (high - low)) if high > low else low
        self.message2send = {}
        return messages

    def receive_responses(self, messages) -> None:
        self.last_responses = messages = tuple(messages)
        memory, time2forget, period = self._memory, self.time2forget, self.memory_period
        for message in messages:
            content = message.content
            if 'state' in content:
                # Kept quirk: every camera that sent its state counts as a neighbour, however far.
                self.neighboring_teammate_states[message.sender] = content['state']
            for target in content.get('target_states', ()):
                values = target.values
                memory[target.index] = values
                time2forget[target.index] = period
                if values[3]:
                    self.never_loaded[target.index] = False

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None) -> np.ndarray:
        observation = self._accept(observation)
        x, y, _, rx, ry, theta, max_range = observation[_OWN:_OWN + 7].tolist()
        reach = RANGE_FACTOR * max_range
        by_range, by_load = self.filterout_beyond_range, self.filterout_unloaded
        never_loaded = self.never_loaded
        best, best_distance = None, math.inf
        for t, left in enumerate(self.time2forget):
            if left > 0:
                values = self._memory[t]
                distance = math.hypot(values[0] - x, values[1] - y)
                if by_range and not distance < reach:
                    continue
                if by_load and not (values[3] or never_loaded[t]):
                    continue
                if distance < best_distance:
                    best, best_distance = values, distance
        if best is None:
            if self._draw() < RANDOM_ACTION_PROBABILITY:
                self._prev_action = self._sample_action().tolist()
            return np.array(self._prev_action)
        orientation = math.atan2(ry, rx) * RAD2DEG
        bearing = math.atan2(best[1] - y, best[0] - x) * RAD2DEG
        rotation = (bearing - orientation + 180.0) % 360.0 - 180.0
        zoom = desired_viewing_angle(best_distance, theta, math.hypot(rx, ry), max_range) - theta
        low, high = self._action_low, self._action_high
        action = [min(max(rotation, low[0]), high[0]), min(max(zoom, low[1]), high[1])]
        self._prev_action = action
        return np.array(action)


class GreedyTargetAgent(NoisyWalker, TargetAgentBase):
    """Run straight to the destination warehouse of the carried cargo; when unloaded, to a random
    warehouse still believed to have cargo. Sticky random noise (see `NoisyWalker`) is the only
    way around obstacles. Warehouses found empty are broadcast to the team (responses round).

    Args:
        seed: seed of the agent's generator.
        noise_scale: scale of the noise, a fraction of the step box (0.5). The noise drawn at
            reset always uses 0.5 (kept from the original).
    """

    def __init__(self, seed: int | None = None, noise_scale: float = 0.5) -> None:
        self.noise_scale = float(noise_scale)
        self._goal_bits = [0.0] * NUM_WAREHOUSES
        self.non_empty_warehouses = set(range(NUM_WAREHOUSES))
        self.need_communication = False
        super().__init__(seed=seed)

    def reset(self, observation) -> None:
        super().reset(observation)
        observation = np.asarray(observation, dtype=np.float64)
        self._start_walk(observation)
        self._goal_bits = observation[_OWN + 6:_OWN + 6 + NUM_WAREHOUSES].tolist()
        self.non_empty_warehouses = set(range(NUM_WAREHOUSES))
        self.need_communication = False

    @property
    def goal_bits(self) -> np.ndarray:
        """int64 (4,): the current goal (cargo weight per destination, or a single 1 when unloaded)."""
        return np.array(self._goal_bits, dtype=np.int64)

    @property
    def goal(self) -> int | None:
        """Index of the warehouse the target heads for, or None."""
        for w, bit in enumerate(self._goal_bits):
            if bit:
                return w
        return None

    @property
    def goal_location(self) -> np.ndarray | None:
        goal = self.goal
        return None if goal is None else WAREHOUSES[goal].copy()

    def observe(self, observation, info: dict | None = None) -> None:
        observation = self._accept(observation)
        self.last_observation, self.last_info = observation, info
        begin = _OWN + 6 + NUM_WAREHOUSES
        empty = observation[begin:begin + NUM_WAREHOUSES].tolist()
        if empty[0] or empty[1] or empty[2] or empty[3]:
            seen_empty = {w for w, bit in enumerate(empty) if bit}
            if seen_empty & self.non_empty_warehouses:
                self.non_empty_warehouses -= seen_empty
                self.need_communication = True

    def send_responses(self):
        if not self.need_communication:
            return ()
        self.need_communication = False
        return [self.pack_message({'non_empty_warehouses': set(self.non_empty_warehouses)})]

    def receive_responses(self, messages) -> None:
        self.last_responses = messages = tuple(messages)
        for message in messages:
            warehouses = message.content.get('non_empty_warehouses')
            if warehouses is not None:
                self.non_empty_warehouses &= warehouses

    def _greedy_action(self, observation: np.ndarray) -> list:
        own = observation[_OWN:_OWN + TARGET_STATE_DIM_PRIVATE].tolist()
        x, y, loaded, step = own[0], own[1], own[3], own[4]
        bits = own[6:6 + NUM_WAREHOUSES]
        if bits[0] or bits[1] or bits[2] or bits[3]:
            self._goal_bits = bits
        else:
            bits = self._goal_bits
        goal = 0 if bits[0] else 1 if bits[1] else 2 if bits[2] else 3 if bits[3] else None
        if goal is None or (not loaded and goal not in self.non_empty_warehouses):
            self._goal_bits = [0.0] * NUM_WAREHOUSES
            goal = None
            if self.non_empty_warehouses:
                choices = sorted(self.non_empty_warehouses)
                goal = choices[min(int(self._draw() * len(choices)), len(choices) - 1)]
                self._goal_bits[goal] = 1.0
        gx, gy = (x, y) if goal is None else _WAREHOUSES[goal]
        return self._walk(observation, x, y, step, gx, gy)

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None) -> np.ndarray:
        return np.array(self._greedy_action(self._accept(observation)))
