"""Schedules of a training run: piecewise functions of the decision-step count (docs/training.md).

A schedule is ((step, value), ...): a step function (`interpolate=False`: the value of the last breakpoint
reached, e.g. learning rates) or linear between breakpoints (`interpolate=True`: entropy coefficients,
exploration rates); constant before the first and after the last breakpoint.

A step is a decision-step count, or a share of the run's budget written 'P%' (P from 0 to 100: P / 100 x
`--steps`), so that a schedule scales with the budget: [[0, 0.03], ['50%', 0.01], ['100%', 0]] ends the bonus
at 2 M decisions in a run of 4 M and at 10 M in a run of 10 M. The shares resolve against the run's budget when
the schedule is read (`resolve_schedule`; a run resumed with a larger `--steps` stretches them with it); a
schedule of counts only is the same at every budget.
"""

from __future__ import annotations

import itertools
import math
import re

__all__ = ['ACTIVATIONS', 'budget_share', 'check_network_options', 'piecewise', 'resolve_schedule']

ACTIVATIONS = ('tanh', 'relu')
"""The hidden activations of the trainers' networks."""

SCHEDULE_VALUES = {'lr_schedule': ('a learning rate >= 0 (0: the weights stay)', lambda v: v >= 0),
                   'entropy_schedule': ('an entropy coefficient >= 0', lambda v: v >= 0),
                   'epsilon_schedule': ('an exploration rate in [0, 1]', lambda v: 0 <= v <= 1)}
"""What each schedule option's values may be: (in words, the test)."""


_SHARE = re.compile(r'^\s*(\d+(?:\.\d*)?|\.\d+)\s*%\s*$')


def _percent(step) -> float | None:
    """P of a schedule step 'P%' (None for a step that is not a string); ValueError unless P is from 0 to 100."""
    if not isinstance(step, str):
        return None
    match = _SHARE.match(step)
    if match is None or float(match.group(1)) > 100:
        raise ValueError(f"a share of the budget is 'P%' with P from 0 to 100, got {step!r}")
    return float(match.group(1))


def budget_share(step) -> float | None:
    """The share of the budget (0 to 1) a schedule step 'P%' stands for; None for a step that is not a string.
    ValueError (naming the valid form and range) for a string that is not 'P%' with P from 0 to 100."""
    percent = _percent(step)
    return None if percent is None else percent / 100


def resolve_schedule(schedule, budget: int | None) -> tuple[tuple[float, float], ...]:
    """The schedule's points with every step in decision steps: a share 'P%' becomes P / 100 x `budget` (a whole
    number of steps stays an int), counts stay as they are. ValueError when a share is there and `budget` is None."""
    points = []
    for step, value in schedule:
        percent = _percent(step)
        if percent is not None:
            if budget is None:
                raise ValueError(f'the schedule step {step!r} is a share of the budget; it needs the run\'s --steps')
            step = percent * budget / 100                  # (P x budget first: whole shares of whole budgets exact)
            step = int(step) if step.is_integer() else step
        points.append((step, value))
    return tuple(points)


def piecewise(schedule, step: float, interpolate: bool, budget: int | None = None) -> float:
    """Value of a ((step, value), ...) schedule at `step`: a step function, or linear between breakpoints; steps
    written as shares of the budget ('40%') are read against `budget` (the run's `--steps`)."""
    points = sorted(resolve_schedule(schedule, budget))
    if step <= points[0][0]:
        return float(points[0][1])
    for (s0, v0), (s1, v1) in itertools.pairwise(points):
        if step < s1:
            return float(v0 + (v1 - v0) * (step - s0) / (s1 - s0)) if interpolate else float(v0)
    return float(points[-1][1])


def check_network_options(config, schedules: tuple[str, ...] = (), shares: bool = False) -> None:
    """The checks every trainer's config shares (torch-free, also `mate rllib-train`'s): its `activation`, when it has
    one, is one of `ACTIVATIONS`, and each schedule field named in `schedules` has at least one point, each point a
    [step, value] pair with a finite step >= 0 (or, with `shares`, a share of the budget 'P%', P from 0 to 100) and a
    value `SCHEDULE_VALUES` allows. ValueError naming the option as the command line spells it, and the valid range,
    otherwise."""
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
            steps = 'a decision-step count >= 0' + (" or a share of --steps from '0%' to '100%'" if shares else '')
            if isinstance(step, str):
                if not shares:
                    raise ValueError(f'{flag}: a step is {steps} (this command takes no share of the budget), '
                                     f'got {step!r}')
                try:
                    budget_share(step)
                except ValueError:
                    raise ValueError(f'{flag}: a step is {steps}, got {step!r}') from None
            elif isinstance(step, bool) or not isinstance(step, (int, float)) or not math.isfinite(step) or step < 0:
                raise ValueError(f'{flag}: a step is {steps}, got {step}')
            if not (math.isfinite(value) and valid(value)):
                raise ValueError(f'{flag}: each value is {words}, got {value} (at step {step})')
