"""MessageFilter: drop (or edit) messages on their way between teammates.

`filter(unwrapped_env, message) -> bool` is called for every routed message (a broadcast is first
expanded into one copy per teammate, the sender included, each with its own deep-copied content); the
message is delivered iff it returns a truthy value, and the filter may modify the message (e.g. add
noise to its content). Filters stack.

Placement: inside MultiCamera/MultiTarget/SingleCamera/SingleTarget a filter sees both teams' messages
(the built-in agents talk through the inner env); outside, only the messages of your own team.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from mate.messages import Message

from .base import MateWrapper, assert_mate_environment

__all__ = ['MessageFilter']


class MessageFilter(MateWrapper):
    """Deliver only the messages for which `filter(env.unwrapped, message)` is truthy.

        env = mate.make('MultiAgentTracking-v0', wrappers=[
            mate.WrapperSpec(mate.MessageFilter, filter=lambda env, message: message.sender != 0)])
    """

    def __init__(self, env, filter: Callable[..., bool]) -> None:
        assert_mate_environment(env, type(self).__name__)
        if not callable(filter):
            raise TypeError(f'{type(self).__name__}: filter must be callable (env, message) -> bool, got {filter!r}')
        super().__init__(env)
        self.filter = filter

    def keep(self, messages: list[Message]) -> list[bool]:
        """Whether to deliver each routed message (override to decide for a whole batch at once)."""
        base = self.env.unwrapped
        return [bool(self.filter(base, message)) for message in messages]

    def send_messages(self, messages: Message | Iterable[Message]) -> None:
        """Route `messages` (broadcasts expanded), filter them, and send the kept ones through the inner env."""
        messages = [messages] if isinstance(messages, Message) else list(messages)
        if not messages:
            return
        routed = self.env.unwrapped.route_messages(messages)
        kept = [message for message, keep in zip(routed, self.keep(routed)) if keep]
        if kept:
            self.env.send_messages(kept)
