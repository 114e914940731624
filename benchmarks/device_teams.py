"""The device teams' play against the CPU teams': greedy vs greedy on MATE-4v8-9 over many seeds.

    python benchmarks/device_teams.py [--seeds 300] [--json benchmarks/results/device_teams.json]

The device teams (`mate.teams.device`) run the rules of the CPU teams with other random streams (counter-based,
one per agent, so that a GPU thread can draw them), so their games differ draw for draw and must agree in
distribution. Both pairings play `--seeds` games (env seeds 0..S-1, the teams seeded alike), each to the end of its
first episode, in `play_batch`; the device teams run on the host here (`HostTeam`: the same row functions the
kernels run, which the simulator tests check are the kernels' games). Reported: the mean episode coverage rate and
its standard error for each, their difference in standard errors of the difference (the issue's bar: within 3),
and each pairing's env steps per second on this machine.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from mate.tools.bench import machine_facts
from mate.config import read_config
from mate.teams import GreedyTeam, play_batch
from mate.teams.device import HostTeam

PRESET = 'MATE-4v8-9'


def pairing(kind: str, seeds: int) -> dict:
    config = read_config(PRESET)
    if kind == 'cpu':
        cameras, targets = (lambda n, c: GreedyTeam('camera', n, c, seed=0)), \
            (lambda n, c: GreedyTeam('target', n, c, seed=0))
    else:
        cameras, targets = (lambda n, c: HostTeam('greedy', 'camera', n, c, seed=0)), \
            (lambda n, c: HostTeam('greedy', 'target', n, c, seed=0))
    episodes, timing = play_batch(config, cameras, targets, episodes=seeds, seed=0)
    coverage = np.array([episode.coverage_rate for episode in episodes])
    return dict(teams=kind, episodes=seeds, mean_coverage_rate=float(coverage.mean()),
                standard_error=float(coverage.std(ddof=1) / math.sqrt(seeds)),
                env_steps_per_second=float(timing['env_steps_per_second']))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seeds', type=int, default=300)
    parser.add_argument('--json', default='benchmarks/results/device_teams.json')
    args = parser.parse_args(argv)
    play_batch(read_config(PRESET), lambda n, c: HostTeam('greedy', 'camera', n, c, seed=0),
               lambda n, c: HostTeam('greedy', 'target', n, c, seed=0), episodes=2, seed=0, max_episode_steps=20)
    cpu, device = pairing('cpu', args.seeds), pairing('device', args.seeds)
    difference = device['mean_coverage_rate'] - cpu['mean_coverage_rate']
    z = difference / math.hypot(cpu['standard_error'], device['standard_error'])
    result = dict(preset=PRESET, machine=machine_facts(), cpu_teams=cpu, device_teams=device,
                  difference=difference, difference_in_standard_errors=z)
    print(json.dumps(result, indent=2))
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(result, indent=2) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
