"""Trainer benchmark: decisions per second of `mate train` trainers, learning included, on the paper's settings
(HRL cameras on MATE-4v8-9, flat targets on MATE-2v4-0), through the command line.

    python benchmarks/trainers.py [--steps 25600] [--only NAME ...] [--device cpu|cuda] [--num-envs B]
                                  [--hidden W W] [--tree PATH --tree PATH ...] [--json FILE]

Protocol: each setting trains `--steps` decision steps in a fresh temporary run directory (`mate train`, defaults
otherwise: 64 envs x 25 decisions per PPO iteration, 16 envs and an update per 128 decisions for the off-policy
trainers, which start learning after 5,120 decision steps so that their first log row is collection only); the
figure is decisions per second between the first log row at or after 5,120 decisions (compilation, warm-up and
the first replay fill left out) and the last one. `--tree PATH` runs the command of a checkout at PATH (its `mate`
package first on PYTHONPATH) instead of the installed one; several trees run side by side, setting by setting, so
that a before/after comparison shares the machine's state (the command lines of checkouts from before the
learning-stack redesign, whose TarMAC, I2C, LSTM and MA-TD3 runs were options of `mate train mappo` / `maddpg`,
are translated). Run it alone on the machine: two jobs on two cores halve each other.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

OFF_POLICY = ['--learning-starts', '5120']
SETTINGS = {
    # name: the `mate train` arguments of the current command line
    'mappo-hrl-camera': ['mappo', '--hrl'],
    'ippo-target': ['ippo', '--team', 'target'],
    'mappo-target': ['mappo', '--team', 'target'],
    'mappo-lstm-target': ['mappo-lstm', '--team', 'target', '--actor', 'mlp'],
    'tarmac-target': ['tarmac', '--team', 'target'],
    'i2c-target': ['i2c', '--team', 'target'],
    'iql-hrl-camera': ['iql', '--hrl', *OFF_POLICY],
    'qmix-hrl-camera': ['qmix', '--hrl', *OFF_POLICY],
    'iql-target': ['iql', '--team', 'target', *OFF_POLICY],
    'matd3-target': ['matd3', '--team', 'target', *OFF_POLICY],
    'matd3-camera': ['matd3', '--team', 'camera', *OFF_POLICY],
}
BEFORE_REDESIGN = {
    # the same runs on a checkout from before the learning-stack redesign (issue 31)
    'mappo-lstm-target': ['mappo', '--team', 'target', '--actor', 'mlp', '--lstm', '256'],
    'tarmac-target': ['mappo', '--team', 'target', '--comm', 'tarmac'],
    'i2c-target': ['mappo', '--team', 'target', '--comm', 'i2c'],
    'matd3-target': ['maddpg', '--team', 'target', *OFF_POLICY],
    'matd3-camera': ['maddpg', '--team', 'camera', *OFF_POLICY],
}


def old_command_line(tree: Path) -> bool:
    """Whether the checkout at `tree` predates the redesign (no `mate/learn/mappo.py`)."""
    return not (tree / 'mate' / 'learn' / 'mappo.py').exists()


def measure(name: str, steps: int, tree: Path | None = None, extra: list[str] = ()) -> dict:
    """Train setting `name` for `steps` decisions with the checkout `tree` (None: the installed mate)."""
    arguments = BEFORE_REDESIGN.get(name, SETTINGS[name]) if tree and old_command_line(tree) else SETTINGS[name]
    env = dict(os.environ, MATE_COMPILE_NOTICE='0')
    if tree is not None:
        env['PYTHONPATH'] = os.pathsep.join([str(tree), env.get('PYTHONPATH', '')])
    with tempfile.TemporaryDirectory() as run_dir:
        command = [sys.executable, '-m', 'mate', 'train', *arguments, '--steps', str(steps), '--no-progress',
                   '--run-dir', run_dir, *extra]
        start = time.perf_counter()
        with tempfile.TemporaryFile('w+') as stderr:
            child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=stderr, text=True, env=env,
                                     cwd=run_dir)   # (not this checkout)
            cpu_at_row = _cpu_at_rows(child, Path(run_dir) / 'progress.csv')
            wall = time.perf_counter() - start
            if child.returncode != 0:
                stderr.seek(0)
                raise RuntimeError(f'{" ".join(command)} exited with {child.returncode}:\n{stderr.read()[-3000:]}')
        with open(Path(run_dir) / 'progress.csv', newline='') as f:
            rows = [{k: float(v) for k, v in row.items() if v not in ('', None)} for row in csv.DictReader(f)]
    first = next(i for i, r in enumerate(rows) if r['env_steps'] >= 5_120)
    decisions = rows[-1]['env_steps'] - rows[first]['env_steps']
    rate = decisions / max(rows[-1]['wall_seconds'] - rows[first]['wall_seconds'], 1e-9)
    cpu = None
    if first in cpu_at_row and len(rows) - 1 in cpu_at_row:
        cpu = round(decisions / max(cpu_at_row[len(rows) - 1] - cpu_at_row[first], 1e-9), 1)
    return dict(setting=name, tree=str(tree) if tree else 'installed', decisions_per_second=round(rate, 1),
                decisions_per_cpu_second=cpu, decisions=int(rows[-1]['env_steps']), seconds=round(wall, 1),
                command=' '.join(command[3:]))


def _cpu_at_rows(child: subprocess.Popen, progress: Path, every: float = 0.05) -> dict[int, float]:
    """Wait for `child` to end, reading its CPU seconds (user + system, all threads: /proc/PID/stat, Linux) whenever
    a log row appears in `progress`: {row index: CPU seconds when it was seen}. CPU time leaves out the time the
    process waited for a core (another job, a VM's steal), which wall-clock rates count: the steadier figure on a
    shared machine. Empty where /proc is not there."""
    stat, ticks, seen, cpu = Path(f'/proc/{child.pid}/stat'), os.sysconf('SC_CLK_TCK'), 0, {}
    while child.poll() is None:
        try:
            rows = progress.read_text().count('\n') - 1 if progress.exists() else 0
            if rows > seen:
                fields = stat.read_text().rsplit(')', 1)[1].split()
                now = (int(fields[11]) + int(fields[12])) / ticks
                cpu.update({row: now for row in range(seen, rows)})
                seen = rows
        except (OSError, IndexError, ValueError):
            pass
        time.sleep(every)
    return cpu


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--steps', type=int, default=25_600, help='decision steps per setting (default 25,600)')
    parser.add_argument('--only', nargs='+', choices=list(SETTINGS), default=list(SETTINGS))
    parser.add_argument('--tree', type=Path, action='append', default=None,
                        help='a checkout whose mate to run (repeat for side-by-side runs); default: the installed one')
    parser.add_argument('--device', default=None, help='--device of the runs (checkouts after the redesign only)')
    parser.add_argument('--num-envs', type=int, default=None, help='--num-envs of the runs (default: each trainer\'s)')
    parser.add_argument('--hidden', type=int, nargs='+', default=None, help='--hidden of the runs (default: each\'s)')
    parser.add_argument('--json', type=Path, default=None)
    args = parser.parse_args(argv)
    extra = ((['--device', args.device] if args.device else []) + (['--num-envs', str(args.num_envs)] if args.num_envs
             else []) + (['--hidden', *map(str, args.hidden)] if args.hidden else []))
    trees = args.tree or [None]
    results = []
    print('decisions per second (wall) / per CPU second\n\n| setting | '
          + ' | '.join(str(t) if t else 'installed' for t in trees) + ' |\n|---|' + '---:|' * len(trees), flush=True)
    for name in args.only:
        cells = []
        for tree in trees:
            row = measure(name, args.steps, tree, extra)
            results.append(row)
            cpu = row['decisions_per_cpu_second']
            cells.append(f"{row['decisions_per_second']:,.0f} / " + ('-' if cpu is None else f'{cpu:,.0f}'))
        print(f"| {name} | {' | '.join(cells)} |", flush=True)
    if args.json:
        from mate.tools.bench import machine_facts

        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(dict(machine=machine_facts(), extra=extra, results=results), indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
