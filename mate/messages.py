"""Communication between teammates: the `Team` enum, the `Message` record and the `MessageChannel`.

The channel is plain bookkeeping owned by an environment: it routes messages (a broadcast becomes one
copy per teammate, the sender included), queues them per recipient, remembers everything delivered
during the current step (for the info dicts) and counts sender -> recipient edges per step and per
episode. It knows nothing about the simulation. See docs/environment/communication.md.
"""

from __future__ import annotations

import copy
import dataclasses
import enum
import operator
from collections.abc import Iterable
from typing import Any, Optional, Union

import numpy as np

__all__ = ['Team', 'Message', 'MessageChannel', 'as_team', 'values_equal']


class Team(enum.IntEnum):
    """The two teams of the game."""

    CAMERA = 0
    TARGET = 1


def values_equal(a: Any, b: Any) -> bool:
    """Whether two message contents hold the same values: dicts by keys and values, lists and tuples
    item by item (a list never equals a tuple), arrays by shape and elements, anything else by `==`
    (agent state views compare their vectors). Never raises on arrays, unlike a plain `==`."""
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.shape == b.shape
                and bool(np.array_equal(a, b)))
    if isinstance(a, dict):
        return (isinstance(b, dict) and a.keys() == b.keys()
                and all(values_equal(value, b[key]) for key, value in a.items()))
    if isinstance(a, (list, tuple)):
        return (type(a) is type(b) and len(a) == len(b)
                and all(values_equal(x, y) for x, y in zip(a, b)))
    equal = a == b
    return bool(np.all(equal)) if isinstance(equal, np.ndarray) else bool(equal)


@dataclasses.dataclass
class Message:
    """One message between two agents of the same team.

    `recipient=None` means broadcast to every teammate (the sender included). Item access is forwarded to
    `content`: `key in msg`, `msg[key]` and `msg[key] = value`.
    """

    sender: int
    recipient: Optional[int]
    content: Any
    team: Team
    broadcasting: bool = False

    def __eq__(self, other: Any) -> bool:
        """Equal when every field is; the content by value (`values_equal`), so that two runs of a
        seeded episode deliver equal messages even when their contents hold arrays or state views."""
        if not isinstance(other, Message):
            return NotImplemented
        return (self.sender == other.sender and self.recipient == other.recipient and self.team == other.team
                and self.broadcasting == other.broadcasting and values_equal(self.content, other.content))

    __hash__ = None

    def __contains__(self, key: Any) -> bool:
        return key in self.content

    def __getitem__(self, key: Any) -> Any:
        return self.content[key]

    def __setitem__(self, key: Any, value: Any) -> None:
        self.content[key] = value


