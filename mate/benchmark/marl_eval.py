"""Results in marl-eval's JSON layout (Gorsane et al., 2022), from flat records.

The layout followed is that of marl-eval 0.0.4 (PyPI `id-marl-eval` 0.0.4), read in its sdist: the README's
"Data Structure for Raw Experiment data", the loader `marl_eval/utils/data_processing_utils.py`
(`data_process_pipeline`, `create_matrices_for_rliable`), `marl_eval/utils/diagnose_data_errors.py`
(`DiagnoseData`) and the run naming of `marl_eval/json_tools/json_logger.py` (`JsonLogger`):

```text
{environment: {task: {algorithm: {run: {
    "step_0": {"step_count": int, metric: [value per evaluation episode], ...},
    ...
    "step_k": {...},
    "absolute_metrics": {metric: [value per episode of the absolute evaluation], ...}}}}}}
```

What the loader needs, and what `marl_eval_json` therefore checks before it writes anything:

- it lower-cases every key, so names must differ other than by case at each level;
- within an environment, every task has the same algorithms, every (task, algorithm) the same runs, every
  run the same steps, and every step and `absolute_metrics` the same metrics: it reads all of them by the
  names of the first task, algorithm and run (and `DiagnoseData` flags any difference);
- a key containing "absolute" is the absolute metrics, and older versions of the loader take the last key
  of a run for them: `absolute_metrics` is written last, after the steps in order;
- metric values are lists of numbers (it takes their mean); `step_count` increases from step to step (the
  evaluation interval is read from its differences); a key containing "step_count" is never a metric;
- algorithm names have no commas (its probability-of-improvement plots split on them);
- it adds `mean_<metric>`, `norm_<metric>` and `mean_norm_<metric>` beside each metric, so a metric may
  not be named so.

Runs given as integers (seeds) are named `seed_<seed>`, as `JsonLogger` names them; steps `step_<index>`.
"""

from __future__ import annotations

import json
import math
import numbers
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = ['StepRecord', 'AbsoluteRecord', 'marl_eval_json', 'write_marl_eval']

ABSOLUTE = 'absolute_metrics'
STEP_COUNT = 'step_count'


@dataclass(frozen=True)
class StepRecord:
    """One metric at one evaluation of one run: the values of its evaluation episodes."""

    environment: str
    """The environment (e.g. 'MATE')."""
    task: str
    """The task (e.g. 'MATE-4v8-9 cameras')."""
    algorithm: str
    """The algorithm or setting; no commas."""
    run: int | str
    """The run: its seed (written as `seed_<seed>`) or a name."""
    step: int
    """The index of the evaluation in the run, 0, 1, ... (written as `step_<index>`)."""
    step_count: int
    """Environment steps (decisions) trained when the evaluation ran."""
    metric: str
    """The metric's name (e.g. 'return', 'coverage')."""
    values: Sequence[float]
    """One value per evaluation episode (or one value, for a metric over all of them)."""


@dataclass(frozen=True)
class AbsoluteRecord:
    """One absolute metric of one run: the best policy of the run re-evaluated, one value per episode."""

    environment: str
    """The environment."""
    task: str
    """The task."""
    algorithm: str
    """The algorithm or setting; no commas."""
    run: int | str
    """The run: its seed or a name, as in its `StepRecord`s."""
    metric: str
    """The metric's name: the same metrics as the run's steps."""
    values: Sequence[float]
    """One value per episode of the absolute evaluation (10 x the episodes of a step, by the protocol)."""


def _name(value: object, what: str) -> str:
    if not isinstance(value, str) or not value:
        raise ValueError(f'{what}: a non-empty string, got {value!r}')
    return value


def _run_key(run: int | str) -> str:
    if isinstance(run, str) and run:
        return run
    if isinstance(run, numbers.Integral) and not isinstance(run, bool):
        return f'seed_{int(run)}'
    raise ValueError(f'run: a seed (int) or a non-empty name, got {run!r}')


