"""mate.benchmark.marl_eval writes what marl-eval's loader reads.

marl-eval cannot be installed beside mate (id-marl-eval 0.0.4 pins pandas==1.4.4), so its schema is
restated here as a validator, from its loader (marl_eval/utils/data_processing_utils.py:
`data_process_pipeline`, `create_matrices_for_rliable`), its `DiagnoseData` checks and its README, read in
the 0.0.4 sdist; `loader_matrices` reads a document the way `create_matrices_for_rliable` does. The
validator is written independently of the module, and is itself tested on broken documents.
"""

from __future__ import annotations

import copy
import json
import math
import random
import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mate.benchmark.marl_eval import AbsoluteRecord, StepRecord, marl_eval_json, write_marl_eval

STEP_KEY = re.compile(r'^step_\d+$')


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def marl_eval_problems(document) -> list[str]:  # noqa: C901 (one check per rule of the loader)
    """What keeps marl-eval 0.0.4's loader from reading `document` as intended; [] when nothing."""
    problems: list[str] = []

    def keys_unique_lowercased(mapping: dict, where: str) -> None:
        lowered = [key.lower() for key in mapping]
        if len(set(lowered)) != len(lowered):
            problems.append(f'{where}: keys collide once lower-cased')

    if not isinstance(document, dict) or not document:
        return ['not a non-empty object']
    try:
        json.dumps(document, allow_nan=False)
    except (TypeError, ValueError) as error:
        problems.append(f'not strict JSON: {error}')
    keys_unique_lowercased(document, 'environments')
    for env, tasks in document.items():
        if not isinstance(tasks, dict) or not tasks:
            problems.append(f'{env}: no tasks')
            continue
        keys_unique_lowercased(tasks, env)
        algorithm_sets, run_sets, step_lists, metric_sets = set(), set(), set(), set()
        for task, algorithms in tasks.items():
            if not isinstance(algorithms, dict) or not algorithms:
                problems.append(f'{env}/{task}: no algorithms')
                continue
            keys_unique_lowercased(algorithms, f'{env}/{task}')
            algorithm_sets.add(frozenset(algorithms))
            for algorithm, runs in algorithms.items():
                if ',' in algorithm:
                    problems.append(f'{algorithm}: comma in an algorithm name')
                if not isinstance(runs, dict) or not runs:
                    problems.append(f'{env}/{task}/{algorithm}: no runs')
                    continue
                keys_unique_lowercased(runs, f'{env}/{task}/{algorithm}')
                run_sets.add(frozenset(runs))
                for run, steps in runs.items():
                    where = f'{env}/{task}/{algorithm}/{run}'
                    if not isinstance(steps, dict) or not steps:
                        problems.append(f'{where}: no steps')
                        continue
                    keys = list(steps)
                    absolute = [key for key in keys if 'absolute' in key.lower()]
                    if absolute != ['absolute_metrics']:
                        problems.append(f'{where}: needs exactly one "absolute_metrics", has {absolute}')
                    elif keys[-1] != 'absolute_metrics':
                        problems.append(f'{where}: "absolute_metrics" is not the last key')
                    step_keys = [key for key in keys if 'absolute' not in key.lower()]
                    if not step_keys:
                        problems.append(f'{where}: no evaluation steps')
                    step_lists.add(tuple(step_keys))
                    counts = []
                    for key in keys:
                        metrics = steps[key]
                        if not isinstance(metrics, dict) or not metrics:
                            problems.append(f'{where}/{key}: not a non-empty object')
                            continue
                        is_step = 'absolute' not in key.lower()
                        if is_step:
                            if not STEP_KEY.match(key):
                                problems.append(f'{where}/{key}: steps are named step_<index>')
                            count = metrics.get('step_count')
                            if not isinstance(count, int) or isinstance(count, bool) or count < 0:
                                problems.append(f'{where}/{key}: step_count must be a non-negative int')
                            else:
                                counts.append(count)
                        names = [m for m in metrics if m != 'step_count']
                        for name in names:
                            lower = name.lower()
                            if 'step_count' in lower or lower.startswith(('mean_', 'norm_')):
                                problems.append(f'{where}/{key}/{name}: reserved metric name')
                            values = metrics[name]
                            if not isinstance(values, list) or not values or not all(map(_is_number, values)):
                                problems.append(f'{where}/{key}/{name}: not a non-empty list of numbers')
                        keys_unique_lowercased(metrics, f'{where}/{key}')
                        metric_sets.add(frozenset(names))
                    if any(b <= a for a, b in zip(counts, counts[1:])):
                        problems.append(f'{where}: step_count does not increase from step to step')
        for what, sets in [('algorithms', algorithm_sets), ('runs', run_sets), ('steps', step_lists),
                           ('metrics', metric_sets)]:
            if len(sets) > 1:
                problems.append(f'{env}: not the same {what} everywhere')
    return problems