def _as_index(value: Any, what: str) -> int:
    """`value` as a Python int (numpy integers accepted); TypeError for anything else, bools included."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f'{what} must be an integer, got {value!r}')
    try:
        return operator.index(value)
    except TypeError:
        raise TypeError(f'{what} must be an integer, got {value!r}') from None


def _as_team(value: Any) -> Team:
    """`value` as a `Team` member; ValueError if it names no team."""
    try:
        return Team(value)
    except ValueError:
        raise ValueError(f'{value!r} is not a team: expected Team.CAMERA or Team.TARGET') from None


class MessageChannel:
    """Per-team message queues, per-step delivery buffers and edge counters of one environment.

    Args:
        num_cameras: N_c, number of agents in team CAMERA (may be 0).
        num_targets: N_t, number of agents in team TARGET (may be 0).

    Per team of N agents the channel holds: N queues (emptied by `receive`), N per-step buffers (kept until
    `end_step`), an (N, N) int64 per-step edge matrix and an (N, N) int64 per-episode edge matrix, where
    entry [s, r] counts the messages from sender s to recipient r.
    """

    def __init__(self, num_cameras: int, num_targets: int) -> None:
        self._sizes = {Team.CAMERA: int(num_cameras), Team.TARGET: int(num_targets)}
        if min(self._sizes.values()) < 0:
            raise ValueError(f'team sizes must be non-negative, got {num_cameras} and {num_targets}')
        self._total_edges = {team: np.zeros((n, n), dtype=np.int64) for team, n in self._sizes.items()}
        self._clear_step()

    # ------------------------------------------------------------------ sizes and per-step state

    def num_agents(self, team: Team) -> int:
        """Number of agents in `team`."""
        return self._sizes[_as_team(team)]

    def buffer(self, team: Team) -> list[list[Message]]:
        """Messages delivered to each agent of `team` this step (all rounds, received or not): N lists."""
        return [list(messages) for messages in self._buffers[_as_team(team)]]

    def edges(self, team: Team) -> np.ndarray:
        """Per-step edge counts of `team`, int64 (N, N): [sender, recipient]. Row sums = out-edges."""
        return self._edges[_as_team(team)].copy()

    def total_edges(self, team: Team) -> np.ndarray:
        """Per-episode edge counts of `team` up to the last `end_step`, int64 (N, N)."""
        return self._total_edges[_as_team(team)].copy()

    def step_summary(self, team: Team) -> tuple[list[list[Message]], list[int], list[int]]:
        """This step's messages delivered to each agent of `team` (fresh lists, as `buffer`) and
        each agent's out- and in-edge counts (Python ints)."""
        team = _as_team(team)
        count = self._sizes[team]
        if not self._sent_this_step:
            return [[] for _ in range(count)], [0] * count, [0] * count
        edges = self._edges[team]
        return self.buffer(team), edges.sum(axis=1).tolist(), edges.sum(axis=0).tolist()

    def end_step(self) -> None:
        """Add this step's edges to the episode totals; clear per-step edges, buffers and queues."""
        if not self._sent_this_step:
            return  # nothing to add or clear
        for team, edges in self._edges.items():
            self._total_edges[team] += edges
        self._clear_step()

    def reset(self) -> None:
        """Clear everything, the per-episode edge totals included."""
        self._clear_step()
        for totals in self._total_edges.values():
            totals[...] = 0

    def _clear_step(self) -> None:
        """Fresh per-step edge matrices, buffers and queues (new lists: earlier results stay intact)."""
        self._sent_this_step = False
        self._edges = {team: np.zeros((n, n), dtype=np.int64) for team, n in self._sizes.items()}
        self._buffers = {team: [[] for _ in range(n)] for team, n in self._sizes.items()}
        self._queues = {team: [[] for _ in range(n)] for team, n in self._sizes.items()}

    # ------------------------------------------------------------------ sending

    def route(self, messages: Iterable[Message]) -> list[Message]:
        """Expand broadcasts into one copy per teammate (sender included, deep-copied content,
        `broadcasting=True`); keep peer-to-peer messages as they are. Does not touch the channel."""
        routed = []
        for message in messages:
            if message.recipient is not None:
                routed.append(message)
                continue
            for recipient in range(self._sizes[_as_team(message.team)]):
                routed.append(dataclasses.replace(
                    message, recipient=recipient, content=copy.deepcopy(message.content), broadcasting=True,
                ))
        return routed

    def send(self, messages: Union[Message, Iterable[Message]]) -> None:
        """Deliver one message or an iterable of messages of a single team.

        Everything is validated before anything is queued, so a failing call leaves the channel unchanged.

        Raises:
            TypeError: an item is not a `Message`, or a sender/recipient is not an integer.
            ValueError: the messages belong to different teams, or a sender/recipient is out of range.
        """
        messages = self._validate(messages)
        self._sent_this_step = self._sent_this_step or bool(messages)
        for message in self.route(messages):
            team = _as_team(message.team)
            self._queues[team][message.recipient].append(message)
            self._buffers[team][message.recipient].append(message)
            self._edges[team][message.sender, message.recipient] += 1

    def _validate(self, messages: Union[Message, Iterable[Message]]) -> list[Message]:
        """The messages as a list, after checking types, the common team and index ranges."""
        messages = [messages] if isinstance(messages, Message) else list(messages)
        for message in messages:
            if not isinstance(message, Message):
                raise TypeError(f'expected Message objects, got {type(message).__name__}: {message!r}')
        if not messages:
            return messages
        team = _as_team(messages[0].team)
        for message in messages:
            other = _as_team(message.team)
            if other is not team:
                raise ValueError(f'all messages sent in one call must belong to the same team, '
                                 f'got both {team.name} and {other.name}')
            self._check_range(team, message.sender, 'sender')
            if message.recipient is not None:
                self._check_range(team, message.recipient, 'recipient')
        return messages

    def _check_range(self, team: Team, value: Any, role: str) -> int:
        """`value` as an agent index of `team`; ValueError naming the valid range if it is outside."""
        index = _as_index(value, f'message {role}')
        size = self._sizes[team]
        if not 0 <= index < size:
            if size == 0:
                valid = 'there are no valid agent indices'
            else:
                valid = f'valid {role}s are 0..{size - 1}' + (' or None for broadcast' if role == 'recipient' else '')
            raise ValueError(f'message {role} {index} is out of range: team {team.name} has {size} agents, {valid}')
        return index

    # ------------------------------------------------------------------ receiving

    def receive(self, agent_id: Any = None, agent: Any = None):
        """Fetch and dequeue messages.

        With no argument: `(camera_lists, target_lists)`, one list per slot of the queued messages, and all
        queues are emptied. With `agent_id=(team, index)`, or `agent` (any object with `TEAM` and `index`
        attributes; such an object may also be passed as `agent_id`): that agent's queued list; only its
        queue is emptied. Messages stay in the per-step buffer either way.

        Raises:
            ValueError: both arguments given, an unknown team, or an index out of range.
        """
        if agent_id is not None and agent is not None:
            raise ValueError('pass either agent_id or agent, not both')
        if agent_id is None and agent is None:
            received = tuple(self._queues[team] for team in Team)
            self._queues = {team: [[] for _ in range(n)] for team, n in self._sizes.items()}
            return received
        team, index = self._agent_key(agent if agent is not None else agent_id)
        received, self._queues[team][index] = self._queues[team][index], []
        return received

    def _agent_key(self, agent: Any) -> tuple[Team, int]:
        """(team, index) of an agent object (with `TEAM` and `index`) or of a `(team, index)` pair."""
        if hasattr(agent, 'TEAM') and hasattr(agent, 'index'):
            team, index = agent.TEAM, agent.index
        else:
            try:
                team, index = agent
            except (TypeError, ValueError):
                raise ValueError(f'expected a (team, index) pair or an agent object, got {agent!r}') from None
        team = _as_team(team)
        index = _as_index(index, 'agent index')
        if not 0 <= index < self._sizes[team]:
            raise ValueError(f'agent index {index} is out of range: team {team.name} '
                             f'has {self._sizes[team]} agents')
        return team, index


def as_team(team) -> Team:
    """A `Team` from a Team, its value or its name ('camera' / 'target'); ValueError otherwise."""
    if isinstance(team, str):
        name = team.strip().upper()
        if name in Team.__members__:
            return Team[name]
        raise ValueError(f"team must be 'camera' or 'target', got {team!r}")
    try:
        return Team(team)
    except ValueError:
        raise ValueError(f"team must be 'camera' or 'target', got {team!r}") from None
