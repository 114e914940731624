"""Golden runs of `mate train` and `mate psro`: one short fixed-seed CPU run per trainer variant, whose log rows
and final weights are kept as test data (tests/data/golden/NAME.json), so that a change of the learning code can
be shown to reproduce them exactly, or said to change them on purpose.

    python tests/learn/golden.py --record [NAMES...]   run the variants, write tests/data/golden/NAME.json
    python tests/learn/golden.py --check [NAMES...]    rerun them; per variant: bitwise equal, or the largest
                                                       relative difference, the first differences and whether
                                                       the suite's comparison (below) passes
    python tests/learn/golden.py --list                the variants and their command lines
    ... --data DIR                                     another folder of recordings: record a baseline in a
                                                       scratch folder before a refactor, check against it after

The runs go through the command line (`mate.cli.main.main(argv)`, in this process), whose flags outlive the
Python API. What is compared (`run_variant`):

* `logs`: every log row of `progress.csv` (and, for PSRO, of each best response's `progress.csv`), without the
  wall-clock columns (`TIMING_COLUMNS`);
* `weights`: per policy file (`final.pt`; PSRO: `players/*.pt`) and per network entry of it (each state dict
  but the optimisers'): the sha256 of its tensors' bytes in state-dict order, and per tensor its name, dtype,
  shape, exact float64 sum and sum of absolute values (`math.fsum`: independent of summation order) for a
  tolerant comparison;
* PSRO `state`: the payoff matrices, pools, per-iteration meta-strategies, camera value and exploitability,
  and the best responses' summaries, without their `seconds`.

Everything runs with one torch thread (`torch.set_num_threads(1)` and `--threads 1`) on the CPU, with
`MATE_REPRODUCIBLE=1` (`mate.tools.reproducible`: MKL and ATen kernels pinned).

How a rerun is judged (`judge`): a recording keeps the `fingerprint` of the machine it was made on (CPU vendor,
family, model and ISA, ATen's capability, Python, torch, numpy and numba, the kernel variables). On a machine with
the same fingerprint, or with `MATE_GOLDEN_EXACT=1`, every number must be bitwise equal (and the weights' digests).
Elsewhere the kernels sum in other orders, so the comparison is `ACROSS_MACHINES`: log values and weight sums within
a tolerance sized by measurement (9 kernel settings and two CPU families part runs by at most 2e-4; deliberate
one-line changes to a loss or an advantage by 4e-3 and more: `tests/tools/golden_spread.py`), and for the
Q-learners, whose greedy actions fork at near ties, the counters only (`FORKING`).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import datetime
import hashlib
import io
import json
import math
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault('MATE_REPRODUCIBLE', '1')   # recorded and checked with kernels pinned (mate.tools.reproducible)
import mate  # noqa: E402,F401  (first: it pins the kernels before anything imports torch)

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / 'tests' / 'data' / 'golden'
RUN_DIR = '{run_dir}'
"""Placeholder of the run directory in a command line (replaced by a fresh folder per run)."""

# ---------------------------------------------------------------------------- the variants

# PPO (cameras: MATE-4v8-9, frame skip 5): 4 envs x 10 decisions per iteration, 3 iterations of 2 epochs x 2
# minibatches; --horizon 40 raw steps = 8 decisions (targets: 80 raw steps, frame skip 10), so episodes end by
# truncation inside the rollouts (bootstrapped from the critic) and the episode columns are filled.
_PPO = ['--seed', '1', '--steps', '120', '--num-envs', '4', '--rollout-length', '10', '--epochs', '2',
        '--minibatches', '2']
# Off-policy (IQL, QMIX, MADDPG): one log row per 5,120 decision steps (not a CLI option) and one at the end.
# 32 envs x 180 decisions = 5,760 decision steps: 2 rows, ~86 updates from step 256 on, hard target copies
# (IQL, QMIX) every 500 steps, replay rings of 4,000 that wrap; --horizon 100 raw steps = 20 decisions (cameras).
_OFF = ['--seed', '1', '--steps', '5760', '--num-envs', '32', '--horizon', '100', '--buffer-size', '4000',
        '--batch-size', '32', '--update-every', '64', '--learning-starts', '256']
_COMMON = ['--threads', '1', '--no-progress', '--fresh', '--run-dir', RUN_DIR]

VARIANTS: dict[str, list[str]] = {
    'mappo-camera': ['train', 'mappo', *_PPO, '--horizon', '40', *_COMMON],
    'ippo-camera': ['train', 'ippo', *_PPO, '--horizon', '40', *_COMMON],
    'mappo-camera-mlp': ['train', 'mappo', '--actor', 'mlp', *_PPO, '--horizon', '40', *_COMMON],
    # --paper: the MLP actor, the adaptive KL penalty (kl_coeff column) and the paper's schedules
    'mappo-camera-paper': ['train', 'mappo', '--paper', *_PPO, '--horizon', '40', *_COMMON],
    'hrl-mappo-camera': ['train', 'mappo', '--hrl', *_PPO, '--horizon', '40', *_COMMON],
    'mappo-camera-lstm': ['train', 'mappo-lstm', '--actor', 'mlp', '--lstm', '16', *_PPO, '--horizon', '40',
                          *_COMMON],
    'mappo-camera-tarmac': ['train', 'tarmac', '--lstm', '16', *_PPO, '--horizon', '40', *_COMMON],
    'mappo-camera-i2c': ['train', 'i2c', '--lstm', '16', '--influence-samples', '4', *_PPO, '--horizon', '40',
                         *_COMMON],
    'mappo-target': ['train', 'mappo', '--team', 'target', *_PPO, '--horizon', '80', *_COMMON],
    'mappo-camera-memory-velocity-difference': ['train', 'mappo', '--memory', '25', '--velocity', '--credit',
                                                'difference', *_PPO, '--horizon', '40', *_COMMON],
    'iql-camera': ['train', 'iql', *_OFF, *_COMMON],
    'hrl-iql-camera': ['train', 'iql', '--hrl', '--selection', 'joint', *_OFF, *_COMMON],
    'qmix-camera': ['train', 'qmix', *_OFF, '--sequence-length', '8', *_COMMON],
    # MADDPG acts uniformly at random for its first 10,000 decision steps (not a CLI option): 10,560 steps
    # (3 rows) end with 17 decisions of the actors plus exploration noise
    'maddpg-target': ['train', 'maddpg', '--team', 'target', *[a if a != '5760' else '10560' for a in _OFF],
                      *_COMMON],
    # one PSRO iteration on MATE-2v4-0: two best responses (HRL-MAPPO cameras with the mixed reward, MAPPO
    # targets; 2 envs x 25 decisions per iteration, 3 iterations each) and the 2 x 2 payoff matrix (2 episodes
    # of 20 raw steps per entry)
    'psro': ['psro', '--iterations', '1', '--br-steps', '150', '--eval-episodes', '2', '--eval-steps', '20',
             '--num-envs', '2', '--workers', '1', '--seed', '1', '--out', RUN_DIR],
}
"""Variant name -> the arguments of `mate.cli.main.main` (RUN_DIR: the run directory)."""

TIMING_COLUMNS = frozenset({'wall_seconds', 'steps_per_second', 'collect_share', 'seconds',
                            'env_steps_per_second'})
"""Wall-clock columns and keys, left out of what is compared."""
PSRO_STATE_KEYS = ('payoff', 'payoff_sem', 'coverage', 'real_coverage', 'pools', 'iterations', 'best_responses')

# ---------------------------------------------------------------------------- running and reading a run


def command_line(name: str, folder) -> list[str]:
    return [str(folder) if arg == RUN_DIR else arg for arg in VARIANTS[name]]


def run_variant(name: str, folder) -> dict:
    """Run variant `name` with its run directory in `folder` (created) and return what is compared:
    {'logs': {file: {'columns', 'rows'}}, 'weights': {file: {entry: {'sha256', 'tensors'}}}[, 'state']}."""
    import torch

    from mate.cli.main import main

    torch.set_num_threads(1)
    folder = Path(folder)
    argv = command_line(name, folder)
    with contextlib.redirect_stdout(io.StringIO()) as out:
        status = main(argv)
    if status != 0:
        raise RuntimeError(f'golden run {name}: `mate {" ".join(argv)}` exited with {status}:\n{out.getvalue()}')
    if VARIANTS[name][0] == 'psro':
        state = json.loads((folder / 'state.json').read_text())
        players = sorted(p for p in (folder / 'players').glob('*.pt'))
        return dict(logs={str(p.relative_to(folder)): read_log(p)
                          for p in sorted((folder / 'players').glob('*/progress.csv'))},
                    weights={str(p.relative_to(folder)): weight_summary(p) for p in players},
                    state=without_timing({key: state[key] for key in PSRO_STATE_KEYS}))
    # the networks of the run's end: its final checkpoint (the algorithm state's `networks`)
    return dict(logs={'progress.csv': read_log(folder / 'progress.csv')},
                weights={'final.pt': weight_summary(folder / 'checkpoint.pt')})


def _value(text: str):
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def read_log(path) -> dict:
    """The rows of a progress.csv without the timing columns: {'columns': [...], 'rows': [[value, ...], ...]}
    (numbers parsed: Python's csv writes floats with repr, so they round-trip exactly)."""
    with open(path, newline='') as f:
        reader = csv.reader(f)
        header = next(reader)
        keep = [i for i, column in enumerate(header) if column not in TIMING_COLUMNS]
        rows = [[_value(row[i]) for i in keep] for row in reader]
    return dict(columns=[header[i] for i in keep], rows=rows)


def _is_state_dict(value) -> bool:
    import torch

    return (isinstance(value, dict) and len(value) > 0 and all(isinstance(v, torch.Tensor) for v in value.values()))


def tensor_bytes(tensor) -> bytes:
    tensor = tensor.detach().cpu().contiguous()
    return tensor.numpy().tobytes()


def weight_summary(path) -> dict:
    """{entry: {'sha256', 'tensors': [[name, dtype, shape, fsum, fsum of abs], ...]}} of every network entry
    (a state dict: a non-empty dict of tensors, the optimisers' excluded) of the torch file `path`."""
    import numpy as np
    import torch

    data = torch.load(path, map_location='cpu', weights_only=True)
    if isinstance(data.get('state'), dict) and 'networks' in data['state']:   # a format-2 run checkpoint
        data = data['state']['networks']
    summary = {}
    for entry, value in data.items():
        if 'optimizer' in entry or not _is_state_dict(value):
            continue
        digest, tensors = hashlib.sha256(), []
        for key, tensor in value.items():
            digest.update(tensor_bytes(tensor))
            values = tensor.detach().cpu().to(torch.float64).numpy().ravel()
            tensors.append([key, str(tensor.dtype).removeprefix('torch.'), list(tensor.shape),
                            math.fsum(values.tolist()), math.fsum(np.abs(values).tolist())])
        summary[entry] = dict(sha256=digest.hexdigest(), tensors=tensors)
    return summary


def without_timing(value):
    if isinstance(value, dict):
        return {k: without_timing(v) for k, v in value.items() if k not in TIMING_COLUMNS}
    if isinstance(value, list):
        return [without_timing(v) for v in value]
    return value


def versions() -> dict:
    import numpy
    import torch

    from mate.tools.bench import machine_facts
    from mate.tools.reproducible import KERNEL_PINS

    return dict(python=platform.python_version(), torch=torch.__version__, numpy=numpy.__version__,
                machine=platform.machine(), processor=machine_facts()['processor'],
                kernels={key: os.environ.get(key) for key in KERNEL_PINS})


# ---------------------------------------------------------------------------- comparison

def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _same(a, b) -> bool:
    """Exactly equal (NaN equal to NaN)."""
    if _number(a) and _number(b):
        return a == b or (math.isnan(a) and math.isnan(b))
    return a == b


def _close(a, b, rtol: float, atol: float, scale: float | None = None) -> bool:
    """|a - b| <= atol + rtol * scale (default |b|); NaN only equal to NaN, infinities only to themselves."""
    if _same(a, b):
        return True
    if not (_number(a) and _number(b)) or any(math.isnan(x) or math.isinf(x) for x in (a, b)):
        return False
    return abs(a - b) <= atol + rtol * (abs(b) if scale is None else scale)


def relative_difference(a, b, scale: float | None = None) -> float:
    if _same(a, b):
        return 0.0
    if not (_number(a) and _number(b)) or any(math.isnan(x) or math.isinf(x) for x in (a, b)):
        return math.inf
    return abs(a - b) / max(abs(b) if scale is None else scale, 1e-300)


# ---------------------------------------------------------------------------- how to compare

KERNEL_VARIABLES = ('MKL_CBWR', 'ATEN_CPU_CAPABILITY', 'MKL_ENABLE_INSTRUCTIONS', 'MKL_DEBUG_CPU_TYPE',
                    'ONEDNN_MAX_CPU_ISA', 'NPY_DISABLE_CPU_FEATURES', 'MATE_REPRODUCIBLE')
"""Environment variables that choose kernels (MKL's branch, ATen's vector width, oneDNN's and numpy's ISA)."""
ISA_FLAGS = ('sse4_2', 'avx', 'avx2', 'fma', 'avx512f', 'avx512_vnni', 'avx512_bf16', 'avx512_fp16', 'avx_vnni',
             'amx_tile')
"""The CPU flags (/proc/cpuinfo) that decide which kernels MKL, oneDNN, ATen and numpy run."""


def _cpuinfo() -> dict:
    try:
        with open('/proc/cpuinfo') as info:
            return {key.strip(): value.strip() for key, value in
                    (line.split(':', 1) for line in info if ':' in line)}
    except OSError:
        return {}


def fingerprint() -> dict:
    """What the last bits of a run depend on besides the code: the CPU (vendor, family, model, the ISA extensions
    that choose kernels, the capability ATen picked), the library versions and the kernel variables in force.
    Two machines with equal fingerprints run the same kernels: a golden run reproduces there bit for bit."""
    import numba
    import numpy
    import torch

    cpu = _cpuinfo()
    flags = set(cpu.get('flags', '').split())
    return dict(vendor=cpu.get('vendor_id', platform.processor()), family=cpu.get('cpu family'),
                model=cpu.get('model'), isa=[flag for flag in ISA_FLAGS if flag in flags],
                aten=torch.backends.cpu.get_cpu_capability(), machine=platform.machine(),
                python=platform.python_version(), torch=torch.__version__, numpy=numpy.__version__,
                numba=numba.__version__, kernels={key: os.environ.get(key) for key in KERNEL_VARIABLES})


def pinned_environment(variables: dict[str, str]) -> dict[str, str]:
    """This process's environment with every `KERNEL_VARIABLES` entry removed, then `MATE_REPRODUCIBLE=0` (so that
    mate pins nothing) and `variables` set: a child process runs the kernels `variables` choose."""
    env = {key: value for key, value in os.environ.items() if key not in KERNEL_VARIABLES}
    return dict(env, MATE_REPRODUCIBLE='0', **variables)


def same_machine(recorded: dict | None, current: dict) -> bool:
    """Whether a recording's fingerprint (None: recorded before fingerprints were kept) is this machine's."""
    return recorded is not None and recorded == current


@dataclasses.dataclass(frozen=True)
class Tolerance:
    """How far a rerun may part from its recording. `rows`: a log value's difference relative to the larger of
    |recorded value| and the root mean square of its column's recorded values (a loss that crosses 0 is judged at
    its column's size); `tensors`: a weight tensor's sum relative to its sum of |x|, and that sum relative to
    itself; `atol`: absolute slack of both (a column that is exactly 0 everywhere)."""

    rows: float
    tensors: float
    atol: float


BITWISE = Tolerance(0.0, 0.0, 0.0)
"""The same machine (or MATE_GOLDEN_EXACT=1): every number bit for bit, and the weights' digests too."""
ACROSS_MACHINES = Tolerance(rows=2e-3, tensors=5e-4, atol=1e-7)
"""Another CPU family, ISA or library build: sized by measurement (docs/contributors/testing.md, "Golden runs on
another machine"): 9 kernel settings of one Intel Xeon and the AMD EPYC recordings part the non-forking variants by
at most 2e-4 in a log value and 3e-5 in a weight sum, while each deliberate one-line change to an advantage or a
loss parts every PPO variant by at least 4e-3 in some log value and 3e-3 in some weight sum."""
FORKING = frozenset({'iql-camera', 'hrl-iql-camera', 'qmix-camera'})
"""Variants whose runs fork on another machine: a greedy argmax (the behaviour policy, double Q-learning's next
action, HRL's selection) flips at a near tie once the Q-values differ in their last bits, and from there the run is
another (measured: 3e-2 apart in the first log row under another ATen or MKL kernel, even with epsilon 1 all run
long). Across machines only their `BOOKKEEPING` columns and the weights' layout are compared."""
BOOKKEEPING = frozenset({'iteration', 'env_steps', 'raw_steps', 'episodes', 'epsilon', 'lr', 'buffer'})
"""Log columns that the schedule and the counters alone decide (no network output reaches them): compared exactly
on every machine."""


def tolerance_for(name: str, record: dict, current: dict | None = None, exact: bool = False) -> tuple[Tolerance, str]:
    """How to compare a rerun of variant `name` with its recording here, and why: bitwise with `exact`
    (MATE_GOLDEN_EXACT=1) or on the machine it was recorded on (`same_machine`), else `ACROSS_MACHINES`."""
    current = fingerprint() if current is None else current
    recorded = record.get('fingerprint')
    if exact:
        return BITWISE, 'bitwise (MATE_GOLDEN_EXACT=1)'
    if same_machine(recorded, current):
        return BITWISE, 'bitwise (recorded on this machine: the same CPU, ISA, libraries and kernel variables)'
    where = (record.get('versions') or {}).get('processor', 'an unknown machine')
    scope = ('the counters only (its greedy actions fork on another machine)' if name in FORKING
             else f'within rtol {ACROSS_MACHINES.rows:g} (log values) / {ACROSS_MACHINES.tensors:g} (weights)')
    differs = 'no fingerprint was kept' if recorded is None else \
        ', '.join(f'{key} {recorded.get(key)!r} -> {current.get(key)!r}' for key in current
                  if recorded.get(key) != current.get(key))
    return ACROSS_MACHINES, f'across machines (recorded on {where}; {differs}): {scope}'


def judge(name: str, expected: dict, found: dict, exact: bool = False) -> tuple['Comparison', str]:
    """Compare a rerun of variant `name` with its recording as `tolerance_for` says; returns the `Comparison` and
    how it was made (for the failure message)."""
    tolerance, how = tolerance_for(name, expected, exact=exact)
    return Comparison(name, expected, found, tolerance, forking=name in FORKING and tolerance != BITWISE), how


def _column_scales(log: dict) -> dict:
    """Column -> the root mean square of its recorded numbers (0 for a column without numbers)."""
    scales = {}
    for i, column in enumerate(log['columns']):
        values = [row[i] for row in log['rows'] if _number(row[i]) and math.isfinite(row[i])]
        scales[column] = math.sqrt(math.fsum(v * v for v in values) / len(values)) if values else 0.0
    return scales


class Comparison:
    """The differences between a recorded result (`expected`) and a rerun (`found`) of one variant.

    `tolerance`: `BITWISE` (every number exactly, and the weights' digests) or another `Tolerance`; `forking`:
    compare only the `BOOKKEEPING` columns and the weights' layout (a variant in `FORKING`, across machines).
    `problems`: messages of the differences beyond the tolerance; `differences`: every difference, within it or
    not; `exact`: whether everything is bitwise equal; `max_relative`: the largest relative difference of any
    compared number (log values relative to their scale, tensor sums relative to their sums of |x|);
    `skipped`: how many numbers were left out (a forking variant's)."""

    def __init__(self, name: str, expected: dict, found: dict, tolerance: Tolerance = BITWISE,
                 forking: bool = False):
        self.name, self.problems, self.differences, self.exact, self.max_relative = name, [], [], True, 0.0
        self.tolerance, self.forking, self.skipped = tolerance, forking, 0
        self._logs(expected.get('logs', {}), found.get('logs', {}))
        self._weights(expected.get('weights', {}), found.get('weights', {}), tolerance == BITWISE)
        if 'state' in expected or 'state' in found:
            self._tree('state', expected.get('state'), found.get('state'))

    def _problem(self, text: str) -> None:
        self.exact = False
        self.problems.append(f'golden run {self.name}: {text}')

    def _number_pair(self, where: str, a, b, rtol: float, scale: float | None = None) -> None:
        if _same(a, b):
            return
        self.exact = False
        rel = relative_difference(b, a, scale)
        self.max_relative = max(self.max_relative, rel)
        self.differences.append(f'{where}: recorded {a!r}, now {b!r} (relative {rel:.3g})')
        if not _close(b, a, rtol, self.tolerance.atol, scale):
            self._problem(f'{where}: recorded {a!r}, now {b!r} (relative difference {rel:.3g}, '
                          f'beyond rtol {rtol:g} / atol {self.tolerance.atol:g})')

    def _logs(self, expected: dict, found: dict) -> None:
        if sorted(expected) != sorted(found):
            self._problem(f'log files differ: recorded {sorted(expected)}, now {sorted(found)}')
        for file in sorted(set(expected) & set(found)):
            a, b = expected[file], found[file]
            if a['columns'] != b['columns']:
                self._problem(f'{file}: columns differ: recorded {a["columns"]}, now {b["columns"]} '
                              f'(missing {[c for c in a["columns"] if c not in b["columns"]]}, '
                              f'new {[c for c in b["columns"] if c not in a["columns"]]})')
            if len(a['rows']) != len(b['rows']):
                self._problem(f'{file}: {len(a["rows"])} rows recorded, {len(b["rows"])} now')
            scales = _column_scales(a)
            for r, (row_a, row_b) in enumerate(zip(a['rows'], b['rows'])):
                values_b = dict(zip(b['columns'], row_b))
                for column, value_a in zip(a['columns'], row_a):
                    if column not in values_b:
                        continue
                    if self.forking and column not in BOOKKEEPING:
                        self.skipped += 1
                        continue
                    value_b = values_b[column]
                    iteration = f' (iteration {row_a[0]})' if a['columns'][0] == 'iteration' else ''
                    where = f'{file} row {r}{iteration} column {column!r}'
                    if column in BOOKKEEPING and not _same(value_a, value_b):   # a counter: exactly, anywhere
                        self._problem(f'{where}: recorded {value_a!r}, now {value_b!r} (a counter)')
                    elif _number(value_a) and _number(value_b):
                        scale = max(abs(value_a), scales[column]) if math.isfinite(value_a) else None
                        self._number_pair(where, value_a, value_b, self.tolerance.rows, scale)
                    elif value_a != value_b:
                        self._problem(f'{where}: recorded {value_a!r}, now {value_b!r}')

    def _weights(self, expected: dict, found: dict, exact_digests: bool) -> None:
        if sorted(expected) != sorted(found):
            self._problem(f'weight files differ: recorded {sorted(expected)}, now {sorted(found)}')
        for file in sorted(set(expected) & set(found)):
            a, b = expected[file], found[file]
            if list(a) != list(b):
                self._problem(f'{file}: network entries differ: recorded {list(a)}, now {list(b)}')
            for entry in [e for e in a if e in b]:
                tensors_a, tensors_b = a[entry]['tensors'], b[entry]['tensors']
                if a[entry]['sha256'] != b[entry]['sha256']:
                    self.exact = False
                    if exact_digests:
                        self._problem(f'{file} {entry}: sha256 of the tensors differs (recorded '
                                      f'{a[entry]["sha256"][:16]}..., now {b[entry]["sha256"][:16]}...; '
                                      'a bitwise comparison asks for the same bytes)')
                layout_a = [t[:3] for t in tensors_a]
                layout_b = [t[:3] for t in tensors_b]
                if layout_a != layout_b:
                    self._problem(f'{file} {entry}: tensors (name, dtype, shape) differ: recorded {layout_a}, '
                                  f'now {layout_b}')
                    continue
                if self.forking:
                    self.skipped += 2 * len(tensors_a)
                    continue
                for (key, _, _, sum_a, abs_a), (_, _, _, sum_b, abs_b) in zip(tensors_a, tensors_b):
                    scale = max(abs(abs_a), abs(abs_b))
                    self._number_pair(f'{file} {entry} tensor {key!r} sum', sum_a, sum_b, self.tolerance.tensors,
                                      scale)
                    self._number_pair(f'{file} {entry} tensor {key!r} sum of |x|', abs_a, abs_b,
                                      self.tolerance.tensors)

    def _tree(self, where: str, a, b) -> None:
        if isinstance(a, dict) and isinstance(b, dict):
            if sorted(a) != sorted(b):
                self._problem(f'{where}: keys differ: recorded {sorted(a)}, now {sorted(b)}')
            for key in [k for k in a if k in b]:
                self._tree(f'{where}.{key}', a[key], b[key])
        elif isinstance(a, list) and isinstance(b, list):
            if len(a) != len(b):
                self._problem(f'{where}: {len(a)} items recorded, {len(b)} now')
            for i, (x, y) in enumerate(zip(a, b)):
                self._tree(f'{where}[{i}]', x, y)
        elif _number(a) and _number(b):
            self._number_pair(where, a, b, self.tolerance.rows)
        elif a != b:
            self._problem(f'{where}: recorded {a!r}, now {b!r}')

    def report(self, limit: int = 20) -> str:
        lines = self.problems[:limit]
        if len(self.problems) > limit:
            lines.append(f'... and {len(self.problems) - limit} more')
        return '\n'.join(lines)


def record_path(name: str, data: Path = DATA) -> Path:
    return Path(data) / f'{name}.json'


def load_record(name: str, data: Path = DATA) -> dict:
    return json.loads(record_path(name, data).read_text())


def rerecord_hint(name: str) -> str:
    return (f'if this change is meant, re-record with `python tests/learn/golden.py --record {name}` and say '
            'in the commit which change it is and why')


# ---------------------------------------------------------------------------- entry point

def _timed_run(name: str) -> tuple[dict, float]:
    with tempfile.TemporaryDirectory(prefix=f'mate-golden-{name}-') as folder:
        started = time.perf_counter()
        result = run_variant(name, Path(folder) / 'run')
        return result, time.perf_counter() - started


def record(names: list[str], data: Path = DATA) -> None:
    Path(data).mkdir(parents=True, exist_ok=True)
    for name in names:
        result, seconds = _timed_run(name)
        payload = dict(name=name, command=['mate', *VARIANTS[name]], versions=versions(), fingerprint=fingerprint(),
                       recorded=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds'),
                       seconds=round(seconds, 2), **result)
        record_path(name, data).write_text(json.dumps(payload, indent=1, allow_nan=True) + '\n')
        print(f'{name}: recorded in {seconds:.1f} s -> {record_path(name, data)}', flush=True)


def check(names: list[str], data: Path = DATA) -> int:
    failures = 0
    for name in names:
        if not record_path(name, data).exists():
            print(f'{name}: no recording ({record_path(name, data)}); run --record {name}')
            failures += 1
            continue
        expected = load_record(name, data)
        found, seconds = _timed_run(name)
        if expected['command'] != ['mate', *VARIANTS[name]]:
            print(f'{name}: NOTE the command line changed since the recording: {expected["command"]}')
        comparison = Comparison(name, expected, found)
        if comparison.exact:
            print(f'{name}: EXACT (log rows, state and weight digests bitwise equal; {seconds:.1f} s)', flush=True)
            continue
        failures += 1
        tolerant, how = judge(name, expected, found)
        verdict = 'BEYOND ITS TOLERANCE' if tolerant.problems else 'within its tolerance'
        print(f'{name}: DIFFERENT, {verdict} (the suite compares it {how}); largest relative difference '
              f'{comparison.max_relative:.3g}; {seconds:.1f} s', flush=True)
        for label, lines in (('differs', comparison.differences), ('FAILS the test', tolerant.problems)):
            for line in lines[:10]:
                print(f'    {label}: {line}')
            if len(lines) > 10:
                print(f'    {label}: ... and {len(lines) - 10} more')
    return 1 if failures else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    action = parser.add_mutually_exclusive_group(required=True)
    action.add_argument('--record', action='store_true', help='run the variants and write their JSON files')
    action.add_argument('--check', action='store_true', help='rerun the variants and compare bitwise')
    action.add_argument('--list', action='store_true', help='print the variants and their command lines')
    parser.add_argument('--data', type=Path, default=DATA, metavar='DIR',
                        help='the folder of the recordings (default tests/data/golden): a scratch folder records '
                             'a baseline before a refactor and checks against it')
    parser.add_argument('names', nargs='*', metavar='NAME', help=f'variants (default all): {", ".join(VARIANTS)}')
    args = parser.parse_args(argv)
    unknown = [n for n in args.names if n not in VARIANTS]
    if unknown:
        parser.error(f'unknown variants {unknown}; known: {", ".join(VARIANTS)}')
    names = args.names or list(VARIANTS)
    if args.list:
        for name in names:
            print(f'{name}: mate {" ".join(VARIANTS[name])}')
        return 0
    import torch

    torch.set_num_threads(1)
    if args.record:
        record(names, args.data)
        return 0
    return check(names, args.data)


if __name__ == '__main__':
    sys.exit(main())
