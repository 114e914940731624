"""Trainer benchmark: decisions per second of every `mate train` algorithm at its default settings, learning
included, on the paper's settings (HRL cameras on MATE-4v8-9, flat targets on MATE-2v4-0).

    python benchmarks/trainers.py [--steps 25600] [--json benchmarks/results/trainers.json]

Protocol: each trainer runs `--steps` decision steps (defaults otherwise; one torch thread; off-policy learners
start learning after 5,120 decision steps instead of 5,000 so that the first log row is collection only) in a
fresh temporary run directory; the figure is decisions per second between the end of the first log row (5,120
decisions: compilation, warm-up and the off-policy learners' first replay fill excluded) and the last one.
MAPPO and IPPO collect 64 envs x 25 decisions per iteration; the off-policy trainers 16 envs and one update per
128 decisions. Run it alone on the machine: two jobs on two cores halve each other.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from mate.bench import machine_facts

SETTINGS = {
    # name: (trainer, config keyword arguments)
    'mappo-hrl-camera': ('ppo', dict(algo='mappo', team='camera', hrl=True)),
    'ippo-target': ('ppo', dict(algo='ippo', team='target')),
    'iql-hrl-camera': ('dqn', dict(algo='iql', team='camera', hrl=True)),
    'qmix-hrl-camera': ('dqn', dict(algo='qmix', team='camera', hrl=True)),
    'iql-target': ('dqn', dict(algo='iql', team='target')),
    'maddpg-target': ('maddpg', dict(team='target')),
    'maddpg-camera': ('maddpg', dict(team='camera')),
}


def measure(name: str, steps: int) -> dict:
    from mate.learn.dqn import DQNConfig, train_dqn
    from mate.learn.maddpg import MADDPGConfig, train_maddpg
    from mate.learn.ppo import PPOConfig, train

    kind, kwargs = SETTINGS[name]
    rows = []
    with tempfile.TemporaryDirectory() as run_dir:
        if kind == 'ppo':
            train(PPOConfig(total_steps=steps, torch_threads=1, **kwargs), run_dir, progress=False, callback=rows.append)
        elif kind == 'dqn':
            train_dqn(DQNConfig(total_steps=steps, learning_starts=5_120, **kwargs), run_dir, progress=False,
                      callback=rows.append)
        else:
            train_maddpg(MADDPGConfig(total_steps=steps, learning_starts=5_120, random_steps=5_120, **kwargs), run_dir,
                         progress=False, callback=rows.append)
    first = next(r for r in rows if r['env_steps'] >= 5_120)
    last = rows[-1]
    rate = (last['env_steps'] - first['env_steps']) / max(last['wall_seconds'] - first['wall_seconds'], 1e-9)
    return dict(setting=name, decisions_per_second=round(rate, 1), decisions=last['env_steps'],
                seconds=last['wall_seconds'])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--steps', type=int, default=25_600, help='decision steps per trainer (default 25,600)')
    parser.add_argument('--only', nargs='+', choices=list(SETTINGS), default=list(SETTINGS))
    parser.add_argument('--json', type=Path, default=None)
    args = parser.parse_args(argv)
    results = []
    print('| trainer, setting | decisions/s (learning included) |\n|---|---|')
    for name in args.only:
        start = time.perf_counter()
        row = measure(name, args.steps)
        row['wall_seconds'] = round(time.perf_counter() - start, 1)
        results.append(row)
        print(f"| {name} | {row['decisions_per_second']:,.0f} |", flush=True)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(dict(machine=machine_facts(), results=results), indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
