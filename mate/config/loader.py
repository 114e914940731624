"""Loading of mate configurations: preset names, YAML/JSON files, mappings and overrides.

`read_config` resolves its argument to a mapping, deep-merges keyword overrides on top
and returns the validated, normalised dict described in `mate.config.schema`.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping
from pathlib import Path

import yaml

from mate.config.schema import (
    ConfigError,
    MissingKeyError,
    did_you_mean,
    normalize_config,
)

__all__ = [
    'PRESETS_DIR', 'DEFAULT_CONFIG', 'ENV_ID_SUFFIX', 'read_config', 'list_presets', 'preset_path', 'preset_name',
    'deep_merge',
]

PRESETS_DIR = Path(__file__).resolve().parent / 'presets'
"""Directory of the preset YAML files shipped with mate."""
DEFAULT_CONFIG = 'MATE-4v8-9.yaml'
"""The preset used when `read_config` gets neither a config nor overrides."""
ENV_ID_SUFFIX = '-v0'
"""What turns a preset name into an environment id of `mate.make` (`'MATE-4v8-9'` -> `'MATE-4v8-9-v0'`)."""
DEFAULT_ENV_ID = 'MultiAgentTracking-v0'
"""The environment id with no preset of its own: as a config name it stands for `DEFAULT_CONFIG`."""

_SUFFIXES = ('.yaml', '.yml', '.json')
_PRESET_SUFFIXES = ('.yaml', '.yml')

_EMPTY_START_HINT = (
    '\nhint: no config was given, so overrides start from an empty configuration '
    "(as in the original MATE); pass e.g. config='MATE-4v8-9' to override a preset."
)


def list_presets() -> list[str]:
    """Names of the shipped presets, without extension, sorted (e.g. ``'MATE-4v8-9'``)."""
    return sorted(path.stem for path in PRESETS_DIR.glob('*.yaml'))


def preset_name(name: object) -> str | None:
    """The shipped preset a name stands for, in either spelling, or None if it names none.

    `name`: a preset name (``'MATE-4v8-9'``, extension optional) or an environment id of `mate.make`
    (``'MATE-4v8-9-v0'``; ``'MATE-v0'`` is the preset ``'MATE'`` and ``'MultiAgentTracking-v0'`` the default,
    ``'MATE-4v8-9'``), case-insensitive. The one place where names are resolved: `read_config` (hence
    `mate.make_team_vec`, `mate.score_policy`, the PettingZoo adapters and the command line) and `mate.make` /
    `mate.make_vec` (`mate.envs.registration.resolve_config`) all ask it.
    """
    if not isinstance(name, str):
        return None
    stem = name.strip()
    if Path(stem).suffix.lower() in _PRESET_SUFFIXES:
        stem = stem[: -len(Path(stem).suffix)]
    if stem.lower() == DEFAULT_ENV_ID.lower():
        stem = Path(DEFAULT_CONFIG).stem
    elif stem.lower().endswith(ENV_ID_SUFFIX):
        stem = stem[: -len(ENV_ID_SUFFIX)]
    by_lower = {preset.lower(): preset for preset in list_presets()}
    return by_lower.get(stem.lower())


def preset_path(name: str) -> Path:
    """The file of preset `name` (``'MATE-4v8-9'``, ``'MATE-4v8-9.yaml'``, ``'MATE-4v8-9-v0'``; case-insensitive).

    Raises `ConfigError` with the closest preset names when there is no such preset.
    """
    path = _find_preset(str(name))
    if path is None:
        raise _unknown_config(str(name))
    return path


def read_config(config: object = None, **overrides: object) -> dict:
    """Load, merge and validate a configuration; return it as a new normalised dict.

    Args:
        config: ``None``; a preset name such as ``'MATE-4v8-9'`` (extension optional) or its
            environment id ``'MATE-4v8-9-v0'`` (`preset_name`);
            a path (str or os.PathLike) to a ``.yaml`` / ``.yml`` / ``.json`` file, tried
            as given (relative paths against the working directory), then as a preset;
            or a mapping (never mutated).
        **overrides: top-level keys deep-merged over the loaded mapping: nested mappings
            are merged key by key, any other value replaces the loaded one.

    With neither `config` nor overrides, the default preset `DEFAULT_CONFIG` is loaded.
    With overrides but no `config`, the overrides start from an EMPTY mapping, not
    from the default preset: a quirk of the original MATE that mate keeps on purpose.

    Raises:
        ConfigError: (a ValueError) unknown preset or file, unreadable file, or the
            first invalid key; its ``path`` and ``value`` attributes locate the problem.
    """
    if config is None and not overrides:
        config = DEFAULT_CONFIG
    base = {} if config is None else _load(config)
    merged = deep_merge(base, overrides)
    try:
        return normalize_config(merged)
    except MissingKeyError as error:
        if config is None and error.path in ('target', 'num_cargoes_per_target'):
            raise MissingKeyError(str(error) + _EMPTY_START_HINT, error.path, error.value) from None
        raise


def deep_merge(base: Mapping, overrides: Mapping) -> dict:
    """A new dict: `base` with `overrides` merged in recursively (neither is mutated)."""
    merged = dict(base)
    for key, value in overrides.items():
        if isinstance(value, Mapping) and isinstance(merged.get(key), Mapping):
            merged[key] = deep_merge(merged[key], value)
        else:
            merged[key] = value
    return merged


def _load(config: object) -> Mapping:
    """The mapping a config argument stands for (file contents or the mapping itself)."""
    if isinstance(config, Mapping):
        return config
    if isinstance(config, (str, os.PathLike)):
        return _read_file(_resolve(os.fsdecode(config)))
    raise ConfigError(
        f'config: got {config!r} (a {type(config).__name__}), expected None, a preset name, '
        'a path to a .yaml/.yml/.json file or a mapping',
        'config',
        config,
    )


def _resolve(text: str) -> Path:
    """The file named by `text`: an existing config file first, then a preset."""
    path = Path(text).expanduser()
    if path.is_file() and path.suffix.lower() in _SUFFIXES:
        return path
    preset = _find_preset(text)
    if preset is not None:
        return preset
    if path.is_file():
        raise ConfigError(
            f'config: unsupported file extension of {text!r}, expected .yaml, .yml or .json',
            'config',
            text,
        )
    raise _unknown_config(text)


def _find_preset(name: str) -> Path | None:
    """The preset file called `name` (a preset name or an env id, `preset_name`), if any."""
    preset = preset_name(name)
    return None if preset is None else PRESETS_DIR / f'{preset}.yaml'


def _unknown_config(text: str) -> ConfigError:
    """The error for a name that is neither a config file nor a preset (one line: the closest names in the
    spelling given, preset names or env ids, and the presets)."""
    presets = list_presets()
    stem = text
    if Path(text).suffix.lower() in _SUFFIXES:
        stem = text[: -len(Path(text).suffix)]
    choices = presets
    if re.search(r'-v\d+$', stem):     # spelled as an env id: suggest ids
        choices = [DEFAULT_ENV_ID] + [f'{preset}{ENV_ID_SUFFIX}' for preset in presets]
    message = f'unknown preset or config file {text!r}'
    hint = did_you_mean(Path(stem).name, choices)
    if hint:
        message += f': {hint}'
    message += (f' Known presets: {", ".join(presets)} (each also as its env id, e.g. '
                f"'{Path(DEFAULT_CONFIG).stem}{ENV_ID_SUFFIX}'), or a .yaml/.yml/.json file")
    return ConfigError(message, 'config', text)


def _read_file(path: Path) -> Mapping:
    """Parse a YAML or JSON config file; its top level must be a mapping."""
    try:
        with path.open(encoding='utf-8') as file:
            if path.suffix.lower() == '.json':
                content = json.load(file)
            else:
                content = yaml.safe_load(file)
    except (OSError, ValueError, yaml.YAMLError) as error:
        message = f'config: cannot read {str(path)!r}: {error}'
        raise ConfigError(message, 'config', str(path)) from error
    if not isinstance(content, Mapping):
        raise ConfigError(
            f'config: the file {str(path)!r} must hold a mapping at the top level, '
            f'got a {type(content).__name__}',
            'config',
            content,
        )
    return content
