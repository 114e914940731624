"""The verdict rule's error rate (`mate.benchmark.verdicts`): on null data a decisive verdict comes at most 5 % of the
time (within simulation error) at 3, 5 and 10 runs, and the test against a reference holds its level exactly at every
share of the runs' variance; the exact test agrees with scipy's; Holm, TOST, the paired reference interval and the
direction check behave as documented."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mate.benchmark import verdicts

TRIALS = 600
SLACK = 2 * math.sqrt(verdicts.ALPHA * (1 - verdicts.ALPHA) / TRIALS)
"""Two standard errors of a simulated rate of 5 % over TRIALS null experiments."""


REFERENCE_TRIALS = 2000
REFERENCE_SLACK = 2 * math.sqrt(verdicts.ALPHA * (1 - verdicts.ALPHA) / REFERENCE_TRIALS)
MODELS = {'committed runs, run sd 0.003': dict(run_sd=0.003),
          'committed runs, run sd 0.01': dict(run_sd=0.01),
          'runs spread most': dict(run_sd=0.3, noise_sd=0.5, learner_episode_sd=0.0, reference_episode_sd=0.5,
                                   shared_episode_sd=1.0, episodes=40)}
"""Models of claims against a reference (`simulate_reference_claims`): fitted to the committed reports (the runs'
part of the variance from a fifth to four fifths of it at 3 runs), and one where the runs' spread is most of it."""


@pytest.mark.slow
@pytest.mark.parametrize('runs', [3, 5, 10])
def test_null_data_gives_a_decisive_verdict_at_most_five_percent_of_the_time(runs):
    rate = verdicts.simulate_false_decisive_rate(runs, trials=TRIALS, kind='settings', reps=500, seed=runs)
    assert rate <= verdicts.ALPHA + SLACK, rate


@pytest.mark.slow
@pytest.mark.parametrize('runs', [3, 5, 10])
@pytest.mark.parametrize('model', list(MODELS))
def test_null_data_against_a_reference_is_decisive_at_most_five_percent_of_the_time(runs, model):
    rate = verdicts.simulate_false_decisive_rate(runs, trials=REFERENCE_TRIALS, kind='reference', reps=500,
                                                 seed=runs, **MODELS[model])
    assert rate <= verdicts.ALPHA + REFERENCE_SLACK, rate


def _exact_level(runs: int, share: float, freedom) -> float:
    """The exact level at 5 % of the t-test of a mean whose variance is a runs' part (runs - 1 degrees of freedom,
    `share` of the whole) and a known episodes' part, with `freedom(runs_part, episodes_part)` degrees of freedom:
    the mean over the runs' chi-square (10,000 quantiles) of P(|Z| > critical value x the estimate's sd)."""
    from scipy.stats import chi2, norm, t as student

    square = chi2.ppf((np.arange(10_000) + 0.5) / 10_000, runs - 1) / (runs - 1)
    runs_part, episodes_part = share * square, 1.0 - share
    critical = student.ppf(1 - verdicts.ALPHA / 2, freedom(runs_part, episodes_part))
    return float(np.mean(2 * norm.sf(critical * np.sqrt(runs_part + episodes_part))))


@pytest.mark.parametrize('runs', [2, 3, 4, 5, 10, 30])
def test_the_reference_test_holds_its_level_at_every_share_of_the_runs_variance(runs):
    """Under the normal model with the episodes' part known, `reference_freedom`'s degrees of freedom keep the level
    at most 5 % whatever the runs' share of the variance; Satterthwaite's plain estimate does not at few runs."""
    shares = np.linspace(0.0, 1.0, 41)
    ours = [_exact_level(runs, share, lambda a, b: verdicts.reference_freedom(a, b, runs)) for share in shares]
    assert max(ours) <= verdicts.ALPHA + 1e-4, max(ours)
    plain = max(_exact_level(runs, share, lambda a, b: (a + b) ** 2 / (a ** 2 / (runs - 1))) for share in shares[1:])
    if runs <= 5:
        assert plain > verdicts.ALPHA + 0.005, plain          # 7.8 % at 3 runs, 5.8 % at 5


