"""Score trained policies with `mate evaluate` (seeds 0-19 by default, the Python greedy agents as opponents, no
rendering) and print a markdown table: coverage rate for cameras, normalised target return for targets.

    python scripts/evaluate_table.py --team camera results/runs/iql-hrl-camera-4v8-9-seed*/final.pt greedy
    python scripts/evaluate_table.py --team target --config MATE-2v4-0 --max-episode-steps 5000 \\
        results/runs/maddpg-target-2v4-0-seed*/final.pt pretrained:mappo-target-2v4-0 greedy

A path is played as `checkpoint:PATH`; anything else (`greedy`, `pretrained:NAME`) is passed as the agent spec.
The episodes are played as `mate evaluate` plays them: all at once in one vector env (batched: the greedy
opponents play the Python agents' episodes draw for draw), or one after the other in the single env with
`--single-env`. `--json OUT` also writes every row (policy, mean, std, episodes, seconds).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

METRIC = {'camera': 'coverage_rate', 'target': 'normalized_target_return'}


def evaluate(spec: str, team: str, config: str, episodes: int, seed: int, max_steps: int, single_env: bool) -> dict:
    agent = f'checkpoint:{spec}' if Path(spec).is_file() else spec
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / 'result.json'
        command = [sys.executable, '-m', 'mate.cli', 'evaluate', '--config', config, f'--{team}-agent', agent,
                   '--episodes', str(episodes), '--seed', str(seed), '--max-episode-steps', str(max_steps),
                   '--no-render', '--json', str(out), *(['--single-env'] if single_env else [])]
        start = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
        seconds = time.perf_counter() - start
        summary = json.loads(out.read_text())['summary']
    row = next(r for r in summary if r['key'] == METRIC[team])
    return dict(policy=spec, mean=row['mean'], std=row['std'], episodes=episodes, single_env=single_env,
                seconds=round(seconds, 1))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('policies', nargs='+', help='checkpoint paths or agent specs of the scored team')
    parser.add_argument('--team', choices=('camera', 'target'), required=True)
    parser.add_argument('--config', default='MATE-4v8-9')
    parser.add_argument('--episodes', type=int, default=20)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--max-episode-steps', type=int, default=2000)
    parser.add_argument('--single-env', action='store_true', help='one episode after the other in the single env')
    parser.add_argument('--json', type=Path, default=None)
    args = parser.parse_args(argv)
    rows = []
    print(f'| policy ({args.team}s, {args.config}, seeds {args.seed}-{args.seed + args.episodes - 1}) '
          f'| {METRIC[args.team].replace("_", " ")} (mean ± std{", single env" if args.single_env else ""}) |')
    print('|---|---|')
    for spec in args.policies:
        row = evaluate(spec, args.team, args.config, args.episodes, args.seed, args.max_episode_steps, args.single_env)
        rows.append(row)
        print(f"| {spec} | {row['mean']:.3f} ± {row['std']:.3f} |", flush=True)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
