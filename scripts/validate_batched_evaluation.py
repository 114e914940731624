"""Does batched play (`mate evaluate --batched`) score like the single-env deployment agents (`mate evaluate`)?

    python scripts/validate_batched_evaluation.py [--episodes 100] [--json scripts/results/batched-agreement.json]

Protocol: for each pairing, seeds 0..E-1 are played both ways: one episode at a time by
`mate.evaluate.play_episode` with the Python agents (policy agents, Python greedy agents), and all at once
by `mate.teams.play_batch` with the batched teams (the same policy as a `mate.learn.policy.PolicyTeam`, the
batched greedy agents of `mate.teams`). Both teams are seeded like the env (row i of a team seeded with 0
plays as the agents `play_episode` builds for seed i: the greedy teams follow the Python agents' random
streams draw for draw) and the shipped policies act deterministically (argmax), so the two runs should play
the same episodes: the script reports how many episodes agree to 1e-9 and the largest difference, and (as a
sample comparison for policies that sample, whose batched and single-env draws differ) mean, standard
error and the difference of the means in units of its standard error (|z| < 2: no difference this test
can see). Pairings (as in the issue):

* shipped HRL-MAPPO cameras vs greedy targets, MATE-4v8-9, at most 2000 steps: coverage rate;
* greedy cameras vs shipped MAPPO targets, MATE-2v4-0, at most 5000 steps: normalised target return.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

import mate
from mate.evaluate import play_episode
from mate.learn.policy import load_agent, make_team
from mate.teams import play_batch

PAIRINGS = {
    'hrl-cameras-vs-greedy-targets': ('MATE-4v8-9', 'pretrained:hrl-mappo-camera-4v8-9', 'greedy', 2000,
                                      'coverage_rate'),
    'greedy-cameras-vs-mappo-targets': ('MATE-2v4-0', 'greedy', 'pretrained:mappo-target-2v4-0', 5000,
                                        'normalized_target_return'),
}


def _python_factory(spec: str, team: mate.Team):
    if spec == 'greedy':
        return mate.GreedyCameraAgent if team is mate.Team.CAMERA else mate.GreedyTargetAgent
    return load_agent(spec, team)


def _summary(values) -> dict:
    values = np.asarray(values, dtype=float)
    return {'mean': float(values.mean()), 'std': float(values.std(ddof=1)),
            'sem': float(values.std(ddof=1) / np.sqrt(len(values))), 'n': int(len(values))}


def compare(name: str, episodes: int) -> dict:
    preset, camera, target, max_steps, metric = PAIRINGS[name]
    env = mate.make(f'{preset}-v0')
    start = time.perf_counter()
    single = [getattr(play_episode(env, _python_factory(camera, mate.Team.CAMERA),
                                   _python_factory(target, mate.Team.TARGET), seed, max_steps), metric)
              for seed in range(episodes)]
    single_seconds = time.perf_counter() - start
    counts = (env.num_cameras, env.num_targets, env.num_obstacles)
    batch, timing = play_batch(preset, make_team(camera, 'camera', episodes, counts, seed=0),
                               make_team(target, 'target', episodes, counts, seed=0), episodes, 0, max_steps)
    batched = [getattr(e, metric) for e in batch]
    a, b = _summary(single), _summary(batched)
    spread = np.hypot(a['sem'], b['sem'])
    z = (b['mean'] - a['mean']) / spread if spread > 0 else 0.0
    difference = np.abs(np.asarray(batched) - np.asarray(single))
    return {'pairing': name, 'preset': preset, 'metric': metric, 'single_env': a, 'batched': b, 'z': float(z),
            'identical_episodes': int((difference <= 1e-9).sum()), 'max_difference': float(difference.max()),
            'single_env_seconds': single_seconds, 'batched_seconds': timing['seconds']}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--episodes', type=int, default=100, help='seeds 0..E-1 per pairing (default 100)')
    parser.add_argument('--pairings', nargs='+', choices=sorted(PAIRINGS), default=list(PAIRINGS),
                        help='which pairings to play (default: both)')
    parser.add_argument('--json', default=None, help='also write the results here')
    args = parser.parse_args(argv)
    rows = []
    for name in args.pairings:
        row = compare(name, args.episodes)
        rows.append(row)
        a, b = row['single_env'], row['batched']
        print(f"{name}: {row['metric']} single-env {a['mean']:.4f} +- {a['sem']:.4f} (sem), batched "
              f"{b['mean']:.4f} +- {b['sem']:.4f}; z = {row['z']:+.2f}; {row['identical_episodes']}/{a['n']} episodes "
              f"identical (largest difference {row['max_difference']:.2g}); {row['single_env_seconds']:.0f} s vs "
              f"{row['batched_seconds']:.1f} s", flush=True)
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
