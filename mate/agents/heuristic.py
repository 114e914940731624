"""Heuristic agents: cameras assigned by a central controller from a pose score table; targets that
run like greedy targets and drift away from the centres of the camera sectors they are in.

Camera team protocol (docs/agents.md): every camera sends its observation to
the controller (the camera with index 0) in the requests round; the controller pools what the
team sees, picks a pose (orientation, viewing angle) for every camera with targets in reach, and
sends each its pose in the responses round. A camera without an answer plans alone.

Pose scores. For a camera with maximum sight range R_max and minimum viewing angle theta_min,
the candidate poses are 36 orientations (-180, -170, ..., 170) x 21 viewing angles
(linspace(theta_min, 180, 21)), pose index = angle_index * 36 + orientation_index, each with its
sight range R = R_max sqrt(theta_min / theta). Relative target positions are snapped to a polar
grid (41 distances linspace(0, R_max, 41) x 72 bearings -180, -175, ..., 175; grid index =
bearing_index * 41 + distance_index). A point inside a pose's sector scores
(d / d_in) (1 - rho / R), where d is its distance to the sector's boundary and d_in the radius of
the sector's inscribed circle; outside it scores 0 (the best score is about 0.5).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit

from ..constants import (
    CAMERA_STATE_DIM_PRIVATE,
    CAMERA_STATE_DIM_PUBLIC,
    PRESERVED_DIM,
    TARGET_STATE_DIM_PUBLIC,
)
from .base import CameraAgentBase
from .geometry import RAD2DEG, normalize_angle
from .greedy import RANDOM_ACTION_PROBABILITY, GreedyTargetAgent

__all__ = ['HeuristicCameraAgent', 'HeuristicTargetAgent', 'calculate_scores']

_OWN = PRESERVED_DIM
NUM_PERMUTATIONS = 32
"""Random camera orders tried by the controller's greedy assignment."""
CONTROLLER_INDEX = 0
NUM_ORIENTATIONS, NUM_VIEWING_ANGLES = 36, 21
NUM_DISTANCES, NUM_BEARINGS = 41, 72


@functools.lru_cache(maxsize=8)
def calculate_scores(max_sight_range: float, min_viewing_angle: float):
    """The pose table of a camera: returns read-only `(state_mesh, coord_grid, scores)`.

    state_mesh: float64 (756, 3), [orientation (deg), viewing angle (deg), sight range] per pose.
    coord_grid: float64 (2952, 2), relative (x, y) of each grid point.
    scores: float64 (2952, 756), score of grid point g under pose p (see the module docstring).
    Memoised on its arguments; callers round them to 8 decimals.
    """
    orientations = np.arange(-180.0, 180.0, 360.0 / NUM_ORIENTATIONS)
    viewing_angles = np.linspace(min_viewing_angle, 180.0, NUM_VIEWING_ANGLES)
    pose_orientation, pose_angle = (a.ravel() for a in np.meshgrid(orientations, viewing_angles))
    pose_range = max_sight_range * np.sqrt(min_viewing_angle / pose_angle)
    state_mesh = np.stack([pose_orientation, pose_angle, pose_range], axis=1)

    distances = np.linspace(0.0, max_sight_range, NUM_DISTANCES)
    bearings = np.arange(-180.0, 180.0, 360.0 / NUM_BEARINGS)
    rho, phi = (a.ravel() for a in np.meshgrid(distances, bearings))
    coord_grid = np.stack([rho * np.cos(np.deg2rad(phi)), rho * np.sin(np.deg2rad(phi))], axis=1)

    rho, phi = rho[:, None], phi[:, None]
    scores = np.empty((rho.shape[0], state_mesh.shape[0]))
    for begin in range(0, state_mesh.shape[0], NUM_ORIENTATIONS):   # one viewing angle at a time
        poses = slice(begin, begin + NUM_ORIENTATIONS)
        o, theta, reach = pose_orientation[poses], pose_angle[poses], pose_range[poses]
        half = theta / 2.0
        inradius = np.where(theta < 180.0, reach / (1.0 + 1.0 / np.sin(np.deg2rad(half))), reach / 2.0)
        delta = np.abs(normalize_angle(phi - o))
        inside = (rho <= reach) & (delta <= half)
        to_arc = np.minimum(rho, reach - rho)
        to_edge = rho * np.sin(np.deg2rad(np.minimum(half - delta, 90.0)))
        depth = np.maximum(np.minimum(to_arc, to_edge), 0.0)
        scores[:, poses] = np.where(inside, (depth / inradius) * (1.0 - rho / reach), 0.0)
    for array in (state_mesh, coord_grid, scores):
        array.setflags(write=False)
    return state_mesh, coord_grid, scores


