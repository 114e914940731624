"""Verdicts with a controlled error rate: when may a report say a claim is *confirmed* or *refuted*?

An interval alone over-claims at a handful of runs: with both settings drawn from one distribution, "the 95 % CI
of P(X > Y) lies above 1/2" is decisive 20 % of the time at 3 runs a side and 9 % at 5, and "the IQM's CI lies
beyond a reference taken as exact" 26 % / 9 %. A verdict here is decisive only when the interval and a test whose
false-positive rate is at most `ALPHA` agree, after Holm's correction over a report's claims:

* **two settings** (`better` > `worse`): the exact two-sided permutation test of the Mann-Whitney U statistic on
  the runs' scores (`mann_whitney_p`; every split of the pooled runs enumerated, ties counted). Its smallest
  p-value is 2 / C(n + m, n): with 3 runs a side 0.1, so 3 vs 3 can never be decisive at 5 %; 4 vs 4 gives
  0.029, 5 vs 5 0.0079.
* **a setting against a reference** (a rule team played on the same held-out episodes): both are samples of the
  same games, so the difference is paired by episode. The interval is a paired bootstrap over runs and episodes of
  the IQM over runs of each run's mean difference to the reference (`paired_reference_interval`); the test a
  t-test on the mean difference whose standard error adds the runs' spread and the episodes' spread
  (`reference_p`, n - 1 degrees of freedom), so the reference's own sampling noise counts.
* **agreement** (`kind='agree'`): without a declared margin no test can show two settings equal, and the verdict
  reads *no difference detected* (or *differ*, when the two-setting rule is decisive). With a margin d, the two
  one-sided t-tests (TOST, Welch) decide *equivalent* (|difference| < d at level `ALPHA`).

The verdicts: *confirmed* / *refuted* (decisive, in the claim's direction or against it), *unresolved*, and for
agreement claims *equivalent* / *not shown equivalent* (with a margin), *differ* or *no difference detected*.
`weigh` gathers the evidence on one claim, `decide` gives an experiment's verdicts (`mate.benchmark.report` calls
both). `simulate_false_decisive_rate` measures the
rule's error rate on null data (tests/benchmark/test_verdicts.py: at most 5 % at 3, 5 and 10 runs).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np

__all__ = ['ALPHA', 'ENUMERATION_LIMIT', 'MIN_RUNS', 'holm', 'mann_whitney_p', 'paired_reference_interval',
           'reference_p', 'equivalence_p', 'runs_for_a_decisive_verdict', 'simulate_false_decisive_rate', 'weigh',
           'decide']

ALPHA = 0.05
"""The false-positive rate a decisive verdict is held to (two-sided, after Holm's correction)."""
ENUMERATION_LIMIT = 200_000
"""Splits of the pooled runs enumerated exactly; beyond, `mann_whitney_p` draws this many random splits."""
MIN_RUNS = 3
"""Runs of each setting a claim needs before it is weighed at all (with fewer, a bootstrap interval has no width).
A decisive verdict between two settings needs more: 4 a side (`runs_for_a_decisive_verdict`)."""


def _u_statistic(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """U of x over y (pairs with x > y, ties 1/2) for each row of x (k, n) and y (k, m)."""
    greater = (x[..., :, None] > y[..., None, :]).sum(axis=(-2, -1))
    ties = (x[..., :, None] == y[..., None, :]).sum(axis=(-2, -1))
    return greater + 0.5 * ties


def mann_whitney_p(x: Sequence[float], y: Sequence[float], seed: int = 0) -> float:
    """The two-sided p-value of the exact permutation test of the Mann-Whitney U statistic: the share of the splits
    of the pooled scores into groups of len(x) and len(y) whose U lies at least as far from its mean n m / 2 as the
    observed one (exact enumeration up to `ENUMERATION_LIMIT` splits, random splits beyond)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    n, m = len(x), len(y)
    if n < 1 or m < 1:
        raise ValueError(f'a permutation test needs runs on both sides, got {n} and {m}')
    pooled = np.concatenate([x, y])
    centre = n * m / 2.0
    observed = abs(float(_u_statistic(x[None], y[None])[0]) - centre)
    if math.comb(n + m, n) <= ENUMERATION_LIMIT:
        chosen = np.array(list(itertools.combinations(range(n + m), n)), dtype=np.int64)
    else:
        rng = np.random.default_rng(seed)
        chosen = np.argsort(rng.random((ENUMERATION_LIMIT, n + m)), axis=1)[:, :n]
    mask = np.zeros((len(chosen), n + m), dtype=bool)
    np.put_along_axis(mask, chosen, True, axis=1)
    order = np.argsort(~mask, axis=1, kind='stable')      # the chosen indices first, then the others
    split = pooled[order]
    u = _u_statistic(split[:, :n], split[:, n:])
    return float(np.mean(np.abs(u - centre) >= observed - 1e-9))


def holm(pvalues: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values (the family-wise error rate over the claims of one report)."""
    p = np.asarray(pvalues, dtype=float)
    order = np.argsort(p, kind='stable')
    adjusted = np.empty_like(p)
    running = 0.0
    for rank, index in enumerate(order):
        running = max(running, min(1.0, (len(p) - rank) * p[index]))
        adjusted[index] = running
    return adjusted.tolist()


def _differences(episodes, reference) -> np.ndarray:
    episodes, reference = np.asarray(episodes, dtype=float), np.asarray(reference, dtype=float)
    if episodes.ndim != 2 or reference.shape != episodes.shape[1:]:
        raise ValueError(f'paired episodes: the runs (runs, episodes) and the reference (episodes,) must share their '
                         f'episodes, got shapes {episodes.shape} and {reference.shape}')
    return episodes - reference


def reference_p(episodes, reference) -> float:
    """Two-sided p-value that the runs' mean paired difference to the reference is 0.

    `episodes` (runs, E): each run's metric on the E held-out episodes; `reference` (E,): the reference team's on
    the same episodes. The standard error adds the spread of the runs' mean differences (/ runs) and the spread of
    the episodes' mean differences (/ E): the reference's sampling noise counts. Student's t with runs - 1 degrees
    of freedom (one run: p = 1)."""
    difference = _differences(episodes, reference)
    runs, count = difference.shape
    if runs < 2:
        return 1.0
    from scipy.stats import t as student

    variance = difference.mean(axis=1).var(ddof=1) / runs + difference.mean(axis=0).var(ddof=1) / count
    if variance <= 0.0:
        return 0.0 if difference.mean() != 0.0 else 1.0
    statistic = float(difference.mean() / math.sqrt(variance))
    return float(2.0 * student.sf(abs(statistic), runs - 1))


def paired_reference_interval(episodes, reference, reps: int = 50_000, confidence: float = 0.95,
                              seed: int = 0) -> tuple[float, float, float]:
    """(point, low, high): the IQM over runs of each run's mean paired difference to the reference, and its
    percentile interval from a bootstrap that resamples the runs and, independently, the episodes (the same
    resampled episodes for the runs and the reference)."""
    from .stats import iqm

    difference = _differences(episodes, reference)
    runs, count = difference.shape
    rng = np.random.default_rng(seed)
    chunk = max(1, (1 << 22) // max(count, 1))
    values = []
    for start in range(0, reps, chunk):
        size = min(chunk, reps - start)
        weights = rng.multinomial(count, np.full(count, 1.0 / count), size=size) / count      # (size, E)
        per_run = weights @ difference.T                                                      # (size, runs)
        picked = rng.integers(0, runs, size=(size, runs))
        values.append(iqm(np.take_along_axis(per_run, picked, axis=1)[..., None]))   # (size, runs, 1 task)
    values = np.concatenate([np.atleast_1d(v) for v in values])
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(values, [tail, 1.0 - tail])
    return float(iqm(difference.mean(axis=1))), float(low), float(high)


def equivalence_p(x: Sequence[float], y: Sequence[float], margin: float) -> float:
    """The p-value of the two one-sided Welch t-tests (TOST) that |mean(x) - mean(y)| < `margin`: the larger of
    the two one-sided p-values (small: the settings are equivalent within the margin)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if margin <= 0:
        raise ValueError(f'an equivalence margin must be positive, got {margin}')
    if len(x) < 2 or len(y) < 2:
        return 1.0
    from scipy.stats import t as student

    vx, vy = x.var(ddof=1) / len(x), y.var(ddof=1) / len(y)
    error = math.sqrt(vx + vy)
    difference = float(x.mean() - y.mean())
    if error == 0.0:
        return 0.0 if abs(difference) < margin else 1.0
    freedom = (vx + vy) ** 2 / ((vx ** 2 / (len(x) - 1) if vx else 0.0) + (vy ** 2 / (len(y) - 1) if vy else 0.0))
    lower = student.sf((difference + margin) / error, freedom)      # H0: difference <= -margin
    upper = student.cdf((difference - margin) / error, freedom)     # H0: difference >= margin
    return float(max(lower, upper))


def runs_for_a_decisive_verdict(alpha: float = ALPHA, most: int = 20) -> int:
    """The fewest runs a side for which the exact two-sided permutation test can reach `alpha` (4 at 5 %)."""
    for runs in range(1, most + 1):
        if 2.0 / math.comb(2 * runs, runs) <= alpha:
            return runs
    raise ValueError(f'no number of runs up to {most} reaches alpha {alpha}')


def simulate_false_decisive_rate(runs: int, trials: int = 400, kind: str = 'settings', episodes: int = 40,
                                 reps: int = 1000, seed: int = 0) -> float:
    """The share of `trials` null experiments in which the rule gives a decisive verdict.

    `kind='settings'`: two settings with `runs` runs each, every score from one normal distribution; decisive when
    the interval of P(X > Y) excludes 1/2 and `mann_whitney_p` < ALPHA. `kind='reference'`: `runs` runs whose
    episodes share the reference's expected score (each run a random offset plus per-episode noise, the episodes'
    difficulty common to runs and reference); decisive when `paired_reference_interval` excludes 0 and `reference_p`
    < ALPHA."""
    from .stats import improvement_intervals

    rng = np.random.default_rng(seed)
    decisive = 0
    for trial in range(trials):
        if kind == 'settings':
            x, y = rng.normal(size=runs), rng.normal(size=runs)
            _, low, high = improvement_intervals({'x': x, 'y': y}, pairs=[('x', 'y')], reps=reps,
                                                 seed=trial)[('x', 'y')]
            decisive += (low > 0.5 or high < 0.5) and mann_whitney_p(x, y) < ALPHA
        elif kind == 'reference':
            difficulty = rng.normal(scale=1.0, size=episodes)
            reference = difficulty + rng.normal(scale=0.5, size=episodes)
            played = difficulty + rng.normal(scale=0.3, size=(runs, 1)) + rng.normal(scale=0.5, size=(runs, episodes))
            _, low, high = paired_reference_interval(played, reference, reps=reps, seed=trial)
            decisive += (low > 0 or high < 0) and reference_p(played, reference) < ALPHA
        else:
            raise ValueError(f"kind must be 'settings' or 'reference', got {kind!r}")
    return decisive / trials


# ============================================================================ the claims of a report


def weigh(claim, task: str, scores: dict, reference_scores: dict, episodes: dict, reference_episodes: dict,
          reps: int) -> dict:
    """The evidence on one claim (`mate.benchmark.experiments.Claim`) in one task, before `decide` gives the verdict.

    `scores`: setting label -> per-run scores (runs,), higher better (population experiments: the exploitability
    negated); `reference_scores`: reference team -> its mean score; `episodes`: setting label -> the runs' absolute
    metric per held-out episode (runs, E), and `reference_episodes`: reference team -> (E,) on the same episodes (a
    claim against a reference needs both). Returns the claim's row: text, better, worse, task, kind and either
    `verdict` (no data, too few runs) or the statistic with its interval (point, low, high), the test and its raw
    p-value `p`, and `lean`: 'holds' / 'fails' when the interval lies on one side, else None."""
    from .stats import improvement_intervals

    row = dict(text=claim.text, better=claim.better, worse=claim.worse, task=task, kind=claim.kind)
    sides = [claim.better, claim.worse]
    present = [side for side in sides if side in scores]
    judged = len(present) == 2 or (len(present) == 1 and any(side in reference_scores for side in sides))
    if not judged:
        return dict(row, verdict='no data')
    runs = min(len(scores[side]) for side in present)
    if runs < MIN_RUNS:
        return dict(row, verdict=f'too few runs ({runs}; a verdict needs {MIN_RUNS})')
    if len(present) == 2:
        better, worse = (np.asarray(scores[side], dtype=float) for side in sides)
        point, low, high = improvement_intervals({'b': better, 'w': worse}, pairs=[('b', 'w')], reps=reps)[('b', 'w')]
        row.update(statistic='probability of improvement', point=point, low=low, high=high,
                   lean='holds' if low > 0.5 else 'fails' if high < 0.5 else None)
        if claim.kind == 'agree' and claim.margin is not None:
            return dict(row, test=f'equivalence within {claim.margin:g} (TOST)',
                        p=equivalence_p(better, worse, claim.margin))
        return dict(row, test='exact Mann-Whitney', p=mann_whitney_p(better, worse))
    setting = present[0]
    reference = next(side for side in sides if side != setting)
    if setting not in episodes or reference not in reference_episodes:
        return dict(row, verdict='no data (the episodes are not kept)')
    point, low, high = paired_reference_interval(episodes[setting], reference_episodes[reference], reps=reps)
    above, below = low > 0.0, high < 0.0
    holds, fails = (above, below) if setting == claim.better else (below, above)
    return dict(row, statistic=f'IQM of {setting} - {reference} ({reference_scores[reference]:.3f}), '
                               'paired by episode', point=point, low=low, high=high,
                lean='holds' if holds else 'fails' if fails else None,
                test='paired t (runs and episodes)', p=reference_p(episodes[setting], reference_episodes[reference]))


def decide(rows: list[dict]) -> list[dict]:
    """The verdicts of one experiment's weighed claims (`weigh`): Holm's correction over every claim with a test
    (`p_holm`), then a verdict decisive only where the interval and the corrected test agree at `ALPHA`:

    * a claim that one side is better: *confirmed* (the interval on the claim's side, p_holm < ALPHA), *refuted*
      (on the other side, p_holm < ALPHA), else *unresolved*;
    * an agreement claim without a margin: *differ* (the interval of P excludes 1/2, p_holm < ALPHA), else *no
      difference detected*; with a margin: *equivalent* (TOST p_holm < ALPHA), else *not shown equivalent*."""
    tested = [row for row in rows if 'p' in row]
    for row, adjusted in zip(tested, holm([row['p'] for row in tested])):
        decisive, lean = adjusted < ALPHA, row.pop('lean')
        row['p_holm'] = adjusted
        if row['kind'] == 'agree' and 'TOST' in row['test']:
            row['verdict'] = 'equivalent' if decisive else 'not shown equivalent'
        elif row['kind'] == 'agree':
            row['verdict'] = 'differ' if decisive and lean else 'no difference detected'
        else:
            row['verdict'] = {'holds': 'confirmed', 'fails': 'refuted'}.get(lean if decisive else None, 'unresolved')
    return rows
