"""Verdicts with a controlled error rate: when may a report say a claim is *confirmed* or *refuted*?

An interval alone over-claims at a handful of runs: with both settings drawn from one distribution, "the 95 % CI
of P(X > Y) lies above 1/2" is decisive 20 % of the time at 3 runs a side and 9 % at 5, and "the IQM's CI lies
beyond a reference taken as exact" 26 % / 9 %. A verdict here is decisive only when the interval and a test whose
false-positive rate is at most `ALPHA` agree, after Holm's correction over a report's claims, and when the test's
own statistic points the interval's way:

* **two settings** (`better` > `worse`): the exact two-sided permutation test of the Mann-Whitney U statistic on
  the runs' scores (`mann_whitney_p`; every split of the pooled runs enumerated, ties counted). Its smallest
  p-value is 2 / C(n + m, n): with 3 runs a side 0.1, so 3 vs 3 can never be decisive at 5 %; 4 vs 4 gives
  0.029, 5 vs 5 0.0079.
* **a setting against a reference** (a rule team played on the same held-out episodes): both are samples of the
  same games, so the difference is paired by episode. The interval is a paired bootstrap over runs and episodes of
  the IQM over runs of each run's mean difference to the reference (`paired_reference_interval`); the test a t-test
  on the mean difference of the two-way layout runs x episodes (`reference_p`): its variance the runs' part plus
  the episodes' (each counted once, from the analysis of variance), its degrees of freedom Satterthwaite's with the
  runs' part at the upper end of its one-sided `RUNS_VARIANCE_LEVEL` interval (`reference_freedom`), so the
  reference's own sampling noise counts and the test holds its level at 3 runs as at 30.
* **agreement** (`kind='agree'`): without a declared margin no test can show two settings equal, and the verdict
  reads *no difference detected* (or *differ*, when the two-setting rule is decisive). With a margin d, the two
  one-sided t-tests (TOST, Welch) decide *equivalent* (|difference| < d at level `ALPHA`).

The verdicts: *confirmed* / *refuted* (decisive, in the claim's direction or against it), *unresolved*, and for
agreement claims *equivalent* / *not shown equivalent* (with a margin), *differ* or *no difference detected*. A claim
whose test is significant but whose tested statistic (the mean difference; for two settings U) and interval point
opposite ways is *unresolved* with a `reason` saying so (a few outlying runs move a mean and not an IQM); every
verdict that is not decisive gets its `reason` in a few words (too few runs for the exact test to reach `ALPHA`, an
interval across 1/2 or 0, a test not significant after Holm's correction), which the report's claims table shows.
`weigh` gathers the evidence on one claim, `decide` gives an experiment's verdicts (`mate.benchmark.report` calls
both). `simulate_false_decisive_rate` measures the rule's error rate on null data and `simulate_reference_claims`
its rates against a reference at any true effect (tests/benchmark/test_verdicts.py: at most 5 % on null data at 3,
5 and 10 runs).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np

__all__ = ['ALPHA', 'ENUMERATION_LIMIT', 'MIN_RUNS', 'REFERENCE_TEST', 'RUNS_VARIANCE_LEVEL', 'holm', 'mann_whitney_p',
           'paired_reference_interval', 'reference_p', 'reference_freedom', 'equivalence_p', 'p_value',
           'runs_for_a_decisive_verdict', 'smallest_mann_whitney_p', 'simulate_false_decisive_rate',
           'simulate_reference_claims', 'weigh', 'decide']

ALPHA = 0.05
"""The false-positive rate a decisive verdict is held to (two-sided, after Holm's correction)."""
ENUMERATION_LIMIT = 200_000
"""Splits of the pooled runs enumerated exactly; beyond, `mann_whitney_p` draws this many random splits (its
p-value then (1 + k) / (1 + N): never 0, at least 1 / 200,001)."""
MIN_RUNS = 3
"""Runs of each setting a claim needs before it is weighed at all (with fewer, a bootstrap interval has no width).
A decisive verdict between two settings needs more: 4 a side (`runs_for_a_decisive_verdict`)."""
RUNS_VARIANCE_LEVEL = 0.8
"""`reference_freedom` takes the runs' part of the variance at the upper end of its one-sided interval at this
level (the part x (runs - 1) / its chi-square's 20 % point). Satterthwaite's plain estimate is liberal at few runs
(its exact level reaches 7.8 % at 3 runs and 5.8 % at 5 where the runs' part is most of the variance); at 0.8 the
exact level is at most `ALPHA` at every share of the runs' part and every number of runs from 2 to 50
(tests/benchmark/test_verdicts.py computes it), at 0.75 it is 5.1 % at 3 runs."""


def _u_statistic(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """U of x over y (pairs with x > y, ties 1/2) for each row of x (k, n) and y (k, m)."""
    greater = (x[..., :, None] > y[..., None, :]).sum(axis=(-2, -1))
    ties = (x[..., :, None] == y[..., None, :]).sum(axis=(-2, -1))
    return greater + 0.5 * ties


def mann_whitney_p(x: Sequence[float], y: Sequence[float], seed: int = 0) -> float:
    """The two-sided p-value of the exact permutation test of the Mann-Whitney U statistic: the share of the splits
    of the pooled scores into groups of len(x) and len(y) whose U lies at least as far from its mean n m / 2 as the
    observed one (exact enumeration up to `ENUMERATION_LIMIT` splits; beyond, (1 + k) / (1 + N) of N random splits
    of which k are as extreme, the observed split counted with them: a valid p-value, never 0)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    n, m = len(x), len(y)
    if n < 1 or m < 1:
        raise ValueError(f'a permutation test needs runs on both sides, got {n} and {m}')
    pooled = np.concatenate([x, y])
    centre = n * m / 2.0
    observed = abs(float(_u_statistic(x[None], y[None])[0]) - centre)
    exact = math.comb(n + m, n) <= ENUMERATION_LIMIT
    if exact:
        chosen = np.array(list(itertools.combinations(range(n + m), n)), dtype=np.int64)
    else:
        rng = np.random.default_rng(seed)
        chosen = np.argsort(rng.random((ENUMERATION_LIMIT, n + m)), axis=1)[:, :n]
    mask = np.zeros((len(chosen), n + m), dtype=bool)
    np.put_along_axis(mask, chosen, True, axis=1)
    order = np.argsort(~mask, axis=1, kind='stable')      # the chosen indices first, then the others
    split = pooled[order]
    u = _u_statistic(split[:, :n], split[:, n:])
    extreme = int(np.sum(np.abs(u - centre) >= observed - 1e-9))
    return extreme / len(chosen) if exact else (1 + extreme) / (1 + len(chosen))      # the observed split counts


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


def reference_freedom(runs_part, episodes_part, runs: int, episodes_terms=0.0):
    """Satterthwaite's degrees of freedom of the variance `runs_part` + `episodes_part` of a mean paired difference,
    with the runs' part (runs - 1 degrees of freedom) at the upper end of its one-sided `RUNS_VARIANCE_LEVEL`
    interval: runs_part x (runs - 1) / chi2.ppf(1 - RUNS_VARIANCE_LEVEL, runs - 1). `episodes_terms`: the episodes'
    part's own term of the formula (its mean squares squared over their degrees of freedom; 0: taken as known).
    The parts are variances of the mean (the metric's units squared); arrays broadcast; infinite where both parts'
    terms are 0. With no episodes' part it is runs - 1; it grows towards the episodes' own degrees of freedom as
    their part dominates."""
    from scipy.stats import chi2

    freedom = runs - 1
    upper = np.asarray(runs_part, dtype=float) * freedom / chi2.ppf(1.0 - RUNS_VARIANCE_LEVEL, freedom)
    denominator = upper ** 2 / freedom + np.asarray(episodes_terms, dtype=float)
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(denominator > 0, (upper + episodes_part) ** 2 / np.where(denominator > 0, denominator, 1.0),
                        np.inf)


def _reference_tests(difference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mean, p), each of shape (...): the mean paired difference and `reference_p`'s p-value for differences
    (..., runs, E) (leading axes: independent experiments)."""
    from scipy.stats import t as student

    runs, count = difference.shape[-2:]
    mean = difference.mean(axis=(-2, -1))
    if runs < 2:
        return mean, np.ones_like(mean)
    run_means, episode_means = difference.mean(axis=-1), difference.mean(axis=-2)        # (..., runs), (..., E)
    runs_part = run_means.var(axis=-1, ddof=1) / runs           # = the runs' mean square / (runs E)
    if count > 1:
        residual = difference - run_means[..., :, None] - episode_means[..., None, :] + mean[..., None, None]
        residual_square = (residual ** 2).sum(axis=(-2, -1)) / ((runs - 1) * (count - 1))
        episodes_square = runs * episode_means.var(axis=-1, ddof=1)
        episodes_part = np.maximum(episodes_square - residual_square, 0.0) / (runs * count)
        scale = (runs * count) ** 2
        episodes_terms = np.where(episodes_part > 0, episodes_square ** 2 / scale / (count - 1)
                                  + residual_square ** 2 / scale / ((runs - 1) * (count - 1)), 0.0)
    else:
        episodes_part = episodes_terms = np.zeros_like(mean)
    variance = runs_part + episodes_part
    freedom = reference_freedom(runs_part, episodes_part, runs, episodes_terms)
    with np.errstate(divide='ignore', invalid='ignore'):
        statistic = np.abs(mean) / np.sqrt(variance)
        p = 2.0 * student.sf(statistic, freedom)
    p = np.where(variance > 0, p, np.where(mean != 0, 0.0, 1.0))
    return mean, p


def reference_p(episodes, reference) -> float:
    """Two-sided p-value that the runs' mean paired difference to the reference is 0.

    `episodes` (runs, E): each run's metric on the E held-out episodes; `reference` (E,): the reference team's on
    the same episodes. The differences are a two-way layout, difference[r, e] = effect + run r's own + episode e's
    own (common to the runs: the reference's sampling noise and what makes an episode easier for the one team than
    for the other) + noise. The variance of their mean is estimated from the analysis of variance, each part counted
    once: the runs' part (the variance of the runs' means / runs) plus the episodes' (the episodes' mean square less
    the residual one, / (runs E), at least 0); Student's t with `reference_freedom`'s degrees of freedom (between
    runs - 1, where the runs' part is all of it, and the episodes' hundreds, where it is none; one run: p = 1)."""
    _, p = _reference_tests(_differences(episodes, reference))
    return float(p)


def _bootstrap_iqms(difference: np.ndarray, reps: int, seed: int) -> np.ndarray:
    """(..., reps): the IQM over resampled runs of each run's mean paired difference over resampled episodes, for
    differences (..., runs, E); every leading index gets the same draws (those of `paired_reference_interval` with
    this seed; with leading axes one matrix product serves them all, equal to theirs up to rounding)."""
    from .stats import iqm

    runs, count = difference.shape[-2:]
    rng = np.random.default_rng(seed)
    chunk = max(1, (1 << 22) // max(count, 1))
    lead = difference.shape[:-2]
    values = []
    for start in range(0, reps, chunk):
        size = min(chunk, reps - start)
        weights = rng.multinomial(count, np.full(count, 1.0 / count), size=size) / count      # (size, E)
        if lead:        # one product for every experiment: (... runs, E) @ (E, size)
            per_run = np.swapaxes((difference.reshape(-1, count) @ weights.T).reshape(*lead, runs, size), -1, -2)
        else:
            per_run = weights @ difference.T                                                  # (size, runs)
        picked = np.broadcast_to(rng.integers(0, runs, size=(size, runs)), (*lead, size, runs))
        values.append(np.reshape(iqm(np.take_along_axis(per_run, picked, axis=-1)[..., None]), (*lead, size)))
    return np.concatenate(values, axis=-1)


def paired_reference_interval(episodes, reference, reps: int = 50_000, confidence: float = 0.95,
                              seed: int = 0) -> tuple[float, float, float]:
    """(point, low, high): the IQM over runs of each run's mean paired difference to the reference, and its
    percentile interval from a bootstrap that resamples the runs and, independently, the episodes (the same
    resampled episodes for the runs and the reference)."""
    from .stats import iqm

    difference = _differences(episodes, reference)
    values = _bootstrap_iqms(difference, reps, seed)
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


def smallest_mann_whitney_p(n: int, m: int) -> float:
    """The smallest p-value the exact two-sided Mann-Whitney test can give with `n` and `m` runs: 2 / C(n + m, n)
    (every run of one side above every run of the other: 0.1 at 3 a side, 0.029 at 4, 0.0079 at 5; 1 with a side
    empty)."""
    return min(1.0, 2.0 / math.comb(n + m, n)) if n and m else 1.0


def runs_for_a_decisive_verdict(alpha: float = ALPHA, most: int = 20) -> int:
    """The fewest runs a side for which the exact two-sided permutation test can reach `alpha` (4 at 5 %)."""
    for runs in range(1, most + 1):
        if smallest_mann_whitney_p(runs, runs) <= alpha:
            return runs
    raise ValueError(f'no number of runs up to {most} reaches alpha {alpha}')


def simulate_reference_claims(runs: int, effect: float = 0.0, trials: int = 2000, episodes: int = 320,
                              run_sd: float = 0.005, noise_sd: float = 0.04, learner_episode_sd: float = 0.012,
                              reference_episode_sd: float = 0.037, shared_episode_sd: float = 0.02, reps: int = 500,
                              seed: int = 0) -> dict[str, float]:
    """How often the rule decides a claim "the setting scores above the reference" in `trials` simulated experiments
    (one claim each, before Holm's correction): {'confirmed': share, 'refuted': share, 'decisive': their sum}. At
    `effect` 0 'decisive' is the false-decisive rate; at an effect > 0 'confirmed' is the power.

    Each experiment: `runs` runs of a setting and the reference team, all on the same `episodes` games. A game e has
    a difficulty both teams share (sd `shared_episode_sd`), one for the setting common to its runs
    (`learner_episode_sd`) and one for the reference (`reference_episode_sd`: its own sampling noise); run r adds its
    own offset (`run_sd`) and per-game noise (`noise_sd`):

        played[r, e] = effect + shared[e] + learner[e] + run[r] + noise[r, e],   reference[e] = shared[e] + own[e]

    The defaults are the committed reports' claims against the greedy teams on MATE-4v8-9 and MATE-4v8-0, fitted
    by the analysis of variance of `reference_p`: runs' sd 0.002-0.010, shared 0.016-0.030, the setting's own
    0.007-0.016, the reference's 0.034-0.041, noise 0.031-0.046, 320 episodes. Decisive as `decide` decides: the
    interval of `paired_reference_interval` on one side of 0 (`reps` replications, the same draws in every
    experiment: those every report's claim gets with its seed), `reference_p` < ALPHA and the mean difference on
    the interval's side. Vectorised over the experiments (about a second per 1,000 at 5 runs)."""
    rng = np.random.default_rng(seed)
    confirmed = refuted = 0
    for start in range(0, trials, 500):
        size = min(500, trials - start)
        shared = rng.normal(scale=shared_episode_sd, size=(size, 1, episodes))
        reference = shared + rng.normal(scale=reference_episode_sd, size=(size, 1, episodes))
        played = (effect + shared + rng.normal(scale=learner_episode_sd, size=(size, 1, episodes))
                  + rng.normal(scale=run_sd, size=(size, runs, 1)) + rng.normal(scale=noise_sd,
                                                                                size=(size, runs, episodes)))
        difference = played - reference
        values = _bootstrap_iqms(difference, reps, seed)
        low, high = np.quantile(values, [0.025, 0.975], axis=-1)
        mean, p = _reference_tests(difference)
        significant = p < ALPHA
        confirmed += int(np.sum(significant & (low > 0) & (mean > 0)))
        refuted += int(np.sum(significant & (high < 0) & (mean < 0)))
    return dict(confirmed=confirmed / trials, refuted=refuted / trials, decisive=(confirmed + refuted) / trials)


def simulate_false_decisive_rate(runs: int, trials: int = 400, kind: str = 'settings', reps: int = 1000,
                                 seed: int = 0, **model) -> float:
    """The share of `trials` null experiments in which the rule gives a decisive verdict.

    `kind='settings'`: two settings with `runs` runs each, every score from one normal distribution; decisive when
    the interval of P(X > Y) excludes 1/2 and `mann_whitney_p` < ALPHA. `kind='reference'`: `runs` runs whose
    episodes share the reference's expected score, `simulate_reference_claims`' 'decisive' at effect 0 (`model`: its
    keyword arguments, e.g. `run_sd`, `episodes`)."""
    from .stats import improvement_intervals

    if kind == 'reference':
        return simulate_reference_claims(runs, 0.0, trials, reps=reps, seed=seed, **model)['decisive']
    if kind != 'settings':
        raise ValueError(f"kind must be 'settings' or 'reference', got {kind!r}")
    if model:
        raise ValueError(f"kind='settings' takes no model, got {', '.join(sorted(model))}")
    rng = np.random.default_rng(seed)
    decisive = 0
    for trial in range(trials):
        x, y = rng.normal(size=runs), rng.normal(size=runs)
        _, low, high = improvement_intervals({'x': x, 'y': y}, pairs=[('x', 'y')], reps=reps, seed=trial)[('x', 'y')]
        decisive += (low > 0.5 or high < 0.5) and mann_whitney_p(x, y) < ALPHA
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
    p-value `p` (against a reference also `mean`, the mean paired difference setting - reference the test tests),
    `runs` (setting label -> its runs), and for `decide`: `lean`, 'holds' / 'fails' when the interval lies on one
    side, else None, and `test_lean`, the side the tested statistic is on (U against n m / 2; the mean difference
    against 0)."""
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
    row['runs'] = {side: len(scores[side]) for side in present}
    if len(present) == 2:
        better, worse = (np.asarray(scores[side], dtype=float) for side in sides)
        point, low, high = improvement_intervals({'b': better, 'w': worse}, pairs=[('b', 'w')], reps=reps)[('b', 'w')]
        row.update(statistic='probability of improvement', point=point, low=low, high=high,
                   lean='holds' if low > 0.5 else 'fails' if high < 0.5 else None,
                   test_lean='holds' if point > 0.5 else 'fails' if point < 0.5 else None)   # point: U / (n m)
        if claim.kind == 'agree' and claim.margin is not None:
            return dict(row, test=f'equivalence within {claim.margin:g} (TOST)',
                        p=equivalence_p(better, worse, claim.margin))
        return dict(row, test='exact Mann-Whitney', p=mann_whitney_p(better, worse))
    setting = present[0]
    reference = next(side for side in sides if side != setting)
    if setting not in episodes or reference not in reference_episodes:
        return dict(row, verdict='no data (the episodes are not kept)')
    point, low, high = paired_reference_interval(episodes[setting], reference_episodes[reference], reps=reps)
    mean, p = (float(value) for value in _reference_tests(_differences(episodes[setting],
                                                                        reference_episodes[reference])))

    def side(above: bool, below: bool) -> str | None:
        holds, fails = (above, below) if setting == claim.better else (below, above)
        return 'holds' if holds else 'fails' if fails else None

    return dict(row, statistic=f'IQM of {setting} - {reference} ({reference_scores[reference]:.3f}), '
                               'paired by episode', point=point, low=low, high=high, lean=side(low > 0.0, high < 0.0),
                test_lean=side(mean > 0.0, mean < 0.0), test=REFERENCE_TEST, p=p, mean=mean)


def decide(rows: list[dict]) -> list[dict]:
    """The verdicts of one experiment's weighed claims (`weigh`): Holm's correction over every claim with a test
    (`p_holm`), then a verdict decisive only where the interval and the corrected test agree at `ALPHA` and the
    tested statistic lies on the interval's side:

    * a claim that one side is better: *confirmed* (the interval on the claim's side, p_holm < ALPHA), *refuted*
      (on the other side, p_holm < ALPHA), else *unresolved*;
    * an agreement claim without a margin: *differ* (the interval of P excludes 1/2, p_holm < ALPHA), else *no
      difference detected*; with a margin: *equivalent* (TOST p_holm < ALPHA), else *not shown equivalent*.

    A claim whose interval and corrected test are decisive but whose tested statistic lies on the other side (the
    mean difference of a few outlying runs against the IQM of the rest) is *unresolved* (*no difference detected*)
    with a `reason` that says so; every other verdict that is not decisive (*unresolved*, *no difference detected*,
    *not shown equivalent*) gets a `reason` too (`_not_decisive`)."""
    tested = [row for row in rows if 'p' in row]
    for row, adjusted in zip(tested, holm([row['p'] for row in tested])):
        lean, test_lean = row.pop('lean'), row.pop('test_lean', None)
        decisive = adjusted < ALPHA
        row['p_holm'] = adjusted
        if decisive and lean and test_lean != lean and 'TOST' not in row['test']:
            row['reason'] = _disagreement(row, lean)
            decisive = False
        elif not (decisive and (lean or 'TOST' in row['test'])):
            row['reason'] = _not_decisive(row, lean, len(tested))
        if row['kind'] == 'agree' and 'TOST' in row['test']:
            row['verdict'] = 'equivalent' if decisive else 'not shown equivalent'
        elif row['kind'] == 'agree':
            row['verdict'] = 'differ' if decisive and lean else 'no difference detected'
        else:
            row['verdict'] = {'holds': 'confirmed', 'fails': 'refuted'}.get(lean if decisive else None, 'unresolved')
    return rows


REFERENCE_TEST = 'paired t, runs x episodes'
"""The name of the test of a claim against a reference in a report (`reference_p`)."""


def p_value(p: float) -> str:
    """'0.0079', '0.10', '<0.0001': two significant digits."""
    return '<0.0001' if p < 1e-4 else f'{p:.2g}' if p < 0.1 else f'{p:.2f}'


def _not_decisive(row: dict, lean: str | None, claims: int) -> str:
    """Why a claim's verdict is not decisive, in a few words: the exact test cannot reach `ALPHA` with so few runs,
    or the interval includes 1/2 (0 against a reference), or the test's p after Holm's correction over the `claims`
    tested claims is not below `ALPHA` (the raw p named when it alone was)."""
    if 'TOST' in row['test']:
        return f"the equivalence test's p after Holm, {p_value(row['p_holm'])}, is not below {ALPHA:g}"
    if row['test'] == 'exact Mann-Whitney':
        n, m = row['runs'].values()
        floor = smallest_mann_whitney_p(n, m)
        if floor >= ALPHA:
            runs = f'{n} runs a side' if n == m else f'{n} and {m} runs'
            return f"{runs} cannot be decisive: the exact test's p is at least {p_value(floor)}"
    centre = '1/2' if row['statistic'] == 'probability of improvement' else '0'
    interval = f'the interval includes {centre}' if lean is None else \
        f'the interval is {"above" if row["low"] > (0.5 if centre == "1/2" else 0.0) else "below"} {centre}'
    if row['p_holm'] < ALPHA:
        return f"{interval} (the test's p after Holm is {p_value(row['p_holm'])})"
    joint = ' but' if lean else ' and'
    if row['p'] < ALPHA:
        return (f"{interval}{joint} the test's p, {p_value(row['p'])}, is {p_value(row['p_holm'])} after Holm's "
                f'correction over {claims} claims, not below {ALPHA:g}')
    return f"{interval}{joint} the test's p after Holm, {p_value(row['p_holm'])}, is not below {ALPHA:g}"


def _disagreement(row: dict, lean: str) -> str:
    """Why a claim whose interval and test are decisive has no decisive verdict: they point opposite ways."""
    interval = f'its interval [{row["low"]:.3g}, {row["high"]:.3g}]'
    if 'mean' in row:
        return (f'the tested mean difference ({row["mean"]:+.3g}) and {interval} lie on opposite sides of 0, so '
                'the test does not support the interval\'s side')
    return (f'the tested U puts P(better > worse) at {row["point"]:.3g}, on the other side of 1/2 from {interval}, '
            'so the test does not support the interval\'s side')