@njit(cache=True)
def _grid_distance(coord_grid, g, dx, dy):
    ex, ey = coord_grid[g, 0] - dx, coord_grid[g, 1] - dy
    return ex * ex + ey * ey


@njit(cache=True)
def _nearest_grid_point(coord_grid, dx, dy):
    """Index of the grid point nearest to (dx, dy) (Euclidean; the first index on ties).

    Exact, but searches only the points that can beat a first guess: rays whose angular distance
    and rings whose radial distance stay within the guess's distance (with a safety margin).
    """
    num_points = coord_grid.shape[0]
    num_bearings = NUM_BEARINGS
    num_distances = num_points // num_bearings
    bearing_step = 360.0 / num_bearings
    distance_step = math.hypot(coord_grid[num_distances - 1, 0], coord_grid[num_distances - 1, 1]) / (num_distances - 1)
    r = math.sqrt(dx * dx + dy * dy)
    phi = math.atan2(dy, dx) * (180.0 / math.pi)
    j0 = int(round((phi + 180.0) / bearing_step)) % num_bearings
    i0 = min(max(int(round(r / distance_step)), 0), num_distances - 1)
    best = j0 * num_distances + i0
    best_distance = _grid_distance(coord_grid, best, dx, dy)
    radius = math.sqrt(best_distance) * (1.0 + 1e-9) + 1e-9
    everywhere = radius >= r
    window = 0.0 if everywhere else math.asin(radius / r) * (180.0 / math.pi) + 1e-6
    for j in range(num_bearings):
        offset = abs((-180.0 + bearing_step * j - phi + 180.0) % 360.0 - 180.0)
        if not everywhere and offset > window:
            continue
        centre = r * math.cos(offset * (math.pi / 180.0)) if offset < 90.0 else 0.0
        low = max(int(math.floor((centre - radius) / distance_step)) - 1, 0)
        high = min(int(math.ceil((centre + radius) / distance_step)) + 1, num_distances - 1)
        for i in range(low, high + 1):
            g = j * num_distances + i
            distance = _grid_distance(coord_grid, g, dx, dy)
            if distance < best_distance or (distance == best_distance and g < best):
                best, best_distance = g, distance
    return best


@njit(cache=True)
def _nearest_grid_point_brute_force(coord_grid, dx, dy):
    """Reference for `_nearest_grid_point` (tests): scan every point."""
    best, best_distance = 0, np.inf
    for g in range(coord_grid.shape[0]):
        distance = _grid_distance(coord_grid, g, dx, dy)
        if distance < best_distance:
            best, best_distance = g, distance
    return best


@njit(cache=True)
def _best_pose(scores_c, hits_c, covered, num_targets):
    """argmax over poses of score + number of not-yet-covered targets the pose sees (first on ties)."""
    best, best_value = 0, -np.inf
    for p in range(scores_c.shape[0]):
        count = 0
        for t in range(num_targets):
            if hits_c[p, t] and not covered[t]:
                count += 1
        value = scores_c[p] + count
        if value > best_value:
            best, best_value = p, value
    return best


@njit(cache=True)
def joint_assignment(cameras, targets, coord_grid, scores, state_mesh, permutations, rotation_step, zooming_step):
    """Greedy camera-to-pose assignment over several camera orders; the best order wins.

    cameras: (n, 9) private camera states; targets: (m, 2) target locations; permutations: (K, n)
    camera orders. For each order, cameras in turn take the pose maximising (summed scores of
    their in-reach targets + number of targets newly covered); an order is rated by
    (total score + targets covered, -total cost, order, poses) compared lexicographically, the cost
    of a camera being max(|orientation change| / rotation_step, |angle change| / zooming_step)
    (orientation change not wrapped). Returns (best order (n,), poses in that order (n,), whether
    each camera has a target in reach (n,)).
    """
    n, m, num_poses = cameras.shape[0], targets.shape[0], scores.shape[1]
    summed = np.zeros((n, num_poses))
    hits = np.zeros((n, num_poses, m), dtype=np.bool_)
    in_reach = np.zeros(n, dtype=np.bool_)
    orientation = np.empty(n)
    _pose_scores(cameras, targets, coord_grid, scores, summed, hits, in_reach, orientation)
    # the pose a camera picks depends only on which of its own in-reach targets are covered: memoise
    can_memoise = m <= 62
    in_reach_bits = _in_reach_bits(hits) if can_memoise else np.zeros(n, dtype=np.int64)
    memo_key = np.full((n, 64), -1, dtype=np.int64)
    memo_pose = np.zeros((n, 64), dtype=np.int64)
    memo_size = np.zeros(n, dtype=np.int64)

    best_order = permutations[0].copy()
    best_poses = np.zeros(n, dtype=np.int64)
    best_total, best_cost = -np.inf, np.inf
    poses = np.zeros(n, dtype=np.int64)
    covered = np.zeros(m, dtype=np.bool_)
    for k in range(permutations.shape[0]):
        order = permutations[k]
        total, cost = _assign(order, cameras, summed, hits, state_mesh, orientation, rotation_step, zooming_step,
                              can_memoise, in_reach_bits, memo_key, memo_pose, memo_size, poses, covered)
        if _better(total, cost, order, poses, best_total, best_cost, best_order, best_poses):
            best_total, best_cost = total, cost
            for j in range(n):  # not a slice copy: that compiles numba's shape-mismatch error (40% of the compile)
                best_order[j], best_poses[j] = order[j], poses[j]
    return best_order, best_poses, in_reach


