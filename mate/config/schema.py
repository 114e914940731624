"""Schema of a mate configuration: validation, default filling and normalisation.

`normalize_config(mapping)` checks every key of a configuration mapping and returns a
new plain dict (only dict / list / str / int / float / bool) that the simulation core
consumes as is:

* every top-level key is present (``name`` only if given; ``camera`` and ``obstacle``
  only if given, an absent section meaning zero entities of that kind);
* in each entity section, ``location`` is a list of ``[x, y]`` and
  ``location_random_range`` a list of flat ``[x_low, x_high, y_low, y_high]`` lists;
* in ``obstacle``, either ``radius`` or ``radius_random_range`` (``[low, high]``) is kept.

Lengths are in world units, angles in degrees. The first problem found raises a
`ConfigError` naming the key path, the offending value and what is expected.
Normalising a normalised config returns an equal dict.
"""

from __future__ import annotations

import difflib
import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from mate.constants import MAX_CAMERA_VIEWING_ANGLE, NUM_WAREHOUSES

__all__ = ['ConfigError', 'MissingKeyError', 'normalize_config', 'SCHEMA']


class ConfigError(ValueError):
    """An invalid configuration.

    Attributes:
        path: where the problem is, e.g. ``'camera.min_viewing_angle'`` or
            ``'obstacle.location_random_range[3]'`` (``'config'`` for the argument itself).
        value: the offending value (``None`` for a missing key).
    """

    def __init__(self, message: str, path: str = 'config', value: object = None) -> None:
        super().__init__(message)
        self.path = path
        self.value = value


class MissingKeyError(ConfigError):
    """A required key is absent."""


class _Sentinel:
    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return self.name


REQUIRED = _Sentinel('REQUIRED')
"""Default of a key that must be given."""
OMIT = _Sentinel('OMIT')
"""Default of a key that stays absent from the output when not given."""


# ----------------------------------------------------------------------------- helpers


def _show(value: object, limit: int = 80) -> str:
    """A short repr of `value` (numpy scalars and arrays shown as Python values)."""
    if isinstance(value, (np.generic, np.ndarray)):
        value = value.tolist()
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + '...'


def _type_name(value: object) -> str:
    """The type of `value` with an article, e.g. ``'an int'`` or ``'a str'``."""
    name = type(value).__name__
    return f"{'an' if name[0] in 'aeiou' else 'a'} {name}"


def _join(prefix: str, key: object) -> str:
    return f'{prefix}.{key}' if prefix else str(key)


def _fail(path: str, value: object, expected: str, note: str = '') -> ConfigError:
    """The error for `value` at `path` that is not `expected`."""
    message = f'{path}: got {_show(value)}'
    if note:
        message += f' ({note})'
    return ConfigError(f'{message}, expected {expected}', path, value)


def _is_bool(value: object) -> bool:
    return isinstance(value, (bool, np.bool_))


def _is_sequence(value: object) -> bool:
    """Lists, tuples and numpy arrays with at least one dimension."""
    if isinstance(value, np.ndarray):
        return value.ndim >= 1
    return isinstance(value, (list, tuple))


def _type_note(value: object) -> str:
    """Why `value` is not a number, when its type says so."""
    note = _type_name(value)
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return note
        note += '; numbers must not be quoted, and YAML reads 1e3 as a string: write 1.0e+3'
    return note


def _finite(value: object, path: str, expected: str = 'a finite number') -> float:
    """`value` as a finite float; bools and strings are rejected."""
    if _is_bool(value) or not isinstance(value, numbers.Real):
        raise _fail(path, value, expected, _type_note(value))
    number = float(value)
    if not math.isfinite(number):
        raise _fail(path, value, expected, 'NaN and infinities are rejected')
    return number


def did_you_mean(word: object, choices: list[str]) -> str:
    """A ``did you mean 'a' or 'b'?`` phrase (empty if nothing is close)."""
    matches = difflib.get_close_matches(str(word), choices, n=3, cutoff=0.6)
    if not matches:
        return ''
    quoted = [repr(m) for m in matches]
    listed = quoted[0] if len(quoted) == 1 else ', '.join(quoted[:-1]) + ' or ' + quoted[-1]
    return f'did you mean {listed}?'


# ----------------------------------------------------------------------------- fields


