"""Batched rule-based opponents for training rollouts: one numpy call acts for every env of a batch.

The built-in `GreedyTargetAgent` / `GreedyCameraAgent` are Python objects acting for one agent of one
env. The learner steps B envs at once through `mate.make_vec`, so it needs the same rules evaluated
on arrays. These classes follow the greedy rules (spec agents-and-wrappers.md §7.4-7.5) on
(B, N, D) raw observations and keep per-row state that is re-initialised row by row when an env
starts a new episode (`reset(observation, mask)`).

Differences from the per-agent Python agents (documented, deliberate):

* `VecGreedyTarget`: the warehouses known empty are one set per env (B, 4). With the Python agents
  every target broadcasts newly seen empty warehouses in the same step's responses round and all
  receivers intersect, so their sets agree as well; the only difference is the random streams.
* `VecGreedyCamera`: sightings are shared among cameras immediately (a teammate's sighting enters
  a camera's memory in the same step when the target is within 1.1 x that camera's maximum sight
  range), while the Python cameras pace their messages with random delays of 6-49 steps. The batched
  camera is therefore at least as well informed as the Python one.

Validation numbers are in docs/training.md (`scripts/validate_opponents.py`).
"""

from __future__ import annotations

import numpy as np

from ..constants import NUM_WAREHOUSES, PRESERVED_DIM, WAREHOUSES
from ..messages import Team
from ..spaces import observation_indices_of

__all__ = ['VecGreedyCamera', 'VecGreedyTarget', 'desired_viewing_angles']

_OWN = PRESERVED_DIM
NOISE_SCALE = 0.5
REFRESH_MOVING, REFRESH_STUCK = 0.05, 0.75
RANGE_FACTOR = 1.1
RANDOM_ACTION_PROBABILITY = 0.1


class VecGreedyTarget:
    """Greedy targets for B envs: run to the cargo's destination, or, unloaded, to a random warehouse
    not known to be empty; sticky noise of half the step box, redrawn with probability 0.05 per step
    while moving and 0.75 after a (nearly) blocked step.

    Args:
        num_envs: batch size B.
        num_targets: targets per env.
        seed: seed of the numpy generator.
    """

    def __init__(self, num_envs: int, num_targets: int, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)
        shape = (num_envs, num_targets)
        self.goal_bits = np.zeros(shape + (NUM_WAREHOUSES,))
        self.non_empty = np.ones((num_envs, NUM_WAREHOUSES), dtype=bool)
        self.prev_location = np.zeros(shape + (2,))
        self.noise = np.zeros(shape + (2,))

    def reset(self, observation: np.ndarray, mask: np.ndarray | None = None) -> None:
        """Start new episodes in the rows `mask` (all rows if None) from raw observations (B, Nt, Dt)."""
        mask = slice(None) if mask is None else np.asarray(mask, dtype=bool)
        own = np.asarray(observation[mask, :, _OWN:_OWN + 14], dtype=np.float64)
        step = own[..., 4:5]
        self.prev_location[mask] = own[..., 0:2]
        self.noise[mask] = NOISE_SCALE * step * self.rng.uniform(-1.0, 1.0, own[..., 0:2].shape)
        self.goal_bits[mask] = own[..., 6:10]
        self.non_empty[mask] = True

    def act(self, observation: np.ndarray) -> np.ndarray:
        """(B, Nt, 2) moves from raw observations (B, Nt, Dt); updates the rows' state."""
        own = np.asarray(observation[..., _OWN:_OWN + 14], dtype=np.float64)
        location, loaded, step = own[..., 0:2], own[..., 3] > 0.5, own[..., 4:5]
        bits, empty = own[..., 6:10], own[..., 10:14] > 0.5
        self.non_empty &= ~empty.any(axis=1)                      # team-wide knowledge, this step
        has_bits = bits.any(axis=-1, keepdims=True)
        goal_bits = np.where(has_bits, bits, self.goal_bits)
        has_goal = goal_bits.any(axis=-1)
        goal = np.argmax(goal_bits != 0, axis=-1)                 # first set bit
        goal_known_empty = ~np.take_along_axis(self.non_empty[:, None, :].repeat(goal.shape[1], 1),
                                               goal[..., None], axis=-1)[..., 0]
        renew = ~has_goal | (~loaded & goal_known_empty)
        if renew.any():
            counts = self.non_empty.sum(axis=-1)                   # (B,)
            pick = np.minimum((self.rng.random(goal.shape) * counts[:, None]).astype(np.int64),
                              np.maximum(counts[:, None] - 1, 0))  # k-th non-empty warehouse
            rank = np.cumsum(self.non_empty, axis=-1) - 1           # (B, 4)
            chosen = np.argmax((rank[:, None, :] == pick[..., None]) & self.non_empty[:, None, :], axis=-1)
            available = (counts > 0)[:, None]
            new_bits = np.where(available[..., None], np.eye(NUM_WAREHOUSES)[chosen], 0.0)
            goal_bits = np.where(renew[..., None], new_bits, goal_bits)
            goal = np.where(renew, chosen, goal)
            has_goal = np.where(renew, available, has_goal)
        self.goal_bits = goal_bits
        point = np.where(has_goal[..., None], WAREHOUSES[goal], location)
        direction = point - location
        norm = np.linalg.norm(direction, axis=-1, keepdims=True)
        direction = np.where(norm > step, direction * step / np.maximum(norm, 1e-12), direction)
        moving = np.linalg.norm(location - self.prev_location, axis=-1) > 0.2 * step[..., 0]
        refresh = self.rng.random(moving.shape) < np.where(moving, REFRESH_MOVING, REFRESH_STUCK)
        fresh = NOISE_SCALE * step * self.rng.uniform(-1.0, 1.0, self.noise.shape)
        self.noise = np.where(refresh[..., None], fresh, self.noise)
        self.prev_location = location.copy()
        return np.clip(direction + self.noise, -step, step)