@njit(cache=True)
def _pose_scores(cameras, targets, coord_grid, scores, summed, hits, in_reach, orientation) -> None:
    """Per camera and pose: the summed scores of the camera's in-reach targets (summed (n, P)), which of them the
    pose covers (hits (n, P, m)), whether any target is in reach (n,), and the camera's orientation (degrees)."""
    for c in range(cameras.shape[0]):
        x, y, max_range = cameras[c, 0], cameras[c, 1], cameras[c, 6]
        orientation[c] = math.atan2(cameras[c, 4], cameras[c, 3]) * (180.0 / math.pi)
        for t in range(targets.shape[0]):
            dx, dy = targets[t, 0] - x, targets[t, 1] - y
            if math.sqrt(dx * dx + dy * dy) <= max_range:
                in_reach[c] = True
                g = _nearest_grid_point(coord_grid, dx, dy)
                for p in range(scores.shape[1]):
                    s = scores[g, p]
                    summed[c, p] += s
                    if s > 0.0:
                        hits[c, p, t] = True


@njit(cache=True)
def _in_reach_bits(hits):
    """(n,) the bits of the targets some pose of each camera covers (m <= 62)."""
    n, num_poses, m = hits.shape
    bits = np.zeros(n, dtype=np.int64)
    for c in range(n):
        for t in range(m):
            for p in range(num_poses):
                if hits[c, p, t]:
                    bits[c] |= np.int64(1) << t
                    break
    return bits


@njit(cache=True)
def _assign(order, cameras, summed, hits, state_mesh, orientation, rotation_step, zooming_step, can_memoise,
            in_reach_bits, memo_key, memo_pose, memo_size, poses, covered):
    """The cameras of `order` take their poses in turn (into `poses`, `covered` the targets covered); returns the
    order's (total score + targets covered, total cost)."""
    m = covered.shape[0]
    covered[:] = False
    covered_bits = np.int64(0)
    total, cost = 0.0, 0.0
    for j in range(order.shape[0]):
        c = order[j]
        pose = -1
        if can_memoise:
            key = covered_bits & in_reach_bits[c]
            for e in range(memo_size[c]):
                if memo_key[c, e] == key:
                    pose = memo_pose[c, e]
                    break
        if pose < 0:
            pose = _best_pose(summed[c], hits[c], covered, m)
            if can_memoise and memo_size[c] < 64:
                memo_key[c, memo_size[c]] = covered_bits & in_reach_bits[c]
                memo_pose[c, memo_size[c]] = pose
                memo_size[c] += 1
        poses[j] = pose
        cost += max(abs(state_mesh[pose, 0] - orientation[c]) / rotation_step,
                    abs(state_mesh[pose, 1] - cameras[c, 5]) / zooming_step)
        for t in range(m):
            if hits[c, pose, t] and not covered[t]:
                covered[t] = True
                if can_memoise:
                    covered_bits |= np.int64(1) << t
        total += summed[c, pose]
    num_covered = 0
    for t in range(m):
        if covered[t]:
            num_covered += 1
    return total + num_covered, cost


@njit(cache=True)
def _better(total, cost, order, poses, best_total, best_cost, best_order, best_poses) -> bool:
    """Whether an order rated (total, cost, order, poses) beats the best so far, compared lexicographically (a
    larger total, then a smaller cost, then the larger order, then the larger poses)."""
    if total != best_total:
        return total > best_total
    if cost != best_cost:
        return cost < best_cost
    for j in range(order.shape[0]):
        if order[j] != best_order[j]:
            return order[j] > best_order[j]
    for j in range(order.shape[0]):
        if poses[j] != best_poses[j]:
            return poses[j] > best_poses[j]
    return False


