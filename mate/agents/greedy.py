"""Greedy agents: cameras track the nearest remembered target; targets run to their destination.

Both share what they learn with teammates: cameras their own state (once) and the targets they
see; targets the warehouses they found empty. Decision rules and their quirks follow the
original MATE (docs/agents.md; docs/differences.md, "Kept on purpose").

The rules are written once, on arrays, in `mate.teams.rules`: these agents call them on their own
row, and the batched teams of `mate.teams` on every agent of B games, so that a batched game plays
exactly like these agents (same seed, same episode). The agents keep the life cycle and the
`mate.Message` protocol: messages are built here from what the rules decide.
"""

from __future__ import annotations

import numpy as np

from ..constants import CAMERA_STATE_DIM_PRIVATE, NUM_WAREHOUSES, PRESERVED_DIM, TARGET_STATE_DIM_PUBLIC, WAREHOUSES
from .base import CameraAgentBase, TargetAgentBase
from ..teams import rules
from ..teams.rules import MAX_VIEWING_ANGLE, RANDOM_ACTION_PROBABILITY, RANGE_FACTOR, ZOOM_ITERATIONS  # noqa: F401
from .naive import ONE_ROW, NoisyWalker, as_row
from .utils import CameraStatePrivate, TargetStatePublic

__all__ = ['GreedyCameraAgent', 'GreedyTargetAgent']

_OWN = PRESERVED_DIM
_RECORD = TARGET_STATE_DIM_PUBLIC + 1


def desired_viewing_angle(distance: float, viewing_angle: float, sight_range: float,
                          max_sight_range: float) -> float:
    """The widest viewing angle (degrees) whose sector, at constant area theta R^2, has its inscribed
    circle centred on a target `distance` away; clipped to [min viewing angle, 180]
    (`mate.teams.rules.desired_viewing_angle`, which the agents use).

    Fixed-point iteration theta <- area / (distance (1 + sin(min(theta / 2, 90 deg))))^2, 20 rounds
    from 180 degrees, unless the target is beyond reach (min angle) or very close (180 degrees).
    """
    return rules.desired_viewing_angle(float(distance), float(viewing_angle), float(sight_range),
                                                float(max_sight_range))


