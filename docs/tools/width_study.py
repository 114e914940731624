"""Width study (issue 31): HRL-MAPPO cameras (MATE-4v8-9) and MAPPO targets (MATE-2v4-0) with hidden layers of 64,
128 and 256 units, 3 seeds each, at equal decision budgets: learning per decision, then each final policy played
on held-out seeds.

    python docs/tools/width_study.py run [--steps N] [--widths 64 128 256] [--seeds 0 1 2] [--out runs/width]
    python docs/tools/width_study.py report [--out runs/width] [--json docs/tools/results/width-study.json]

`run` trains every missing (setting, width, seed) one after the other with `mate train` (every core for the
update; a run already complete is skipped, an interrupted one resumes). `report` reads the runs: the training
curves' episode metric (cameras: the step-mean coverage of the last 25 training episodes; targets: their
normalised target return) at 25 %, 50 % and 100 % of the budget, and each final policy (`final.pt`) played for
100 episodes on seeds 10,000-10,099 (never used in training) against the greedy agents, batched; mean and
standard deviation over the seeds of each width. Decisions per second are measured apart, on a quiet machine,
with `python benchmarks/trainers.py --only mappo-hrl-camera mappo-target --hidden W W` (the long runs here share
the machine with other work).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

SETTINGS = {
    # name: (mate train arguments, the curve's column, the evaluation's metric, the evaluated team, decisions)
    'hrl-mappo-camera-4v8-9': (['mappo', '--hrl'], 'episode_coverage', 'coverage_rate', 'camera', 1_000_000),
    'mappo-target-2v4-0': (['mappo', '--team', 'target'], 'episode_normalized_target_return',
                           'normalized_target_return', 'target', 500_000),
}
"""The settings and their budgets: 1 M decisions of the HRL cameras, 500k of the targets (which learn most of what
they learn at 1 M by then: docs/training.md), what the 2-core machine allowed in one session."""
EVALUATION_SEEDS = 10_000
"""First seed of the held-out evaluation episodes (training seeds are the env seeds derived from 0, 1, 2)."""


def run_dir(out: Path, setting: str, width: int, seed: int) -> Path:
    return out / f'{setting}-w{width}-seed{seed}'


def train(out: Path, steps: int | None, widths, seeds) -> None:
    for setting, (arguments, *_, budget) in SETTINGS.items():
        for width in widths:
            for seed in seeds:
                folder = run_dir(out, setting, width, seed)
                if (folder / 'final.pt').exists():
                    continue
                command = [sys.executable, '-m', 'mate', 'train', *arguments, '--hidden', str(width), str(width),
                           '--steps', str(steps or budget), '--seed', str(seed), '--run-dir', str(folder),
                           '--no-progress']
                print(' '.join(command[2:]), flush=True)
                subprocess.run(command, check=True, stdout=subprocess.DEVNULL)


def curve(folder: Path, column: str):
    with open(folder / 'progress.csv', newline='') as f:
        rows = list(csv.DictReader(f))
    steps = np.array([float(r['env_steps']) for r in rows])
    values = np.array([float(r[column] or 'nan') for r in rows])
    return steps, values


def value_at(steps, values, fraction: float) -> float:
    """The curve's value at the first logged point at or after `fraction` of the budget."""
    index = int(np.searchsorted(steps, fraction * steps[-1]))
    return float(values[min(index, len(values) - 1)])


def evaluate(folder: Path, team: str, metric: str, episodes: int = 100) -> float:
    import mate
    from mate.policies.policy import PolicyTeam, load_policy
    from mate.teams import GreedyTeam, play_batch

    policy = load_policy(folder / 'final.pt')
    config = policy.spec.game
    vec = mate.make_vec(policy.spec.env_id, num_envs=1, config=policy.spec.config)
    counts = (vec.num_cameras, vec.num_targets, vec.num_obstacles)
    other = 'target' if team == 'camera' else 'camera'
    learned = PolicyTeam(policy, team, episodes, counts, seed=EVALUATION_SEEDS)
    greedy = GreedyTeam(other, episodes, counts, seed=EVALUATION_SEEDS)
    cameras, targets = (learned, greedy) if team == 'camera' else (greedy, learned)
    results, _ = play_batch(config, cameras, targets, episodes, seed=EVALUATION_SEEDS)
    return float(np.mean([getattr(r, metric) for r in results]))


def report(out: Path, widths, seeds, path: Path | None) -> dict:
    table = {}
    for setting, (_, column, metric, team, _) in SETTINGS.items():
        for width in widths:
            cells = dict(curve={25: [], 50: [], 100: []}, evaluation=[], decisions=None)
            for seed in seeds:
                folder = run_dir(out, setting, width, seed)
                if not (folder / 'final.pt').exists():
                    continue
                steps, values = curve(folder, column)
                cells['decisions'] = int(steps[-1])
                for percent in cells['curve']:
                    cells['curve'][percent].append(value_at(steps, values, percent / 100))
                cells['evaluation'].append(evaluate(folder, team, metric))
            table[f'{setting} w{width}'] = cells
            if cells['evaluation']:
                curve_text = '  '.join(f'{p}%: {np.mean(v):.3f}' for p, v in cells['curve'].items())
                print(f'{setting} hidden {width}x{width}: {len(cells["evaluation"])} seeds, {cells["decisions"]:,} '
                      f'decisions; training {curve_text}; evaluation {np.mean(cells["evaluation"]):.4f} '
                      f'± {np.std(cells["evaluation"], ddof=1) if len(cells["evaluation"]) > 1 else 0:.4f}', flush=True)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(table, indent=1))
    return table


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('command', choices=('run', 'report'))
    parser.add_argument('--steps', type=int, default=None, help="decisions per run (default: the setting's budget)")
    parser.add_argument('--widths', type=int, nargs='+', default=[64, 128, 256])
    parser.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2])
    parser.add_argument('--out', type=Path, default=Path('runs/width'))
    parser.add_argument('--json', type=Path, default=None)
    args = parser.parse_args(argv)
    if args.command == 'run':
        train(args.out, args.steps, args.widths, args.seeds)
    else:
        report(args.out, args.widths, args.seeds, args.json)
    return 0


if __name__ == '__main__':
    sys.exit(main())
