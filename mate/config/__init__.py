"""Configuration of mate: the presets, `read_config` and the validating schema.

A configuration is a mapping in the schema of the original MATE (see
`mate.config.schema`); `read_config` loads one from a preset name, a YAML/JSON file or
a mapping, merges keyword overrides and returns a validated, normalised plain dict.

    >>> from mate.config import read_config
    >>> config = read_config('MATE-4v8-9', camera={'radius': 30.0})
    >>> len(config['camera']['location_random_range']), config['camera']['radius']
    (4, 30.0)
"""

from mate.config.loader import (
    DEFAULT_CONFIG,
    PRESETS_DIR,
    list_presets,
    preset_name,
    preset_path,
    read_config,
)
from mate.config.schema import ConfigError

__all__ = [
    'read_config', 'ConfigError', 'PRESETS_DIR', 'DEFAULT_CONFIG', 'list_presets', 'preset_name', 'preset_path',
]
