"""mate.benchmark.stats against rliable, and the invariants of its statistics.

The reference, tests/data/rliable-reference.json, holds rliable 1.2.0's estimates on fixed score matrices
(written by tests/tools/rliable_reference.py in a virtual environment of its own: rliable does not import
beside mate's dependencies). Point estimates are deterministic: ours equal rliable's to 1e-12.

Interval ends are Monte Carlo estimates (50,000 replications on both sides, different random streams), so
they agree only within the Monte Carlo error. Each end is checked against our bootstrap distribution of
the statistic, 50,000 replications drawn on a third stream:

- level: both rliable's end and ours are quantiles of that distribution at the interval's level (2.5 % or
  97.5 %) within LEVEL_TOLERANCE. The level of an empirical quantile of n replications has a standard
  deviation of sqrt(p (1 - p) / n) = 0.07 % at p = 2.5 % and n = 50,000, 0.099 % for the difference of
  two independent estimates: 0.5 % is 5 of those. This holds for any bootstrap distribution, also the
  lattices that few runs and tied scores make (on those, an end is the atom where the level falls).
- width: |ours - rliable| <= WIDTH_TOLERANCE x the interval's width. Measured over 20 seeds, the standard
  deviation of our ends is at most 0.45 % of the width where the bootstrap distribution is smooth at the
  end (0.64 % for the difference of two independent estimates): 3 % is 4.7 of those. Where it is a lattice
  (one value holds more than ATOM of the replications near the end) an end may also sit on the
  neighbouring atom (measured: a standard deviation of up to 2 % of the width over seeds), so there the
  tolerance is at least the lattice step. On the recorded reference every end is within 1.3 % of the width.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from mate.benchmark import stats
from mate.benchmark.stats import (curve_intervals, improvement_intervals, interval_estimates, iqm, mean,
                                  normalised, probability_of_improvement, stratified_bootstrap)

REFERENCE = json.loads((Path(__file__).resolve().parents[1] / 'data' / 'rliable-reference.json').read_text())
REPS = REFERENCE['reps']
LEVEL_TOLERANCE = 0.005
WIDTH_TOLERANCE = 0.03
ATOM = 0.001
"""An end is on a lattice when one value holds more than this share of the replications within
LEVEL_TOLERANCE of the interval's level around it."""

SUITES = REFERENCE['suites']
STATISTICS = {'IQM': iqm, 'mean': mean}


def matrices(suite: str) -> dict[str, np.ndarray]:
    return {name: np.array(scores) for name, scores in SUITES[suite]['scores'].items()}


def replications(arrays, statistic, seed: int = 12345) -> np.ndarray:
    """Our bootstrap distribution of `statistic`: REPS values, from `stats`'s own resampler."""
    rng = np.random.default_rng(seed)
    return np.asarray(statistic(*[stats._resample(rng, a, REPS) for a in arrays]))


def check_end(values: np.ndarray, ours: float, theirs: float, level: float, width: float, what: str) -> None:
    """Our interval end `ours` and rliable's `theirs` against our replications `values`, drawn on a stream
    of their own (see the module's docstring)."""
    for who, end in (('rliable', theirs), ('our', ours)):
        below, at_most = np.mean(values < end), np.mean(values <= end)
        assert below - LEVEL_TOLERANCE <= level <= at_most + LEVEL_TOLERANCE, (
            f'{what}: {who} end {end} is a {below:.4f}-{at_most:.4f} quantile of our replications, not {level}')
    window = values[(values >= np.quantile(values, max(level - LEVEL_TOLERANCE, 0)))
                    & (values <= np.quantile(values, min(level + LEVEL_TOLERANCE, 1)))]
    atoms, counts = np.unique(window, return_counts=True)
    allowed = WIDTH_TOLERANCE * width
    if counts.max() > ATOM * len(values) and len(atoms) > 1:
        # a lattice at the end: the two estimates may sit on neighbouring atoms
        allowed = max(allowed, np.diff(atoms).max())
    assert abs(ours - theirs) <= allowed, (
        f'{what}: ours {ours}, rliable {theirs}: {abs(ours - theirs) / width:.2%} of the width, '
        f'allowed {allowed / width:.2%}')


# -------------------------------------------------------------------------------- against rliable


