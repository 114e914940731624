"""Score trained policies with `mate evaluate` (seeds 0-19 by default, the Python greedy agents as opponents, no
rendering) and print a markdown table: coverage rate for cameras, normalised target return for targets.

    python docs/tools/evaluate_table.py --team camera results/runs/iql-hrl-camera-4v8-9-seed*/final.pt greedy
    python docs/tools/evaluate_table.py --team target --config MATE-2v4-0 --max-episode-steps 5000 \\
        results/runs/maddpg-target-2v4-0-seed*/final.pt pretrained:mappo-target-2v4-0 greedy

A path is played as `checkpoint:PATH`; anything else (`greedy`, `pretrained:NAME`) is passed as the agent spec.
The episodes are played as `mate evaluate` plays them: all at once in one vector env (batched: the greedy
opponents play the Python agents' episodes draw for draw), or one after the other in the single env with
`--single-env`. `--json OUT` also writes every row (policy, mean, std, episodes, seconds, and each episode's score);
`--markdown OUT` writes the printed tables with the command that made them.

`--against SPEC` (one of the policies; repeatable) adds paired differences: every policy and SPEC play the same
seeds, and each policy listed before SPEC gets its mean per-episode difference from SPEC with a 95 % bootstrap
interval (10,000 resamples of the episodes, `mate.benchmark.stats.stratified_bootstrap`). How the shipped
`pretrained:mappo-target-4v8-0` was tested against the file shipped before it (OLD.pt, `git show
518904f:mate/pretrained/mappo-target-4v8-0.pt`), on seeds no run trained, evaluated or was chosen on:

    python docs/tools/evaluate_table.py --team target --config MATE-4v8-0 --max-episode-steps 5000 \\
        --episodes 320 --seed 3000000 --against OLD.pt --against greedy \\
        --markdown docs/results/pretrained/mappo-target-4v8-0.md \\
        pretrained:mappo-target-4v8-0 OLD.pt greedy
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from mate.benchmark.stats import mean, stratified_bootstrap

METRIC = {'camera': 'coverage_rate', 'target': 'normalized_target_return'}


def evaluate(spec: str, team: str, config: str, episodes: int, seed: int, max_steps: int, single_env: bool) -> dict:
    agent = f'checkpoint:{spec}' if Path(spec).is_file() else spec
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / 'result.json'
        command = [sys.executable, '-m', 'mate', 'evaluate', '--config', config, f'--{team}-agent', agent,
                   '--episodes', str(episodes), '--seed', str(seed), '--max-episode-steps', str(max_steps),
                   '--no-render', '--json', str(out), *(['--single-env'] if single_env else [])]
        start = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
        seconds = time.perf_counter() - start
        played = json.loads(out.read_text())
    row = next(r for r in played['summary'] if r['key'] == METRIC[team])
    return dict(policy=spec, mean=row['mean'], std=row['std'], episodes=episodes, single_env=single_env,
                seconds=round(seconds, 1), seeds=[e['seed'] for e in played['episodes']],
                scores=[e[METRIC[team]] for e in played['episodes']])


def paired_rows(rows: list[dict], against: str) -> list[str]:
    """Markdown rows: the mean per-episode difference from `against` of each policy listed before it, with a 95 %
    bootstrap interval and the share of episodes it scores higher."""
    position = next(i for i, r in enumerate(rows) if r['policy'] == against)
    reference = rows[position]
    lines = []
    for row in rows[:position]:
        if row['seeds'] != reference['seeds']:
            raise ValueError(f"{row['policy']} and {against} played different seeds: no paired difference")
        difference = np.subtract(row['scores'], reference['scores'])
        point, low, high = stratified_bootstrap(difference, mean, reps=10_000)
        won = float(np.mean(difference > 0))
        lines.append(f"| {row['policy']} - {against} | {point:+.3f} [{low:+.3f}, {high:+.3f}] | {won:.2f} |")
    return lines


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
    parser.add_argument('--markdown', type=Path, default=None, help='also write the tables (and this command) here')
    parser.add_argument('--against', action='append', default=[], metavar='SPEC',
                        help='one of the policies (repeatable): add the paired difference from it of each policy '
                             'listed before it')
    args = parser.parse_args(argv)
    for spec in args.against:
        if spec not in args.policies:
            parser.error(f'--against {spec!r}: must be one of the policies {args.policies}')
    rows = []
    lines = [f'| policy ({args.team}s, {args.config}, seeds {args.seed}-{args.seed + args.episodes - 1}) '
             f'| {METRIC[args.team].replace("_", " ")} (mean ± std{", single env" if args.single_env else ""}) |',
             '|---|---|']
    print('\n'.join(lines))
    for spec in args.policies:
        row = evaluate(spec, args.team, args.config, args.episodes, args.seed, args.max_episode_steps, args.single_env)
        rows.append(row)
        lines.append(f"| {spec} | {row['mean']:.3f} ± {row['std']:.3f} |")
        print(lines[-1], flush=True)
    if args.against:
        paired = ['', '| paired difference (same seeds) | mean [95 % bootstrap CI] | share of episodes higher |',
                  '|---|---|---|', *(line for spec in args.against for line in paired_rows(rows, spec))]
        print('\n'.join(paired))
        lines += paired
    if args.markdown:
        command = ' '.join(['python docs/tools/evaluate_table.py', *(argv if argv is not None else sys.argv[1:])])
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text(f'`{command}`\n\n' + '\n'.join(lines) + '\n')
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
