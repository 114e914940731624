"""Environment IDs and `mate.make`: build an environment from an ID, a config and wrappers.

IDs: `MultiAgentTracking-v0` and `MATE-v0` (default preset MATE-4v8-9 unless `config=` is
given) and `MATE-<preset>-v0` for every shipped preset (e.g. `MATE-8v8-9-v0`). The same IDs
are registered with Gymnasium, so `gymnasium.make('MATE-4v8-9-v0')` works too. `mate.make` and
`mate.make_vec` take the preset names as well (`'MATE-8v8-9'`), as everything that takes a config
name takes the ids (`mate.config.preset_name` reads both spellings).
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Callable, Iterable
from typing import Any

import gymnasium as gym

from ..config import list_presets, preset_name
from .multi_agent_tracking import MultiAgentTracking

__all__ = ['make', 'make_environment', 'WrapperSpec', 'registered_ids', 'resolve_config']


class WrapperSpec:
    """A wrapper with its arguments, applied later: `WrapperSpec(W, *args, **kw)(env) == W(env, *args, **kw)`."""

    def __init__(self, wrapper: Callable, *args: Any, **kwargs: Any) -> None:
        if not callable(wrapper):
            raise TypeError(f'WrapperSpec needs a wrapper class or callable, got {wrapper!r}')
        self.wrapper, self.args, self.kwargs = wrapper, args, kwargs

    def __call__(self, env):
        return self.wrapper(env, *self.args, **self.kwargs)

    def __repr__(self) -> str:
        name = getattr(self.wrapper, '__name__', repr(self.wrapper))
        return f'WrapperSpec({name}, args={self.args}, kwargs={self.kwargs})'


def make_environment(config: Any = None, wrappers: Iterable[Callable] = (), **overrides: Any):
    """Build `MultiAgentTracking(config, **overrides)` and apply `wrappers` in order."""
    env = MultiAgentTracking(config, **overrides)
    for wrapper in wrappers:
        if not callable(wrapper):
            raise TypeError(f'wrappers must be WrapperSpec objects, wrapper classes or callables; got {wrapper!r}')
        env = wrapper(env)
    return env


def _preset_ids() -> dict[str, str | None]:
    ids: dict[str, str | None] = {'MultiAgentTracking-v0': None, 'MATE-v0': None}
    for preset in list_presets():
        if preset != 'MATE':
            ids[f'{preset}-v0'] = preset
    return ids


_IDS = _preset_ids()
_BY_LOWER = {env_id.lower(): env_id for env_id in _IDS}


def registered_ids() -> list[str]:
    """Every environment ID `mate.make` accepts."""
    return list(_IDS)


def make(env_id: str = 'MultiAgentTracking-v0', config: Any = None, wrappers: Iterable[Callable] = (),
         **overrides: Any):
    """Make an environment by ID. `config=` replaces the ID's preset; overrides are deep-merged.

    With no config and no preset behind the ID, overrides alone start from an empty
    configuration (as in the original MATE): pass `config='MATE-4v8-9'` to tweak a preset.
    """
    return make_environment(resolve_config(env_id, config), wrappers=wrappers, **overrides)


def resolve_config(env_id: str, config: Any = None) -> Any:
    """The configuration an ID stands for: `config` when given, else the ID's preset (None for
    the default IDs). `env_id` is a registered ID (`registered_ids`) or a preset name
    (`'MATE-4v8-9'`, as `read_config` takes it; `mate.config.preset_name`), case-insensitive.
    Unknown names raise ValueError (one line) with the closest known IDs."""
    if isinstance(env_id, str) and env_id.strip().lower() in _BY_LOWER:
        preset = _IDS[_BY_LOWER[env_id.strip().lower()]]
    else:
        preset = preset_name(env_id)
        if preset is None:
            spelled_as_id = re.search(r'-v\d+$', str(env_id)) is not None    # suggest in the spelling given
            close = difflib.get_close_matches(str(env_id), list(_IDS) if spelled_as_id else list_presets(), n=3)
            hint = f' Did you mean {" or ".join(map(repr, close))}?' if close else ''
            raise ValueError(f'unknown environment id {env_id!r}.{hint} Known ids: {", ".join(_IDS)} '
                             "(or a preset name: an id without '-v0', e.g. 'MATE-4v8-9')")
    return preset if config is None else config


def _register_with_gymnasium() -> None:
    for env_id, preset in _IDS.items():
        if env_id not in gym.registry:
            gym.register(env_id, entry_point='mate.envs.registration:make_environment',
                         vector_entry_point='mate.envs.vector:make_vector_from_gymnasium',
                         kwargs={} if preset is None else {'config': preset},
                         disable_env_checker=True, order_enforce=False)


_register_with_gymnasium()