@pytest.mark.parametrize('suite', list(SUITES))
def test_point_estimates_equal_rliable(suite):
    for algorithm, scores in matrices(suite).items():
        reference = SUITES[suite]['estimates'][algorithm]
        assert iqm(scores) == pytest.approx(reference['IQM']['point'], abs=1e-12, rel=0)
        assert mean(scores) == pytest.approx(reference['mean']['point'], abs=1e-12, rel=0)
    scores = matrices(suite)
    for entry in SUITES[suite]['improvement'].values():
        assert probability_of_improvement(scores[entry['x']], scores[entry['y']]) == pytest.approx(
            entry['point'], abs=1e-12, rel=0)


@pytest.mark.parametrize('suite', list(SUITES))
def test_intervals_agree_with_rliable(suite):
    estimates = interval_estimates(matrices(suite), reps=REPS)
    for algorithm, scores in matrices(suite).items():
        for name, statistic in STATISTICS.items():
            reference = SUITES[suite]['estimates'][algorithm][name]
            point, low, high = estimates[algorithm][name]
            assert point == pytest.approx(reference['point'], abs=1e-12, rel=0)
            values = replications([scores], statistic)
            width = reference['high'] - reference['low']
            check_end(values, low, reference['low'], 0.025, width, f'{suite} {algorithm} {name} low')
            check_end(values, high, reference['high'], 0.975, width, f'{suite} {algorithm} {name} high')


@pytest.mark.parametrize('suite', list(SUITES))
def test_improvement_intervals_agree_with_rliable(suite):
    scores = matrices(suite)
    pairs = [(entry['x'], entry['y']) for entry in SUITES[suite]['improvement'].values()]
    intervals = improvement_intervals(scores, pairs=pairs, reps=REPS)
    for entry in SUITES[suite]['improvement'].values():
        x, y = entry['x'], entry['y']
        point, low, high = intervals[(x, y)]
        assert point == pytest.approx(entry['point'], abs=1e-12, rel=0)
        values = replications([scores[x], scores[y]], probability_of_improvement)
        width = entry['high'] - entry['low']
        check_end(values, low, entry['low'], 0.025, width, f'{suite} P({x} > {y}) low')
        check_end(values, high, entry['high'], 0.975, width, f'{suite} P({x} > {y}) high')


def test_curve_intervals_agree_with_rliable():
    reference = REFERENCE['curve']
    scores = np.array(reference['scores'])  # (runs, tasks, steps)
    curves = curve_intervals({'curve': scores}, reps=REPS)['curve']
    for name, statistic in STATISTICS.items():
        points, lows, highs = curves[name]
        np.testing.assert_allclose(points, reference[name]['point'], atol=1e-12, rtol=0)
        for step in range(scores.shape[-1]):
            values = replications([scores[..., step]], statistic)
            width = reference[name]['high'][step] - reference[name]['low'][step]
            check_end(values, lows[step], reference[name]['low'][step], 0.025, width, f'{name} step {step} low')
            check_end(values, highs[step], reference[name]['high'][step], 0.975, width, f'{name} step {step} high')


def test_reference_was_recorded_with_rliable():
    assert REFERENCE['reps'] >= 50_000 and REFERENCE['confidence'] == 0.95
    assert {'rliable', 'numpy', 'arch'} <= set(REFERENCE['versions'])


# ------------------------------------------------------------------------------------- properties

finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
score_matrices = hnp.arrays(np.float64, st.tuples(st.integers(1, 8), st.integers(1, 4)), elements=finite)


@settings(max_examples=200, deadline=None)
@given(score_matrices)
def test_iqm_lies_between_the_quartiles(scores):
    low, high = np.percentile(scores, [25, 75])
    tolerance = 1e-9 * (1 + np.abs(scores).max())
    assert low - tolerance <= iqm(scores) <= high + tolerance