def test_the_reference_test_has_more_power_than_the_runs_alone_allow():
    """At an effect of one runs' sd (0.005, the committed reports' middle), 5 runs: the rule confirms the claim
    about twice as often as the t-test with runs - 1 degrees of freedom it replaced (0.11 in the same simulation)."""
    rates = verdicts.simulate_reference_claims(5, effect=0.005, trials=REFERENCE_TRIALS, run_sd=0.005, seed=1)
    assert rates['confirmed'] > 0.18 and rates['refuted'] == 0.0, rates


def test_a_decisive_test_whose_statistic_points_the_other_way_leaves_the_claim_unresolved():
    """The audit's example: 54 runs 0.005 below the reference and 6 runs 0.5 above it. The IQM's interval lies
    below 0, the mean difference (+0.046) is significant (p 0.025) above it: not *refuted*, *unresolved*."""
    from mate.benchmark.experiments import Claim

    rng = np.random.default_rng(4)
    reference = rng.normal(0.5, 0.05, size=320)
    offsets = np.r_[np.full(54, -0.005), np.full(6, 0.5)]
    played = reference + offsets[:, None] + rng.normal(scale=1e-4, size=(60, 320))
    claim = Claim('A beats the greedy team', 'A', 'greedy')
    row = verdicts.decide([verdicts.weigh(claim, 'task', {'A': played.mean(axis=1)}, {'greedy': reference.mean()},
                                          {'A': played}, {'greedy': reference}, reps=2000)])[0]
    assert row['high'] < 0 < row['mean'] and row['p_holm'] < verdicts.ALPHA
    assert row['mean'] == pytest.approx(0.0455, abs=1e-3) and row['p'] == pytest.approx(0.025, abs=2e-3)
    assert row['verdict'] == 'unresolved' and 'opposite sides of 0' in row['reason']
    agreeing = verdicts.decide([verdicts.weigh(claim, 'task', {'A': played.mean(axis=1)}, {'greedy': reference.mean()},
                                               {'A': played[:54]}, {'greedy': reference}, reps=2000)])[0]
    assert agreeing['verdict'] == 'refuted' and 'reason' not in agreeing        # the 54 alone: the same side


def test_the_random_split_p_value_is_never_zero():
    """Beyond `ENUMERATION_LIMIT` splits the p-value is (1 + k) / (1 + N): 15 runs above 15 others (exact p 2 /
    C(30, 15), 1.3e-8) give 1 / 200,001, not 0; on overlapping groups it estimates scipy's exact p."""
    from scipy.stats import mannwhitneyu

    assert math.comb(30, 15) > verdicts.ENUMERATION_LIMIT
    assert verdicts.mann_whitney_p(np.arange(15) + 100.0, np.arange(15)) == 1 / (1 + verdicts.ENUMERATION_LIMIT)
    rng = np.random.default_rng(5)
    x, y = rng.normal(size=10), rng.normal(size=11) + 0.6
    exact = mannwhitneyu(x, y, method='exact').pvalue
    error = math.sqrt(exact * (1 - exact) / verdicts.ENUMERATION_LIMIT)
    assert abs(verdicts.mann_whitney_p(x, y) - exact) < 4 * error + 1e-5


def test_the_exact_test_is_scipys_and_3_vs_3_is_never_decisive():
    from scipy.stats import mannwhitneyu

    rng = np.random.default_rng(0)
    for n, m in ((3, 3), (4, 6), (5, 5), (8, 7)):
        x, y = rng.normal(size=n), rng.normal(size=m) + 1.0
        assert verdicts.mann_whitney_p(x, y) == pytest.approx(mannwhitneyu(x, y, method='exact').pvalue)
    assert verdicts.mann_whitney_p([1, 2, 3], [4, 5, 6]) == pytest.approx(0.1)    # the smallest p at 3 vs 3
    assert verdicts.mann_whitney_p([1, 2, 3, 4, 5], [6, 7, 8, 9, 10]) == pytest.approx(2 / 252)
    assert verdicts.runs_for_a_decisive_verdict() == 4
    assert verdicts.mann_whitney_p([1, 1, 1], [1, 1, 1]) == 1.0                    # ties: no evidence