def loader_matrices(document: dict, env: str, metric: str):
    """The (runs x tasks) absolute-metric means and (runs x tasks x steps) step means of one algorithm each,
    read as marl-eval's `create_matrices_for_rliable` reads them (by the first task's, algorithm's and
    run's names, lower-cased)."""
    lowered = _lower_keys(document)
    data = lowered[env.lower()]
    tasks = list(data)
    algorithms = list(data[tasks[0]])
    runs = list(data[tasks[0]][algorithms[0]])
    steps = [s for s in data[tasks[0]][algorithms[0]][runs[0]] if 'absolute' not in s]
    final, curves = {}, {}
    for algorithm in algorithms:
        final[algorithm] = [[_mean(data[t][algorithm][r]['absolute_metrics'][metric]) for t in tasks]
                            for r in runs]
        curves[algorithm] = [[[_mean(data[t][algorithm][r][s][metric]) for s in steps] for t in tasks]
                             for r in runs]
    return final, curves


def _lower_keys(value):
    if isinstance(value, dict):
        return {key.lower(): _lower_keys(item) for key, item in value.items()}
    return value


def _mean(values) -> float:
    return sum(values) / len(values)


def records(tasks=('MATE-4v8-9 cameras', 'MATE-2v4-0 targets'), algorithms=('greedy', 'mappo'),
            seeds=(10, 2, 0), steps=3, metrics=('return', 'coverage'), episodes=4):
    """A rectangular result set, the values a function of their coordinates (so a test can recompute)."""
    out = []
    for t, task in enumerate(tasks):
        for a, algorithm in enumerate(algorithms):
            for seed in seeds:
                for step in range(steps):
                    for m, metric in enumerate(metrics):
                        values = [t + a / 10 + seed / 100 + step / 1000 + m + e / 1e4 for e in range(episodes)]
                        out.append(StepRecord('MATE', task, algorithm, seed, step, 1000 * (step + 1), metric, values))
                for m, metric in enumerate(metrics):
                    values = [t + a / 10 + seed / 100 + m - e / 1e4 for e in range(10 * episodes)]
                    out.append(AbsoluteRecord('MATE', task, algorithm, seed, metric, values))
    return out


@pytest.fixture
def document():
    return marl_eval_json(records())


def test_output_is_valid(document):
    assert marl_eval_problems(document) == []


def test_layout(document):
    run = document['MATE']['MATE-4v8-9 cameras']['mappo']['seed_2']
    assert list(document['MATE']) == ['MATE-4v8-9 cameras', 'MATE-2v4-0 targets']
    assert list(document['MATE']['MATE-4v8-9 cameras']) == ['greedy', 'mappo']
    assert list(document['MATE']['MATE-4v8-9 cameras']['mappo']) == ['seed_0', 'seed_2', 'seed_10']
    assert list(run) == ['step_0', 'step_1', 'step_2', 'absolute_metrics']
    assert run['step_1'] == {'step_count': 2000,
                             'return': pytest.approx([0.1 + 0.02 + 0.001 + e / 1e4 for e in range(4)]),
                             'coverage': pytest.approx([1.1 + 0.02 + 0.001 + e / 1e4 for e in range(4)])}
    assert len(run['absolute_metrics']['return']) == 40


def test_loader_reads_the_numbers_back(document):
    final, curves = loader_matrices(document, 'MATE', 'return')
    seeds = [0, 2, 10]
    for a, algorithm in enumerate(['greedy', 'mappo']):
        for r, seed in enumerate(seeds):
            for t in range(2):
                assert final[algorithm][r][t] == pytest.approx(t + a / 10 + seed / 100 - 39 / 2e4)
                for step in range(3):
                    assert curves[algorithm][r][t][step] == pytest.approx(
                        t + a / 10 + seed / 100 + step / 1000 + 3 / 2e4)


def test_written_file_is_the_document(tmp_path, document):
    path = write_marl_eval(tmp_path / 'report' / 'marl_eval.json', records())
    text = path.read_text()
    assert json.loads(text) == document
    assert list(json.loads(text)['MATE']['MATE-2v4-0 targets']['greedy']['seed_10'])[-1] == 'absolute_metrics'


