"""rliable's aggregates on fixed score matrices: the reference `mate.benchmark.stats` is tested against
(tests/benchmark/test_stats.py reads tests/data/rliable-reference.json).

rliable cannot be imported beside mate's own dependencies (its dependency `arch` breaks on the pandas 3.x
that Ray pulls in), so this script runs in a throwaway virtual environment outside the repository and
imports neither mate nor anything of it:

    python -m venv /tmp/rliable-env
    /tmp/rliable-env/bin/pip install rliable 'pandas<2.2' 'numpy<2'
    /tmp/rliable-env/bin/python tests/tools/rliable_reference.py [--reps 50000] [--json tests/data/rliable-reference.json]

(recorded with rliable 1.2.0, arch 7.2.0, numpy 1.26.4, pandas 2.1.4, scipy 1.17.1, Python 3.11: the file
states the versions it was written with).

What it computes, for every suite of score matrices (algorithm -> runs x tasks, drawn from a fixed numpy
generator; one algorithm's scores on a 0.25 grid so that runs tie, one with outliers):

- point estimates: `metrics.aggregate_iqm` and `metrics.aggregate_mean` of each matrix;
- interval estimates: `rly.get_interval_estimates(scores, lambda x: np.array([iqm(x), mean(x)]),
  reps=REPS)` (percentile method, 95 %);
- probability of improvement of every pair of algorithms (in suite order): `metrics.probability_of_improvement`
  and its interval, `rly.get_interval_estimates({pair: [x, y]}, probability_of_improvement, reps=REPS)`;
- one sample-efficiency curve (runs x tasks x steps): IQM and mean per step with intervals, as rliable's
  examples do it (a statistic that returns one value per step).

rliable 1.2.0 draws its bootstrap indices from numpy's global generator (`np.random.choice` in
`StratifiedBootstrap.update_indices`), so the script seeds it (`np.random.seed(SEED)`) before every call.
The score matrices are written into the file, so the test needs no generator of its own.
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np
from rliable import library as rly
from rliable import metrics

SEED = 0
CONFIDENCE = 0.95


def score_suites() -> dict[str, dict[str, np.ndarray]]:
    """suite name -> algorithm -> scores (runs, tasks), all drawn from one fixed generator."""
    rng = np.random.default_rng(20240932)
    suites = {}
    for runs, tasks in [(5, 1), (10, 1), (5, 3), (10, 3)]:
        smooth = rng.normal(0.5, 0.2, size=(runs, tasks))
        # on a 0.25 grid: runs tie with each other and with the other algorithms' grid values
        ties = np.round(rng.normal(0.5, 0.25, size=(runs, tasks)) * 4) / 4
        outliers = rng.normal(0.4, 0.1, size=(runs, tasks))
        outliers[0, :] = 5.0          # one run far above
        outliers[-1, 0] = -3.0        # one far below on the first task
        suites[f'{runs}x{tasks}'] = {'smooth': smooth, 'ties': ties, 'outliers': outliers}
    return suites


def curve_scores() -> np.ndarray:
    """(runs, tasks, steps): 6 runs, 2 tasks, 5 evaluation steps of a learning curve with noise."""
    rng = np.random.default_rng(7)
    steps = np.linspace(0.0, 1.0, 5)
    return steps[None, None, :] * rng.uniform(0.5, 1.5, size=(6, 2, 1)) + rng.normal(0, 0.1, size=(6, 2, 5))


def both(scores: np.ndarray) -> np.ndarray:
    return np.array([metrics.aggregate_iqm(scores), metrics.aggregate_mean(scores)])


def per_step(scores: np.ndarray) -> np.ndarray:
    """IQM of every step, then mean of every step: (2 * steps,)."""
    steps = scores.shape[-1]
    return np.array([metrics.aggregate_iqm(scores[..., s]) for s in range(steps)]
                    + [metrics.aggregate_mean(scores[..., s]) for s in range(steps)])


def interval(func, scores, reps: int):
    """rliable's point estimate and (lower, upper) of `func` on one entry, seeded."""
    np.random.seed(SEED)
    points, intervals = rly.get_interval_estimates(
        {'x': scores}, func, reps=reps, confidence_interval_size=CONFIDENCE)
    return np.asarray(points['x'], dtype=float), np.asarray(intervals['x'], dtype=float)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--reps', type=int, default=50_000, help='bootstrap replications per interval')
    parser.add_argument('--json', type=Path, default=Path('tests/data/rliable-reference.json'))
    args = parser.parse_args(argv)

    started = time.perf_counter()
    out_suites = {}
    for name, suite in score_suites().items():
        entry = {'scores': {a: s.tolist() for a, s in suite.items()}, 'estimates': {}, 'improvement': {}}
        for algorithm, scores in suite.items():
            point, bounds = interval(both, scores, args.reps)
            assert np.isclose(point[0], metrics.aggregate_iqm(scores)), 'point estimate is func(scores)'
            entry['estimates'][algorithm] = {
                stat: {'point': float(point[i]), 'low': float(bounds[0, i]), 'high': float(bounds[1, i])}
                for i, stat in enumerate(['IQM', 'mean'])}
        names = list(suite)
        for i, x in enumerate(names):
            for y in names[i + 1:]:
                point, bounds = interval(metrics.probability_of_improvement, [suite[x], suite[y]], args.reps)
                entry['improvement'][f'{x} > {y}'] = {'x': x, 'y': y, 'point': float(point),
                                                      'low': float(bounds[0, 0]), 'high': float(bounds[1, 0])}
        out_suites[name] = entry
        print(f'{name}: done at {time.perf_counter() - started:.0f} s', flush=True)

    curve = curve_scores()
    steps = curve.shape[-1]
    point, bounds = interval(per_step, curve, args.reps)
    out_curve = {'scores': curve.tolist()}
    for i, stat in enumerate(['IQM', 'mean']):
        part = slice(i * steps, (i + 1) * steps)
        out_curve[stat] = {'point': point[part].tolist(), 'low': bounds[0, part].tolist(),
                           'high': bounds[1, part].tolist()}

    result = {
        'description': ('rliable point and interval estimates (stratified bootstrap, percentile method) '
                        'on fixed score matrices, for tests/benchmark/test_stats.py; written by '
                        'tests/tools/rliable_reference.py'),
        'date': datetime.date.today().isoformat(),
        'command': ' '.join(['python', 'tests/tools/rliable_reference.py', *sys.argv[1:]]),
        'versions': {name: metadata.version(name) for name in ['rliable', 'arch', 'numpy', 'scipy', 'pandas']}
                    | {'python': platform.python_version()},
        'reps': args.reps,
        'confidence': CONFIDENCE,
        'seed': SEED,
        'suites': out_suites,
        'curve': out_curve,
        'seconds': round(time.perf_counter() - started, 1),
    }
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=1) + '\n')
    print(f'wrote {args.json} in {result["seconds"]} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
