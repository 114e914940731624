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


def test_the_example_imports_only_the_public_api():
    tree = ast.parse(EXAMPLE.read_text())
    modules = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    modules |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert {m for m in modules if m and m.startswith('mate')} == {'mate'}
    used = {node.attr for node in ast.walk(tree)
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == 'mate'}
    assert used <= {'make_team_vec', 'score_policy'}, used
    assert len(EXAMPLE.read_text().splitlines()) <= 300


def test_the_example_trains_and_scores_at_a_tiny_budget(tmp_path):
    pytest.importorskip('torch', reason='needs the train extra')
    run = tmp_path / 'run'
    result = subprocess.run([sys.executable, str(EXAMPLE), '--steps', '128', '--num-envs', '2', '--rollout', '16',
                             '--horizon', '20', '--eval-episodes', '1', '--run-dir', str(run)],
                            cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    assert 'iterations of 16 x 2 decisions (128 decision steps)' in result.stdout
    score_line = result.stdout.splitlines()[-2]
    assert score_line.split()[0] == 'PPO' and 'greedy' in score_line and 'random' in score_line
    absolute = json.loads((run / 'absolute.json').read_text())
    assert absolute['metric'] == 'coverage_rate' and len(absolute['episodes']) == 10
    assert f"PPO {absolute['mean']:.3f}" in score_line