def test_record_order_does_not_matter_for_runs_and_steps():
    shuffled = records()
    random.Random(0).shuffle(shuffled)
    # environments, tasks, algorithms keep first-appearance order; runs and steps are sorted
    ordered = marl_eval_json(records())
    other = marl_eval_json(shuffled)
    assert other == ordered
    task = next(iter(other['MATE']))
    algorithm = next(iter(other['MATE'][task]))
    assert list(other['MATE'][task][algorithm]) == ['seed_0', 'seed_2', 'seed_10']
    assert list(other['MATE'][task][algorithm]['seed_0'])[:3] == ['step_0', 'step_1', 'step_2']


def test_numpy_numbers_are_plain_json(tmp_path):
    import numpy as np
    path = write_marl_eval(tmp_path / 'marl_eval.json', [
        StepRecord('E', 'T', 'A', np.int64(3), np.int64(0), np.int64(7), 'r', np.array([0.5, 1.5])),
        AbsoluteRecord('E', 'T', 'A', np.int64(3), 'r', np.float32([2.0]))])
    assert json.loads(path.read_text()) == {'E': {'T': {'A': {'seed_3': {
        'step_0': {'step_count': 7, 'r': [0.5, 1.5]}, 'absolute_metrics': {'r': [2.0]}}}}}}


def test_named_runs_are_kept():
    doc = marl_eval_json([StepRecord('E', 'T', 'A', 'run_1', 0, 5, 'return', [1.0]),
                          AbsoluteRecord('E', 'T', 'A', 'run_1', 'return', [1.0, 2.0])])
    assert doc == {'E': {'T': {'A': {'run_1': {'step_0': {'step_count': 5, 'return': [1.0]},
                                               'absolute_metrics': {'return': [1.0, 2.0]}}}}}}
    assert marl_eval_problems(doc) == []


# the validator catches broken documents: each mutation breaks one rule of the loader
def _run(doc):
    return doc['MATE']['MATE-4v8-9 cameras']['mappo']['seed_2']


def _drop_absolute(doc):
    del _run(doc)['absolute_metrics']


def _absolute_first(doc):
    run = _run(doc)
    absolute = run.pop('absolute_metrics')
    rest = dict(run)
    run.clear()
    run.update({'absolute_metrics': absolute, **rest})


def _rename_step(doc):
    run = _run(doc)
    items = list(run.items())
    run.clear()
    run.update({('evaluation_1' if key == 'step_1' else key): value for key, value in items})


def _scalar_values(doc):
    _run(doc)['step_0']['return'] = 0.5


def _string_values(doc):
    _run(doc)['step_0']['return'] = ['0.5']


def _nan_values(doc):
    _run(doc)['step_0']['return'] = [float('nan')]


def _missing_metric(doc):
    del _run(doc)['step_2']['coverage']


def _missing_absolute_metric(doc):
    del _run(doc)['absolute_metrics']['coverage']


def _missing_step_count(doc):
    del _run(doc)['step_1']['step_count']


def _decreasing_step_count(doc):
    _run(doc)['step_2']['step_count'] = 1


def _comma(doc):
    task = doc['MATE']['MATE-4v8-9 cameras']
    task['mappo, comm'] = task.pop('mappo')


def _case_collision(doc):
    task = doc['MATE']['MATE-4v8-9 cameras']
    task['MAPPO'] = copy.deepcopy(task['mappo'])


def _missing_run(doc):
    del doc['MATE']['MATE-2v4-0 targets']['greedy']['seed_0']


def _missing_algorithm(doc):
    del doc['MATE']['MATE-2v4-0 targets']['greedy']


def _missing_step(doc):
    del _run(doc)['step_1']


def _reserved_metric(doc):
    for step in _run(doc).values():
        step['mean_return'] = step.pop('return')


BREAKS = [_drop_absolute, _absolute_first, _rename_step, _scalar_values, _string_values, _nan_values,
          _missing_metric, _missing_absolute_metric, _missing_step_count, _decreasing_step_count, _comma,
          _case_collision, _missing_run, _missing_algorithm, _missing_step, _reserved_metric]


@pytest.mark.parametrize('breaks', BREAKS, ids=[f.__name__.strip('_') for f in BREAKS])
def test_validator_catches_a_broken_document(document, breaks):
    broken = copy.deepcopy(document)
    breaks(broken)
    assert marl_eval_problems(broken), f'{breaks.__name__} went unnoticed'


def test_validator_catches_a_broken_file(tmp_path, document):
    path = tmp_path / 'marl_eval.json'
    broken = copy.deepcopy(document)
    _drop_absolute(broken)
    path.write_text(json.dumps(broken))
    assert marl_eval_problems(json.loads(path.read_text()))


# the writer refuses what the loader could not read
def _without(predicate, extra=()):
    return [r for r in records() if not predicate(r)] + list(extra)