def _metric(value: object) -> str:
    metric = _name(value, 'metric')
    lower = metric.lower()
    if STEP_COUNT in lower or 'absolute' in lower or lower.startswith(('mean_', 'norm_')):
        raise ValueError(f'metric {metric!r}: marl-eval reserves the names that contain "step_count" or '
                         '"absolute" or start with "mean_" or "norm_"')
    return metric


def _values(values: object, where: str) -> list[float]:
    try:
        items = list(values)  # type: ignore[call-overload]
    except TypeError:
        items = None
    if items is None or isinstance(values, (str, bytes)) or not all(
            isinstance(v, numbers.Real) and not isinstance(v, bool) for v in items):
        raise ValueError(f'{where}: values must be a list of numbers, got {values!r}')
    out = [float(v) for v in items]
    if not out:
        raise ValueError(f'{where}: no values')
    if not all(math.isfinite(v) for v in out):
        raise ValueError(f'{where}: NaN or infinite values')
    return out


def _count(value: object, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise ValueError(f'{what}: a non-negative integer, got {value!r}')
    return int(value)


def _unique_by_case(keys: Iterable[str], where: str) -> None:
    seen: dict[str, str] = {}
    for key in keys:
        if key.lower() in seen and seen[key.lower()] != key:
            raise ValueError(f'{where}: {seen[key.lower()]!r} and {key!r} differ only by case '
                             '(marl-eval lower-cases its keys)')
        seen[key.lower()] = key


def _run_order(key: str) -> tuple:
    """Seeds in numeric order, then named runs in alphabetical order."""
    number = key[5:] if key.startswith('seed_') else ''
    return (0, int(number), key) if number.isdigit() else (1, 0, key)


def marl_eval_json(records: Iterable[StepRecord | AbsoluteRecord]) -> dict:
    """The marl-eval JSON document of `records`, as a dict (see the module's docstring for the layout).

    Environments, tasks and algorithms keep the order of their first record; runs are sorted (seeds by
    number), steps by index, and `absolute_metrics` comes last in every run.

    Args:
        records: every `StepRecord` and `AbsoluteRecord` of the results; each (run, step, metric) and
            (run, absolute metric) once.

    Returns:
        {environment: {task: {algorithm: {run: {'step_<i>': {...}, ..., 'absolute_metrics': {...}}}}}}.

    Raises:
        ValueError: a record is malformed or repeated, a run has no absolute metrics, or the results are
            not rectangular as marl-eval's loader needs (see the module's docstring).
    """
    tree = _tree(records)
    document: dict = {}
    _unique_by_case(tree, 'environments')
    for environment, tasks in tree.items():
        _unique_by_case(tasks, f'{environment}: tasks')
        shape = None  # (algorithms, runs, step indices, metrics) of the environment's first run
        document[environment] = {}
        for task, algorithms in tasks.items():
            _unique_by_case(algorithms, f'{environment}/{task}: algorithms')
            document[environment][task] = {}
            for algorithm, runs in algorithms.items():
                _unique_by_case(runs, f'{environment}/{task}/{algorithm}: runs')
                document[environment][task][algorithm] = {}
                for run in sorted(runs, key=_run_order):
                    where = f'{environment}/{task}/{algorithm}/{run}'
                    here = _checked_run(runs[run], where, algorithms, runs)
                    if shape is None:
                        shape = here
                    elif here != shape:
                        parts = ['algorithms', 'runs', 'steps', 'metrics']
                        which = next(p for p, a, b in zip(parts, here, shape) if a != b)
                        raise ValueError(f'{where}: its {which} differ from those of the first run of '
                                         f'{environment!r} (marl-eval needs the same in every run)')
                    document[environment][task][algorithm][run] = _run_document(runs[run])
    return document


def _tree(records: Iterable[StepRecord | AbsoluteRecord]) -> dict:
    """The records checked one by one and gathered as environment -> task -> algorithm -> run -> (steps: index ->
    (step_count, metrics), absolute metrics); ValueError for a malformed or repeated record, or none."""
    tree: dict = {}
    for record in records:
        if not isinstance(record, (StepRecord, AbsoluteRecord)):
            raise ValueError(f'records: StepRecord or AbsoluteRecord, got {type(record).__name__}')
        environment = _name(record.environment, 'environment')
        task = _name(record.task, 'task')
        algorithm = _name(record.algorithm, 'algorithm')
        if ',' in algorithm:
            raise ValueError(f'algorithm {algorithm!r}: marl-eval forbids commas in algorithm names')
        run = _run_key(record.run)
        metric = _metric(record.metric)
        where = f'{environment}/{task}/{algorithm}/{run}'
        steps, absolute = tree.setdefault(environment, {}).setdefault(task, {}).setdefault(
            algorithm, {}).setdefault(run, ({}, {}))
        if isinstance(record, AbsoluteRecord):
            if metric in absolute:
                raise ValueError(f'{where}: absolute metric {metric!r} given twice')
            absolute[metric] = _values(record.values, f'{where}/{ABSOLUTE}/{metric}')
            continue
        index = _count(record.step, f'{where}: step')
        step_count = _count(record.step_count, f'{where}/step_{index}: step_count')
        known_count, metrics = steps.setdefault(index, (step_count, {}))
        if known_count != step_count:
            raise ValueError(f'{where}/step_{index}: step_count {step_count} and {known_count} in two records')
        if metric in metrics:
            raise ValueError(f'{where}/step_{index}: metric {metric!r} given twice')
        metrics[metric] = _values(record.values, f'{where}/step_{index}/{metric}')
    if not tree:
        raise ValueError('records: none')
    return tree


def _checked_run(run: tuple[dict, dict], where: str, algorithms: dict, runs: dict) -> tuple:
    """Check one run of the tree (evaluation steps and absolute metrics present, step counts increasing, the same
    metrics at every step as in the absolute metrics); returns its shape (algorithms, runs, step indices, metrics),
    which marl-eval needs equal in every run of an environment."""
    steps, absolute = run
    if not steps:
        raise ValueError(f'{where}: no evaluation steps')
    if not absolute:
        raise ValueError(f'{where}: no absolute metrics (marl-eval needs them in every run)')
    indices = sorted(steps)
    counts = [steps[i][0] for i in indices]
    if any(b <= a for a, b in zip(counts, counts[1:])):
        raise ValueError(f'{where}: step_count must increase with the step index, got {counts}')
    metrics = set(absolute)
    for i in indices:
        if set(steps[i][1]) != metrics:
            raise ValueError(f'{where}/step_{i}: metrics {sorted(steps[i][1])}, but {ABSOLUTE} has {sorted(metrics)}')
    _unique_by_case(metrics, f'{where}: metrics')
    return sorted(algorithms), sorted(runs), indices, sorted(metrics)


def _run_document(run: tuple[dict, dict]) -> dict:
    """One run in marl-eval's layout: 'step_<i>' by index, each with its step count and metrics, then
    'absolute_metrics'."""
    steps, absolute = run
    out = {f'step_{i}': {STEP_COUNT: steps[i][0], **steps[i][1]} for i in sorted(steps)}
    out[ABSOLUTE] = dict(absolute)
    return out


def write_marl_eval(path: str | Path, records: Iterable[StepRecord | AbsoluteRecord]) -> Path:
    """Write `marl_eval_json(records)` to `path` (strict JSON, keys in order), creating its folder.

    Args:
        path: the file to write, conventionally `marl_eval.json`.
        records: every `StepRecord` and `AbsoluteRecord` of the results.

    Returns:
        The path written.
    """
    document = marl_eval_json(records)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(document, indent=1, allow_nan=False) + '\n')
    return path