class HeuristicCameraAgent(CameraAgentBase):
    """Camera whose pose is chosen by the team's controller (camera 0) from a pose score table.

    Each camera moves straight towards its assigned (orientation, viewing angle), clipped to its
    step limits; with no assignment it keeps its previous action, or with probability 0.1 draws a
    random one. The controller tries 32 random camera orders (drawn from its generator).

    Args:
        seed: seed of the agent's generator.
    """

    def __init__(self, seed: int | None = None) -> None:
        self.joint_goal_state = None
        self._assigned_goal = None
        self._prev_action = [0.0, 0.0]
        self._table_key = None
        super().__init__(seed=seed)

    # The pose table is shared through calculate_scores' cache (copies and pickles stay small).
    @property
    def state_mesh(self) -> np.ndarray:
        """Candidate poses (756, 3) of this camera's table (None before reset)."""
        return None if self._table_key is None else calculate_scores(*self._table_key)[0]

    @property
    def coord_grid(self) -> np.ndarray:
        """Polar grid of relative target positions (2952, 2) (None before reset)."""
        return None if self._table_key is None else calculate_scores(*self._table_key)[1]

    @property
    def scores(self) -> np.ndarray:
        """Score of each grid point under each pose (2952, 756) (None before reset)."""
        return None if self._table_key is None else calculate_scores(*self._table_key)[2]

    @property
    def controller_index(self) -> int:
        return CONTROLLER_INDEX

    @property
    def is_controller(self) -> bool:
        return self.index == CONTROLLER_INDEX

    @property
    def prev_action(self) -> np.ndarray:
        return np.array(self._prev_action)

    def reset(self, observation) -> None:
        super().reset(observation)
        state = self.state
        self._table_key = (round(state.max_sight_range, 8), round(state.min_viewing_angle, 8))
        calculate_scores(*self._table_key)
        self.joint_goal_state = None
        self._assigned_goal = None
        self._prev_action = [0.0, 0.0]

    def observe(self, observation, info: dict | None = None) -> None:
        self.last_observation = self._accept(observation)
        self.last_info = info
        self.joint_goal_state = None
        self._assigned_goal = None

    def send_requests(self):
        if self.is_controller or self.last_observation is None:
            return ()
        return [self.pack_message(self.last_observation, recipient=CONTROLLER_INDEX)]

    def receive_requests(self, messages) -> None:
        self.last_requests = messages = tuple(messages)
        if not self.is_controller:
            return
        joint = {self.index: self.last_observation}
        for message in messages:
            joint[message.sender] = message.content
        self.joint_goal_state = self._plan(list(joint), np.stack(list(joint.values())))

    def send_responses(self):
        if not self.is_controller or not self.joint_goal_state:
            return ()
        return [self.pack_message(goal, recipient=c) for c, goal in self.joint_goal_state.items() if c != self.index]

    def receive_responses(self, messages) -> None:
        self.last_responses = messages = tuple(messages)
        if messages:
            self._assigned_goal = messages[-1].content

    def get_joint_goal_state(self, camera_states, target_states) -> dict:
        """Poses for the given cameras: {camera index: (orientation, viewing angle)} for every camera
        with a target within its maximum sight range (cameras absent from the dict get none).

        camera_states: `CameraStatePrivate` views (their `index` names the camera); target_states:
        views of the known targets (anything with a location). Draws the camera orders from this
        agent's generator.
        """
        cameras = np.array([state.values for state in camera_states], dtype=np.float64).reshape(-1, 9)
        targets = np.array([state.values[:2] for state in target_states], dtype=np.float64).reshape(-1, 2)
        return self._assign([state.index for state in camera_states], cameras, targets)

    def _plan(self, camera_indices: list, observations: np.ndarray) -> dict:
        """`get_joint_goal_state` for the cameras whose observations (n, D) are given, pooling the
        targets they see (each target located by the first observation, in row order, that sees it)."""
        cameras = observations[:, _OWN:_OWN + CAMERA_STATE_DIM_PRIVATE]
        begin, width = int(self.observation_indices[2]), TARGET_STATE_DIM_PUBLIC + 1
        records = observations[:, begin:begin + width * self.num_targets].reshape(len(cameras), -1, width)
        seen = records[:, :, TARGET_STATE_DIM_PUBLIC] != 0
        found = seen.any(axis=0)
        first = seen.argmax(axis=0)
        targets = records[first[found], np.flatnonzero(found), 0:2]
        return self._assign(camera_indices, cameras, targets)

    def _assign(self, camera_indices: list, cameras: np.ndarray, targets: np.ndarray) -> dict:
        n = len(camera_indices)
        permutations = np.argsort(self.np_random.random((NUM_PERMUTATIONS, n)), axis=1, kind='stable')
        high = self._action_high
        mesh, grid, scores = calculate_scores(*self._table_key)
        order, poses, in_reach = joint_assignment(np.ascontiguousarray(cameras), np.ascontiguousarray(targets),
                                                  grid, scores, mesh, permutations, float(high[0]), float(high[1]))
        return {camera_indices[c]: (float(mesh[pose, 0]), float(mesh[pose, 1]))
                for c, pose in zip(order.tolist(), poses.tolist()) if in_reach[c]}

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None) -> np.ndarray:
        # uses this step's observation from observe(), like the original
        if self.is_controller and self.joint_goal_state is not None:
            goal = self.joint_goal_state.get(self.index)
        elif self._assigned_goal is not None:
            goal = self._assigned_goal
        else:   # no answer from the controller: plan alone
            goal = self._plan([self.index], self.last_observation[None, :]).get(self.index)
        if goal is None or None in goal:
            if self._draw() < RANDOM_ACTION_PROBABILITY:
                self._prev_action = self._sample_action().tolist()
            return np.array(self._prev_action)
        own = self.last_observation[_OWN:_OWN + CAMERA_STATE_DIM_PUBLIC].tolist()
        orientation = math.atan2(own[4], own[3]) * RAD2DEG
        rotation = (goal[0] - orientation + 180.0) % 360.0 - 180.0
        zoom = goal[1] - own[5]
        low, high = self._action_low, self._action_high
        action = [min(max(rotation, low[0]), high[0]), min(max(zoom, low[1]), high[1])]
        self._prev_action = action
        return np.array(action)