REFUSED = {
    'repeated step metric': records() + [
        StepRecord('MATE', 'MATE-2v4-0 targets', 'greedy', 0, 0, 1000, 'return', [1.0])],
    'repeated absolute metric': records() + [
        AbsoluteRecord('MATE', 'MATE-2v4-0 targets', 'greedy', 0, 'return', [1.0])],
    'no absolute metrics': _without(lambda r: isinstance(r, AbsoluteRecord) and r.run == 2 and r.algorithm == 'mappo'),
    'absolute metric missing': _without(lambda r: isinstance(r, AbsoluteRecord) and r.run == 2
                                        and r.metric == 'coverage'),
    'step metric missing': _without(lambda r: isinstance(r, StepRecord) and r.run == 2 and r.step == 1
                                    and r.metric == 'coverage'),
    'step missing in one run': _without(lambda r: isinstance(r, StepRecord) and r.run == 2 and r.step == 1),
    'run missing in one task': _without(lambda r: r.run == 10 and r.task == 'MATE-2v4-0 targets'),
    'algorithm missing in one task': _without(lambda r: r.algorithm == 'greedy' and r.task == 'MATE-2v4-0 targets'),
    'two step counts for a step': records() + [
        StepRecord('MATE', 'MATE-2v4-0 targets', 'greedy', 0, 0, 999, 'other', [1.0])],
    'step count not increasing': [StepRecord('E', 'T', 'A', 0, 0, 10, 'r', [1.0]),
                                  StepRecord('E', 'T', 'A', 0, 1, 10, 'r', [1.0]),
                                  AbsoluteRecord('E', 'T', 'A', 0, 'r', [1.0])],
    'comma': [StepRecord('E', 'T', 'A,B', 0, 0, 1, 'r', [1.0]), AbsoluteRecord('E', 'T', 'A,B', 0, 'r', [1.0])],
    'case collision': [StepRecord('E', 'T', a, 0, 0, 1, 'r', [1.0]) for a in ('mappo', 'MAPPO')]
                      + [AbsoluteRecord('E', 'T', a, 0, 'r', [1.0]) for a in ('mappo', 'MAPPO')],
    'reserved metric': [StepRecord('E', 'T', 'A', 0, 0, 1, 'mean_r', [1.0])],
    'step_count metric': [StepRecord('E', 'T', 'A', 0, 0, 1, 'step_count', [1.0])],
    'NaN': [StepRecord('E', 'T', 'A', 0, 0, 1, 'r', [float('nan')])],
    'no values': [StepRecord('E', 'T', 'A', 0, 0, 1, 'r', [])],
    'text values': [StepRecord('E', 'T', 'A', 0, 0, 1, 'r', ['1.5'])],
    'a text, not a list': [StepRecord('E', 'T', 'A', 0, 0, 1, 'r', '1')],
    'boolean values': [StepRecord('E', 'T', 'A', 0, 0, 1, 'r', [True])],
    'negative step': [StepRecord('E', 'T', 'A', 0, -1, 1, 'r', [1.0])],
    'float step count': [StepRecord('E', 'T', 'A', 0, 0, 1.5, 'r', [1.0])],
    'empty name': [StepRecord('', 'T', 'A', 0, 0, 1, 'r', [1.0])],
    'no records': [],
    'not a record': [('E', 'T', 'A', 0, 0, 1, 'r', [1.0])],
}


@pytest.mark.parametrize('name', list(REFUSED))
def test_writer_refuses(name):
    with pytest.raises(ValueError) as error:
        marl_eval_json(REFUSED[name])
    assert '\n' not in str(error.value)


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 3), st.integers(1, 3), st.lists(st.integers(0, 50), min_size=1, max_size=4, unique=True),
       st.integers(1, 4), st.integers(1, 3), st.integers(1, 5), st.randoms(use_true_random=False))
def test_any_rectangular_result_set_is_valid(n_tasks, n_algorithms, seeds, steps, n_metrics, episodes, rng):
    tasks = [f'task {i}' for i in range(n_tasks)]
    algorithms = [f'algorithm {i}' for i in range(n_algorithms)]
    metrics = [f'metric_{i}' for i in range(n_metrics)]
    given_records = records(tasks, algorithms, seeds, steps, metrics, episodes)
    rng.shuffle(given_records)
    doc = marl_eval_json(given_records)
    assert marl_eval_problems(doc) == []
    run = doc['MATE'][tasks[0]][algorithms[0]][f'seed_{min(seeds)}']
    assert list(run) == [f'step_{i}' for i in range(steps)] + ['absolute_metrics']
