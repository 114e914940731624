"""`examples/own_policy_ppo.py`, the CleanRL-style file of "Bring your own algorithm": it runs at a tiny budget,
prints its held-out score beside the references', keeps the run files, and uses mate's public API only."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / 'examples' / 'own_policy_ppo.py'


def test_the_custom_experiment_can_decide_its_claims():
    """Built, `examples/custom_experiment.py` warns of no claim its seeds cannot decide (5 runs a side: Holm's
    correction over its three claims)."""
    pytest.importorskip('torch', reason='needs the train extra')
    import warnings

    from mate.benchmark.user import load_experiment

    with warnings.catch_warnings():
        warnings.simplefilter('error')
        experiment = load_experiment(EXAMPLE.parent / 'custom_experiment.py')
    assert experiment.seeds == 5 and [r if isinstance(r, str) else r.label for r in experiment.references][-1] == \
        'sweeping cameras'


def test_the_example_imports_only_the_public_api():
    tree = ast.parse(EXAMPLE.read_text())
    modules = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    modules |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert {m for m in modules if m and m.startswith('mate')} == {'mate'}
    used = {node.attr for node in ast.walk(tree)
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == 'mate'}
    assert used <= {'make_team_vec', 'score_policy'}, used
    assert len(EXAMPLE.read_text().splitlines()) <= 300


@pytest.mark.slow
def test_the_example_trains_and_scores_at_a_tiny_budget(tmp_path):
    pytest.importorskip('torch', reason='needs the train extra')
    run, cache = tmp_path / 'run', tmp_path / 'cache'
    result = subprocess.run([sys.executable, str(EXAMPLE), '--steps', '128', '--num-envs', '2', '--rollout', '16',
                             '--horizon', '20', '--eval-episodes', '1', '--run-dir', str(run),
                             '--reference-cache', str(cache)],
                            cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    assert len(list(cache.glob('*.json'))) == 6      # 3 references x (evaluation, absolute), for the next run
    assert any(line.startswith('trained in ') and ' s, scored in ' in line for line in result.stdout.splitlines())
    assert 'not writable' not in result.stderr, result.stderr     # torch's warning about a read-only array
    assert 'iterations of 16 x 2 decisions (128 decision steps)' in result.stdout
    score_line = result.stdout.splitlines()[-2]
    assert score_line.split()[0] == 'PPO' and 'greedy' in score_line and 'random' in score_line
    absolute = json.loads((run / 'absolute.json').read_text())
    assert absolute['metric'] == 'coverage_rate' and len(absolute['episodes']) == 10
    assert f"PPO {absolute['mean']:.3f}" in score_line


@pytest.mark.slow
def test_the_custom_experiment_runs_from_another_folder_and_reports(tmp_path):
    """`examples/custom_experiment.py` (the example's PPO beside mate's MAPPO) copied outside the repository, run by
    `mate benchmark run FILE` at one seed and a tiny budget, and reported."""
    pytest.importorskip('torch', reason='needs the train extra')
    import shutil

    for name in ('custom_experiment.py', 'own_policy_ppo.py'):
        shutil.copy(EXAMPLE.parent / name, tmp_path / name)
    run = [sys.executable, '-m', 'mate', 'benchmark']
    result = subprocess.run([*run, 'run', 'custom_experiment.py', '--out', 'out', '--seeds', '0', '--steps', '200'],
                            cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stdout + result.stderr
    result = subprocess.run([*run, 'report', 'out', '--out', 'report', '--reps', '200'], cwd=tmp_path,
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads((tmp_path / 'report' / 'results.json').read_text())['custom-ppo-vs-mappo']
    assert set(summary['tasks']['MATE-4v8-9 cameras']['settings']) == {'my PPO', 'MAPPO'}
    assert list(summary['tasks']['MATE-4v8-9 cameras']['references']) == ['random', 'greedy', 'upper-bound',
                                                                          'sweeping cameras']
    claims = {claim['text']: claim for claim in summary['claims']}
    against = claims['my PPO cameras cover more than the sweeping cameras']      # one seed: weighed, no verdict yet
    assert against['worse'] == 'sweeping cameras' and against['verdict'].startswith('too few runs (1;')
    assert (tmp_path / 'report' / 'marl_eval.json').exists() and (tmp_path / 'report' / 'results.md').exists()
