"""How far the golden runs part under other kernels, and how far a deliberate mistake parts them: the evidence behind
`golden.ACROSS_MACHINES` (tests/learn/golden.py; docs/contributors/testing.md, "Golden runs on another machine").

    python tests/tools/golden_spread.py record OUT [--pins NAME ...]     every variant under each kernel pin, into
                                                                         OUT/PIN (one process each)
    python tests/tools/golden_spread.py mutate OUT [--pins ...] [--mutations ...]
                                                                         the PPO variants with each mutation, under
                                                                         each pin, into OUT/PIN+MUTATION
    python tests/tools/golden_spread.py table OUT [--base PIN] [--against DIR]
                                                                         per variant and folder: the largest relative
                                                                         difference to the base pin's recording (log
                                                                         values as the suite scales them; weights),
                                                                         and whether `ACROSS_MACHINES` passes it

One machine plays several: ATen's kernels (`ATEN_CPU_CAPABILITY`), MKL's branches (`MKL_CBWR`,
`MKL_ENABLE_INSTRUCTIONS`, `MKL_DEBUG_CPU_TYPE`) and numpy's dispatch (`NPY_DISABLE_CPU_FEATURES`) choose the
kernels another CPU would run. Each pin runs with `MATE_REPRODUCIBLE=0`, so that its variables stand as given.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

NUMPY_AVX512 = 'AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR'
PINS: dict[str, dict[str, str]] = {
    'reproducible': {'MKL_CBWR': 'COMPATIBLE', 'ATEN_CPU_CAPABILITY': 'avx2'},   # = MATE_REPRODUCIBLE=1
    'aten-default': {'MKL_CBWR': 'COMPATIBLE', 'ATEN_CPU_CAPABILITY': 'default'},
    'aten-avx512': {'MKL_CBWR': 'COMPATIBLE', 'ATEN_CPU_CAPABILITY': 'avx512'},
    'mkl-auto': {'ATEN_CPU_CAPABILITY': 'avx2'},
    'mkl-avx2': {'MKL_CBWR': 'AVX2', 'ATEN_CPU_CAPABILITY': 'avx2'},
    'mkl-avx512': {'MKL_CBWR': 'AVX512', 'ATEN_CPU_CAPABILITY': 'avx512'},
    'mkl-instructions-avx2': {'MKL_ENABLE_INSTRUCTIONS': 'AVX2', 'MKL_DEBUG_CPU_TYPE': '5'},
    'unpinned': {},
    'numpy-no-avx512': {'MKL_CBWR': 'COMPATIBLE', 'ATEN_CPU_CAPABILITY': 'avx2',
                        'NPY_DISABLE_CPU_FEATURES': NUMPY_AVX512},
}
"""Kernel settings of one machine, by name: the environment variables each sets (the others unset)."""


@contextlib.contextmanager
def mutated(name: str):
    """The learning code with one deliberate one-line change (`MUTATIONS`), undone on exit."""
    import mate.learn.ppo as ppo
    import mate.learn.ppo_loop as loop

    saved = {(module, attr): getattr(module, attr) for module in (ppo, loop)
             for attr in ('compute_gae', 'ppo_update', 'learning_targets') if hasattr(module, attr)}
    gae, update, targets = ppo.compute_gae, ppo.ppo_update, ppo.learning_targets
    if name == 'gae-lambda':           # lambda 0.95 -> 0.931 in the advantages
        ppo.compute_gae = lambda r, v, d, last, gamma, lam: gae(r, v, d, last, gamma, lam * 0.98)
    elif name == 'entropy-sign':       # the entropy bonus becomes a penalty
        def flipped(optimizer, parameters, config, dist, actions, old, adv, predicted, returns, entropy, *rest,
                    **kwargs):
            return update(optimizer, parameters, config, dist, actions, old, adv, predicted, returns, -entropy,
                          *rest, **kwargs)
        ppo.ppo_update = loop.ppo_update = flipped
    elif name == 'advantage-scale':    # standardised advantages 2 % too large
        def scaled(*args, **kwargs):
            advantages, returns = targets(*args, **kwargs)
            return advantages * 1.02, returns
        ppo.learning_targets = loop.learning_targets = scaled
    elif name != 'none':
        raise ValueError(f'unknown mutation {name!r}; known: {", ".join(MUTATIONS)}')
    try:
        yield
    finally:
        for (module, attr), value in saved.items():
            setattr(module, attr, value)


MUTATIONS = ('gae-lambda', 'entropy-sign', 'advantage-scale')
"""The deliberate one-line changes `mutated` makes (each to an advantage or a loss of the PPO family)."""
PPO_VARIANTS = ('mappo-camera', 'ippo-camera', 'mappo-camera-mlp', 'mappo-camera-paper', 'hrl-mappo-camera',
                'mappo-camera-lstm', 'mappo-camera-tarmac', 'mappo-camera-i2c', 'mappo-target',
                'mappo-camera-memory-velocity-difference')


def run_pinned(pin: str, arguments: list[str], timeout: float = 1800) -> subprocess.CompletedProcess:
    """Run `python tests/tools/golden_spread.py ARGUMENTS` in a process with the kernel variables of `pin`."""
    from tests.learn import golden

    env = golden.pinned_environment(PINS[pin])
    return subprocess.run([sys.executable, __file__, *arguments], env=env, capture_output=True, text=True,
                          timeout=timeout, cwd=ROOT)


def _inner_record(out: Path, names: list[str], mutation: str) -> None:
    from tests.learn import golden

    with mutated(mutation):
        golden.record(names, out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('action', choices=('record', 'mutate', 'table', 'inner'))
    parser.add_argument('out', type=Path)
    parser.add_argument('--pins', nargs='+', default=list(PINS), choices=list(PINS))
    parser.add_argument('--mutations', nargs='+', default=list(MUTATIONS), choices=list(MUTATIONS))
    parser.add_argument('--names', nargs='+', default=None)
    parser.add_argument('--mutation', default='none')
    parser.add_argument('--base', default='reproducible', help='the folder (under OUT) the others are compared to')
    parser.add_argument('--against', type=Path, nargs='*', default=[], help='more folders of recordings to compare')
    args = parser.parse_args(argv)
    if args.action == 'inner':            # in the pinned process
        from tests.learn import golden

        _inner_record(args.out, args.names or list(golden.VARIANTS), args.mutation)
        return 0
    if args.action in ('record', 'mutate'):
        jobs = ([(pin, 'none') for pin in args.pins] if args.action == 'record'
                else [(pin, m) for pin in args.pins for m in args.mutations])
        for pin, mutation in jobs:
            folder = args.out / (pin if mutation == 'none' else f'{pin}+{mutation}')
            names = args.names or ([] if mutation == 'none' else list(PPO_VARIANTS))
            result = run_pinned(pin, ['inner', str(folder), '--mutation', mutation, *(['--names', *names] if names
                                                                                     else [])])
            print(f'{folder.name}: exit {result.returncode}', flush=True)
            if result.returncode:
                print(result.stderr[-2000:])
                return 1
        return 0
    return table(args.out, args.base, args.against)


def table(out: Path, base: str, against: list[Path]) -> int:
    """Print, per variant, each folder's largest relative difference to `out/base`: 'L' log values, 'W' weight sums,
    then 'ok' or 'FAILS' as the suite's across-machines comparison judges it."""
    from tests.learn import golden

    folders = [f for f in sorted(out.iterdir()) if f.is_dir() and f.name != base] + list(against)
    print('| variant | ' + ' | '.join(f.name for f in folders) + ' |')
    print('|---|' + '---|' * len(folders))
    for name in golden.VARIANTS:
        expected = golden.load_record(name, out / base)
        cells = []
        for folder in folders:
            if not golden.record_path(name, folder).exists():
                cells.append('')
                continue
            found = golden.load_record(name, folder)
            plain = golden.Comparison(name, expected, found, golden.ACROSS_MACHINES)
            judged = golden.Comparison(name, expected, found, golden.ACROSS_MACHINES, forking=name in golden.FORKING)
            logs = max([_relative(d) for d in plain.differences if ' row ' in d] or [0.0])
            weights = max([_relative(d) for d in plain.differences if ' tensor ' in d] or [0.0])
            cells.append('exact' if plain.exact else
                         f'L {logs:.0e} W {weights:.0e} {"FAILS" if judged.problems else "ok"}')
        print(f'| {name} | ' + ' | '.join(cells) + ' |', flush=True)
    return 0


def _relative(difference: str) -> float:
    return float(difference.rsplit('(relative ', 1)[1].split(')')[0])


if __name__ == '__main__':
    sys.exit(main())