@dataclass(frozen=True)
class Number:
    """A real (or integer) number within an interval, NaN and infinities rejected."""

    default: object
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    unit: str = ''

    def describe(self) -> str:
        """E.g. ``'a number in (0, 180] (degrees)'`` or ``'an integer >= 4'``."""
        kind = 'an integer' if self.integer else 'a number'
        low, high = f'{self.low:g}', f'{self.high:g}'
        if math.isinf(self.low) and math.isinf(self.high):
            text = kind
        elif math.isinf(self.high):
            text = f"{kind} {'>' if self.low_open else '>='} {low}"
        elif math.isinf(self.low):
            text = f"{kind} {'<' if self.high_open else '<='} {high}"
        else:
            left, right = '(' if self.low_open else '[', ')' if self.high_open else ']'
            text = f'{kind} in {left}{low}, {high}{right}'
        return f'{text} ({self.unit})' if self.unit else text

    def check(self, value: object, path: str) -> float | int:
        """`value` as a Python float (int for integer fields), within the interval."""
        number = _finite(value, path, self.describe())
        if self.integer:
            if not number.is_integer():
                raise _fail(path, value, self.describe())
            number = int(value) if isinstance(value, numbers.Integral) else int(number)
        if not self._inside(number):
            raise _fail(path, value, self.describe())
        return number

    def _inside(self, number: float) -> bool:
        above = number > self.low if self.low_open else number >= self.low
        below = number < self.high if self.high_open else number <= self.high
        return above and below


def _positive(default: float, unit: str = '') -> Number:
    return Number(default, low=0.0, low_open=True, unit=unit)


@dataclass(frozen=True)
class Flag:
    """A boolean (``true`` / ``false``; numbers are not accepted)."""

    default: object

    def check(self, value: object, path: str) -> bool:
        if not _is_bool(value):
            raise _fail(path, value, 'a bool (true or false)', _type_name(value))
        return bool(value)


@dataclass(frozen=True)
class Choice:
    """One of a few strings."""

    default: object
    choices: tuple[str, ...]

    def check(self, value: object, path: str) -> str:
        if isinstance(value, str) and value in self.choices:
            return str(value)
        expected = ' or '.join(repr(c) for c in self.choices)
        if isinstance(value, str):
            note = did_you_mean(value, list(self.choices))
        else:
            note = _type_name(value)
        raise _fail(path, value, expected, note)


@dataclass(frozen=True)
class Text:
    """Any string."""

    default: object = OMIT

    def check(self, value: object, path: str) -> str:
        if not isinstance(value, str):
            raise _fail(path, value, 'a string', _type_name(value))
        return str(value)


@dataclass(frozen=True)
class Locations:
    """A list of fixed positions ``[x, y]`` (world units)."""

    default: object = ()

    def check(self, value: object, path: str) -> list[list[float]]:
        if not _is_sequence(value):
            raise _fail(path, value, 'a list of [x, y] positions', _type_name(value))
        return [_point(item, f'{path}[{i}]') for i, item in enumerate(value)]


def _point(value: object, path: str) -> list[float]:
    """A position ``[x, y]`` as two finite floats."""
    if not _is_sequence(value) or len(value) != 2:
        raise _fail(path, value, 'a position [x, y] of two finite numbers')
    return [_finite(v, f'{path}[{i}]') for i, v in enumerate(value)]


_RANGE_FORMATS = '[x_low, x_high, y_low, y_high] or {low: [x_low, y_low], high: [x_high, y_high]}'
_ORDER_NOTE = (
    'mate requires low <= high on every axis, a check the original MATE did not make'
)


@dataclass(frozen=True)
class LocationRanges:
    """A list of boxes from which positions are sampled uniformly (world units).

    Each box is written flat ``[x_low, x_high, y_low, y_high]``, as a mapping
    ``{low: [x_low, y_low], high: [x_high, y_high]}`` or as a Box-like object with
    ``low`` and ``high``; the output is always flat.
    """

    default: object = ()

    def check(self, value: object, path: str) -> list[list[float]]:
        if not _is_sequence(value):
            raise _fail(path, value, f'a list of ranges {_RANGE_FORMATS}', _type_name(value))
        return [_location_range(item, f'{path}[{i}]') for i, item in enumerate(value)]


