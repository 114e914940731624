"""Differential test against trajectories recorded from the original MATE (tests/data/original/).

Every recorded transition is replayed on its own: snapshot k is loaded with `set_world`, the joint
observation is compared, the recorded joint action k is stepped, and the resulting world, rewards and
termination are compared with what the original produced (snapshot k + 1).

Two tiers of fields:
  strict  must agree on every transition: camera dynamics, target motion and collisions, cargo
          bookkeeping, counters, termination;
  soft    everything that depends on occlusion (view masks, coverage, tracked steps, bounties,
          rewards, observations) may disagree on at most SOFT_TOLERANCE of the transitions: the original
          approximates an obstacle's silhouette by an interpolated polygon, our exact segment-versus-disc
          test differs from it on rare boundary cases.
A target that picks up cargo draws its destination at random, so its new cargo is checked for
consistency with the snapshot instead of equality with the recording.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

import mate

ORIGINAL = Path(__file__).resolve().parent / 'data' / 'original'
MIN_FIXTURES = 6
SOFT_TOLERANCE = 0.005  # share of transitions on which a soft field may disagree
RTOL, ATOL = 1e-7, 1e-6
ANGLE_ATOL = 1e-6       # degrees, compared modulo 360

# The original's warehouses (terrain [-1000, 1000]^2): squares of half-width 75 in the corners, NE, NW, SW, SE.
# Written out here rather than imported from mate, so that the test does not trust what it checks.
ORIGINAL_WAREHOUSES = np.array([[925.0, 925.0], [-925.0, 925.0], [-925.0, -925.0], [925.0, -925.0]])
ORIGINAL_WAREHOUSE_HALF_WIDTH = 75.0

# What `set_world` reads from a snapshot.
SNAPSHOT_INPUTS = (
    'camera_state', 'camera_orientation', 'camera_viewing_angle', 'camera_sight_range',
    'target_state', 'target_goal', 'target_freight', 'target_bounty', 'target_steps',
    'target_tracked_steps', 'obstacle_state', 'remaining_cargoes', 'awaiting_cargo_counts',
    'num_delivered_cargoes', 'episode_step',
)

# Strict fields of the world after a step, compared as they are, for every entity.
STRICT_NUMERIC = ('camera_state', 'camera_viewing_angle', 'camera_sight_range', 'target_steps',
                  'num_delivered_cargoes', 'awaiting_cargo_counts', 'episode_step')
STRICT_ANGLES = ('camera_orientation',)
STRICT_EXACT = ('target_is_colliding',)
# Strict fields of the targets that picked up nothing at this step (a pick-up draws a random destination).
STRICT_UNLESS_PICKUP = ('target_goal', 'target_freight')
TARGET_MOTION = slice(0, 6)  # target_state: x, y, sight range, loaded, speed, capacity
TARGET_CARGO = slice(6, 14)  # target_state: units carried per destination, empty-warehouse bits
GOAL_BITS = slice(6, 10)

# Soft fields of the world after a step (occlusion-dependent).
SOFT_NUMERIC = ('coverage_rate', 'target_tracked_steps')
SOFT_EXACT = ('camera_target_view_mask', 'camera_obstacle_view_mask', 'camera_camera_view_mask',
              'target_camera_view_mask', 'target_obstacle_view_mask', 'target_target_view_mask')
SOFT_UNLESS_PICKUP = ('target_bounty',)


def _fixture_paths() -> list[Path]:
    # a missing or empty folder yields one failing case instead of none
    return sorted(ORIGINAL.glob('*.npz')) or [ORIGINAL / 'NO-FIXTURES.npz']


@lru_cache(maxsize=None)
def _read_fixture(path: Path) -> tuple[dict, dict[str, np.ndarray]]:
    meta = json.loads(path.with_suffix('.json').read_text())
    with np.load(path) as npz:
        arrays = {key: npz[key] for key in npz.files}
    for array in arrays.values():
        array.setflags(write=False)  # shared by the tests through the cache
    return meta, arrays


def load_fixture(path: Path) -> tuple[dict, dict[str, np.ndarray]]:
    """The metadata and the arrays of a recorded fixture, as writable copies."""
    meta, arrays = _read_fixture(path)
    return json.loads(json.dumps(meta)), {key: array.copy() for key, array in arrays.items()}


def _close(got, expected) -> bool:
    got, expected = np.asarray(got, dtype=np.float64), np.asarray(expected, dtype=np.float64)
    return got.shape == expected.shape and bool(np.allclose(got, expected, rtol=RTOL, atol=ATOL))


def _same_angles(got, expected) -> bool:
    got, expected = np.asarray(got, dtype=np.float64), np.asarray(expected, dtype=np.float64)
    if got.shape != expected.shape:
        return False
    wrapped = np.mod(got - expected + 180.0, 360.0) - 180.0
    return bool(np.all(np.abs(wrapped) <= ANGLE_ATOL))


def _equal(got, expected) -> bool:
    return np.array_equal(np.asarray(got, dtype=bool), np.asarray(expected, dtype=bool))


def _text(value) -> str:
    return np.array2string(np.asarray(value), precision=7, threshold=30, max_line_width=200).replace('\n', ' ')


@dataclass(frozen=True)
class Mismatch:
    fixture: str
    step: int
    field: str
    expected: object
    got: object

    def __str__(self) -> str:
        return (f'{self.fixture}, step {self.step}, {self.field}: '
                f'expected {_text(self.expected)}, got {_text(self.got)}')


@dataclass
class Replay:
    """The outcome of replaying one fixture."""
    fixture: str
    transitions: int = 0
    strict: list[Mismatch] = field(default_factory=list)
    soft: list[Mismatch] = field(default_factory=list)

    @property
    def soft_steps(self) -> set[int]:
        return {mismatch.step for mismatch in self.soft}

    @property
    def soft_rate(self) -> float:
        return len(self.soft_steps) / max(self.transitions, 1)


def _warehouse_at(location) -> int | None:
    """The index of the (original's) warehouse that contains `location`, None outside them all."""
    inside = np.max(np.abs(ORIGINAL_WAREHOUSES - np.asarray(location)), axis=1) <= ORIGINAL_WAREHOUSE_HALF_WIDTH + 1e-9
    return int(np.flatnonzero(inside)[0]) if inside.sum() == 1 else None


def _check_pickups(name: str, step: int, picked: np.ndarray, waiting: np.ndarray, after: dict) -> list[Mismatch]:
    """Pick-ups at a step: each target's new destination must have cargo waiting at its warehouse in the
    snapshot, it must carry min(capacity, units waiting) units for it and nothing for the others, and the
    waiting cargo must be the snapshot's less exactly what was picked up."""
    failures = []
    state, goals = np.asarray(after['target_state']), np.asarray(after['target_goal'])
    expected_remaining = np.array(waiting, dtype=np.int64)
    for t in np.flatnonzero(picked):
        warehouse, goal = _warehouse_at(state[t, :2]), int(goals[t])
        what = f'pick-up of target {t}'
        if warehouse is None or not 0 <= goal < len(ORIGINAL_WAREHOUSES) or waiting[warehouse, goal] <= 0:
            failures.append(Mismatch(name, step, what, f'a destination with cargo waiting at warehouse {warehouse}',
                                     f'destination {goal} at location {state[t, :2]}'))
            continue
        expected_bits = np.zeros(len(ORIGINAL_WAREHOUSES))
        expected_bits[goal] = min(int(state[t, 5]), int(waiting[warehouse, goal]))
        if not _close(state[t, GOAL_BITS], expected_bits):
            failures.append(Mismatch(name, step, f'{what}: units carried per destination',
                                     expected_bits, state[t, GOAL_BITS]))
        expected_remaining[warehouse, goal] -= int(round(state[t, GOAL_BITS][goal]))
    if not _close(after['remaining_cargoes'], expected_remaining):
        failures.append(Mismatch(name, step, 'remaining_cargoes (snapshot less the loads picked up)',
                                 expected_remaining, after['remaining_cargoes']))
    return failures


def replay(name: str, meta: dict, data: dict[str, np.ndarray], steps: int | None = None) -> Replay:
    """Replay the first `steps` (default all) recorded transitions of a fixture and collect every mismatch."""
    result = Replay(name)
    env = mate.make('MultiAgentTracking-v0', config=meta['config'])
    try:
        env.reset(seed=0)
        world = env.unwrapped
        num_steps = len(data['done']) if steps is None else min(steps, len(data['done']))
        for k in range(num_steps):
            strict, soft = result.strict, result.soft

            def compare(tier, what, same, got, expected):
                if not same(got, expected):
                    tier.append(Mismatch(name, k, what, expected, got))

            world.set_world({key: np.array(data[key][k]) for key in SNAPSHOT_INPUTS})
            cam_obs, tgt_obs = world.joint_observation()
            compare(soft, 'camera observation of the snapshot', _close, cam_obs, data['camera_observation'][k])
            compare(soft, 'target observation of the snapshot', _close, tgt_obs, data['target_observation'][k])

            (cam_obs, tgt_obs), (cam_reward, tgt_reward), terminated, truncated, _ = env.step(
                (data['camera_action'][k], data['target_action'][k]))
            after = world.get_world()
            result.transitions += 1
            expected = {key: array[k + 1] for key, array in data.items() if len(array) > len(data['done'])}
            picked = np.asarray(data['pickup'][k], dtype=bool)
            kept = ~picked

            # strict tier
            for key in STRICT_NUMERIC:
                compare(strict, key, _close, after[key], expected[key])
            for key in STRICT_ANGLES:
                compare(strict, key, _same_angles, after[key], expected[key])
            for key in STRICT_EXACT:
                compare(strict, key, _equal, after[key], expected[key])
            state = np.asarray(after['target_state'])
            compare(strict, 'target_state[:, 0:6] (location, sight range, loaded, speed, capacity)', _close,
                    state[:, TARGET_MOTION], expected['target_state'][:, TARGET_MOTION])
            compare(strict, 'target_state[:, 6:14] (cargo) of targets without a pick-up', _close,
                    state[kept, TARGET_CARGO], expected['target_state'][kept, TARGET_CARGO])
            for key in STRICT_UNLESS_PICKUP:
                compare(strict, f'{key} of targets without a pick-up', _close,
                        np.asarray(after[key])[kept], expected[key][kept])
            if picked.any():
                strict.extend(_check_pickups(name, k, picked, data['remaining_cargoes'][k], after))
            else:
                compare(strict, 'remaining_cargoes', _close, after['remaining_cargoes'], expected['remaining_cargoes'])
            compare(strict, 'done (terminated or truncated)', lambda a, b: a == b,
                    bool(terminated or truncated), bool(data['done'][k]))

            # soft tier
            compare(soft, 'camera team reward', _close, cam_reward, data['camera_team_reward'][k])
            compare(soft, 'target team reward', _close, tgt_reward, data['target_team_reward'][k])
            for key in SOFT_NUMERIC:
                compare(soft, key, _close, after[key], expected[key])
            for key in SOFT_EXACT:
                compare(soft, key, _equal, after[key], expected[key])
            for key in SOFT_UNLESS_PICKUP:
                compare(soft, f'{key} of targets without a pick-up', _close,
                        np.asarray(after[key])[kept], expected[key][kept])
            if not picked.any():  # a pick-up's random destination shows in the observations
                compare(soft, 'camera observation returned by step', _close, cam_obs, expected['camera_observation'])
                compare(soft, 'target observation returned by step', _close, tgt_obs, expected['target_observation'])
    finally:
        env.close()
    return result


def _summary(result: Replay, limit: int = 10) -> str:
    lines = [f'{result.fixture}: {result.transitions} transitions, {len(result.strict)} strict mismatches, '
             f'soft mismatches on {len(result.soft_steps)} steps ({100 * result.soft_rate:.2f}%, '
             f'at most {100 * SOFT_TOLERANCE:.2f}% allowed)']
    lines += [f'  strict: {mismatch}' for mismatch in result.strict[:limit]]
    lines += [f'  soft:   {mismatch}' for mismatch in result.soft[:limit]]
    return '\n'.join(lines)


def test_recorded_fixtures_are_present():
    paths = sorted(ORIGINAL.glob('*.npz'))
    assert len(paths) >= MIN_FIXTURES, f'expected at least {MIN_FIXTURES} fixtures in {ORIGINAL}, found {len(paths)}'
    missing = [path.name for path in paths if not path.with_suffix('.json').is_file()]
    assert not missing, f'fixtures without their .json metadata in {ORIGINAL}: {missing}'


@pytest.mark.parametrize('path', _fixture_paths(), ids=lambda path: path.stem)
def test_fixture_matches_original(path):
    assert path.is_file(), f'no recorded fixtures in {ORIGINAL}'
    meta, data = load_fixture(path)
    result = replay(path.stem, meta, data)
    assert result.transitions == len(data['done']) > 0, f'{path.stem}: nothing was replayed'
    assert not result.strict, f'strict mismatches against the original\n{_summary(result)}'
    assert result.soft_rate <= SOFT_TOLERANCE, f'too many occlusion-dependent mismatches\n{_summary(result)}'


# ------------------------------------------------------------------ the check itself bites

PROBE = ORIGINAL / '4v8-9-clear-greedy-both.npz'
PROBE_STEPS = 12


def _first_move(data: dict[str, np.ndarray]) -> tuple[int, int]:
    """The first (step, target) at which a target moved by more than one unit."""
    moved = np.linalg.norm(np.diff(data['target_state'][:PROBE_STEPS + 1, :, :2], axis=0), axis=-1) > 1.0
    steps, targets = np.nonzero(moved)
    assert len(steps), f'{PROBE.stem}: no target moves in the first {PROBE_STEPS} steps'
    return int(steps[0]), int(targets[0])


def test_unchanged_probe_passes():
    meta, data = load_fixture(PROBE)
    result = replay(PROBE.stem, meta, data, steps=PROBE_STEPS)
    assert result.transitions == PROBE_STEPS
    assert not result.strict and not result.soft, _summary(result)


def test_a_changed_action_is_a_strict_failure():
    meta, data = load_fixture(PROBE)
    step, target = _first_move(data)
    data['target_action'][step, target] = 0.0  # the target now stays where it was
    result = replay(PROBE.stem, meta, data, steps=PROBE_STEPS)
    flagged = [m for m in result.strict if m.step == step and m.field.startswith('target_state[:, 0:6]')]
    assert flagged, (f'stopping target {target} at step {step} went unnoticed by the strict tier\n'
                     f'{_summary(result)}')


def test_a_changed_snapshot_is_a_strict_failure():
    meta, data = load_fixture(PROBE)
    data['camera_state'][3, 0, 0] += 30.0  # camera 0 stands 30 units further east in snapshot 3
    result = replay(PROBE.stem, meta, data, steps=PROBE_STEPS)
    # cameras do not move: step 2 no longer leads to snapshot 3, and step 3 starts from the wrong place
    flagged = {m.step for m in result.strict if m.field == 'camera_state'}
    assert flagged == {2, 3}, (f'expected camera_state mismatches at steps 2 and 3 after moving camera 0 in '
                               f'snapshot 3, got steps {sorted(flagged)}\n{_summary(result)}')


def test_a_changed_observation_is_a_soft_failure():
    meta, data = load_fixture(PROBE)
    data['camera_observation'][5] += 1.0  # the recorded observation of snapshot 5 no longer matches
    result = replay(PROBE.stem, meta, data, steps=PROBE_STEPS)
    assert not result.strict, _summary(result)
    assert result.soft_steps == {4, 5}, (  # returned by step 4, observed again from snapshot 5
        f'expected soft mismatches at steps 4 and 5 only, got steps {sorted(result.soft_steps)}\n{_summary(result)}')
    assert result.soft_rate > SOFT_TOLERANCE
