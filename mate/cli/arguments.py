"""What the `mate` commands share to read their arguments: the parser with short errors, the error a command
raises for a mistake in its arguments, and argparse types for numbers in a range.

A mistake in the arguments (a number out of range, an unknown preset or agent, a bad checkpoint, a missing
file) is reported by `mate.cli.main.main` in one line, `mate COMMAND: error: MESSAGE`, with exit status 2.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from contextlib import contextmanager

__all__ = ['ArgumentParser', 'CommandError', 'in_range', 'non_negative_int', 'number', 'number_phrase', 'positive_int',
           'resolving_arguments']


class CommandError(SystemExit):
    """A mistake in a command's arguments: `main` prints `mate COMMAND: error: MESSAGE` and returns 2.

    A SystemExit (carrying the message), so that code running a sub-command without `main` stops
    with the message too, as it does on argparse's errors."""


@contextmanager
def resolving_arguments():
    """Report the ValueError / TypeError of turning arguments into objects (agent names, keyword
    arguments, configs, checkpoints) as a CommandError with the same message."""
    try:
        yield
    except (ValueError, TypeError) as exc:
        raise CommandError(str(exc)) from exc


def number(kind: type = int, minimum: float | None = None, above: float | None = None,
           maximum: float | None = None) -> Callable[[str], float]:
    """argparse type: a finite `kind` (int or float) that is >= `minimum`, > `above` and <= `maximum` (each when
    given); an integer may be written as a whole number in any float notation ('2e6', '1000.0')."""
    expected = number_phrase(kind, minimum, above, maximum)

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            value = _whole(text) if kind is int else math.nan
        if not in_range(value, minimum, above, maximum):
            raise argparse.ArgumentTypeError(f'expected {expected}, got {text!r}')
        return value

    return parse


def in_range(value: float, minimum: float | None = None, above: float | None = None,
             maximum: float | None = None) -> bool:
    """Whether `value` is finite, >= `minimum`, > `above` and <= `maximum` (each when given)."""
    return bool(math.isfinite(value) and (minimum is None or value >= minimum) and (above is None or value > above)
                and (maximum is None or value <= maximum))


def number_phrase(kind: type = float, minimum: float | None = None, above: float | None = None,
                  maximum: float | None = None) -> str:
    """'an integer >= 1', 'a number > 0 and <= 1': what `number` accepts, in words."""
    bounds = [f'{relation} {bound:g}' for relation, bound in (('>=', minimum), ('>', above), ('<=', maximum))
              if bound is not None]
    return f"{'an integer' if kind is int else 'a number'}{' ' if bounds else ''}{' and '.join(bounds)}"


def _whole(text: str) -> float:
    """The integer a float notation of a whole number stands for ('2e6'), else NaN."""
    try:
        value = float(text)
    except ValueError:
        return math.nan
    return int(value) if math.isfinite(value) and value == int(value) else math.nan


positive_int, non_negative_int = number(int, minimum=1), number(int, minimum=0)


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser whose errors are two short lines (the message, then where to find the
    options) instead of the long usage text."""

    def error(self, message: str):
        self.exit(2, f'{self.prog}: error: {message}\n(see {self.prog} -h)\n')
