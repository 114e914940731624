"""Greedy vs greedy on MATE-4v8-9 with the Python agents, one episode per seed: the reference the batched
greedy teams are tested against (tests/teams/test_greedy_statistics.py).

    python tests/tools/greedy_reference.py [--seeds 300] [--json tests/data/greedy-4v8-9-python-300.json]

Protocol (`mate evaluate`, reference/groundtruth.md): for seed s = 0, ..., S-1, `mate.evaluation.evaluate.play_episode`
with a fresh MATE-4v8-9 env reset with seed s, `GreedyCameraAgent(seed=s).spawn(4)` and
`GreedyTargetAgent(seed=s).spawn(8)`, at most 2000 steps. Writes every episode's coverage rate, their
mean, sample standard deviation and standard error, with the date and the command line.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time
from pathlib import Path

import numpy as np

import mate
from mate.evaluation.evaluate import play_episode

PRESET = 'MATE-4v8-9'
MAX_STEPS = 2000


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seeds', type=int, default=300, help='seeds 0..N-1 (default 300)')
    parser.add_argument('--json', default='tests/data/greedy-4v8-9-python-300.json', help='where to write')
    args = parser.parse_args(argv)
    env = mate.make(f'{PRESET}-v0')
    start = time.perf_counter()
    coverage = []
    for seed in range(args.seeds):
        result = play_episode(env, mate.GreedyCameraAgent, mate.GreedyTargetAgent, seed, MAX_STEPS)
        coverage.append(result.coverage_rate)
        if (seed + 1) % 50 == 0:
            print(f'{seed + 1} episodes, mean coverage {np.mean(coverage):.4f}', file=sys.stderr, flush=True)
    values = np.array(coverage)
    std = float(values.std(ddof=1))
    report = {
        'what': 'greedy cameras vs greedy targets, Python agents (mate.evaluation.evaluate.play_episode), '
                'one episode per seed',
        'preset': PRESET, 'max_steps': MAX_STEPS, 'seeds': list(range(args.seeds)),
        'coverage_rate': coverage, 'mean': float(values.mean()), 'std': std,
        'standard_error': std / float(np.sqrt(len(values))),
        'date': datetime.date.today().isoformat(),
        'command': ' '.join(['python tests/tools/greedy_reference.py', *(argv if argv is not None else sys.argv[1:])]),
        'seconds': round(time.perf_counter() - start, 1),
    }
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [f' {json.dumps(key)}: {json.dumps(value)}' for key, value in report.items()]   # one line per key
    path.write_text('{\n' + ',\n'.join(lines) + '\n}\n')
    print(f'mean coverage {report["mean"]:.4f} +- {report["standard_error"]:.4f} (standard error) over '
          f'{args.seeds} seeds; wrote {path}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
