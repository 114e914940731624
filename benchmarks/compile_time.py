"""Cold-start benchmark: how long a first run takes while numba compiles the kernels, and warm.

    python benchmarks/compile_time.py [--repeat 3] [--json benchmarks/results/compile_time.json]

Each case runs in a fresh subprocess, first with an empty NUMBA_CACHE_DIR (cold: everything
compiles, as on a fresh install) and then again with the cache that run filled (warm: loads).
Cases: the first env step (`mate.make`, `reset`, one `step`), `mate evaluate --no-render
--episodes 1` and `mate evaluate --episodes 1` (which also renders and writes a GIF). Reports the
median over `--repeat` rounds of the wall time and of the CPU time (user + system) of the
subprocess; on a busy machine the CPU time is the steadier of the two.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mate.tools.bench import machine_facts

FIRST_STEP = ("import mate; env = mate.make('MultiAgentTracking-v0'); env.reset(seed=0); "
              "env.step(env.action_space.sample())")


def mate_command() -> list[str]:
    """The `mate` console script of this Python (or the CLI through `python -c`)."""
    script = shutil.which('mate', path=str(Path(sys.executable).parent))
    return [script] if script else [sys.executable, '-m', 'mate']


CASES = {
    'first env step': [sys.executable, '-c', FIRST_STEP],
    'mate evaluate --no-render --episodes 1': [*mate_command(), 'evaluate', '--no-render', '--episodes', '1'],
    'mate evaluate --episodes 1 (GIF)': [*mate_command(), 'evaluate', '--episodes', '1'],
}


def timed_run(command: list[str], cache_dir: str, work_dir: str) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one run of `command` with this numba cache directory."""
    env = {**os.environ, 'NUMBA_CACHE_DIR': cache_dir, 'SDL_VIDEODRIVER': 'dummy', 'MATE_COMPILE_NOTICE': '0'}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, env=env, cwd=work_dir, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def measure(repeat: int, progress=print) -> list[dict]:
    """Cold then warm runs of every case, `repeat` rounds; medians and every round."""
    rounds = {(case, cache): [] for case in CASES for cache in ('cold', 'warm')}
    for index in range(repeat):
        for case, command in CASES.items():
            with tempfile.TemporaryDirectory(prefix='mate-numba-cache-') as cache_dir, \
                    tempfile.TemporaryDirectory(prefix='mate-compile-time-') as work_dir:
                for cache in ('cold', 'warm'):
                    wall, cpu = timed_run(command, cache_dir, work_dir)
                    rounds[case, cache].append((wall, cpu))
                    progress(f'round {index + 1}/{repeat}  {case:42s} {cache}: {wall:6.1f} s wall, {cpu:6.1f} s CPU')
    return [{'case': case, 'cache': cache,
             'median_wall_seconds': statistics.median(wall for wall, _ in seen),
             'median_cpu_seconds': statistics.median(cpu for _, cpu in seen),
             'wall_seconds': [wall for wall, _ in seen], 'cpu_seconds': [cpu for _, cpu in seen]}
            for (case, cache), seen in rounds.items()]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--repeat', type=int, default=3, help='rounds (default 3); medians are reported')
    parser.add_argument('--json', default='benchmarks/results/compile_time.json', help='where to write the results')
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f'--repeat must be an integer >= 1, got {args.repeat}')
    results = measure(args.repeat)
    print(f"\n{'case':42s} {'cache':5s} {'wall (median)':>14s} {'CPU (median)':>13s}")
    for result in results:
        print(f"{result['case']:42s} {result['cache']:5s} {result['median_wall_seconds']:12.1f} s "
              f"{result['median_cpu_seconds']:11.1f} s")
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({'machine': machine_facts(), 'repeat': args.repeat, 'results': results}, indent=2))
    print(f'results written to {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