def desired_viewing_angles(distance, viewing_angle, sight_range, max_sight_range, iterations: int = 20):
    """Array version of `mate.agents.greedy.desired_viewing_angle` (degrees, element-wise)."""
    half = 0.5 * np.pi / 180.0
    theta_min = viewing_angle * (sight_range / max_sight_range) ** 2
    area = viewing_angle * sight_range ** 2
    theta = np.full(np.shape(distance), 180.0)
    for _ in range(iterations):
        reach = distance * (1.0 + np.sin(np.minimum(theta * half, 0.5 * np.pi)))
        theta = area / np.maximum(reach * reach, 1e-12)
    theta = np.clip(theta, theta_min, 180.0)
    theta = np.where(distance <= 0.5 * np.sqrt(area / 180.0), 180.0, theta)
    far = distance * (1.0 + np.sin(theta_min * half)) >= max_sight_range
    return np.where(far, theta_min, theta)


class VecGreedyCamera:
    """Greedy cameras for B envs: aim at the nearest target seen in the last `memory_period` steps
    (by the camera or, immediately, a teammate) within 1.1 x the maximum sight range, and zoom so the
    target sits at the centre of the sector's inscribed circle; with no candidate keep the previous
    action, or with probability 0.1 draw a uniform random one.
    """

    def __init__(self, num_envs: int, num_cameras: int, num_targets: int, num_obstacles: int,
                 seed: int | None = None, memory_period: int = 25) -> None:
        self.rng = np.random.default_rng(seed)
        self.period = int(memory_period)
        begin = int(observation_indices_of(Team.CAMERA, num_cameras, num_targets, num_obstacles)[2])
        self.records = slice(begin, begin + 5 * num_targets)
        self.num_targets = num_targets
        self.memory = np.zeros((num_envs, num_cameras, num_targets, 4))
        self.time2forget = np.zeros((num_envs, num_cameras, num_targets), dtype=np.int64)
        self.prev_action = np.zeros((num_envs, num_cameras, 2))

    def _targets(self, observation):
        records = np.asarray(observation[..., self.records], dtype=np.float64)
        records = records.reshape(records.shape[:-1] + (self.num_targets, 5))
        return records[..., :4], records[..., 4] > 0.5

    def reset(self, observation: np.ndarray, mask: np.ndarray | None = None) -> None:
        mask = slice(None) if mask is None else np.asarray(mask, dtype=bool)
        values, seen = self._targets(observation[mask])
        self.memory[mask] = values
        self.time2forget[mask] = np.where(seen, self.period, 0)
        self.prev_action[mask] = 0.0

    def act(self, observation: np.ndarray) -> np.ndarray:
        observation = np.asarray(observation, dtype=np.float64)
        own = observation[..., _OWN:_OWN + 9]
        x, y, rx, ry, theta, max_range = (own[..., k] for k in (0, 1, 3, 4, 5, 6))
        reach = RANGE_FACTOR * max_range                                     # (B, Nc)
        values, seen = self._targets(observation)                            # (B, Nc, Nt, 4), (B, Nc, Nt)
        self.time2forget = np.maximum(self.time2forget - 1, 0)
        # own sightings first, then any teammate's sighting of a target within this camera's reach
        own_seen = seen
        self.memory = np.where(own_seen[..., None], values, self.memory)
        team_seen = seen.any(axis=1)                                         # (B, Nt)
        first = np.argmax(seen, axis=1)                                      # a camera that saw it
        team_values = np.take_along_axis(values, first[:, None, :, None], axis=1)[:, 0]   # (B, Nt, 4)
        distance_team = np.hypot(team_values[..., 0][:, None] - x[..., None],
                                 team_values[..., 1][:, None] - y[..., None])
        shared = team_seen[:, None, :] & ~own_seen & (distance_team < reach[..., None])
        self.memory = np.where(shared[..., None], team_values[:, None], self.memory)
        self.time2forget = np.where(own_seen | shared, self.period, self.time2forget)
        distance = np.hypot(self.memory[..., 0] - x[..., None], self.memory[..., 1] - y[..., None])
        candidate = (self.time2forget > 0) & (distance < reach[..., None])
        distance = np.where(candidate, distance, np.inf)
        best = np.argmin(distance, axis=-1)                                  # (B, Nc)
        has = candidate.any(axis=-1)
        best_distance = np.take_along_axis(distance, best[..., None], -1)[..., 0]
        best_xy = np.take_along_axis(self.memory[..., :2], best[..., None, None], -2)[..., 0, :]
        orientation = np.degrees(np.arctan2(ry, rx))
        bearing = np.degrees(np.arctan2(best_xy[..., 1] - y, best_xy[..., 0] - x))
        rotation = (bearing - orientation + 180.0) % 360.0 - 180.0
        safe = np.where(has, best_distance, 1.0)
        zoom = desired_viewing_angles(safe, theta, np.hypot(rx, ry), max_range) - theta
        high = own[..., 7:9]
        tracking = np.clip(np.stack([rotation, zoom], axis=-1), -high, high)
        redraw = ~has & (self.rng.random(has.shape) < RANDOM_ACTION_PROBABILITY)
        random = self.rng.uniform(-1.0, 1.0, high.shape) * high
        action = np.where(has[..., None], tracking, np.where(redraw[..., None], random, self.prev_action))
        self.prev_action = action
        return action