def _location_range(value: object, path: str) -> list[float]:
    """One location range as a flat ``[x_low, x_high, y_low, y_high]``."""
    low, high = _bounds(value, path, 2, _RANGE_FORMATS)
    for axis, lo, hi in zip('xy', low, high):
        if lo > hi:
            note = f'{axis}_low {lo:g} > {axis}_high {hi:g}'
            raise _fail(path, value, f'{axis}_low <= {axis}_high; {_ORDER_NOTE}', note)
    return [low[0], high[0], low[1], high[1]]


def _bounds(value: object, path: str, dim: int, formats: str) -> tuple[list[float], list[float]]:
    """The (low, high) corners of a range of `dim` axes, in any accepted format."""
    if isinstance(value, Mapping):
        return _mapping_bounds(value, path, dim, formats)
    if hasattr(value, 'low') and hasattr(value, 'high'):  # a Box-like object
        low, high = np.ravel(value.low).tolist(), np.ravel(value.high).tolist()
        if len(low) != dim or len(high) != dim:
            raise _fail(path, value, formats)
        return _finite_list(low, f'{path}.low'), _finite_list(high, f'{path}.high')
    if not _is_sequence(value) or len(value) != 2 * dim:
        raise _fail(path, value, formats)
    flat = _finite_list(value, path)
    return flat[0::2], flat[1::2]


def _mapping_bounds(
    value: Mapping, path: str, dim: int, formats: str
) -> tuple[list[float], list[float]]:
    """The corners of a range written ``{low: ..., high: ...}``."""
    for key in value:
        if key not in ('low', 'high'):
            hint = did_you_mean(key, ['low', 'high']) or 'valid keys: low, high'
            raise _fail(path, value, formats, f'unknown key {key!r}; {hint}')
    if len(value) != 2:
        raise _fail(path, value, formats, 'both low and high are needed')
    corners = []
    for key in ('low', 'high'):
        corner = value[key]
        if dim == 1 and not _is_sequence(corner):
            corner = [corner]
        if not _is_sequence(corner) or len(corner) != dim:
            raise _fail(f'{path}.{key}', value[key], formats)
        corners.append(_finite_list(corner, f'{path}.{key}'))
    return corners[0], corners[1]


def _finite_list(values: object, path: str) -> list[float]:
    return [_finite(v, f'{path}[{i}]') for i, v in enumerate(values)]


_RADIUS_FORMATS = '[r_low, r_high] or {low: r_low, high: r_high} with 0 <= r_low <= r_high'


@dataclass(frozen=True)
class RadiusRange:
    """A range ``[r_low, r_high]`` of obstacle radii (world units), 0 <= r_low <= r_high."""

    default: object = OMIT

    def check(self, value: object, path: str) -> list[float]:
        low, high = _bounds(value, path, 1, _RADIUS_FORMATS)
        if low[0] < 0.0:
            raise _fail(path, value, _RADIUS_FORMATS, f'r_low {low[0]:g} < 0')
        if low[0] > high[0]:
            note = f'r_low {low[0]:g} > r_high {high[0]:g}'
            raise _fail(path, value, f'r_low <= r_high; {_ORDER_NOTE}', note)
        return [low[0], high[0]]


@dataclass(frozen=True)
class Section:
    """A mapping of named fields, optionally followed by a rule over the whole section."""

    fields: dict = field(default_factory=dict)
    default: object = OMIT
    rule: Callable[[dict, str], None] | None = None

    def check(self, value: object, path: str) -> dict:
        if not isinstance(value, Mapping):
            raise _fail(path or 'config', value, 'a mapping', _type_name(value))
        section = _check_fields(value, self.fields, path)
        if self.rule is not None:
            self.rule(section, path)
        return section


def _check_fields(mapping: Mapping, fields: dict, prefix: str) -> dict:
    """Unknown keys first, then missing required keys, then each field in schema order."""
    _reject_unknown_keys(mapping, fields, prefix)
    for key, spec in fields.items():
        if spec.default is REQUIRED and key not in mapping:
            raise MissingKeyError(
                f'{_join(prefix, key)}: missing required key, expected {_expected(spec)}',
                _join(prefix, key),
            )
    out = {}
    for key, spec in fields.items():
        value = mapping.get(key, spec.default)
        if value is not OMIT:
            out[key] = spec.check(value, _join(prefix, key))
    return out


