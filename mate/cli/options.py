"""Command-line options generated from config dataclasses: the dataclass is the one source of defaults and help.

Every field of a config dataclass becomes an option `--field-name` of an argparse parser; its help text is the
field's `metadata['help']` (written with `option(default, 'help')`), its type and choices come from the
annotation:

* `int`, `float`, `str`: a value (numbers parsed and range-checked: `metadata['minimum']`, `['above']`,
  `['maximum']`; `check_ranges(config)` checks the same ranges of a config made in Python);
* `bool`: a switch; `--name` sets True (a field whose default is True gets `--no-name` instead);
* `Literal['a', 'b']`: one of the choices;
* `tuple[int, ...]` / `tuple[float, ...]`: one or more numbers (`--hidden 64 64`);
* `X | None`: as X, default None (the help says what None means);
* schedules, `tuple[tuple[float, float], ...]`: JSON `[[step, value], ...]` (a step may be a string, `"40%"`: a
  share of the budget, `mate.learn.schedules`).

`add_options(parser, Config)` adds them; `config_from(parser, Config, args)` builds the dataclass from the parsed
namespace (its `__post_init__` checks the values; a ValueError becomes the parser's two-line error). An option
of another config cannot be given: it is not on the parser. Fields with `metadata['cli'] = False` are not options.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import types
import typing
from pathlib import Path
from typing import Any, Literal

from .arguments import in_range, number, number_phrase

__all__ = ['add_options', 'check_ranges', 'config_from', 'file_arguments', 'option']

RANGE_KEYS = ('minimum', 'above', 'maximum')


def option(default: Any, help: str, **metadata: Any):   # noqa: A002  (the argparse word)
    """A dataclass field with its command-line help (and optional `minimum`, `above`, `maximum`, `metavar`, `cli`)."""
    if isinstance(default, (list, dict, set)):
        raise TypeError('use a tuple default (dataclass fields are shared between instances)')
    return dataclasses.field(default=default, metadata=dict(help=help, **metadata))


def check_ranges(config) -> None:
    """ValueError naming the option (`--clip must be a number > 0, got -0.1`) when a field of the dataclass
    `config` with a range in its metadata (`minimum`, `above`, `maximum`) holds a number outside it; a tuple field
    is checked number by number, None (an `X | None` field) passes. The command line checks the same when parsing;
    this catches configs made in Python."""
    for field in dataclasses.fields(config):
        bounds = tuple(field.metadata.get(key) for key in RANGE_KEYS)
        if bounds == (None, None, None):
            continue
        value = getattr(config, field.name)
        for item in value if isinstance(value, tuple) else (value,):
            if item is None:
                continue
            if isinstance(item, bool) or not isinstance(item, (int, float)) or not in_range(item, *bounds):
                annotation = _unwrap_optional(typing.get_type_hints(type(config))[field.name])[0]
                kind = (typing.get_args(annotation) or (float,))[0] if typing.get_origin(annotation) is tuple \
                    else annotation
                raise ValueError(f'{flag_of(field.name)} must be {number_phrase(kind, *bounds)}, got {item!r}')


def flag_of(name: str) -> str:
    """'num_envs' -> '--num-envs'."""
    return '--' + name.replace('_', '-')


def _unwrap_optional(annotation):
    """(inner annotation, whether None is allowed) of `X | None` / `Optional[X]`."""
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(annotation)) == 2:
            return args[0], True
    return annotation, False


def _schedule(text: str):
    """A schedule's JSON [[step, value], ...]: numbers, or a step as a string ('40%': a share of the budget, which
    the config checks)."""
    try:
        value = json.loads(text)
        points = tuple((step.strip() if isinstance(step, str) else float(step), float(v)) for step, v in value)
    except (ValueError, TypeError) as exc:
        raise argparse.ArgumentTypeError(f'expected JSON [[step, value], ...], got {text!r} ({exc})') from None
    if not points:
        raise argparse.ArgumentTypeError('a schedule needs at least one [step, value] point')
    return tuple((s if isinstance(s, str) else int(s) if s == int(s) else s, v) for s, v in points)


def _help(field: dataclasses.Field, default_text: str) -> str:
    text = field.metadata.get('help', '')
    return f'{text} (default: {default_text})' if default_text else text


def _show(value) -> str:
    if value is None:
        return 'None'
    if isinstance(value, tuple):
        return json.dumps(value) if value and isinstance(value[0], tuple) else ' '.join(map(str, value))
    if isinstance(value, float) and value.is_integer() and abs(value) >= 1e4:
        return f'{value:,.0f}'
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 1e4:
        return f'{value:,}'
    return str(value)


def add_options(parser: argparse.ArgumentParser, config_class, group: str | None = None, exclude=()) -> None:
    """One option per field of `config_class` (module docstring), in the order of the fields, and one switch per
    preset of `config_class.PRESETS` ({name: (help, {field: value})}: `--name` sets those fields, except the ones
    given explicitly). Fields named in `exclude` get no option (a command that fixes them)."""
    hints = typing.get_type_hints(config_class)
    target = parser.add_argument_group(group) if group else parser
    for name, (text, _) in getattr(config_class, 'PRESETS', {}).items():
        target.add_argument(flag_of(name), action='store_true', dest=f'preset_{name}', default=False, help=text)
    for field in dataclasses.fields(config_class):
        if not field.metadata.get('cli', True) or not field.init or field.name in exclude:
            continue
        annotation, optional = _unwrap_optional(hints[field.name])
        default = field.default
        flag, meta = flag_of(field.name), field.metadata
        kwargs: dict[str, Any] = dict(dest=field.name, default=argparse.SUPPRESS)
        if 'metavar' in meta:
            kwargs['metavar'] = meta['metavar']
        if annotation is bool:
            if default is True:
                target.add_argument(f'--no-{field.name.replace("_", "-")}', action='store_false',
                                    help=f'turn off (on by default): {field.metadata.get("help", field.name)}',
                                    **kwargs)
            else:
                target.add_argument(flag, action='store_true', help=_help(field, ''), **kwargs)
            continue
        origin = typing.get_origin(annotation)
        if origin is Literal:
            choices = typing.get_args(annotation)
            target.add_argument(flag, choices=choices, help=_help(field, _show(default)), **kwargs)
        elif annotation in (int, float):
            target.add_argument(flag, type=number(annotation, *map(meta.get, RANGE_KEYS)),
                                help=_help(field, _show(default)), **kwargs)
        elif annotation is str:
            target.add_argument(flag, help=_help(field, _show(default)), **kwargs)
        elif origin is tuple:
            inner = typing.get_args(annotation)
            if inner and typing.get_origin(inner[0]) is tuple:
                target.add_argument(flag, type=_schedule, metavar=meta.get('metavar', 'JSON'),
                                    help=_help(field, _show(default)), **{k: v for k, v in kwargs.items()
                                                                          if k != 'metavar'})
            else:
                kind = inner[0] if inner else float
                target.add_argument(flag, type=number(kind, *map(meta.get, RANGE_KEYS)),
                                    nargs='+', help=_help(field, _show(default)), **kwargs)
        else:
            raise TypeError(f'{config_class.__name__}.{field.name}: no command-line form for {hints[field.name]!r}')


def config_from(parser: argparse.ArgumentParser, config_class, args: argparse.Namespace, **fixed):
    """The `config_class` instance of parsed `args` (fields not given keep their defaults; `fixed` overrides);
    a ValueError of its validation exits through `parser.error` (two lines, status 2)."""
    names = {f.name for f in dataclasses.fields(config_class) if f.init}
    given = {name: getattr(args, name) for name in names if hasattr(args, name)}
    for preset, (_, values) in getattr(config_class, 'PRESETS', {}).items():
        if getattr(args, f'preset_{preset}', False):
            given = {**values, **given}
    for name, value in given.items():
        if isinstance(value, list):
            given[name] = tuple(value)
    try:
        return config_class(**{**given, **fixed})
    except (ValueError, TypeError) as exc:
        parser.error(str(exc))


def file_arguments(parser: argparse.ArgumentParser, path) -> list[str]:
    """The options of a YAML or JSON config file (`mate train ALGORITHM --config-file FILE`) as command-line tokens
    for `parser`, to be put before the command line's own (which then win): keys are the options' field names
    (`num_envs` or `num-envs`) or preset switches (`paper: true`), values as the command line takes them (a list
    for several numbers, `[[step, value], ...]` for a schedule). ValueError naming an unknown key, with the valid
    ones, or a value of the wrong form; the parser checks ranges and choices as for the command line."""
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise ValueError(f'--config-file: cannot read {path}: {exc.strerror}') from None
    except yaml.YAMLError as exc:
        raise ValueError(f'--config-file {path}: not valid YAML/JSON: {str(exc).splitlines()[0]}') from None
    if data is None:
        return []
    if not isinstance(data, dict):
        raise ValueError(f'--config-file {path}: expected a mapping of options, got a {type(data).__name__}')
    actions = {action.dest: action for action in parser._actions if action.option_strings}
    switches = {action.dest.removeprefix('preset_'): action for dest, action in actions.items()
                if dest.startswith('preset_')}
    tokens: list[str] = []
    for key, value in data.items():
        name = str(key).replace('-', '_')
        action = actions.get(name) or switches.get(name)
        if action is None or name in ('help', 'config_file'):
            valid = sorted(d for d in actions if d not in ('help', 'config_file') and not d.startswith('preset_'))
            raise ValueError(f'--config-file {path}: unknown option {key!r}; the options are {", ".join(valid)}')
        flag = action.option_strings[0]
        if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
            if not isinstance(value, bool):
                raise ValueError(f'--config-file {path}: {key} is true or false, got {value!r}')
            if value == isinstance(action, argparse._StoreTrueAction):    # --flag for true, --no-flag for false
                tokens.append(flag)
            continue
        if value is None:
            continue
        if action.type is _schedule:
            tokens += [flag, json.dumps(value)]
        elif action.nargs == '+':
            tokens += [flag, *map(str, value if isinstance(value, (list, tuple)) else [value])]
        else:
            tokens += [flag, str(value)]
    return tokens