class HeuristicTargetAgent(GreedyTargetAgent):
    """A greedy target that also drifts away from the incentre of any camera sector it is near.

    For every camera it sees whose sector (enlarged by 1.2 in range and half-angle) contains it,
    the drift points from the sector's incentre to the target; the camera whose incentre is
    closest relative to its inscribed radius wins. The drift (at most noise_scale x step size)
    is added to the greedy action unless it points against it. As in the original, the angle test
    is signed, so targets clockwise of a camera's orientation always pass it.

    Args:
        seed: seed of the agent's generator.
        noise_scale: noise scale of the greedy behaviour, and drift length in step sizes (0.5).
    """

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None) -> np.ndarray:
        observation = self._accept(observation)
        ax, ay = self._greedy_action(observation)
        x, y, _, _, step = observation[_OWN:_OWN + 5].tolist()
        begin, width = int(self.observation_indices[2]), CAMERA_STATE_DIM_PUBLIC + 1
        records = observation[begin:begin + width * self.num_cameras].tolist()
        best, best_ratio = None, math.inf
        for c in range(self.num_cameras):
            cx, cy, _, rx, ry, theta, flag = records[width * c:width * (c + 1)]
            if not flag:
                continue
            dx, dy = x - cx, y - cy
            sight_range = math.hypot(rx, ry)
            orientation = math.atan2(ry, rx) * RAD2DEG
            half = 0.5 * theta
            offset = (math.atan2(dy, dx) * RAD2DEG - orientation + 180.0) % 360.0 - 180.0
            if math.hypot(dx, dy) <= 1.2 * sight_range and offset <= 1.2 * half:
                centre_distance = sight_range / (1.0 + math.sin(math.radians(min(half, 90.0))))
                inner_radius = sight_range - centre_distance
                ix, iy = cx + centre_distance * rx / sight_range, cy + centre_distance * ry / sight_range
                ratio = math.hypot(x - ix, y - iy) / inner_radius
                if ratio < best_ratio:
                    best, best_ratio = (ix, iy), ratio
        if best is not None:
            drift_x, drift_y = x - best[0], y - best[1]
            length, limit = math.hypot(drift_x, drift_y), step * self.noise_scale
            if length > limit:
                drift_x, drift_y = drift_x * limit / length, drift_y * limit / length
            if ax * drift_x + ay * drift_y >= 0.0:
                low, high = self._action_low, self._action_high
                ax = min(max(ax + drift_x, low[0]), high[0])
                ay = min(max(ay + drift_y, low[1]), high[1])
        return np.array([ax, ay])
