"""RandomMessageDropout: lose each routed message independently with a fixed probability."""

from __future__ import annotations

import numbers

from mate.messages import Message

from .message_filter import MessageFilter

__all__ = ['RandomMessageDropout']


class RandomMessageDropout(MessageFilter):
    """Drop every routed message with probability `dropout_rate` (0 <= rate <= 1), independently.

    The draws come from the unwrapped env's `np_random` (seeded by `reset(seed=...)`), one per routed
    message; the env's episode stream is separate, so dropout never changes what the world does.
    """

    def __init__(self, env, dropout_rate: float) -> None:
        if not isinstance(dropout_rate, numbers.Real) or not 0.0 <= dropout_rate <= 1.0:
            raise ValueError(f'dropout_rate must be a number in [0, 1], got {dropout_rate!r}')
        self.dropout_rate = float(dropout_rate)
        super().__init__(env, filter=self._survives)

    def _survives(self, env, message: Message) -> bool:
        return bool(env.np_random.random() >= self.dropout_rate)

    def keep(self, messages: list[Message]) -> list[bool]:
        draws = self.env.unwrapped.np_random.random(len(messages))
        return (draws >= self.dropout_rate).tolist()

    def _arguments(self) -> str:
        return f'dropout_rate={self.dropout_rate}'
