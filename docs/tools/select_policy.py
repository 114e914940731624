"""Pick the best policy snapshot of a training run, test it against the greedy agent, and export it.

    python docs/tools/select_policy.py RUN_DIR [--top 6] [--val-episodes 10] [--test-episodes 20]
                                    [--max-steps N] [--deterministic] [--export NAME]

1. shortlist: the `--top` snapshots (RUN_DIR/snapshots/policy-STEPS.pt, written by
   `mate train --snapshot-every`) whose training metric was highest (the progress.csv row of the
   same step: episode coverage for cameras, normalised target return for targets);
2. validation: each candidate plays `--val-episodes` episodes against the other team's greedy agents
   on seeds 1000, 1001, ... (never the test seeds); the best mean wins;
3. test: the winner and the greedy agent of the same team each play `--test-episodes` episodes on
   seeds 0, 1, ... (the `mate evaluate` seeds) against the same greedy opponents;
4. `--export NAME` writes the winner to mate/pretrained/NAME.pt (actor only) with a note of the scores.

The metric is the paper's: the mean coverage rate (cameras) or the normalised target-team episode
return (targets). Episodes are capped at `--max-steps` (default: 2000 for cameras as in `mate evaluate`,
5000 for targets, the training horizon).
"""

from __future__ import annotations

import argparse
import csv
import functools
import json
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.progress import track

import mate
from mate.evaluation.evaluate import play_episode, resolve_agent
from mate.policies.policy import PRETRAINED_DIR, export_policy, load_agent, load_policy
from mate.messages import Team

METRIC = {'camera': ('coverage_rate', 'episode_coverage'),
          'target': ('normalized_target_return', 'episode_normalized_target_return')}


def shortlist(run_dir: Path, team: str, top: int) -> list[Path]:
    """The `top` snapshots with the best smoothed training metric at their step."""
    snapshots = {int(p.stem.split('-')[1]): p for p in (run_dir / 'snapshots').glob('policy-*.pt')}
    if not snapshots:
        raise SystemExit(f'no snapshots in {run_dir / "snapshots"} (train with --snapshot-every N)')
    with open(run_dir / 'progress.csv', newline='') as f:
        score = {int(row['env_steps']): float(row[METRIC[team][1]]) for row in csv.DictReader(f)}
    ranked = sorted(snapshots, key=lambda step: score.get(step, -np.inf), reverse=True)
    return [snapshots[step] for step in ranked[:top]]


def scores(env, team: str, factory, seeds, max_steps: int, label: str) -> np.ndarray:
    """The metric of `factory`'s team against greedy opponents, one value per seed."""
    greedy = resolve_agent('greedy', Team.TARGET if team == 'camera' else Team.CAMERA)
    pair = (factory, greedy) if team == 'camera' else (greedy, factory)
    results = [play_episode(env, *pair, seed=int(seed), max_steps=max_steps)
               for seed in track(list(seeds), description=label, transient=True)]
    return np.array([getattr(r, METRIC[team][0]) for r in results])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('run_dir', type=Path)
    parser.add_argument('--top', type=int, default=6)
    parser.add_argument('--val-episodes', type=int, default=10)
    parser.add_argument('--test-episodes', type=int, default=20)
    parser.add_argument('--max-steps', type=int, default=None)
    parser.add_argument('--deterministic', action='store_true', help='argmax actions instead of sampling')
    parser.add_argument('--export', metavar='NAME', default=None, help='write the winner to mate/pretrained/NAME.pt')
    parser.add_argument('--json', type=Path, default=None, help='write the scores here')
    args = parser.parse_args()
    console = Console()

    first = sorted((args.run_dir / 'snapshots').glob('policy-*.pt'))
    if not first:
        raise SystemExit(f'no snapshots in {args.run_dir / "snapshots"} (train with --snapshot-every N)')
    spec = load_policy(first[0]).spec
    team = spec.team
    max_steps = args.max_steps or (2000 if team == 'camera' else 5000)
    env = mate.make(spec.env_id, config=spec.config)
    candidates = shortlist(args.run_dir, team, args.top)

    def factory(path: Path):
        return functools.partial(load_agent(f'checkpoint:{path}', team), deterministic=args.deterministic)

    validation = {}
    for path in candidates:
        values = scores(env, team, factory(path), range(1000, 1000 + args.val_episodes), max_steps, path.name)
        validation[path] = values.mean()
        console.print(f'{path.name}: validation {METRIC[team][0]} {values.mean():.4f} +- {values.std():.4f}')
    best = max(validation, key=validation.get)
    test_seeds = range(args.test_episodes)
    learned = scores(env, team, factory(best), test_seeds, max_steps, f'test {best.name}')
    greedy = scores(env, team, resolve_agent('greedy', Team[team.upper()]), test_seeds, max_steps, 'test greedy')
    report = dict(run_dir=str(args.run_dir), team=team, env_id=spec.env_id, config=spec.config, metric=METRIC[team][0],
                  snapshot=best.name, deterministic=args.deterministic, max_steps=max_steps,
                  validation={p.name: float(v) for p, v in validation.items()},
                  test_seeds=[0, args.test_episodes - 1],
                  policy=dict(mean=float(learned.mean()), std=float(learned.std())),
                  greedy=dict(mean=float(greedy.mean()), std=float(greedy.std())),
                  wins=int((learned > greedy).sum()))
    console.print(f'test (seeds 0-{args.test_episodes - 1}, {max_steps}-step cap): {best.name} '
                  f'{learned.mean():.4f} +- {learned.std():.4f}  vs greedy {greedy.mean():.4f} +- {greedy.std():.4f}'
                  f'  (better on {report["wins"]}/{args.test_episodes} seeds)')
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))
    if args.export:
        note = (f"{best.name} of {args.run_dir.name}; {METRIC[team][0]} {learned.mean():.4f} +- {learned.std():.4f} vs "
                f"greedy {greedy.mean():.4f} +- {greedy.std():.4f} (seeds 0-{args.test_episodes - 1}, {max_steps} steps, "
                f"{'deterministic' if args.deterministic else 'stochastic'})")
        out = export_policy(best, PRETRAINED_DIR / f'{args.export}.pt', note=note, deterministic=args.deterministic)
        console.print(f'exported {out}')


if __name__ == '__main__':
    main()
