"""The golden runs (tests/learn/golden.py): every trainer variant, rerun from its command line, reproduces the
log rows and final weights recorded in tests/data/golden/NAME.json.

On the machine a recording was made on (its fingerprint) or with MATE_GOLDEN_EXACT=1 everything must be bitwise
equal (log values and the sha256 of every network's tensors); elsewhere within `golden.ACROSS_MACHINES`, and for
the forking Q-learners the counters only (`golden.judge`). A change that is meant is re-recorded with
`python tests/learn/golden.py --record NAME`.
"""

from __future__ import annotations

import copy
import os

import pytest

from . import golden

EXACT = os.environ.get('MATE_GOLDEN_EXACT', '').strip() not in ('', '0', 'false')


def compare(name: str, expected: dict, found: dict, exact: bool = False) -> golden.Comparison:
    """Bitwise with `exact`, else as across machines."""
    return golden.Comparison(name, expected, found, golden.BITWISE if exact else golden.ACROSS_MACHINES)


def failure_message(name: str, comparison: golden.Comparison, how: str = '') -> str:
    return f'{comparison.report()}\n{f"(compared {how})" + chr(10) if how else ""}{golden.rerecord_hint(name)}'


@pytest.fixture(scope='module', autouse=True)
def one_torch_thread():
    torch = pytest.importorskip('torch')
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


@pytest.mark.slow
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
    comparison, how = golden.judge(name, expected, found, exact=EXACT)
    assert not comparison.problems, failure_message(name, comparison, how)


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
    log['rows'][1][column] = before * (1 + 1e-2)
    comparison = compare('mappo-camera', recorded, found)
    assert not comparison.exact and golden.ACROSS_MACHINES.rows < comparison.max_relative <= 1e-2 * (1 + 1e-9)
    message = failure_message('mappo-camera', comparison)
    assert "golden run mappo-camera: progress.csv row 1 (iteration 2) column 'value_loss'" in message
    assert repr(before) in message and repr(before * (1 + 1e-2)) in message
    assert 'python tests/learn/golden.py --record mappo-camera' in message


def test_a_difference_within_the_tolerance_passes_unless_exact(recorded):
    found = copy.deepcopy(recorded)
    found['logs']['progress.csv']['rows'][0][-2] += 1e-9          # clip_fraction 0.0 -> 1e-9: atol 1e-7
    tensor = found['weights']['final.pt']['actor']['tensors'][0]
    tensor[3] += 1e-4 * tensor[4]                                    # a sum off by 1e-4 of the sum of |x|
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


# ---------------------------------------------------------------- which comparison, where

def test_a_recording_of_this_machine_is_compared_bitwise_and_another_within_the_tolerance(recorded):
    here = golden.fingerprint()
    assert here['isa'] == [flag for flag in golden.ISA_FLAGS if flag in here['isa']] and here['torch']
    record = dict(recorded, fingerprint=here)
    assert golden.tolerance_for('mappo-camera', record, here)[0] is golden.BITWISE
    elsewhere = dict(here, vendor='OtherVendor', model='OtherModel')   # (a real model number may be this machine's)
    tolerance, how = golden.tolerance_for('mappo-camera', dict(recorded, fingerprint=elsewhere), here)
    assert tolerance is golden.ACROSS_MACHINES and 'across machines' in how
    assert "vendor 'OtherVendor'" in how and "model 'OtherModel'" in how
    legacy = {key: value for key, value in recorded.items() if key != 'fingerprint'}
    assert 'no fingerprint was kept' in golden.tolerance_for('mappo-camera', legacy, here)[1]
    assert golden.tolerance_for('mappo-camera', legacy, here, exact=True)[0] is golden.BITWISE
    changed_pins = dict(here, kernels=dict(here['kernels'], ATEN_CPU_CAPABILITY='default'))
    assert golden.tolerance_for('mappo-camera', dict(recorded, fingerprint=changed_pins), here)[0] \
        is golden.ACROSS_MACHINES


def test_the_cross_cpu_spread_measured_on_an_intel_xeon_passes_across_machines(recorded):
    """The spread of issue 66 (AMD EPYC recordings rerun on an Intel Xeon): policy loss 3.9e-5 and a tensor sum
    1.8e-5 apart pass; ten times the tolerance fails."""
    found = copy.deepcopy(recorded)
    log = found['logs']['progress.csv']
    column = log['columns'].index('policy_loss')
    log['rows'][2][column] *= 1 + 3.94e-5
    tensor = found['weights']['final.pt']['actor']['tensors'][1]
    tensor[3] += 1.84e-5 * tensor[4]
    comparison = golden.Comparison('mappo-camera', recorded, found, golden.ACROSS_MACHINES)
    assert not comparison.exact and not comparison.problems
    log['rows'][1][column] += 10 * golden.ACROSS_MACHINES.rows * max(abs(v[column]) for v in log['rows'])
    assert golden.Comparison('mappo-camera', recorded, found, golden.ACROSS_MACHINES).problems


