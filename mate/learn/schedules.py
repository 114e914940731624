"""Schedules of a training run: piecewise functions of the decision-step count (docs/training.md).

A schedule is ((step, value), ...): a step function (`interpolate=False`: the value of the last breakpoint
reached, e.g. learning rates) or linear between breakpoints (`interpolate=True`: entropy coefficients,
exploration rates); constant before the first and after the last breakpoint.
"""

from __future__ import annotations

import itertools
import math

__all__ = ['ACTIVATIONS', 'check_network_options', 'piecewise']

ACTIVATIONS = ('tanh', 'relu')
"""The hidden activations of the trainers' networks."""

SCHEDULE_VALUES = {'lr_schedule': ('a learning rate >= 0 (0: the weights stay)', lambda v: v >= 0),
                   'entropy_schedule': ('an entropy coefficient >= 0', lambda v: v >= 0),
                   'epsilon_schedule': ('an exploration rate in [0, 1]', lambda v: 0 <= v <= 1)}
"""What each schedule option's values may be: (in words, the test)."""


def piecewise(schedule, step: float, interpolate: bool) -> float:
    """Value of a ((step, value), ...) schedule: a step function, or linear between breakpoints."""
    points = sorted(schedule)
    if step <= points[0][0]:
        return float(points[0][1])
    for (s0, v0), (s1, v1) in itertools.pairwise(points):
        if step < s1:
            return float(v0 + (v1 - v0) * (step - s0) / (s1 - s0)) if interpolate else float(v0)
    return float(points[-1][1])


def check_network_options(config, schedules: tuple[str, ...] = ()) -> None:
    """The checks every trainer's config shares (torch-free, also `mate rllib-train`'s): its `activation`, when it has
    one, is one of `ACTIVATIONS`, and each schedule field named in `schedules` has at least one point, each point a
    [step, value] pair with a finite step >= 0 and a value `SCHEDULE_VALUES` allows. ValueError naming the option as
    the command line spells it, and the valid range, otherwise."""
    activation = getattr(config, 'activation', None)
    if activation is not None and activation not in ACTIVATIONS:
        raise ValueError(f"--activation must be 'tanh' or 'relu', got {activation!r}")
    for name in schedules:
        flag, points = f'--{name.replace("_", "-")}', getattr(config, name)
        if not points:
            raise ValueError(f'{flag} needs at least one [step, value] point')
        words, valid = SCHEDULE_VALUES[name]
        for point in points:
            if len(point) != 2:
                raise ValueError(f'{flag}: each point is [step, value], got {list(point)}')
            step, value = point
            if not (math.isfinite(step) and step >= 0):
                raise ValueError(f'{flag}: a step is a decision-step count >= 0, got {step}')
            if not (math.isfinite(value) and valid(value)):
                raise ValueError(f'{flag}: each value is {words}, got {value} (at step {step})')
