"""Greedy vs greedy, batched, over seeds 0..299 of MATE-4v8-9 scores like the Python agents.

The reference (tests/data/greedy-4v8-9-python-300.json) holds the Python agents' coverage per seed
(`tests/tools/greedy_reference.py`: `mate.evaluation.evaluate.play_episode`, agents `Cls(seed=s).spawn(N)`). The batched
teams replay those agents draw for draw, so the means should agree to rounding; the test asks for the
looser 3 standard errors of the reference, which also holds for any change that keeps the statistics.
(The original MATE: 0.612 +- 0.048 over seeds 0..19, reference/groundtruth.md.)
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mate.teams import GreedyTeam, play_batch

REFERENCE = Path(__file__).resolve().parents[1] / 'data' / 'greedy-4v8-9-python-300.json'


@pytest.mark.slow
def test_batched_greedy_covers_like_the_python_agents_over_300_seeds():
    reference = json.loads(REFERENCE.read_text())
    seeds = reference['seeds']
    assert seeds == list(range(len(seeds))) and reference['preset'] == 'MATE-4v8-9'
    batch, _ = play_batch(reference['preset'], lambda b, counts: GreedyTeam('camera', b, counts, seed=0),
                          lambda b, counts: GreedyTeam('target', b, counts, seed=0), len(seeds), seed=0,
                          max_episode_steps=reference['max_steps'])
    coverage = np.array([episode.coverage_rate for episode in batch])
    difference = (coverage.mean() - reference['mean']) / reference['standard_error']
    print(f'batched {coverage.mean():.4f}, Python {reference["mean"]:.4f} +- {reference["standard_error"]:.4f}: '
          f'{difference:+.2f} standard errors; seeds with the same coverage: '
          f'{int(np.isclose(coverage, reference["coverage_rate"], rtol=0, atol=1e-12).sum())} of {len(seeds)}')
    assert abs(difference) < 3.0