def test_a_forking_variant_is_compared_on_its_counters_only_across_machines():
    expected = golden.load_record('qmix-camera')
    found = copy.deepcopy(expected)
    log = found['logs']['progress.csv']
    log['rows'][1][log['columns'].index('loss')] *= 1.5               # another run after a greedy action flipped
    next(iter(found['weights']['final.pt'].values()))['tensors'][0][3] += 1.0
    assert 'qmix-camera' in golden.FORKING
    across = golden.Comparison('qmix-camera', expected, found, golden.ACROSS_MACHINES, forking=True)
    assert not across.problems and across.skipped > 0
    assert golden.Comparison('qmix-camera', expected, found, golden.BITWISE).problems
    log['rows'][1][log['columns'].index('env_steps')] += 1               # a counter: compared everywhere
    assert golden.Comparison('qmix-camera', expected, found, golden.ACROSS_MACHINES, forking=True).problems


def test_every_forking_or_bookkeeping_name_exists():
    assert golden.FORKING <= set(golden.VARIANTS)
    columns = {c for name in golden.FORKING for c in golden.load_record(name)['logs']['progress.csv']['columns']}
    assert golden.BOOKKEEPING <= columns | {'lr'}


# ---------------------------------------------------------------- a deliberate mistake fails under any kernels

def _golden_spread():
    """tests/tools/golden_spread.py as a module (its mutations and kernel settings)."""
    import sys

    sys.path.insert(0, str(golden.ROOT / 'tests' / 'tools'))
    import golden_spread

    return golden_spread


def _mutated_run(mutation: str, folder, variables: dict | None = None) -> dict:
    """mappo-target rerun with `mutation` (tests/tools/golden_spread.py), in this process or, with kernel
    `variables`, in a child process that runs the kernels they choose."""
    import json
    import subprocess
    import sys

    if variables is None:
        with _golden_spread().mutated(mutation):
            return golden.run_variant('mappo-target', folder)
    out = folder / 'recording'
    result = subprocess.run([sys.executable, str(golden.ROOT / 'tests' / 'tools' / 'golden_spread.py'), 'inner',
                             str(out), '--names', 'mappo-target', '--mutation', mutation],
                            env=golden.pinned_environment(variables), capture_output=True, text=True, timeout=600,
                            cwd=golden.ROOT)
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads((out / 'mappo-target.json').read_text())


@pytest.mark.slow
@pytest.mark.parametrize('mutation', ['gae-lambda', 'entropy-sign', 'advantage-scale'])
def test_a_mutation_of_an_advantage_or_a_loss_fails_across_machines(mutation, tmp_path):
    expected = golden.load_record('mappo-target')
    comparison = golden.Comparison('mappo-target', expected, _mutated_run(mutation, tmp_path / 'run'),
                                   golden.ACROSS_MACHINES)
    assert comparison.problems, f'{mutation}: within the across-machines tolerance'


@pytest.mark.slow
@pytest.mark.parametrize('pin', ['aten-default', 'mkl-instructions-avx2'])
def test_other_kernels_pass_across_machines_and_a_mutation_under_them_fails(pin, tmp_path):
    """One machine as another CPU: ATen's portable kernels, or MKL's AVX2 branch without its reproducibility mode.
    The rerun differs in its last bits (not bitwise equal) yet passes across machines; the same kernels with a
    mutated advantage fail."""
    pins = _golden_spread().PINS
    expected = golden.load_record('mappo-target')
    here = golden.run_variant('mappo-target', tmp_path / 'here')                  # the suite's kernels
    other = _mutated_run('none', tmp_path / 'other', pins[pin])
    assert not golden.Comparison('mappo-target', here, other, golden.BITWISE).exact, f'{pin}: the same kernels'
    assert not golden.Comparison('mappo-target', expected, other, golden.ACROSS_MACHINES).problems
    mutated = _mutated_run('gae-lambda', tmp_path / 'mutated', pins[pin])
    assert golden.Comparison('mappo-target', expected, mutated, golden.ACROSS_MACHINES).problems
