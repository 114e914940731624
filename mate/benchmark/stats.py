"""Aggregate scores over runs with confidence intervals: IQM, mean, probability of improvement and
stratified-bootstrap intervals, as rliable (Agarwal et al., 2021) defines them, in numpy only.

Scores are arrays of shape `(runs, tasks)`: one score per independent run (seed) and task. A flat array
`(runs,)` is one task. The aggregates also accept leading batch axes, `(..., runs, tasks)`, and return one
value per batch entry: this is how the bootstrap evaluates all its resamples at once.

- `iqm`, `mean`: the interquartile mean (the 25 % trimmed mean of all scores, tasks pooled) and the mean of
  the per-task means.
- `stratified_bootstrap`: a statistic's point estimate and percentile interval, resampling runs with
  replacement independently within each task (the stratum), never across tasks.
- `interval_estimates`: IQM and mean with intervals for every algorithm of a score dict.
- `probability_of_improvement`, `improvement_intervals`: P(X > Y), ties counting 1/2, averaged over tasks,
  and its interval, for pairs of algorithms.
- `curve_intervals`: IQM and mean with intervals at every evaluation step (curves with bands).
- `normalised`: (score - random) / (reference - random).

Tested against rliable 1.2.0 (tests/benchmark/test_stats.py, tests/data/rliable-reference.json written by
tests/tools/rliable_reference.py): point estimates equal, interval ends equal within the Monte Carlo error of
50,000 replications. Random streams differ from rliable's (which draws from numpy's global generator):
ours come from `numpy.random.default_rng`, keyed by `seed` and the algorithm names, so an algorithm's
interval does not depend on which other algorithms are in the dict.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Mapping, Sequence

import numpy as np

__all__ = ['iqm', 'mean', 'stratified_bootstrap', 'interval_estimates', 'probability_of_improvement',
           'improvement_intervals', 'curve_intervals', 'normalised', 'Interval']

Interval = tuple[float, float, float]
"""(point estimate, lower end, upper end) of a confidence interval."""

Statistic = Callable[..., np.ndarray]

_CHUNK_ELEMENTS = 1 << 20
"""Resampled scores held in memory at once (8 MiB of float64): the bootstrap runs in chunks of replications."""


def _scores(scores, name: str = 'scores', *, batched: bool = False) -> np.ndarray:
    """`scores` as a float array `(runs, tasks)` (or `(..., runs, tasks)` when `batched`), or a ValueError."""
    try:
        array = np.asarray(scores, dtype=float)
    except (ValueError, TypeError) as error:
        raise ValueError(f'{name}: ragged or non-numeric scores (every run needs one score per task): '
                         f'{str(error).splitlines()[0]}') from None
    if array.ndim == 0:
        raise ValueError(f'{name}: expected scores of shape (runs,) or (runs, tasks), got a scalar')
    if array.ndim == 1:
        array = array[:, None]
    elif array.ndim > 2 and not batched:
        raise ValueError(f'{name}: expected scores of shape (runs,) or (runs, tasks), got shape {array.shape}')
    if array.size == 0:
        raise ValueError(f'{name}: empty scores, shape {array.shape}')
    if not np.isfinite(array).all():
        raise ValueError(f'{name}: NaN or infinite scores')
    return array


def iqm(scores) -> float | np.ndarray:
    """Interquartile mean: the mean of the middle half of all scores, tasks pooled.

    rliable's `aggregate_iqm`, i.e. `scipy.stats.trim_mean(scores, 0.25, axis=None)`: of the `n = runs *
    tasks` scores sorted, drop `floor(n / 4)` at each end and average the rest.

    Args:
        scores: `(runs,)`, `(runs, tasks)`, or `(..., runs, tasks)` with leading batch axes.

    Returns:
        A float, or an array of the batch shape `(...)`.
    """
    array = _scores(scores, batched=True)
    pooled = np.sort(array.reshape(*array.shape[:-2], -1), axis=-1)
    n = pooled.shape[-1]
    cut = int(0.25 * n)
    value = pooled[..., cut:n - cut].mean(axis=-1)
    return float(value) if value.ndim == 0 else value


def mean(scores) -> float | np.ndarray:
    """Mean over tasks of the mean over runs (rliable's `aggregate_mean`).

    Args:
        scores: `(runs,)`, `(runs, tasks)`, or `(..., runs, tasks)` with leading batch axes.

    Returns:
        A float, or an array of the batch shape `(...)`.
    """
    array = _scores(scores, batched=True)
    value = array.mean(axis=-2).mean(axis=-1)
    return float(value) if value.ndim == 0 else value


def probability_of_improvement(x, y) -> float | np.ndarray:
    """P(X > Y): the probability that a run of algorithm X beats a run of Y on the same task, ties counting
    1/2, averaged over tasks.

    Per task, the Mann-Whitney U statistic of X against Y over the number of pairs: the pairs of runs
    `(i, j)` with `x_i > y_j`, plus half of those with `x_i == y_j`, over `n_x * n_y` (rliable's
    `probability_of_improvement`). So `probability_of_improvement(x, y) == 1 -
    probability_of_improvement(y, x)`.

    Args:
        x: scores of X, `(runs_x,)`, `(runs_x, tasks)` or `(..., runs_x, tasks)`.
        y: scores of Y, `(runs_y,)`, `(runs_y, tasks)` or `(..., runs_y, tasks)`, the same tasks;
            leading batch axes broadcast with those of `x`.

    Returns:
        A float in [0, 1], or an array of the broadcast batch shape.
    """
    x, y = _scores(x, 'x', batched=True), _scores(y, 'y', batched=True)
    if x.shape[-1] != y.shape[-1]:
        raise ValueError(f'x and y: different numbers of tasks ({x.shape[-1]} and {y.shape[-1]})')
    xs, ys = x[..., :, None, :], y[..., None, :, :]  # (..., runs_x, runs_y, tasks)
    wins = np.count_nonzero(xs > ys, axis=(-3, -2)) + 0.5 * np.count_nonzero(xs == ys, axis=(-3, -2))
    value = (wins / (x.shape[-2] * y.shape[-2])).mean(axis=-1)
    return float(value) if value.ndim == 0 else value


def normalised(score, random, reference):
    """(score - random) / (reference - random): 0 at the random team's score, 1 at the reference's.

    Args:
        score: a score or an array of scores.
        random: the random team's score; a float, or an array that broadcasts with `score` (e.g. one per
            task, `(tasks,)` against `(runs, tasks)`).
        reference: the reference's score (greedy, upper bound), broadcasting like `random`.

    Returns:
        A float for float inputs, else an array of the broadcast shape.
    """
    score, random, reference = (np.asarray(v, dtype=float) for v in (score, random, reference))
    span = reference - random
    if not (np.isfinite(span).all() and np.all(span != 0)):
        raise ValueError('normalised: reference and random scores must differ (and be finite)')
    value = (score - random) / span
    return float(value) if value.ndim == 0 else value


# ------------------------------------------------------------------------------------ the bootstrap


def _rng(seed: int, *names: str) -> np.random.Generator:
    """A generator keyed by `seed` and `names` (crc32 of each: stable across runs and Python versions)."""
    return np.random.default_rng([int(seed), *(zlib.crc32(name.encode()) for name in names)])


def _resample(rng: np.random.Generator, array: np.ndarray, reps: int) -> np.ndarray:
    """`reps` stratified resamples of `array` `(*strata, runs, tasks)`: `(reps, *strata, runs, tasks)`.

    Each column (task), and each entry of the leading strata axes (evaluation steps of a curve), draws its
    runs with replacement from its own runs only.
    """
    *strata, runs, tasks = array.shape
    # small integers draw several times faster than int64 ones
    small = np.int16 if runs <= np.iinfo(np.int16).max else np.intp
    picks = rng.integers(0, runs, size=(reps, *strata, runs, tasks), dtype=small)
    # flat index of (stratum, picked run, task): the task and the stratum stay those of the slot
    base = (np.arange(int(np.prod(strata, dtype=int))).reshape(*strata, 1, 1) * (runs * tasks)
            + np.arange(tasks))
    return np.take(array.reshape(-1), np.multiply(picks, tasks, dtype=np.intp) + base)


def _bootstrap(arrays: Sequence[np.ndarray], statistics: Mapping[str, Statistic], reps: int,
               confidence: float, rng: np.random.Generator) -> dict[str, tuple[np.ndarray, ...]]:
    """Point estimates and percentile intervals of `statistics` on the same resamples of `arrays`.

    Every array `(*strata, runs, tasks)` is resampled independently; a statistic takes the resampled arrays
    (in order) with the replications as a leading axis and returns `(reps, *strata)`.
    Returns name -> (point, low, high), each of shape `strata`.
    """
    if not (isinstance(reps, (int, np.integer)) and reps >= 1):
        raise ValueError(f'reps: a positive integer, got {reps!r}')
    if not 0 < confidence < 1:
        raise ValueError(f'confidence: in (0, 1), got {confidence!r}')
    strata = arrays[0].shape[:-2]
    points = {name: np.asarray(f(*arrays), dtype=float) for name, f in statistics.items()}
    for name, point in points.items():
        if point.shape != strata:
            raise ValueError(f'statistic {name!r}: returns shape {point.shape} for one sample, expected {strata}')
    per_rep = sum(a.size for a in arrays)
    chunk = max(1, _CHUNK_ELEMENTS // per_rep)
    values = {name: np.empty((reps, *strata)) for name in statistics}
    for start in range(0, reps, chunk):
        n = min(chunk, reps - start)
        samples = [_resample(rng, a, n) for a in arrays]
        for name, f in statistics.items():
            value = np.asarray(f(*samples), dtype=float)
            if value.shape != (n, *strata):
                raise ValueError(f'statistic {name!r}: returns shape {value.shape} for {n} resamples, '
                                 f'expected {(n, *strata)}: it must accept a leading batch axis')
            values[name][start:start + n] = value
    tail = 100 * (1 - confidence) / 2
    out = {}
    for name, value in values.items():
        low, high = np.percentile(value, [tail, 100 - tail], axis=0)
        out[name] = (points[name], low, high)
    return out


def _as_interval(point, low, high) -> Interval:
    return float(point), float(low), float(high)


def stratified_bootstrap(scores, statistic: Statistic, reps: int = 50_000, confidence: float = 0.95,
                         seed: int = 0) -> Interval:
    """A statistic's point estimate and stratified-bootstrap percentile interval.

    Each replication resamples the runs of every task with replacement, independently per task (the
    stratum), so a resample never mixes tasks; the interval is the `(1 - confidence) / 2` and
    `(1 + confidence) / 2` percentiles of the statistic over the replications (numpy's linear
    interpolation), rliable's `get_interval_estimates(..., method='percentile')`.

    Args:
        scores: `(runs,)` or `(runs, tasks)`; or a tuple of such arrays (e.g. two algorithms' scores, with
            their own numbers of runs), each resampled independently, passed to `statistic` in order.
        statistic: maps scores with a leading batch axis, `(reps, runs, tasks)` (one per array of
            `scores`), to `(reps,)`; it must also accept `(runs, tasks)` and return a scalar. `iqm`, `mean`
            and `probability_of_improvement` do.
        reps: bootstrap replications.
        confidence: the interval's coverage.
        seed: seeds `numpy.random.default_rng`; the same seed gives the same interval.

    Returns:
        (point, low, high): `statistic(scores)` and the interval's ends.
    """
    arrays = [_scores(a, f'scores[{i}]') for i, a in enumerate(scores)] if isinstance(scores, tuple) \
        else [_scores(scores)]
    result = _bootstrap(arrays, {'statistic': statistic}, reps, confidence, np.random.default_rng(seed))
    return _as_interval(*result['statistic'])


def interval_estimates(score_dict: Mapping[str, object],
                       statistics: Mapping[str, Statistic] | None = None, reps: int = 50_000,
                       confidence: float = 0.95, seed: int = 0) -> dict[str, dict[str, Interval]]:
    """Point estimates and stratified-bootstrap intervals of every statistic, for every algorithm.

    In the spirit of rliable's `get_interval_estimates`: each algorithm's scores are resampled on their own;
    its statistics share the same resamples. The random stream of an algorithm is keyed by `seed` and its
    name, so its intervals do not depend on the other entries of `score_dict`.

    Args:
        score_dict: algorithm -> scores `(runs,)` or `(runs, tasks)` (algorithms may differ in runs).
        statistics: name -> statistic (see `stratified_bootstrap`); default `{'IQM': iqm, 'mean': mean}`.
        reps: bootstrap replications.
        confidence: the intervals' coverage.
        seed: the base seed.

    Returns:
        {algorithm: {statistic name: (point, low, high)}}.
    """
    statistics = {'IQM': iqm, 'mean': mean} if statistics is None else dict(statistics)
    if not score_dict:
        raise ValueError('score_dict: no algorithms')
    out = {}
    for algorithm, scores in score_dict.items():
        array = _scores(scores, f'scores of {algorithm!r}')
        result = _bootstrap([array], statistics, reps, confidence, _rng(seed, algorithm))
        out[algorithm] = {name: _as_interval(*value) for name, value in result.items()}
    return out


def improvement_intervals(score_dict: Mapping[str, object],
                          pairs: Sequence[tuple[str, str]] | None = None, reps: int = 50_000,
                          confidence: float = 0.95, seed: int = 0) -> dict[tuple[str, str], Interval]:
    """Probability of improvement with its stratified-bootstrap interval, for pairs of algorithms.

    The two algorithms' runs are resampled independently, each within each task (rliable's
    `StratifiedIndependentBootstrap`). For the reverse pair, `(y, x)`, the estimate is `1 - P(X > Y)`.

    Args:
        score_dict: algorithm -> scores `(runs,)` or `(runs, tasks)`, the same tasks for all.
        pairs: `(x, y)` pairs of names of `score_dict` (P(X > Y) each); default every pair `(a, b)` with `a`
            before `b` in `score_dict`.
        reps: bootstrap replications.
        confidence: the intervals' coverage.
        seed: the base seed (each pair's stream is keyed by it and the two names).

    Returns:
        {(x, y): (point, low, high)}.
    """
    names = list(score_dict)
    if pairs is None:
        pairs = [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]
    out = {}
    for x, y in pairs:
        for name in (x, y):
            if name not in score_dict:
                raise ValueError(f'pairs: {name!r} is not an algorithm of score_dict')
        arrays = [_scores(score_dict[x], f'scores of {x!r}'), _scores(score_dict[y], f'scores of {y!r}')]
        if arrays[0].shape[-1] != arrays[1].shape[-1]:
            raise ValueError(f'{x!r} and {y!r}: different numbers of tasks')
        result = _bootstrap(arrays, {'P': probability_of_improvement}, reps, confidence, _rng(seed, x, y))
        out[(x, y)] = _as_interval(*result['P'])
    return out


def curve_intervals(scores_over_steps: Mapping[str, object],
                    statistics: Mapping[str, Statistic] | None = None, reps: int = 50_000,
                    confidence: float = 0.95, seed: int = 0
                    ) -> dict[str, dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """IQM and mean with stratified-bootstrap intervals at every evaluation step: curves with bands.

    Every step is bootstrapped on its own (the runs of each (task, step) resampled independently), as
    rliable does for sample-efficiency curves; the result at step `s` is that of `interval_estimates` on
    the scores of step `s` (up to the random stream).

    Args:
        scores_over_steps: algorithm -> scores `(runs, steps)` (one task) or `(runs, tasks, steps)`, the
            layout of marl-eval's sample-efficiency matrices.
        statistics: name -> statistic (see `stratified_bootstrap`); default `{'IQM': iqm, 'mean': mean}`.
        reps: bootstrap replications per step.
        confidence: the bands' coverage.
        seed: the base seed (each algorithm's stream is keyed by it and the name).

    Returns:
        {algorithm: {statistic name: (points, lows, highs)}}, three arrays of shape `(steps,)`.
    """
    statistics = {'IQM': iqm, 'mean': mean} if statistics is None else dict(statistics)
    if not scores_over_steps:
        raise ValueError('scores_over_steps: no algorithms')
    out = {}
    for algorithm, scores in scores_over_steps.items():
        name = f'scores of {algorithm!r}'
        try:
            array = np.asarray(scores, dtype=float)
        except (ValueError, TypeError):
            raise ValueError(f'{name}: ragged or non-numeric scores (every run needs every step)') from None
        if array.ndim == 2:
            array = array[:, None, :]
        if array.ndim != 3:
            raise ValueError(f'{name}: expected shape (runs, steps) or (runs, tasks, steps), got {array.shape}')
        # steps become a leading strata axis: (steps, runs, tasks)
        array = _scores(np.moveaxis(array, -1, 0), name, batched=True)
        result = _bootstrap([array], statistics, reps, confidence, _rng(seed, algorithm))
        out[algorithm] = {stat: tuple(np.asarray(v, dtype=float) for v in value)
                          for stat, value in result.items()}
    return out
