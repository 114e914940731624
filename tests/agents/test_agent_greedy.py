"""Greedy camera and target decision rules and messages (spec agents-and-wrappers.md §7.4-7.5)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from handmade import (
    bearing,
    camera_observation,
    camera_private,
    target_observation,
    target_private,
)
from hypothesis import given, settings
from hypothesis import strategies as st

import mate
from mate.agents.greedy import desired_viewing_angle

OWN = camera_private(0.0, 0.0, orientation=0.0, viewing_angle=90.0)


def camera(targets=None, own=OWN, **kwargs):
    return camera_observation(own, index=0, targets=targets, **kwargs)


def fresh_camera(**kwargs):
    agent = mate.GreedyCameraAgent(seed=0, **kwargs)
    agent.reset(camera())
    return agent


def decide(agent, observation):
    agent.observe(observation)
    agent.send_responses()
    agent.receive_responses([])
    return agent.act(observation)


# ---------------------------------------------------------------------------- camera: aiming

def test_camera_turns_towards_the_target_within_its_step():
    agent = fresh_camera()
    action = decide(agent, camera({1: [300.0, 300.0, 500.0, 1.0]}))
    distance = math.hypot(300.0, 300.0)
    zoom = desired_viewing_angle(distance, 90.0, agent.state.sight_range, 1500.0) - 90.0
    np.testing.assert_allclose(action, [5.0, np.clip(zoom, -2.5, 2.5)])


def test_camera_small_turns_are_exact_and_angles_wrap():
    agent = fresh_camera()
    x, y = 800.0 * math.cos(math.radians(2.0)), 800.0 * math.sin(math.radians(2.0))
    assert decide(agent, camera({0: [x, y, 500.0, 0.0]}))[0] == pytest.approx(2.0)
    own = camera_private(0.0, 0.0, orientation=170.0)
    agent = mate.GreedyCameraAgent(seed=0)
    agent.reset(camera(own=own))
    x, y = 800.0 * math.cos(math.radians(-170.0)), 800.0 * math.sin(math.radians(-170.0))
    assert decide(agent, camera({0: [x, y, 500.0, 0.0]}, own=own))[0] == 5.0      # +20 degrees, clipped


def test_camera_aims_at_the_nearest_target():
    agent = fresh_camera()
    action = decide(agent, camera({2: [0.0, -1000.0, 500.0, 0.0], 5: [0.0, 500.0, 500.0, 0.0]}))
    assert action[0] == 5.0


def test_camera_remembers_a_target_for_memory_period_steps():
    agent = fresh_camera(memory_period=5)
    far_below = {6: [0.0, -800.0, 500.0, 0.0]}                 # seen every step
    assert decide(agent, camera({3: [0.0, 300.0, 500.0, 0.0], **far_below}))[0] == 5.0
    for left in (4, 3, 2, 1):                                  # out of sight, still the nearest candidate
        assert decide(agent, camera(far_below))[0] == 5.0
        assert agent.time2forget[3] == left
    assert decide(agent, camera(far_below))[0] == -5.0         # forgotten
    assert agent.time2forget[3] == 0 and agent.time2forget[6] == 5


def test_idle_camera_repeats_its_action_or_draws_a_random_one():
    agent = fresh_camera()
    beyond = camera({0: [1700.0, 0.0, 500.0, 0.0]})        # beyond 1.1 x 1500: ignored
    actions = [tuple(decide(agent, beyond)) for _ in range(400)]
    changes = sum(a != b for a, b in zip(actions, actions[1:]))
    assert 15 <= changes <= 70                              # about 10% of the steps draw a new action
    low, high = agent.action_space.low, agent.action_space.high
    assert all(np.all(np.array(a) >= low) and np.all(np.array(a) <= high) for a in actions)
    unfiltered = fresh_camera(filterout_beyond_range=False)
    assert decide(unfiltered, beyond)[0] == 0.0             # aims straight ahead (bearing 0)
    assert unfiltered.prev_action[1] != 0.0


def test_filterout_unloaded_ignores_targets_seen_loaded_before():
    agent = fresh_camera(filterout_unloaded=True)
    far_below = {6: [0.0, -800.0, 500.0, 1.0]}
    assert decide(agent, camera({4: [0.0, 500.0, 500.0, 0.0], **far_below}))[0] == 5.0   # never seen loaded
    assert agent.never_loaded[4] and not agent.never_loaded[6]
    assert decide(agent, camera({4: [0.0, 500.0, 500.0, 1.0], **far_below}))[0] == 5.0   # loaded
    assert not agent.never_loaded[4]
    assert decide(agent, camera({4: [0.0, 500.0, 500.0, 0.0], **far_below}))[0] == -5.0  # unloaded: ignored
    plain = fresh_camera()
    decide(plain, camera({4: [0.0, 500.0, 500.0, 1.0], **far_below}))
    assert decide(plain, camera({4: [0.0, 500.0, 500.0, 0.0], **far_below}))[0] == 5.0


@settings(max_examples=200, deadline=None)
@given(st.floats(1.0, 1700.0), st.floats(30.0, 180.0))
def test_desired_viewing_angle_centres_the_inscribed_circle(distance, viewing_angle):
    sight_range = 1500.0 * math.sqrt(30.0 / viewing_angle)
    theta = desired_viewing_angle(distance, viewing_angle, sight_range, 1500.0)
    assert 30.0 - 1e-9 <= theta <= 180.0
    if 30.0 + 1e-6 < theta < 180.0 - 1e-6:
        reach = 1500.0 * math.sqrt(30.0 / theta)           # same sector area at the new angle
        centre = reach / (1.0 + math.sin(math.radians(theta / 2)))
        assert centre == pytest.approx(distance, rel=1e-3)


# ---------------------------------------------------------------------------- camera: messages

def test_first_responses_round_sends_the_own_state_to_every_teammate():
    agent = mate.GreedyCameraAgent(seed=0)
    agent.reset(camera())
    agent.observe(camera({1: [100.0, 100.0, 500.0, 0.0]}))
    messages = agent.send_responses()
    assert sorted(m.recipient for m in messages) == [1, 2, 3]
    for message in messages:
        assert set(message.content) == {'state'}                 # sightings only for known neighbours
        assert isinstance(message.content['state'], mate.CameraStatePrivate)
        assert message.content['state'].location.tolist() == [0.0, 0.0]
    assert all(6 <= agent.communication_delay[c] <= 49 for c in (1, 2, 3))
    assert agent.message2send == {}
    agent.observe(camera({1: [100.0, 100.0, 500.0, 0.0]}))
    assert agent.send_responses() == []                           # everyone is waiting


def test_sightings_go_to_known_neighbours_within_their_reach():
    agent = mate.GreedyCameraAgent(seed=0)
    agent.reset(camera())
    agent.observe(camera())
    agent.send_responses()
    neighbour = mate.CameraStatePrivate(np.array(camera_private(1000.0, 0.0, max_sight_range=1000.0)), index=1)
    agent.receive_responses([mate.Message(1, 0, {'state': neighbour}, mate.Team.CAMERA)])
    assert agent.neighboring_teammate_states[1] is neighbour
    agent.communication_delay[:] = [0, 0, 0, 0]
    agent.observe(camera({2: [500.0, 0.0, 500.0, 1.0], 6: [-200.0, 0.0, 500.0, 0.0]}))
    messages = agent.send_responses()
    assert [m.recipient for m in messages] == [1]
    states = messages[0].content['target_states']
    assert [s.index for s in states] == [2]                       # 1200 from the neighbour: > 1.1 x 1000
    assert states[0].location.tolist() == [500.0, 0.0] and states[0].is_loaded


def test_without_range_filter_no_sightings_are_shared():
    agent = mate.GreedyCameraAgent(seed=0, filterout_beyond_range=False)
    agent.reset(camera())
    neighbour = mate.CameraStatePrivate(np.array(camera_private(1000.0, 0.0)), index=1)
    agent.receive_responses([mate.Message(1, 0, {'state': neighbour}, mate.Team.CAMERA)])
    agent.message2send.clear()
    agent.observe(camera({2: [500.0, 0.0, 500.0, 1.0]}))
    assert agent.send_responses() == []


def test_received_sightings_become_candidates():
    agent = fresh_camera()
    sighting = mate.TargetStatePublic(np.array([0.0, 700.0, 500.0, 1.0]), index=7)
    agent.observe(camera())
    agent.receive_responses([mate.Message(2, 0, {'target_states': [sighting]}, mate.Team.CAMERA)])
    assert agent.time2forget[7] == agent.memory_period and not agent.never_loaded[7]
    assert agent.memory[7].location.tolist() == [0.0, 700.0]
    assert agent.act(camera())[0] == 5.0


# ---------------------------------------------------------------------------- targets

def target(own=None, **kwargs):
    return target_observation(own or target_private(0.0, 0.0), index=0, **kwargs)


def test_loaded_target_runs_to_its_destination():
    own = target_private(0.0, 0.0, goal_bits=(0, 0, 2, 0), capacity=2.0, step_size=10.0)
    agent = mate.GreedyTargetAgent(seed=0, noise_scale=0.0)
    agent.reset(target(own))
    assert agent.goal == 2 and agent.goal_bits.tolist() == [0, 0, 2, 0]
    np.testing.assert_array_equal(agent.goal_location, mate.WAREHOUSES[2])
    assert np.all(np.abs(agent.prev_noise) <= 0.5 * 10.0)        # the reset noise ignores noise_scale
    actions = [agent.act(target(own)) for _ in range(30)]       # never moves: noise refreshed w.p. 0.75
    step = 10.0 / math.sqrt(2.0)
    np.testing.assert_allclose(actions[-1], [-step, -step])


def test_initial_noise_uses_half_the_step_whatever_the_noise_scale():
    for seed in range(20):
        agent = mate.GreedyTargetAgent(seed=seed, noise_scale=2.0)
        agent.reset(target())
        assert np.all(np.abs(agent.prev_noise) <= 10.0)


def test_unloaded_target_picks_a_warehouse_believed_non_empty_and_tells_the_team():
    agent = mate.GreedyTargetAgent(seed=3)
    agent.reset(target())
    seen_empty = target(target_private(0.0, 0.0, empty_bits=(1, 1, 0, 1)))
    agent.observe(seen_empty)
    assert agent.non_empty_warehouses == {2} and agent.need_communication
    messages = agent.send_responses()
    assert len(messages) == 1 and messages[0].recipient is None and messages[0].broadcasting
    assert messages[0].content == {'non_empty_warehouses': {2}}
    assert not agent.need_communication and agent.send_responses() == ()
    agent.receive_responses(messages)
    agent.act(seen_empty)
    assert agent.goal == 2


def test_received_empty_warehouses_are_forgotten_as_goals():
    agent = mate.GreedyTargetAgent(seed=0)
    agent.reset(target())
    agent.observe(target())
    agent.receive_responses([mate.Message(3, None, {'non_empty_warehouses': {0, 1}}, mate.Team.TARGET, True)])
    assert agent.non_empty_warehouses == {0, 1}
    goals = set()
    for seed in range(30):
        agent.seed(seed)
        agent._goal_bits = [0.0] * 4
        agent.act(target())
        goals.add(agent.goal)
    assert goals == {0, 1}


def test_targets_end_up_with_no_goal_when_every_warehouse_is_empty():
    agent = mate.GreedyTargetAgent(seed=0, noise_scale=0.0)
    agent.reset(target())
    everything_empty = target(target_private(0.0, 0.0, empty_bits=(1, 1, 1, 1)))
    agent.observe(everything_empty)
    for _ in range(30):
        action = agent.act(everything_empty)
    assert agent.goal is None
    np.testing.assert_allclose(action, [0.0, 0.0])


def test_a_freely_moving_target_keeps_its_noise_most_of_the_time():
    agent = mate.GreedyTargetAgent(seed=5)
    agent.reset(target())
    refreshed, x = 0, 0.0
    for _ in range(400):
        before = tuple(agent.prev_noise)
        x -= 15.0                                            # moved 15 > 0.2 x 20 since the last step
        agent.act(target(target_private(x, 0.0, goal_bits=(0, 1, 0, 0))))
        refreshed += tuple(agent.prev_noise) != before
    assert 5 <= refreshed <= 40                              # about 5% of 400 steps
    assert bearing(-1.0, 0.0) == 180.0