def test_holm_adjusts_step_down():
    assert verdicts.holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert verdicts.holm([0.5]) == [0.5]


def test_a_real_difference_to_the_reference_is_found_and_its_noise_counts():
    rng = np.random.default_rng(1)
    difficulty = rng.normal(size=200)
    reference = difficulty + rng.normal(scale=0.3, size=200)
    better = difficulty + 0.5 + rng.normal(scale=0.3, size=(5, 200))
    point, low, high = verdicts.paired_reference_interval(better, reference, reps=2000)
    assert 0.3 < low < high < 0.7 and low - 0.05 < point < high + 0.05
    assert verdicts.reference_p(better, reference) < 1e-3
    with pytest.raises(ValueError, match='share their episodes'):
        verdicts.reference_p(better, reference[:10])


def test_equivalence_needs_a_margin_and_evidence():
    rng = np.random.default_rng(2)
    x, y = rng.normal(0.5, 0.01, size=10), rng.normal(0.5, 0.01, size=10)
    assert verdicts.equivalence_p(x, y, margin=0.05) < verdicts.ALPHA
    assert verdicts.equivalence_p(x[:3], y[:3] + 0.04, margin=0.05) > verdicts.ALPHA
    with pytest.raises(ValueError, match='margin must be positive'):
        verdicts.equivalence_p(x, y, margin=0)


def test_an_agreement_claim_is_equivalent_only_within_its_declared_margin():
    from mate.benchmark.experiments import Claim

    rng = np.random.default_rng(3)
    scores = {'A': rng.normal(0.5, 0.01, size=8), 'B': rng.normal(0.5, 0.01, size=8)}

    def verdict(claim):
        return verdicts.decide([verdicts.weigh(claim, 'task', scores, {}, {}, {}, reps=500)])[0]

    assert verdict(Claim('A and B agree', 'A', 'B', kind='agree', margin=0.05))['verdict'] == 'equivalent'
    row = verdict(Claim('A and B agree', 'A', 'B', kind='agree'))
    assert row['verdict'] == 'no difference detected' and row['test'] == 'exact Mann-Whitney'
    assert verdict(Claim('A and B agree', 'A', 'B', kind='agree', margin=1e-4))['verdict'] == 'not shown equivalent'
    with pytest.raises(ValueError, match='margin'):
        Claim('A beats B', 'A', 'B', margin=0.05)
    with pytest.raises(ValueError, match='margin'):
        Claim('A and B agree', 'A', 'B', kind='agree', margin=0.0)


def test_holm_over_a_reports_claims_can_take_a_verdict_back():
    """One claim alone at p = 2/70 (4 runs a side, no overlap) is confirmed; beside a second claim it is not."""
    from mate.benchmark.experiments import Claim

    scores = {'A': np.array([0.5, 0.6, 0.7, 0.8]), 'B': np.array([0.1, 0.2, 0.3, 0.4]),
              'C': np.array([0.1, 0.5, 0.3, 0.6])}
    claims = [Claim('A beats B', 'A', 'B'), Claim('C beats B', 'C', 'B')]
    alone = verdicts.decide([verdicts.weigh(claims[0], 'task', scores, {}, {}, {}, reps=500)])
    both = verdicts.decide([verdicts.weigh(claim, 'task', scores, {}, {}, {}, reps=500) for claim in claims])
    assert alone[0]['verdict'] == 'confirmed' and alone[0]['p'] == pytest.approx(2 / 70)
    assert both[0]['verdict'] == 'unresolved' and both[0]['p_holm'] == pytest.approx(4 / 70)


def _runs_of(task: dict, label: str) -> list[float]:
    entry = task['settings'][label]
    if 'values' in entry:
        return entry['values']
    return entry.get('final_exploitability_fresh_values', entry.get('final_exploitability_values'))


