"""Learning curves of the paper's cooperative settings, 3 seeds each, as PNG (mean ± std over seeds).

    python scripts/paper_curves.py --steps 2e6 --out results/       # trains, then plots
    python scripts/paper_curves.py --plot-only --out results/        # plots existing runs

Experiments (spec training.md §0): cameras (flat and HRL) vs batched greedy targets on MATE-4v8-9 (frame
skip 5, coverage-rate reward; curve: rollout coverage rate) and targets vs batched greedy cameras on
MATE-2v4-0 and MATE-4v8-0 (frame skip 10, raw dense reward; curve: episode target reward normalised by the
preset's maximum), and the paper's Fig. 6 observability ablation (`target-2v4-0-full-obs`: the same
targets seeing every entity, drawn with the partial-observability runs in `targets-2v4-0-observability`).
The dashed line is the greedy agent of the trained team in the same setting (batched
greedy opponents, training-length episodes), measured when plotting. Runs go to OUT/runs/NAME-seedS and
resume after an interruption (`mate train` checkpoints). `--jobs 2` runs two trainings at a time.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

EXPERIMENTS = {
    # name: (mate train arguments, figure(s), metric column, y label)
    'camera-4v8-9': (['--team', 'camera', '--config', 'MATE-4v8-9'], 'cameras-4v8-9', 'rollout_coverage',
                     'mean coverage rate'),
    # HRL: the recipe of the shipped policy (pretrained/hrl-mappo-camera-4v8-9.pt), a higher entropy bonus
    'hrl-camera-4v8-9': (['--team', 'camera', '--config', 'MATE-4v8-9', '--hrl',
                          '--entropy-schedule', '[[0, 0.03], [2000000, 0.01], [4000000, 0]]'], 'cameras-4v8-9',
                         'rollout_coverage', 'mean coverage rate'),
    'target-2v4-0': (['--team', 'target', '--config', 'MATE-2v4-0'], ('targets-2v4-0', 'targets-2v4-0-observability'),
                     'episode_normalized_target_return', 'normalised target episode reward'),
    # the paper's Fig. 6 ablation: the same, with the targets seeing everything (EnhancedObservation)
    'target-2v4-0-full-obs': (['--team', 'target', '--config', 'MATE-2v4-0', '--full-observability'],
                              'targets-2v4-0-observability', 'episode_normalized_target_return',
                              'normalised target episode reward'),
    'target-4v8-0': (['--team', 'target', '--config', 'MATE-4v8-0'], 'targets-4v8-0',
                     'episode_normalized_target_return', 'normalised target episode reward'),
}
FIGURE_SETTINGS = {'cameras-4v8-9': ('camera', 'MATE-4v8-9-v0'), 'targets-2v4-0': ('target', 'MATE-2v4-0-v0'),
                   'targets-4v8-0': ('target', 'MATE-4v8-0-v0'),
                   'targets-2v4-0-observability': ('target', 'MATE-2v4-0-v0')}


def greedy_reference(team: str, env_id: str, num_envs: int = 64, seed: int = 0) -> float:
    """The greedy agent of `team` in the learner's setting: batched greedy cameras vs batched greedy targets,
    one training episode per env (the 500-decision horizon in raw steps), scored with the curve's metric:
    step-mean coverage rate (cameras) or normalised target episode reward (targets)."""
    import mate
    from mate.learn import PAPER_SETTINGS, VecGreedyCamera, VecGreedyTarget

    horizon = PAPER_SETTINGS[team]['horizon']
    vec = mate.make_vec(env_id, num_envs=num_envs, max_episode_steps=horizon)
    (camera_obs, target_obs), _ = vec.reset(seed=seed)
    cameras = VecGreedyCamera(num_envs, vec.num_cameras, vec.num_targets, vec.num_obstacles, seed=seed + 1)
    targets = VecGreedyTarget(num_envs, vec.num_targets, seed=seed + 2)
    cameras.reset(camera_obs)
    targets.reset(target_obs)
    live = np.ones(num_envs, dtype=bool)
    coverage, steps, target_return = np.zeros(num_envs), np.zeros(num_envs), np.zeros(num_envs)
    while live.any():
        (camera_obs, target_obs), (_, target_reward), terminated, truncated, infos = vec.step(
            (cameras.act(camera_obs), targets.act(target_obs)))
        coverage += live * infos['coverage_rate']
        target_return += live * target_reward
        steps += live
        live &= ~(terminated | truncated)
    if team == 'camera':
        return float(np.mean(coverage / steps))
    return float(np.mean(target_return) / vec.params.max_target_team_episode_reward)


def run_one(out: Path, name: str, algo: str, seed: int, steps: float, extra: list[str]) -> int:
    run_dir = out / 'runs' / f'{algo}-{name}-seed{seed}'
    command = [sys.executable, '-m', 'mate.cli', 'train', algo, *EXPERIMENTS[name][0], '--steps', str(steps),
               '--seed', str(seed), '--run-dir', str(run_dir), '--no-progress', *extra]
    print(' '.join(command), flush=True)
    return subprocess.call(command, stdout=subprocess.DEVNULL)


def read_curve(path: Path, column: str):
    with open(path, newline='') as f:
        rows = list(csv.DictReader(f))
    x = np.array([float(r['env_steps']) for r in rows])
    y = np.array([float(r[column]) for r in rows])
    return x, y


def plot(out: Path, algos: list[str], seeds: list[int]) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    figures = {}
    for name, (_, names, column, label) in EXPERIMENTS.items():
        for figure in (names,) if isinstance(names, str) else names:
            figures.setdefault(figure, []).append((name, column, label))
    for figure, members in figures.items():
        fig, ax = plt.subplots(figsize=(6, 4))
        drawn = False
        for name, column, label in members:
            for algo in algos:
                curves = [read_curve(p, column) for seed in seeds
                          if (p := out / 'runs' / f'{algo}-{name}-seed{seed}' / 'progress.csv').exists()]
                curves = [(x[~np.isnan(y)], y[~np.isnan(y)]) for x, y in curves if (~np.isnan(y)).sum() > 1]
                if not curves:
                    continue
                grid = np.linspace(0, min(x[-1] for x, _ in curves), 200)
                ys = np.array([np.interp(grid, x, y) for x, y in curves])
                mean, std = ys.mean(0), ys.std(0)
                prefix = 'HRL-' if name.startswith('hrl') else ''
                suffix = (', full obs.' if name.endswith('full-obs') else ', partial obs.') if 'observability' in figure else ''
                ax.plot(grid, mean, label=f'{prefix}{algo.upper()}{suffix} ({len(ys)} seed{"s" * (len(ys) > 1)})')
                ax.fill_between(grid, mean - std, mean + std, alpha=0.25)
                drawn = True
        if not drawn:
            plt.close(fig)
            continue
        team, env_id = FIGURE_SETTINGS[figure]
        ax.axhline(greedy_reference(team, env_id), color='grey', linestyle='--',
                   label=f'greedy {team}s (same setting)')
        ax.set_xlabel('decision steps')
        ax.set_ylabel(label)
        ax.set_title(figure)
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / f'{figure}.png', dpi=120)
        plt.close(fig)
        print(f'wrote {out / f"{figure}.png"}')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--out', default='results', type=Path)
    parser.add_argument('--steps', type=float, default=2e6)
    parser.add_argument('--algos', nargs='+', default=['mappo', 'ippo'])
    parser.add_argument('--seeds', nargs='+', type=int, default=[0, 1, 2])
    parser.add_argument('--experiments', nargs='+', default=list(EXPERIMENTS), choices=list(EXPERIMENTS))
    parser.add_argument('--jobs', type=int, default=1)
    parser.add_argument('--plot-only', action='store_true')
    parser.add_argument('--train-args', default='', help='extra `mate train` arguments, one string')
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if not args.plot_only:
        tasks = [(name, algo, seed) for name in args.experiments for algo in args.algos for seed in args.seeds]
        with ThreadPoolExecutor(args.jobs) as pool:
            codes = list(pool.map(lambda t: run_one(args.out, *t, args.steps, args.train_args.split()), tasks))
        if any(codes):
            print(f'{sum(c != 0 for c in codes)} runs failed', file=sys.stderr)
    plot(args.out, args.algos, args.seeds)


if __name__ == '__main__':
    main()