@settings(max_examples=100, deadline=None)
@given(score_matrices)
def test_iqm_and_mean_equal_scipy(scores):
    scipy_stats = pytest.importorskip('scipy.stats')
    assert iqm(scores) == pytest.approx(scipy_stats.trim_mean(scores, 0.25, axis=None), rel=1e-12, abs=1e-9)
    assert mean(scores) == pytest.approx(scores.mean(axis=0).mean(), rel=1e-12, abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(score_matrices, st.integers(1, 8), st.data())
def test_probability_of_improvement_is_antisymmetric(x, runs_y, data):
    y = data.draw(hnp.arrays(np.float64, (runs_y, x.shape[1]),
                             elements=st.sampled_from([0.0, 0.5, 1.0]) | finite))
    p = probability_of_improvement(x, y)
    assert 0 <= p <= 1
    assert p == pytest.approx(1 - probability_of_improvement(y, x), abs=1e-12)
    assert probability_of_improvement(x, x) == 0.5


def test_probability_of_improvement_counts_ties_half():
    x, y = np.array([[1.0], [2.0]]), np.array([[1.0], [0.0]])
    # pairs (1,1) tie, (1,0) win, (2,1) win, (2,0) win: 3.5 / 4
    assert probability_of_improvement(x, y) == 0.875
    # averaged over tasks
    assert probability_of_improvement(np.hstack([x, x]), np.hstack([y, y + 5])) == (0.875 + 0) / 2


def test_probability_of_improvement_equals_mann_whitney():
    scipy_stats = pytest.importorskip('scipy.stats')
    rng = np.random.default_rng(3)
    x, y = np.round(rng.normal(size=(7, 3)), 1), np.round(rng.normal(size=(9, 3)), 1)
    u = [scipy_stats.mannwhitneyu(x[:, t], y[:, t], alternative='greater').statistic / 63 for t in range(3)]
    assert probability_of_improvement(x, y) == pytest.approx(np.mean(u), abs=1e-12)


@settings(max_examples=30, deadline=None)
@given(finite, st.integers(1, 10), st.integers(1, 3))
def test_constant_scores_give_a_zero_width_interval(value, runs, tasks):
    scores = np.full((runs, tasks), value)
    for statistic in (iqm, mean):
        point, low, high = stratified_bootstrap(scores, statistic, reps=200)
        assert point == low == high == pytest.approx(value, rel=1e-12, abs=1e-12)


def test_resampling_never_mixes_tasks():
    rng = np.random.default_rng(0)
    # each task's scores in a range of its own
    scores = rng.uniform(size=(6, 4)) + 10 * np.arange(4)

    def foreign(resampled):
        """How many resampled scores are not among the scores of their own task, per replication."""
        own = np.stack([np.isin(resampled[..., t], scores[:, t]) for t in range(4)], axis=-1)
        return (~own).sum(axis=(-2, -1))

    assert stratified_bootstrap(scores, foreign, reps=2000) == (0, 0, 0)
    # the same within every step of a curve
    curve = rng.uniform(size=(6, 4, 3)) + 10 * np.arange(4)[:, None] + 100 * np.arange(3)

    def foreign_per_step(resampled):
        own = np.stack([np.stack([np.isin(resampled[..., s, :, t], curve[:, t, s]) for t in range(4)], -1)
                        for s in range(3)], axis=-3)
        return (~own).sum(axis=(-2, -1))

    points, lows, highs = curve_intervals({'a': curve}, {'foreign': foreign_per_step}, reps=500)['a']['foreign']
    assert not points.any() and not lows.any() and not highs.any()


def test_resampling_draws_runs_with_replacement():
    scores = np.arange(10.0)[:, None]
    resampled = stats._resample(np.random.default_rng(0), scores, 1000)
    assert resampled.shape == (1000, 10, 1)
    assert set(np.unique(resampled)) <= set(scores[:, 0])
    # with replacement: on average 10 (1 - 0.9 ** 10) = 6.5 distinct runs of 10
    distinct = np.array([len(np.unique(r)) for r in resampled])
    assert 6.3 < distinct.mean() < 6.7


def test_interval_contains_the_point_and_narrows_with_runs():
    rng = np.random.default_rng(1)
    few, many = rng.normal(size=(5, 1)), rng.normal(size=(80, 1))
    for scores in (few, many):
        point, low, high = stratified_bootstrap(scores, mean, reps=5000)
        assert low <= point <= high
    assert np.diff(stratified_bootstrap(many, mean, reps=5000)[1:]) < np.diff(
        stratified_bootstrap(few, mean, reps=5000)[1:])


def test_same_seed_same_interval_and_entries_independent():
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(10, 2)), rng.normal(size=(10, 2))
    assert stratified_bootstrap(a, iqm, reps=1000, seed=4) == stratified_bootstrap(a, iqm, reps=1000, seed=4)
    assert stratified_bootstrap(a, iqm, reps=1000, seed=4) != stratified_bootstrap(a, iqm, reps=1000, seed=5)
    alone = interval_estimates({'a': a}, reps=1000)
    together = interval_estimates({'b': b, 'a': a}, reps=1000)
    assert alone['a'] == together['a']


