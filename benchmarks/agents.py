"""Agent benchmark: env steps per second with both teams' built-in agents deciding, on MATE-4v8-9.

    python benchmarks/agents.py [--seconds 10] [--batched 256] [--json benchmarks/results/agents.json]

Protocol (reference/groundtruth.md): for seed s = 0, 1, ...: a fresh env reset with seed s,
`Cls(seed=s).spawn(N)` for each team, `group_reset`; each step the camera team's `group_step`
(observe, two communication rounds, act), then the target team's, then `env.step`; the episode
ends when the env says so or after 2000 steps. The clock runs over the step loops only (env
construction, reset and `group_reset` excluded) and seeds are played until `--seconds` have
been spent per pairing. One warm-up episode first (numba kernels are compiled or loaded from
the cache). Also reports the pairing's mean coverage rate, to show the agents did their job.

With `--batched B`, also the batched greedy teams of `mate.teams` (the same rules and random streams):
`play_batch` of B games, seeds 0..B-1, each to the end of its first episode (at most 2000 steps); the
clock runs over the step loop (`play_batch`'s timing), after a warm-up batch of 4 games x 50 steps.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import mate
from mate.evaluation import evaluate
from mate.tools.bench import machine_facts

PRESET = 'MATE-4v8-9-v0'
MAX_STEPS = 2000
ORIGINAL_STEPS_PER_SECOND = {'greedy': 474, 'heuristic': 157}
"""The original MATE on our machines, agents included (groundtruth.md; greedy ranged 339-474)."""
PAIRINGS = {
    'greedy': (mate.GreedyCameraAgent, mate.GreedyTargetAgent),
    'heuristic': (mate.HeuristicCameraAgent, mate.HeuristicTargetAgent),
}


def play_episode(camera_class, target_class, seed: int, max_steps: int = MAX_STEPS) -> dict:
    """One episode of the protocol (`mate.evaluation.evaluate.play_episode`); steps, loop seconds, coverage."""
    result = evaluate.play_episode(mate.make(PRESET), camera_class, target_class, seed, max_steps)
    return {'seed': seed, 'steps': result.episode_length,
            'seconds': result.episode_length / result.steps_per_second, 'coverage_rate': result.coverage_rate}


def measure(name: str, seconds: float) -> dict:
    """Steps/s of one pairing over as many protocol episodes as fit in `seconds`."""
    camera_class, target_class = PAIRINGS[name]
    play_episode(camera_class, target_class, seed=10_000, max_steps=50)   # warm-up
    episodes = []
    while sum(e['seconds'] for e in episodes) < seconds:
        episodes.append(play_episode(camera_class, target_class, seed=len(episodes)))
    steps = sum(e['steps'] for e in episodes)
    elapsed = sum(e['seconds'] for e in episodes)
    rate = steps / elapsed
    return {'pairing': f'{name} vs {name}', 'preset': PRESET, 'episodes': len(episodes), 'steps': steps,
            'seconds': elapsed, 'env_steps_per_second': rate,
            'original_steps_per_second': ORIGINAL_STEPS_PER_SECOND[name],
            'speedup_vs_original': rate / ORIGINAL_STEPS_PER_SECOND[name],
            'mean_coverage_rate': float(np.mean([e['coverage_rate'] for e in episodes]))}


def measure_batched(num_envs: int) -> dict:
    """Env steps/s of `mate.teams.play_batch` with B greedy-vs-greedy games (seeds 0..B-1)."""
    from mate.teams import GreedyTeam, play_batch

    def teams(seed):
        return (lambda b, counts: GreedyTeam('camera', b, counts, seed=seed),
                lambda b, counts: GreedyTeam('target', b, counts, seed=seed))

    play_batch(PRESET.removesuffix('-v0'), *teams(10_000), 4, seed=10_000, max_episode_steps=50)   # warm-up
    episodes, timing = play_batch(PRESET.removesuffix('-v0'), *teams(0), num_envs, seed=0, max_episode_steps=MAX_STEPS)
    rate = timing['env_steps_per_second']
    return {'pairing': f'greedy vs greedy, batched x{num_envs}', 'preset': PRESET, 'episodes': num_envs,
            'steps': timing['env_steps'], 'seconds': timing['seconds'], 'env_steps_per_second': rate,
            'original_steps_per_second': ORIGINAL_STEPS_PER_SECOND['greedy'],
            'speedup_vs_original': rate / ORIGINAL_STEPS_PER_SECOND['greedy'],
            'mean_coverage_rate': float(np.mean([e.coverage_rate for e in episodes]))}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=10.0, help='time budget per pairing (default 10)')
    parser.add_argument('--json', default='benchmarks/results/agents.json', help='where to write the results')
    parser.add_argument('--pairings', nargs='*', default=list(PAIRINGS), choices=list(PAIRINGS))
    parser.add_argument('--batched', type=int, default=0, metavar='B',
                        help='also time B batched greedy-vs-greedy games (mate.teams.play_batch); 0: skip')
    args = parser.parse_args(argv)
    results = []
    for name in args.pairings:
        print(f'measuring {name} vs {name} on {PRESET} ...', file=sys.stderr, flush=True)
        results.append(measure(name, args.seconds))
    if args.batched > 0:
        print(f'measuring {args.batched} batched greedy vs greedy games on {PRESET} ...', file=sys.stderr, flush=True)
        results.append(measure_batched(args.batched))
    header = f'{"pairing":<32} {"episodes":>8} {"steps":>8} {"steps/s":>9} {"original":>9} {"ratio":>7} {"coverage":>9}'
    print(header)
    print('-' * len(header))
    for r in results:
        print(f'{r["pairing"]:<32} {r["episodes"]:>8d} {r["steps"]:>8d} {r["env_steps_per_second"]:>9.0f} '
              f'{r["original_steps_per_second"]:>9d} {r["speedup_vs_original"]:>6.1f}x {r["mean_coverage_rate"]:>9.4f}')
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    protocol = ' '.join(__doc__.split('\n\n')[2].split())
    path.write_text(json.dumps({'machine': machine_facts(), 'protocol': protocol,
                                'results': results}, indent=2))
    print(f'wrote {path}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