def test_no_committed_report_has_a_decisive_verdict_its_runs_do_not_support():
    """Every confirmed, refuted or differ verdict of docs/results/ holds under an exact two-sided test at 5 % on the
    report's own runs (between settings: the Mann-Whitney test recomputed here from each run's score), after Holm's
    correction over the experiment's claims."""
    from pathlib import Path
    import json

    reports = sorted((Path(__file__).resolve().parents[2] / 'docs' / 'results').glob('*/results.json'))
    decisive = 0
    for path in reports:
        for summary in json.loads(path.read_text()).values():
            claims = summary.get('claims', [])
            assert [claim['p_holm'] for claim in claims if 'p' in claim] == pytest.approx(
                verdicts.holm([claim['p'] for claim in claims if 'p' in claim]))
            for claim in claims:
                if claim['verdict'] not in ('confirmed', 'refuted', 'differ', 'equivalent'):
                    continue
                decisive += 1
                assert claim['p_holm'] < verdicts.ALPHA, (path, claim['text'])
                if claim['statistic'] == 'probability of improvement':
                    task = summary['tasks'][claim['task']]
                    p = verdicts.mann_whitney_p(_runs_of(task, claim['better']), _runs_of(task, claim['worse']))
                    assert p == pytest.approx(claim['p']) and p < verdicts.ALPHA, (path, claim['text'])
    assert decisive > 10


def test_every_verdict_that_is_not_decisive_says_why_and_a_decisive_one_needs_no_reason():
    """`decide`'s `reason`, in the report's claims table: 3 runs a side can never reach 5 %; an interval on one side
    whose test is not significant after Holm's correction (raw p named when it alone was); an interval across 1/2;
    an agreement not shown within its margin. A confirmed claim has none."""
    from mate.benchmark.experiments import Claim

    def decided(claims, scores):
        return verdicts.decide([verdicts.weigh(claim, 'task', scores, {}, {}, {}, reps=500) for claim in claims])

    apart = {'A': np.array([0.6, 0.7, 0.8]), 'B': np.array([0.1, 0.2, 0.3])}
    row, = decided([Claim('A beats B', 'A', 'B')], apart)
    assert row['verdict'] == 'unresolved' and row['runs'] == {'A': 3, 'B': 3}
    assert row['reason'] == "3 runs a side cannot be decisive: the exact test's p is at least 0.10"
    assert verdicts.smallest_mann_whitney_p(3, 3) == pytest.approx(0.1)
    assert verdicts.smallest_mann_whitney_p(3, 4) == pytest.approx(2 / 35) and 2 / 35 > verdicts.ALPHA
    row, = decided([Claim('A beats B', 'A', 'B')], {'A': apart['A'], 'B': np.r_[apart['B'], 0.0]})
    assert row['reason'].startswith('3 and 4 runs cannot be decisive')

    five = {'A': np.arange(5) + 10.0, 'B': np.arange(5) + 0.0, 'C': np.r_[0.5, 1.5, 2.5, 12.0, 13.0]}
    alone, = decided([Claim('A beats B', 'A', 'B')], five)
    assert alone['verdict'] == 'confirmed' and 'reason' not in alone
    crowded = decided([Claim('A beats B', 'A', 'B')] * 7, five)       # 7 x 0.0079 = 0.056 after Holm
    assert {row['verdict'] for row in crowded} == {'unresolved'}
    assert crowded[0]['reason'] == ("the interval is above 1/2 but the test's p, 0.0079, is 0.056 after Holm's "
                                    'correction over 7 claims, not below 0.05')
    across, = decided([Claim('C beats B', 'C', 'B')], five)
    assert across['low'] < 0.5 < across['high'] and across['verdict'] == 'unresolved'
    assert across['reason'].startswith('the interval includes 1/2 and the test\'s p after Holm, ')
    agree, = decided([Claim('A and B agree', 'A', 'B', kind='agree', margin=0.5)], five)
    assert agree['verdict'] == 'not shown equivalent' and agree['reason'].startswith("the equivalence test's p")