class GreedyCameraAgent(CameraAgentBase):
    """Aim at the nearest target seen (by itself or a teammate) in the last `memory_period` steps
    and zoom so that the target sits at the centre of the sector's inscribed circle. With no such
    target: keep the previous action, or with probability 0.1 draw a random one.

    Communication (responses round, peer to peer): the camera sends its own state to every
    teammate once, then the targets it saw since its last message to that teammate, filtered to
    the teammate's reach (1.1 x its maximum sight range). After each message to a teammate it waits
    a random U{memory_period // 4, ..., 2 memory_period - 1} steps before the next one to it; what
    could not be sent in a step is dropped.

    The decisions are those of `mate.teams.rules` (`camera_observe`, `camera_outbox`, `camera_act`)
    on the agent's own row; `message2send` holds what waits for the responses round (the own state,
    this step's sightings) and the messages are built from what `camera_outbox` decides.

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
        self.neighboring_teammate_states = {}
        self.message2send = {}
        self._allocate(0, 0)
        rules
        super().__init__(seed=seed)

    def _allocate(self, num_cameras: int, num_targets: int) -> None:
        """The state the rules work on, as arrays of one row of one agent (1, 1, ...)."""
        self._memory = np.zeros((1, 1, num_targets, 4))
        self._time2forget = np.zeros((1, 1, num_targets), dtype=np.int64)
        self._never_loaded = np.ones((1, 1, num_targets), dtype=bool)
        self._pending = np.zeros((1, 1, num_targets), dtype=bool)
        self._pending_state = np.zeros((1, 1), dtype=bool)
        self._own_state = np.zeros((1, 1, 3))
        self._prev_action = np.zeros((1, 1, 2))
        self._delay = np.zeros((1, 1, num_cameras), dtype=np.int64)
        self._known = np.zeros((1, 1, num_cameras), dtype=bool)
        self._neighbour = np.zeros((1, 1, num_cameras, 3))
        self._sent = np.zeros((1, 1, num_cameras), dtype=bool)
        self._sent_state = np.zeros((1, 1), dtype=bool)
        self._sight = np.zeros((1, 1, num_cameras, num_targets), dtype=bool)
        self._high = np.zeros((1, 1, 2))
        self._action = np.zeros((1, 1, 2))
        self._todo = np.ones((1, 1), dtype=bool)
        self._short = np.zeros((1, 1), dtype=bool)
        index = getattr(self, 'index', None)
        self._index = np.full((1, 1), -1 if index is None else index, dtype=np.int64)

    def reset(self, observation) -> None:
        super().reset(observation)
        observation = np.asarray(observation, dtype=np.float64)
        self._allocate(self.num_cameras, self.num_targets)
        self._high[0, 0] = self._action_high
        rules.camera_reset(
            as_row(observation), int(self.observation_indices[2]), ONE_ROW, self.memory_period, self._memory,
            self._time2forget, self._never_loaded, self._pending, self._pending_state, self._own_state,
            self._prev_action, self._delay, self._known)
        self.neighboring_teammate_states = {}
        own = observation[_OWN:_OWN + CAMERA_STATE_DIM_PRIVATE].tolist()
        self.message2send = {'state': CameraStatePrivate.from_values(own, self.index)}

    @property
    def memory(self) -> tuple:
        """Last known public state of every target (all zeros if never seen)."""
        return tuple(TargetStatePublic.from_values(values, t) for t, values in enumerate(self._memory[0, 0].tolist()))

    @property
    def time2forget(self) -> np.ndarray:
        """int64 (Nt,): steps each remembered target stays a candidate (0: not a candidate). A view."""
        return self._time2forget[0, 0]

    @property
    def never_loaded(self) -> np.ndarray:
        """bool (Nt,): targets never seen loaded. A view."""
        return self._never_loaded[0, 0]

    @property
    def communication_delay(self) -> np.ndarray:
        """int64 (Nc,): steps left before the next message to each teammate may go. A view."""
        return self._delay[0, 0]

    @property
    def prev_action(self) -> np.ndarray:
        return self._prev_action[0, 0].copy()

    def observe(self, observation, info: dict | None = None) -> None:
        observation = self._accept(observation)
        self.last_observation, self.last_info = observation, info
        if rules.camera_observe(as_row(observation), int(self.observation_indices[2]), ONE_ROW,
                                         self.memory_period, self._memory, self._time2forget, self._never_loaded,
                                         self._pending):
            begin, width = int(self.observation_indices[2]), _RECORD
            records = observation[begin:begin + width * self.num_targets].tolist()
            seen = self.message2send.setdefault('target_states', [])
            for t in range(self.num_targets):
                if records[width * t + 4]:
                    seen.append(TargetStatePublic.from_values(records[width * t:width * t + 4], t))

    def send_responses(self):
        pending = self.message2send
        self._pending_state[0, 0] = 'state' in pending        # message2send may have been edited
        sightings = pending.get('target_states')
        if not sightings:
            self._pending[...] = False
        outbox = rules.camera_outbox
        draws = self._draw
        arguments = (self._todo, self._index, self.memory_period, self.filterout_beyond_range, self._memory,
                     self._pending, self._pending_state, self._delay, self._known, self._neighbour, draws.values,
                     draws.left, self._sent, self._sent_state, self._sight, self._short)
        outbox(*arguments)
        if self._short[0, 0]:   # the stream ran out: refill it where the agent's _draw() would
            draws.refill()
            outbox(*arguments)
        if not pending:
            return ()
        messages = []
        for c, sent in enumerate(self._sent[0, 0].tolist()):
            if not sent:
                continue
            content = {'state': pending['state']} if 'state' in pending else {}
            kept = self._sight[0, 0, c].tolist()
            if sightings and any(kept):
                content['target_states'] = [s for s in sightings if kept[s.index]]
            messages.append(self.pack_message(content, recipient=c))
        self.message2send = {}
        return messages

    def receive_responses(self, messages) -> None:
        self.last_responses = messages = tuple(messages)
        remember = None
        for message in messages:
            content = message.content
            if 'state' in content:
                # Kept quirk: every camera that sent its state counts as a neighbour, however far.
                state = self.neighboring_teammate_states[message.sender] = content['state']
                values = state.values
                self._known[0, 0, message.sender] = True
                self._neighbour[0, 0, message.sender] = (values[0], values[1], values[6])
            for target in content.get('target_states', ()):
                remember = remember or rules.remember
                x, y, sight_range, loaded = target.values
                remember(self._memory, self._time2forget, self._never_loaded, 0, 0, target.index, x, y, sight_range,
                         loaded, self.memory_period)

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None) -> np.ndarray:
        observation = self._accept(observation)
        draws, space = self._draw, self._space_draw
        if space.left[0, 0] < 2:
            space.refill()
        act = rules.camera_act
        arguments = (as_row(observation), self._todo, self.filterout_unloaded, self.filterout_beyond_range,
                     self._memory, self._time2forget, self._never_loaded, self._high, self._prev_action,
                     draws.values, draws.left, space.values, space.left, self._action, self._short)
        act(*arguments)
        if self._short[0, 0]:   # the stream ran out: refill it where the agent's _draw() would
            draws.refill()
            act(*arguments)
        return self._action[0, 0].copy()


class GreedyTargetAgent(NoisyWalker, TargetAgentBase):
    """Run straight to the destination warehouse of the carried cargo; when unloaded, to a random
    warehouse still believed to have cargo. Sticky random noise (see `NoisyWalker`) is the only
    way around obstacles. Warehouses found empty are broadcast to the team (responses round).

    The decisions are those of `mate.teams.rules` (`target_observe`, `target_act`) on the agent's
    own row.

    Args:
        seed: seed of the agent's generator.
        noise_scale: scale of the noise, a fraction of the step box (0.5). The noise drawn at
            reset always uses 0.5 (kept from the original).
    """

    def __init__(self, seed: int | None = None, noise_scale: float = 0.5) -> None:
        self.noise_scale = float(noise_scale)
        self._goal = np.zeros((1, 1, NUM_WAREHOUSES))
        self._non_empty = np.ones((1, 1, NUM_WAREHOUSES), dtype=bool)
        self._need = np.zeros((1, 1), dtype=bool)
        self._todo = np.ones((1, 1), dtype=bool)
        self._short = np.zeros((1, 1), dtype=bool)
        rules
        super().__init__(seed=seed)

    def reset(self, observation) -> None:
        super().reset(observation)
        observation = np.asarray(observation, dtype=np.float64)
        self._start_walk(observation)
        self._goal, self._non_empty = np.zeros((1, 1, NUM_WAREHOUSES)), np.ones((1, 1, NUM_WAREHOUSES), dtype=bool)
        self._need = np.zeros((1, 1), dtype=bool)
        rules.target_reset(as_row(observation), ONE_ROW, self._goal, self._non_empty, self._need)

    @property
    def _goal_bits(self) -> list:
        return self._goal[0, 0].tolist()

    @_goal_bits.setter
    def _goal_bits(self, bits) -> None:
        self._goal[0, 0] = bits

    @property
    def non_empty_warehouses(self) -> set:
        """Warehouses this target believes still have cargo (a new set; assign one to change it)."""
        return {w for w, believed in enumerate(self._non_empty[0, 0].tolist()) if believed}

    @non_empty_warehouses.setter
    def non_empty_warehouses(self, warehouses) -> None:
        warehouses = set(warehouses)
        self._non_empty[0, 0] = [w in warehouses for w in range(NUM_WAREHOUSES)]

    @property
    def need_communication(self) -> bool:
        """Whether the target has news (warehouses found empty) for the next responses round."""
        return bool(self._need[0, 0])

    @need_communication.setter
    def need_communication(self, value: bool) -> None:
        self._need[0, 0] = bool(value)

    @property
    def goal_bits(self) -> np.ndarray:
        """int64 (4,): the current goal (cargo weight per destination, or a single 1 when unloaded)."""
        return self._goal[0, 0].astype(np.int64)

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
        rules.target_observe(as_row(observation), ONE_ROW, self._non_empty, self._need)

    def send_responses(self):
        if not self._need[0, 0]:
            return ()
        self._need[0, 0] = False
        return [self.pack_message({'non_empty_warehouses': self.non_empty_warehouses})]

    def receive_responses(self, messages) -> None:
        self.last_responses = messages = tuple(messages)
        for message in messages:
            warehouses = message.content.get('non_empty_warehouses')
            if warehouses is not None:
                self.non_empty_warehouses = self.non_empty_warehouses & set(warehouses)

    def _greedy_action(self, observation: np.ndarray) -> list:
        """This step's move [dx, dy] (`mate.teams.rules.target_act` on the agent's own row)."""
        draws, space = self._draw, self._space_draw
        if space.left[0, 0] < 2:
            space.refill()
        act = rules.target_act
        arguments = (as_row(observation), self._todo, self.noise_scale, self._goal, self._non_empty, self._walk_high,
                     self._walk_location, self._walk_noise, draws.values, draws.left, space.values, space.left,
                     self._walk_action, self._short)
        act(*arguments)
        if self._short[0, 0]:   # the stream ran out: refill it where the agent's _draw() would
            draws.refill()
            act(*arguments)
        self._prev_source = observation
        return self._walk_action[0, 0].tolist()

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None) -> np.ndarray:
        return np.array(self._greedy_action(self._accept(observation)))