def _expected(spec: object) -> str:
    if isinstance(spec, Number):
        return spec.describe()
    return 'a mapping' if isinstance(spec, Section) else type(spec).__name__


def _reject_unknown_keys(mapping: Mapping, fields: dict, prefix: str) -> None:
    # The original MATE silently ignored unknown top-level keys (and crashed with a
    # TypeError on unknown section keys). mate deliberately rejects both, so that a
    # typo such as `max_episode_step` does not silently fall back to a default.
    known = list(fields)
    for key in mapping:
        if key not in fields:
            hint = did_you_mean(key, known)
            where = f'in {prefix}' if prefix else 'at the top level'
            message = f'{_join(prefix, key)}: unknown key {key!r}'
            message += f' ({hint})' if hint else ''
            message += f'; valid keys {where}: {", ".join(known)}'
            raise ConfigError(message, _join(prefix, key), mapping[key])


# ----------------------------------------------------------------------------- section rules


def _count(section: dict) -> int:
    """Number of entities a section defines: fixed locations plus random ranges."""
    return len(section['location']) + len(section['location_random_range'])


def _require_targets(section: dict, path: str) -> None:
    if _count(section) < 1:
        raise ConfigError(
            f'{path}: got 0 targets, expected at least one '
            '(len(location) + len(location_random_range) >= 1)',
            path,
            0,
        )


def _one_obstacle_radius(section: dict, path: str) -> None:
    given = [key for key in ('radius', 'radius_random_range') if key in section]
    count = _count(section)
    if len(given) == 2:
        raise ConfigError(
            f'{path}: got both radius and radius_random_range, expected exactly one of them',
            path,
            {key: section[key] for key in given},
        )
    if not given and count > 0:
        raise ConfigError(
            f'{path}: got {count} obstacle(s) but neither radius nor radius_random_range, '
            'expected exactly one of them',
            path,
            None,
        )


# ----------------------------------------------------------------------------- the schema

# Lengths in world units (the terrain is [-1000, 1000]^2), angles in degrees.
CAMERA = {
    'location': Locations(),
    'location_random_range': LocationRanges(),
    'radius': _positive(40.0),  # body radius, blocks targets
    'min_viewing_angle': Number(90.0, 0.0, MAX_CAMERA_VIEWING_ANGLE, low_open=True, unit='degrees'),
    'max_sight_range': _positive(500.0),  # sight range at min_viewing_angle
    'rotation_step': _positive(5.0, 'degrees'),  # largest orientation change per step
    'zooming_step': _positive(2.5, 'degrees'),  # largest viewing-angle change per step
}

TARGET = {
    'location': Locations(),
    'location_random_range': LocationRanges(),
    'step_size': _positive(10.0),  # largest move per step of a capacity-1 target
    'sight_range': _positive(500.0),
}

OBSTACLE = {
    'location': Locations(),
    'location_random_range': LocationRanges(),
    'radius': Number(OMIT, low=0.0),  # exactly one of radius / radius_random_range
    'radius_random_range': RadiusRange(),
    'transmittance': Number(0.0, 0.0, 1.0),  # probability that sight passes through
}

SCHEMA = Section(
    {
        'name': Text(),
        'max_episode_steps': Number(10000, low=0, low_open=True, integer=True),
        'reward_type': Choice('dense', ('dense', 'sparse')),
        'num_cargoes_per_target': Number(REQUIRED, low=NUM_WAREHOUSES, integer=True),
        'high_capacity_target_split': Number(0.5, 0.0, 1.0),
        'targets_start_with_cargoes': Flag(True),
        'bounty_factor': Number(1.0, low=0.0),
        'shuffle_entities': Flag(True),
        'camera': Section(CAMERA),
        'target': Section(TARGET, default=REQUIRED, rule=_require_targets),
        'obstacle': Section(OBSTACLE, rule=_one_obstacle_radius),
    }
)
"""The whole configuration; field defaults are filled when a key is missing."""


def normalize_config(config: object) -> dict:
    """Validate a configuration mapping and return it normalised (see module docstring).

    The argument is never mutated; the result shares no mutable object with it.
    Raises `ConfigError` (a `ValueError`) for the first problem found.
    """
    return SCHEMA.check(config, '')
