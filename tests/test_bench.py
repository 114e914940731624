"""`mate bench`: the measurement plan, best-of-rounds reporting and argument errors (no speed asserted)."""

from __future__ import annotations

import json

import pytest

from mate.cli import main as cli
from mate.tools import bench


def test_plan_covers_single_env_batches_float32_and_the_vector_env():
    results = bench.run(['MATE-2v4-9'], batch_sizes=(1, 1024), seconds=0.05)
    kinds = [(r['kind'], r['batch_size'], r['dtype']) for r in results]
    assert kinds == [('single env', 1, 'float64'), ('README loop', 1, 'float64'), ('batched core', 1, 'float64'),
                     ('batched core', 1024, 'float64'), ('batched core', 1024, 'float32'),
                     ('vector env', 1024, 'float64'), ('vector env', 1024, 'float32')]
    for r in results:
        assert r['steps'] > 0 and r['env_steps_per_second'] == pytest.approx(r['steps'] / r['seconds'])
        assert r['speedup_vs_original'] is None  # no recorded speed of the original for this preset
        assert 'rounds' not in r
        assert r['speedup_vs_single_env'] == pytest.approx(r['env_steps_per_second']
                                                           / results[0]['env_steps_per_second'])
    assert results[0]['speedup_vs_single_env'] == 1.0


def test_repeat_keeps_the_best_round_and_the_median():
    (result,) = bench.run(['MATE-4v8-9'], batch_sizes=(64,), seconds=0.05, float32=False, repeat=3)[2:]
    assert len(result['rounds']) == 3
    assert result['env_steps_per_second'] == max(result['rounds'])
    assert min(result['rounds']) <= result['median_env_steps_per_second'] <= max(result['rounds'])
    assert result['speedup_vs_original'] == pytest.approx(result['env_steps_per_second'] / 731)


def test_bad_repeat_is_rejected():
    with pytest.raises(ValueError, match='repeat must be at least 1'):
        bench.run(repeat=0)
    with pytest.raises(SystemExit):
        cli.main(['bench', '--repeat', '0'])


def test_the_command_writes_json(tmp_path, capsys):
    out = tmp_path / 'bench.json'
    assert cli.main(['bench', '--presets', 'MATE-1v1-0', '--batch-sizes', '1', '--seconds', '0.05',
                     '--repeat', '2', '--json', str(out)]) == 0
    data = json.loads(out.read_text())
    assert data['machine']['cpus'] >= 1 and len(data['results']) == 3
    assert data['machine']['processor']  # the CPU's model, so that runs on other machines are told apart
    assert 'best of 2 rounds' in capsys.readouterr().out
