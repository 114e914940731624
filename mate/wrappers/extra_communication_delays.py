"""ExtraCommunicationDelays: hold every message back for a number of environment steps."""

from __future__ import annotations

import heapq
import itertools
import numbers
from collections.abc import Callable, Iterable

from mate.messages import Message, Team

from .base import MateWrapper, assert_mate_environment

__all__ = ['ExtraCommunicationDelays']


class ExtraCommunicationDelays(MateWrapper):
    """Deliver each message `delay` env steps after it was sent.

    `delay` is an int > 0 or a callable `(unwrapped_env, message) -> int >= 0`. A message sent while
    `env.episode_step == k` is released by the first `send_messages` call made while `episode_step >= k +
    delay` (with the usual agent loop: in the requests round of step k + delay, whichever round it was sent
    in); if nobody sends anything in a step, held messages wait. Released messages are forwarded in
    release order (ties in send order), one inner `send_messages` call per team. The queue is emptied by
    `reset`.

    Differences from the original: equal release steps no longer crash (ties are broken first-in first-out),
    and a release that mixes both teams' messages is split by team instead of failing.
    """

    def __init__(self, env, delay: int | Callable[..., int] = 3) -> None:
        assert_mate_environment(env, type(self).__name__)
        if not callable(delay):
            if not isinstance(delay, numbers.Integral) or isinstance(delay, bool) or delay <= 0:
                raise ValueError(f'delay must be an int > 0 or a callable (env, message) -> int, got {delay!r}')
            delay = int(delay)
        super().__init__(env)
        self.delay = delay
        self._queue: list[tuple[int, int, Message]] = []
        self._order = itertools.count()

    def _arguments(self) -> str:
        if callable(self.delay):
            return f'delay={getattr(self.delay, "__name__", "<callable>")}'
        return f'delay={self.delay!r}'

    @property
    def pending_messages(self) -> list[tuple[int, Message]]:
        """(release step, message) of every held message, in release order."""
        return [(step, message) for step, _, message in sorted(self._queue)]

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self._queue.clear()
        return self.env.reset(seed=seed, options=options)

    def _delay_of(self, message: Message) -> int:
        if not callable(self.delay):
            return self.delay
        delay = self.delay(self.env.unwrapped, message)
        if not isinstance(delay, numbers.Integral) or delay < 0:
            raise ValueError(f'the delay callable must return an int >= 0, got {delay!r} for {message!r}')
        return int(delay)

    def send_messages(self, messages: Message | Iterable[Message]) -> None:
        """Queue `messages` (one team per call), then forward every message whose release step has come."""
        messages = [messages] if isinstance(messages, Message) else list(messages)
        teams = {Team(message.team) for message in messages}
        if len(teams) > 1:
            raise ValueError('all messages sent in one call must belong to the same team, got both teams')
        now = self.env.unwrapped.episode_step
        for message in messages:
            heapq.heappush(self._queue, (now + self._delay_of(message), next(self._order), message))
        released = {Team.CAMERA: [], Team.TARGET: []}
        while self._queue and self._queue[0][0] <= now:
            message = heapq.heappop(self._queue)[2]
            released[Team(message.team)].append(message)
        for team_messages in released.values():
            if team_messages:
                self.env.send_messages(team_messages)