def test_bootstrap_of_a_pair():
    rng = np.random.default_rng(5)
    x, y = rng.normal(1, 1, size=(10, 3)), rng.normal(0, 1, size=(7, 3))
    point, low, high = stratified_bootstrap((x, y), probability_of_improvement, reps=3000)
    assert point == probability_of_improvement(x, y) and low <= point <= high
    assert improvement_intervals({'x': x, 'y': y}, reps=3000)[('x', 'y')][0] == point


def test_curve_intervals_shapes_and_steps():
    rng = np.random.default_rng(6)
    runs_by_steps = rng.normal(size=(5, 7))
    curves = curve_intervals({'a': runs_by_steps}, reps=500)['a']
    for name, statistic in STATISTICS.items():
        points, lows, highs = curves[name]
        assert points.shape == lows.shape == highs.shape == (7,)
        assert np.all(lows <= points) and np.all(points <= highs)
        np.testing.assert_allclose(points, [statistic(runs_by_steps[:, s]) for s in range(7)], atol=1e-15)


def test_normalised():
    assert normalised(0.3, random=0.3, reference=0.7) == 0
    assert normalised(0.7, random=0.3, reference=0.7) == pytest.approx(1)
    per_task = normalised(np.array([[1.0, 5.0], [2.0, 6.0]]), random=np.array([0.0, 4.0]),
                          reference=np.array([2.0, 8.0]))
    np.testing.assert_allclose(per_task, [[0.5, 0.25], [1.0, 0.5]])
    with pytest.raises(ValueError, match='must differ'):
        normalised(1.0, random=0.5, reference=0.5)


BAD_SCORES = {
    'ragged runs': [[1.0, 2.0], [3.0]],
    'empty': np.zeros((0, 3)),
    'empty list': [],
    'NaN': [[1.0], [np.nan]],
    'infinite': [1.0, np.inf],
    'scalar': 1.0,
    'three axes': np.zeros((2, 2, 2)),
    'text': [['a', 'b']],
}


@pytest.mark.parametrize('name', list(BAD_SCORES))
def test_bad_scores_are_refused_in_one_line(name):
    with pytest.raises(ValueError) as error:
        stratified_bootstrap(BAD_SCORES[name], iqm, reps=10)
    assert '\n' not in str(error.value)
    if name != 'three axes':  # the aggregates take leading batch axes
        with pytest.raises(ValueError):
            iqm(BAD_SCORES[name])
    with pytest.raises(ValueError):
        interval_estimates({'a': BAD_SCORES[name]}, reps=10)


def test_bad_arguments_are_refused():
    scores = np.ones((3, 2))
    with pytest.raises(ValueError, match='reps'):
        stratified_bootstrap(scores, iqm, reps=0)
    with pytest.raises(ValueError, match='confidence'):
        stratified_bootstrap(scores, iqm, confidence=1.0)
    with pytest.raises(ValueError, match='leading batch axis'):
        stratified_bootstrap(scores, lambda s: float(np.mean(s)), reps=10)
    with pytest.raises(ValueError, match='tasks'):
        probability_of_improvement(np.ones((3, 2)), np.ones((3, 3)))
    with pytest.raises(ValueError, match='not an algorithm'):
        improvement_intervals({'a': scores}, pairs=[('a', 'b')], reps=10)
    with pytest.raises(ValueError, match='no algorithms'):
        interval_estimates({}, reps=10)
    with pytest.raises(ValueError, match='steps'):
        curve_intervals({'a': [[[[1.0]]]]}, reps=10)
    with pytest.raises(ValueError, match='ragged'):
        curve_intervals({'a': [[1.0, 2.0], [1.0]]}, reps=10)


def test_the_module_does_not_import_torch():
    import subprocess
    import sys
    code = 'import sys, mate.benchmark; assert "torch" not in sys.modules, "torch imported"'
    subprocess.run([sys.executable, '-c', code], check=True)


@settings(max_examples=25, deadline=None)
@given(hnp.arrays(np.float64, st.tuples(st.integers(2, 6), st.integers(1, 3)),
                  elements=st.sampled_from([0.0, 0.25, 0.5, 1.0])))
def test_percentile_interval_matches_a_loop(scores):
    """The vectorised bootstrap equals a plain loop over the same resamples."""
    assume(scores.size > 1)
    rng = np.random.default_rng(9)
    resampled = stats._resample(rng, scores, 300)
    loop = np.array([iqm(r) for r in resampled])
    point, low, high = stratified_bootstrap(scores, iqm, reps=300, seed=9)
    np.testing.assert_allclose((low, high), np.percentile(loop, [2.5, 97.5]), rtol=0, atol=1e-12)
