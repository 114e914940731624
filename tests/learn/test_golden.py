"""The golden runs (tests/learn/golden.py): every trainer variant, rerun from its command line, reproduces the
log rows and final weights recorded in tests/data/golden/NAME.json.

Log values must agree within rtol 1e-5 / atol 1e-7 and each tensor's sum and sum of absolute values within
rtol 1e-5 / atol 1e-6 (the sum relative to the sum of absolute values): another CPU family may sum in another
order in BLAS. With MATE_GOLDEN_EXACT=1 everything must be bitwise equal (log values and the sha256 of every
network's tensors). A change that is meant is re-recorded with `python tests/learn/golden.py --record NAME`.
"""

from __future__ import annotations

import copy
import os

import pytest

from . import golden

EXACT = os.environ.get('MATE_GOLDEN_EXACT', '').strip() not in ('', '0', 'false')


def compare(name: str, expected: dict, found: dict, exact: bool = False) -> golden.Comparison:
    if exact:
        return golden.Comparison(name, expected, found, rtol=0.0, atol=0.0, tensor_rtol=0.0, tensor_atol=0.0,
                                 exact_digests=True)
    return golden.Comparison(name, expected, found)


def failure_message(name: str, comparison: golden.Comparison) -> str:
    return f'{comparison.report()}\n{golden.rerecord_hint(name)}'


@pytest.fixture(scope='module', autouse=True)
def one_torch_thread():
    torch = pytest.importorskip('torch')
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


@pytest.mark.parametrize('name', list(golden.VARIANTS))
def test_golden_run_reproduces(name, tmp_path):
    path = golden.record_path(name)
    assert path.exists(), f'golden run {name}: no recording at {path}; record it with ' \
                          f'`python tests/learn/golden.py --record {name}`'
    expected = golden.load_record(name)
    assert expected['command'] == ['mate', *golden.VARIANTS[name]], (
        f'golden run {name}: its command line changed since the recording ({expected["command"]}); '
        + golden.rerecord_hint(name))
    found = golden.run_variant(name, tmp_path / 'run')
    comparison = compare(name, expected, found, exact=EXACT)
    assert not comparison.problems, failure_message(name, comparison)


# ---------------------------------------------------------------- the comparison itself

@pytest.fixture(scope='module')
def recorded():
    return golden.load_record('mappo-camera')


def test_recordings_hold_no_timing_column():
    for name in golden.VARIANTS:
        record = golden.load_record(name)
        for file, log in record['logs'].items():
            assert not set(log['columns']) & golden.TIMING_COLUMNS, (name, file)
            assert log['rows'] and all(len(row) == len(log['columns']) for row in log['rows']), (name, file)
        assert record['weights'] and all(record['weights'].values()), name
        for networks in record['weights'].values():
            assert not [entry for entry in networks if 'optimizer' in entry], name


def test_an_identical_result_passes_exactly(recorded):
    comparison = compare('mappo-camera', recorded, copy.deepcopy(recorded), exact=True)
    assert comparison.exact and not comparison.problems and comparison.max_relative == 0.0


def test_a_changed_log_value_is_reported_with_its_row_and_column(recorded):
    found = copy.deepcopy(recorded)
    log = found['logs']['progress.csv']
    column = log['columns'].index('value_loss')
    before = log['rows'][1][column]
    log['rows'][1][column] = before * (1 + 1e-3)
    comparison = compare('mappo-camera', recorded, found)
    assert not comparison.exact and comparison.max_relative == pytest.approx(1e-3, rel=1e-6)
    message = failure_message('mappo-camera', comparison)
    assert "golden run mappo-camera: progress.csv row 1 (iteration 2) column 'value_loss'" in message
    assert repr(before) in message and repr(before * (1 + 1e-3)) in message
    assert 'python tests/learn/golden.py --record mappo-camera' in message


def test_a_difference_within_the_tolerance_passes_unless_exact(recorded):
    found = copy.deepcopy(recorded)
    found['logs']['progress.csv']['rows'][0][-2] += 1e-9          # clip_fraction 0.0 -> 1e-9: atol 1e-7
    tensor = found['weights']['final.pt']['actor']['tensors'][0]
    tensor[3] += 1e-7 * tensor[4]                                    # a sum off by 1e-7 of the sum of |x|
    assert not compare('mappo-camera', recorded, found).problems
    strict = compare('mappo-camera', recorded, found, exact=True)
    assert len(strict.problems) == 2 and not strict.exact


def test_changed_weights_are_reported_with_the_tensor(recorded):
    found = copy.deepcopy(recorded)
    name, _, _, total, absolute = found['weights']['final.pt']['critic']['tensors'][2]
    found['weights']['final.pt']['critic']['tensors'][2][4] = absolute * 1.01
    found['weights']['final.pt']['critic']['sha256'] = '0' * 64
    message = failure_message('mappo-camera', compare('mappo-camera', recorded, found))
    assert f"golden run mappo-camera: final.pt critic tensor {name!r} sum of |x|: recorded {absolute!r}" in message
    assert 'sha256' not in message                                   # digests: only with MATE_GOLDEN_EXACT=1
    exact = failure_message('mappo-camera', compare('mappo-camera', recorded, found, exact=True))
    assert 'final.pt critic: sha256 of the tensors differs' in exact


def test_a_digest_alone_fails_only_the_exact_comparison(recorded):
    found = copy.deepcopy(recorded)
    found['weights']['final.pt']['value_norm']['sha256'] = 'f' * 64
    assert not compare('mappo-camera', recorded, found).problems
    assert compare('mappo-camera', recorded, found).exact is False
    assert 'value_norm: sha256' in compare('mappo-camera', recorded, found, exact=True).report()


def test_missing_rows_columns_and_entries_are_reported(recorded):
    found = copy.deepcopy(recorded)
    log = found['logs']['progress.csv']
    del log['rows'][-1]
    column = log['columns'].index('entropy')
    del log['columns'][column]
    for row in log['rows']:
        del row[column]
    del found['weights']['final.pt']['value_norm']
    report = compare('mappo-camera', recorded, found).report()
    assert '3 rows recorded, 2 now' in report
    assert "missing ['entropy']" in report
    assert "network entries differ: recorded ['actor', 'critic', 'value_norm'], now ['actor', 'critic']" in report


def test_a_changed_psro_state_is_reported():
    expected = golden.load_record('psro')
    found = copy.deepcopy(expected)
    found['state']['iterations'][1]['camera_strategy'][0] += 0.5
    found['state']['pools']['camera'][1] = 'players/other.pt'
    report = compare('psro', expected, found).report()
    assert 'state.iterations[1].camera_strategy[0]: recorded' in report
    assert "state.pools.camera[1]: recorded 'players/camera-1.pt', now 'players/other.pt'" in report
