"""Fault injection for the cluster tests: stand-ins for the two PSRO jobs that record each attempt and stall or
fail on request, then run the real job.

A stand-in is `functools.partial(best_response, FOLDER)` (or `payoff_entries`) put in place of
`mate.learn.population.jobs.best_response` in the driver; Ray ships it by value (`ray.cloudpickle.
register_pickle_by_value(faults)`), and in the worker it calls the real job of the worker's own, unpatched module.

In FOLDER, per job KEY ('br-camera-2': the best response of that team and seed; 'entry-1-0-0': the payoff entry
of camera 1, target 0 from env seed 0; `mate psro` plays its entries from seed 3,000,000):

* every attempt leaves `KEY-N` (N = 0, 1, ...), holding the id of the Ray node it ran on;
* with `stall-KEY` present, attempt 0 waits (for its node or driver to be killed) instead of running;
* with `fail-KEY` present, every attempt raises ValueError (the job's own failure, which Ray must not retry).
"""

from __future__ import annotations

import importlib
import os
import time
from pathlib import Path

STALL_SECONDS = 300
"""How long a stalled attempt waits before it fails the test (it is killed within seconds)."""


def _node() -> str:
    try:
        import ray

        return ray.get_runtime_context().get_node_id() or 'local'
    except Exception:  # noqa: BLE001  (not in a Ray worker)
        return 'local'


def attempts(folder, key: str) -> list[str]:
    """The node ids of the attempts of job `key` so far, in order."""
    folder = Path(folder)
    found = sorted(folder.glob(f'{key}-*'), key=lambda path: int(path.name.rpartition('-')[2]))
    return [path.read_text() for path in found]


def _record(folder: str, key: str) -> int:
    """Leave the attempt's marker, then fail or stall as FOLDER asks; returns the attempt's number."""
    folder = Path(folder)
    attempt = len(attempts(folder, key))
    marker = folder / f'.{key}-{attempt}.tmp'       # written whole, then renamed: a reader never sees it empty
    marker.write_text(_node())
    os.replace(marker, folder / f'{key}-{attempt}')
    if (folder / f'fail-{key}').exists():
        raise ValueError(f'injected failure of {key}')
    if attempt == 0 and (folder / f'stall-{key}').exists():
        time.sleep(STALL_SECONDS)
        raise RuntimeError(f'{key}: the stalled attempt was not killed')
    return attempt


def echo(folder: str, key: str, value) -> dict:
    """A job of no work: its attempt recorded as KEY; returns the attempt's number and the size of `value`
    (a list of bytes)."""
    attempt = _record(folder, key)
    return dict(key=key, attempt=attempt, size=sum(len(item) for item in value))


def _attempt(folder: str, key: str, job: str, kwargs: dict):
    _record(folder, key)
    real = getattr(importlib.import_module('mate.learn.population.jobs'), job)
    if getattr(real, 'func', None) is not None:
        raise RuntimeError('the stand-in runs in the process that installed it; run it on Ray')
    return real(**kwargs)


def best_response(folder: str, **kwargs):
    """`jobs.best_response` with its attempts recorded as 'br-TEAM-SEED'."""
    return _attempt(folder, f'br-{kwargs["team"]}-{kwargs["seed"]}', 'best_response', kwargs)


def payoff_entries(folder: str, **kwargs):
    """`jobs.payoff_entries` (one pairing) with its attempts recorded as 'entry-K-L-SEED'."""
    (k, l), = kwargs['pairs']
    return _attempt(folder, f'entry-{k}-{l}-{kwargs["seed"]}', 'payoff_entries', kwargs)


def register() -> None:
    """Make Ray ship this module's functions by value (the workers cannot import the tests)."""
    import sys

    import ray.cloudpickle

    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])


def stand_ins(folder) -> dict:
    """{'best_response': ..., 'payoff_entries': ...}: the stand-ins recording in `folder`, to put in place of the
    jobs of `mate.learn.population.jobs` in a driver; they travel to the Ray workers by value."""
    import functools

    register()
    return dict(best_response=functools.partial(best_response, str(folder)),
                payoff_entries=functools.partial(payoff_entries, str(folder)))
