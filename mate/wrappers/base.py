"""Shared machinery of the MATE wrappers: the `MateWrapper` base class, chain inspection and ordering checks.

Every MATE wrapper is a `gymnasium.Wrapper` whose `reset`/`step` keep the environment's two-team
signature (or the single-team signature once a `MultiCamera`/`MultiTarget`/`SingleCamera`/`SingleTarget`
sits inside). Gymnasium 1.x wrappers no longer forward unknown attributes to the wrapped env; MATE's
wrappers and agents rely on reading env data through a wrapper stack (`env.num_cameras`,
`env.camera_target_view_mask`, `env.send_messages`, ...), so `MateWrapper.__getattr__` forwards every
public name (not starting with `_`) down the chain of `.env`, through foreign Gymnasium wrappers too,
until an object has it.

Ordering: the original checks "wrapper X is somewhere inside" with a metaclass that makes
`isinstance` walk the chain. Here the walk is explicit (`find_wrapper`, `has_wrapper`); `isinstance`
keeps its ordinary meaning. A wrong order raises `WrapperOrderError`, naming which wrapper must come
before (be applied earlier than, i.e. sit inside) which.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np

from mate.constants import (
    CAMERA_STATE_DIM_PRIVATE,
    PRESERVED_DIM,
    TARGET_STATE_DIM_PRIVATE,
)

__all__ = [
    'MateWrapper',
    'WrapperOrderError',
    'assert_base_environment',
    'assert_mate_environment',
    'assert_multi_agent_environment',
    'check_choice',
    'find_wrapper',
    'forbid_inside',
    'forbid_twice',
    'has_wrapper',
    'iter_env_chain',
    'private_states',
    'require_inside',
]


class WrapperOrderError(ValueError):
    """A wrapper was applied in an order the wrappers do not support (see docs/wrappers.md, "Ordering")."""


def iter_env_chain(env: Any) -> Iterator[Any]:
    """Yield `env`, `env.env`, `env.env.env`, ... down to the unwrapped environment (inclusive)."""
    while True:
        yield env
        if not isinstance(env, gym.Wrapper):
            return
        env = env.env


ROLES = {
    'single-team': 'exposes one team only (MultiCamera, MultiTarget, SingleCamera, SingleTarget)',
    'single-agent': 'exposes one agent only (SingleCamera, SingleTarget)',
    'converted': 'observations are no longer absolute and unscaled (RelativeCoordinates, RescaledObservation)',
    'repeated-reward': 'one reward and done flag per agent (RepeatedRewardIndividualDone)',
}
"""What a wrapper may do that other wrappers' ordering checks ask about. A wrapper class lists its roles in
`MateWrapper.ROLES`; the checks name a role instead of a class, so that this module imports no concrete wrapper."""


def _matches(item: Any, what) -> bool:
    if isinstance(what, str):
        return what in getattr(type(item), 'ROLES', ())
    return isinstance(item, what)


def find_wrapper(env: Any, what) -> Any | None:
    """The outermost wrapper in the chain of `env` (itself included) that is an instance of `what` (a class or a
    tuple of classes) or has the role `what` (a name of `ROLES`), or None."""
    if isinstance(what, str) and what not in ROLES:
        raise ValueError(f'unknown wrapper role {what!r}; roles: {", ".join(ROLES)}')
    for item in iter_env_chain(env):
        if _matches(item, what):
            return item
    return None


def has_wrapper(env: Any, what) -> bool:
    """Whether `env` or anything inside it is an instance of `what` or has the role `what` (`find_wrapper`; the
    original's `isinstance(env, cls)`)."""
    return find_wrapper(env, what) is not None


def _names(cls: type | tuple[type, ...]) -> str:
    classes = cls if isinstance(cls, tuple) else (cls,)
    return '/'.join(c.__name__ for c in classes)


class MateWrapper(gym.Wrapper):
    """Base class of every MATE wrapper: a `gymnasium.Wrapper` that forwards MATE attributes.

    Attribute lookup: names defined on the wrapper (instance or class) win; any other public name is
    looked up on the next env of the chain, then the next, down to `MultiAgentTracking`. Names starting
    with `_` are never forwarded. `str(wrapper)` shows the stack, e.g.
    `<DiscreteCamera(levels=5)<MultiAgentTracking>(4 cameras, 8 targets, 9 obstacles)>`.
    """

    ROLES: frozenset = frozenset()
    """What this wrapper does that others' ordering checks ask about (names of `mate.wrappers.base.ROLES`)."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith('_') or name == 'env':
            raise AttributeError(f'{type(self).__name__!r} object has no attribute {name!r}')
        env = self.__dict__.get('env')
        while env is not None:
            try:
                return object.__getattribute__(env, name)
            except AttributeError:
                pass
            env = env.__dict__.get('env') if isinstance(env, gym.Wrapper) else None
        raise AttributeError(f'{type(self).__name__!r} object and the environments it wraps have no '
                             f'attribute {name!r}')

    def _arguments(self) -> str:
        """Constructor arguments shown by `str` (override)."""
        return ''

    def __str__(self) -> str:
        arguments = self._arguments()
        return f'<{type(self).__name__}{f"({arguments})" if arguments else ""}{self.env}>'

    def __repr__(self) -> str:
        return str(self)


class ObservationMateWrapper(MateWrapper):
    """A MATE wrapper that only changes observations: `reset` and `step` pass them through
    `self.observation` (override), everything else is untouched."""

    def observation(self, observation: Any) -> Any:
        raise NotImplementedError

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[Any, Any]:
        observation, infos = self.env.reset(seed=seed, options=options)
        return self.observation(observation), infos

    def step(self, action):
        observation, reward, terminated, truncated, infos = self.env.step(action)
        return self.observation(observation), reward, terminated, truncated, infos


class TeamObservationWrapper(ObservationMateWrapper):
    """Base of the observation wrappers with a `team` argument in {'both', 'camera', 'target',
    'none'} that read absolute, unscaled observations of the two-team env (EnhancedObservation,
    SharedFieldOfView). Sets `self.for_camera`, `self.for_target` and `self._counts`."""

    TEAMS = ('both', 'camera', 'target', 'none')

    def __init__(self, env, team: str = 'both') -> None:
        name = type(self).__name__
        assert_base_environment(env, name)
        check_choice('team', team, self.TEAMS)
        forbid_inside(env, name, 'converted', 'it reads absolute, unscaled values')
        super().__init__(env)
        self.team = team
        self.for_camera = team in ('camera', 'both')
        self.for_target = team in ('target', 'both')
        base = env.unwrapped
        self._counts = (base.num_cameras, base.num_targets, base.num_obstacles)

    def _arguments(self) -> str:
        return f'team={self.team}'


# ---------------------------------------------------------------------------- ordering checks

def assert_mate_environment(env: Any, wrapper: str) -> None:
    """TypeError unless `env` is a `MultiAgentTracking`, possibly wrapped."""
    from mate.envs.multi_agent_tracking import MultiAgentTracking

    if not isinstance(getattr(env, 'unwrapped', None), MultiAgentTracking):
        raise TypeError(f'{wrapper} wraps a MATE environment (mate.MultiAgentTracking, possibly wrapped); '
                        f'got {env!r}')


def assert_multi_agent_environment(env: Any, wrapper: str) -> None:
    """`assert_mate_environment`, and no SingleCamera/SingleTarget inside."""
    assert_mate_environment(env, wrapper)
    forbid_inside(env, wrapper, 'single-agent', 'it needs one observation/reward per agent')


def assert_base_environment(env: Any, wrapper: str) -> None:
    """`assert_mate_environment`, and no single-team wrapper (Multi*/Single*) inside: both teams are exposed."""
    assert_mate_environment(env, wrapper)
    forbid_inside(env, wrapper, 'single-team', 'it needs both teams')


def forbid_inside(env: Any, wrapper: str, what, why: str = '') -> None:
    """WrapperOrderError if a wrapper of class or role `what` is already in the chain: `wrapper` must come before it."""
    found = find_wrapper(env, what)
    if found is not None:
        reason = f' ({why})' if why else ''
        raise WrapperOrderError(
            f'{wrapper} must be applied before {type(found).__name__}{reason}: put {wrapper} earlier in the '
            f'wrappers list (closer to the base environment) than {type(found).__name__}. Got env = {env}')


def require_inside(env: Any, wrapper: str, cls: type | tuple[type, ...]) -> None:
    """WrapperOrderError unless `cls` is in the chain: it must come before `wrapper`."""
    if not has_wrapper(env, cls):
        raise WrapperOrderError(
            f'{wrapper} needs {_names(cls)} to be applied before it: put {_names(cls)} earlier in the '
            f'wrappers list than {wrapper}. Got env = {env}')


def forbid_twice(env: Any, wrapper_cls: type) -> None:
    """WrapperOrderError if `wrapper_cls` already wraps `env`."""
    if has_wrapper(env, wrapper_cls):
        raise WrapperOrderError(f'{wrapper_cls.__name__} may be applied only once. Got env = {env}')


def check_choice(name: str, value: Any, choices: tuple) -> None:
    """ValueError unless `value` is one of `choices`."""
    if value not in choices:
        raise ValueError(f'invalid {name} {value!r}: expected one of {choices}')


# ---------------------------------------------------------------------------- env data

def private_states(env: Any) -> tuple[np.ndarray, np.ndarray]:
    """(camera_states (Nc, 9), target_states (Nt, 14)): every entity's private state, cut from `env.state()`.

    Camera rows: `[x, y, r, R cos phi, R sin phi, theta, R_max, rotation_step, zooming_step]`; target rows:
    `[x, y, sight_range, is_loaded, step_size, capacity, goal_bits(4), empty_bits(4)]` (the target's own
    beliefs, whatever observation wrappers show). Fresh arrays.
    """
    base = env.unwrapped
    nc, nt = base.num_cameras, base.num_targets
    state = base.state()
    end = PRESERVED_DIM + CAMERA_STATE_DIM_PRIVATE * nc
    cameras = state[PRESERVED_DIM:end].reshape(nc, CAMERA_STATE_DIM_PRIVATE)
    targets = state[end:end + TARGET_STATE_DIM_PRIVATE * nt].reshape(nt, TARGET_STATE_DIM_PRIVATE)
    return cameras, targets
