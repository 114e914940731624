"""Evaluation benchmark: env-steps per second of batched policy-vs-policy play (`mate.teams.play_batch` with
`mate.policies.policy.PolicyTeam` and the batched teams of `mate.teams`),
beside the single-env deployment agents that `mate evaluate` drives one episode at a time.

    python benchmarks/evaluation.py [--episodes 100] [--single-seconds 20] [--json benchmarks/results/evaluation.json]

Protocol: for each pairing, `play_batch` plays `--episodes` games in one batch (row i seeded with i) to
the end of each row's first episode; env-steps/s counts the steps of those episodes over the whole
call's wall time (rows that finished early keep being stepped and are not counted). The single-env
figure plays seeds 0, 1, ... with `mate.evaluation.evaluate.play_episode` and the deployment agents (the agents'
time included) for about `--single-seconds`. One warm-up batch of 4 episodes first (compilation and
the first torch calls excluded). Pairings:

* `hrl-cameras-vs-greedy`: the shipped HRL-MAPPO cameras against greedy targets, MATE-4v8-9;
* `greedy-vs-mappo-targets`: greedy cameras against the shipped MAPPO targets, MATE-2v4-0;
* `learned-vs-learned`: HRL cameras (the shipped policy's architecture for MATE-2v4-0, random weights:
  no camera policy for that preset ships) against the shipped MAPPO targets, MATE-2v4-0.

Batched greedy agents are `mate.teams.GreedyTeam` (the Python greedy agents' rules and random streams on
arrays); the single-env column uses the Python greedy agents.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

import mate
from mate.tools.bench import machine_facts
from mate.evaluation.evaluate import play_episode
from mate.policies.policy import (
    AGENT_CLASSES,
    LoadedPolicy,
    PolicyTeam,
    load_policy,
    make_actor,
    make_team,
    pretrained_path,
)
from mate.policies.spec import PolicySpec
from mate.teams import play_batch

MAX_STEPS = {'MATE-4v8-9': 2000, 'MATE-2v4-0': 5000}


def _untrained_hrl_cameras_2v4_0() -> LoadedPolicy:
    """The shipped HRL camera policy's architecture and settings, for MATE-2v4-0, with random weights."""
    shipped = load_policy(pretrained_path('hrl-mappo-camera-4v8-9'), 'camera').spec
    spec = PolicySpec.for_game('camera', 'MATE-2v4-0-v0', frame_skip=shipped.frame_skip, action=shipped.action,
                               memory=shipped.memory, velocity=shipped.velocity, network=shipped.network,
                               hidden=shipped.hidden, activation=shipped.activation, lstm=shipped.lstm,
                               algo=shipped.algo, deterministic=False)
    torch.manual_seed(0)
    return LoadedPolicy(make_actor(spec), spec, 'untrained HRL cameras (2v4-0)')


def pairings() -> dict:
    """name -> (preset, batched camera factory, batched target factory, Python camera factory, Python target factory).
    Both batched teams are seeded with 0, like the env rows: the greedy teams then play as the Python agents of
    `play_episode` for the row's seed (the shipped policies act by argmax)."""
    hrl = load_policy(pretrained_path('hrl-mappo-camera-4v8-9'), 'camera')
    targets = load_policy(pretrained_path('mappo-target-2v4-0'), 'target')
    untrained = _untrained_hrl_cameras_2v4_0()
    camera_agent, target_agent = AGENT_CLASSES[mate.Team.CAMERA], AGENT_CLASSES[mate.Team.TARGET]
    return {
        'hrl-cameras-vs-greedy': (
            'MATE-4v8-9', lambda b, c: PolicyTeam(hrl, 'camera', b, c, seed=0),
            lambda b, c: make_team('greedy', 'target', b, c, seed=0),
            lambda seed: camera_agent(hrl, seed=seed), mate.GreedyTargetAgent),
        'greedy-vs-mappo-targets': (
            'MATE-2v4-0', lambda b, c: make_team('greedy', 'camera', b, c, seed=0),
            lambda b, c: PolicyTeam(targets, 'target', b, c, seed=0),
            mate.GreedyCameraAgent, lambda seed: target_agent(targets, seed=seed)),
        'learned-vs-learned': (
            'MATE-2v4-0', lambda b, c: PolicyTeam(untrained, 'camera', b, c, seed=0),
            lambda b, c: PolicyTeam(targets, 'target', b, c, seed=0),
            lambda seed: camera_agent(untrained, seed=seed), lambda seed: target_agent(targets, seed=seed)),
    }


def measure_single(preset: str, camera_factory, target_factory, seconds: float) -> dict:
    env = mate.make(f'{preset}-v0')
    steps = elapsed = 0.0
    seed = 0
    while elapsed < seconds:
        start = time.perf_counter()
        result = play_episode(env, camera_factory, target_factory, seed, MAX_STEPS[preset])
        elapsed += time.perf_counter() - start
        steps += result.episode_length
        seed += 1
    return {'episodes': seed, 'env_steps': int(steps), 'seconds': elapsed, 'env_steps_per_second': steps / elapsed}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--episodes', type=int, default=100, help='games per batch (default 100)')
    parser.add_argument('--single-seconds', type=float, default=20.0,
                        help='time spent on the single-env agents per pairing (default 20; 0: skip)')
    parser.add_argument('--json', default=None, help='also write the results here')
    args = parser.parse_args(argv)
    results = []
    for name, (preset, cameras, targets, camera_agent, target_agent) in pairings().items():
        play_batch(preset, cameras, targets, episodes=4, seed=10_000, max_episode_steps=MAX_STEPS[preset])  # warm-up
        episodes, timing = play_batch(preset, cameras, targets, episodes=args.episodes, seed=0,
                                      max_episode_steps=MAX_STEPS[preset])
        row = {'pairing': name, 'preset': preset, 'episodes': args.episodes, **timing,
               'mean_coverage': float(np.mean([e.coverage_rate for e in episodes])),
               'mean_normalized_target_return': float(np.mean([e.normalized_target_return for e in episodes]))}
        if args.single_seconds > 0:
            single = measure_single(preset, camera_agent, target_agent, args.single_seconds)
            row['single_env'] = single
            row['speedup_vs_single_env'] = timing['env_steps_per_second'] / single['env_steps_per_second']
        results.append(row)
        line = f"{name:26s} {preset}  batched {timing['env_steps_per_second']:>10,.0f} env-steps/s"
        if 'single_env' in row:
            line += (f"   single-env agents {row['single_env']['env_steps_per_second']:>8,.0f}"
                     f"   x{row['speedup_vs_single_env']:.0f}")
        print(line, flush=True)
    print(f"machine: {machine_facts()['cpus']} cores, {machine_facts()['processor']}")
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({'machine': machine_facts(), 'results': results}, indent=2))
        print(f'written to {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
