"""The verdict rule's error rate (`mate.benchmark.verdicts`): on null data a decisive verdict comes at most 5 % of the
time (within simulation error) at 3, 5 and 10 runs; the exact test agrees with scipy's; Holm, TOST and the paired
reference interval behave as documented."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mate.benchmark import verdicts

TRIALS = 600
SLACK = 2 * math.sqrt(verdicts.ALPHA * (1 - verdicts.ALPHA) / TRIALS)
"""Two standard errors of a simulated rate of 5 % over TRIALS null experiments."""


@pytest.mark.parametrize('runs', [3, 5, 10])
@pytest.mark.parametrize('kind', ['settings', 'reference'])
def test_null_data_gives_a_decisive_verdict_at_most_five_percent_of_the_time(runs, kind):
    rate = verdicts.simulate_false_decisive_rate(runs, trials=TRIALS, kind=kind, reps=500, seed=runs)
    assert rate <= verdicts.ALPHA + SLACK, rate


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
