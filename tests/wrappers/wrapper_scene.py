"""Known worlds for the wrapper tests: a small fixed configuration and a helper that places entities exactly."""

from __future__ import annotations

import copy

import numpy as np

import mate

CONFIG = {
    'name': 'wrapper-tests',
    'max_episode_steps': 30,
    'reward_type': 'dense',
    'num_cargoes_per_target': 4,
    'high_capacity_target_split': 0.5,
    'targets_start_with_cargoes': True,
    'bounty_factor': 1.0,
    'shuffle_entities': False,
    'camera': {'location': [[-500.0, 0.0], [500.0, 0.0]], 'radius': 40.0, 'min_viewing_angle': 30.0,
               'max_sight_range': 1000.0, 'rotation_step': 5.0, 'zooming_step': 2.5},
    'target': {'location_random_range': [[-200.0, 200.0, -200.0, 200.0]] * 3, 'step_size': 20.0,
               'sight_range': 300.0},
    'obstacle': {'location': [[0.0, 500.0], [0.0, -500.0]], 'radius': 50.0, 'transmittance': 0.0},
}
NC, NT, NO = 2, 3, 2
D_C = 22 + 5 * NT + 4 * NO + 7 * NC      # 59
D_T = 27 + 7 * NC + 4 * NO + 5 * NT      # 64


def make_env(wrappers=(), config=None, **overrides):
    """The test env (2 cameras, 3 targets, 2 opaque obstacles, no shuffling), reset with seed 0."""
    env = mate.make('MultiAgentTracking-v0', config=copy.deepcopy(config or CONFIG), wrappers=wrappers, **overrides)
    env.reset(seed=0)
    return env


def sight_range(viewing_angle: float, min_viewing_angle: float = 30.0, max_sight_range: float = 1000.0) -> float:
    return float(np.sqrt(min_viewing_angle * max_sight_range ** 2 / viewing_angle))


def set_scene(env, cameras=None, targets=None, obstacles=None, goals=None, capacities=None, remaining=None,
              empty_bits=None, episode_step=None):
    """Place entities exactly (world snapshot) and return the refreshed joint observations.

    cameras: [(x, y, orientation, viewing_angle)]; targets: [(x, y)]; obstacles: [(x, y, r)];
    goals: destination per target (-1 unloaded; a loaded target carries 1 unit); capacities: 1 or 2 per target;
    remaining: (4, 4) cargo waiting; empty_bits: (Nt, 4).
    """
    base = env.unwrapped
    snap = base.get_world()
    if cameras is not None:
        for c, (x, y, orientation, viewing_angle) in enumerate(cameras):
            r = sight_range(viewing_angle, base.camera_min_viewing_angle, base.camera_max_sight_range)
            snap['camera_state'][c, :2] = x, y
            snap['camera_state'][c, 3:6] = r * np.cos(np.radians(orientation)), r * np.sin(np.radians(orientation)), \
                viewing_angle
            snap['camera_orientation'][c] = orientation
            snap['camera_viewing_angle'][c] = viewing_angle
            snap['camera_sight_range'][c] = r
    if targets is not None:
        for t, (x, y) in enumerate(targets):
            snap['target_state'][t, :2] = x, y
    if capacities is not None:
        snap['target_state'][:, 5] = capacities
        snap['target_state'][:, 4] = base.target_step_size / np.asarray(capacities, dtype=float)
    if goals is not None:
        goals = np.asarray(goals)
        snap['target_goal'] = goals
        snap['target_state'][:, 6:10] = 0.0
        for t, goal in enumerate(goals):
            if goal >= 0:
                snap['target_state'][t, 6 + goal] = 1.0
        snap['target_state'][:, 3] = goals >= 0
        snap['target_freight'] = np.where(goals >= 0, snap['target_freight'].clip(min=1), 0)
        snap['target_bounty'] = np.where(goals >= 0, snap['target_bounty'], 0)
    if obstacles is not None:
        snap['obstacle_state'] = np.asarray(obstacles, dtype=float)
    if remaining is not None:
        snap['remaining_cargoes'] = np.asarray(remaining)
        snap['awaiting_cargo_counts'] = np.asarray(remaining).sum(axis=0) + \
            np.bincount(np.asarray(snap['target_goal'])[np.asarray(snap['target_goal']) >= 0], minlength=4)
    if empty_bits is not None:
        snap['target_state'][:, 10:14] = empty_bits
    if episode_step is not None:
        snap['episode_step'] = episode_step
    base.set_world(snap)
    return base.joint_observation()


# A scene used by several tests: camera 0 at (-500, 0) looking east (+x) with 60 degrees, camera 1 at
# (500, 0) looking north with 30 degrees; target 0 at (0, 0) (seen by camera 0 only), target 1 at (500, 300)
# (seen by camera 1 only; it sees camera 1), target 2 at (-300, 700) (seen by nobody; it sees obstacle 0).
SCENE = {'cameras': [(-500.0, 0.0, 0.0, 60.0), (500.0, 0.0, 90.0, 30.0)],
         'targets': [(0.0, 0.0), (500.0, 300.0), (-300.0, 700.0)],
         'obstacles': [(0.0, 800.0, 50.0), (0.0, -800.0, 50.0)]}
ZERO_ACTION = (np.zeros((NC, 2)), np.zeros((NT, 2)))
