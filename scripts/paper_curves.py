"""Learning curves of the paper's cooperative settings, 3 seeds each, as PNG (mean ± std over seeds).

    python scripts/paper_curves.py                                 # redraw the figures from the shipped logs
    python scripts/paper_curves.py plot --logs DIR --out FIGURES   # draw from other logs
    python scripts/paper_curves.py train --steps 2e6 --out results # train every run (hours), then draw
    python scripts/paper_curves.py table --at 1e5 2e5              # each curve's mean ± std at these budgets

`plot` (the default) reads, for each experiment, algorithm and seed, LOGS/ALGO-NAME-seedS.csv (the thinned
logs shipped in scripts/results/) or LOGS/runs/ALGO-NAME-seedS/progress.csv (what `train` writes; preferred
when both exist), and writes FIGURES/FIGURE.png (default: into LOGS); it exits with status 1 if it finds no
log to draw. `train` runs `mate train` for every (experiment, algorithm, seed) into OUT/runs/ALGO-NAME-seedS
(runs resume after an interruption: `mate train` checkpoints; `--jobs 2` runs two at a time), then draws
from OUT into OUT.

Experiments (spec training.md §0): cameras (flat and HRL) vs batched greedy targets on MATE-4v8-9 (frame
skip 5, coverage-rate reward; curve: rollout coverage rate) and targets vs batched greedy cameras on
MATE-2v4-0 and MATE-4v8-0 (frame skip 10, raw dense reward; curve: episode target reward normalised by the
preset's maximum), and the paper's Fig. 6 observability ablation (`target-2v4-0-full-obs`: the same
targets seeing every entity, drawn with the partial-observability runs in `targets-2v4-0-observability`), and
the HRL cameras' target selection side by side in `cameras-4v8-9-hrl` (HRL-MAPPO; IQL and QMIX choosing one of
the 256 subsets or with a keep/ignore head per target; per-target IQL paid with the difference reward).
The dashed line is the greedy agent of the trained team in the same setting (batched greedy opponents,
training-length episodes), measured when plotting (a few seconds each).
"""

from __future__ import annotations

import argparse
import csv
import functools
import importlib.util
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ALGOS = ('mappo', 'ippo', 'iql', 'qmix', 'maddpg')
PPO_ALGOS = ('mappo', 'ippo')
EXPERIMENTS = {
    # name: (mate train arguments, figure(s), metric column, y label); PPO_ARGUMENTS are added for MAPPO/IPPO
    'camera-4v8-9': (['--team', 'camera', '--config', 'MATE-4v8-9'], 'cameras-4v8-9', 'rollout_coverage',
                     'mean coverage rate'),
    # HRL: the recipe of the shipped policy (pretrained/hrl-mappo-camera-4v8-9.pt), a higher entropy bonus
    'hrl-camera-4v8-9': (['--team', 'camera', '--config', 'MATE-4v8-9', '--hrl'],
                         ('cameras-4v8-9', 'cameras-4v8-9-communication', 'cameras-4v8-9-hrl'), 'rollout_coverage',
                         'mean coverage rate'),
    # the same with TarMAC messages (issue 22; same entropy recipe)
    'hrl-tarmac-camera-4v8-9': (['--team', 'camera', '--config', 'MATE-4v8-9', '--hrl', '--comm', 'tarmac'],
                                'cameras-4v8-9-communication', 'rollout_coverage', 'mean coverage rate'),
    # value-based HRL with a keep/ignore head per target slot instead of the spec's Discrete(256) (the default)
    'hrl-per-target-camera-4v8-9': (['--team', 'camera', '--config', 'MATE-4v8-9', '--hrl', '--selection', 'per-target'],
                                    ('cameras-4v8-9', 'cameras-4v8-9-hrl'), 'rollout_coverage', 'mean coverage rate'),
    # the same, each camera paid its own share of the coverage (difference reward; IQL only: QMIX mixes the team's)
    'hrl-per-target-difference-camera-4v8-9': (['--team', 'camera', '--config', 'MATE-4v8-9', '--hrl', '--selection',
                                                'per-target', '--credit', 'difference'],
                                               'cameras-4v8-9-hrl', 'rollout_coverage', 'mean coverage rate'),
    'target-2v4-0': (['--team', 'target', '--config', 'MATE-2v4-0'], ('targets-2v4-0', 'targets-2v4-0-observability'),
                     'episode_normalized_target_return', 'normalised target episode reward'),
    # the paper's Fig. 6 ablation: the same, with the targets seeing everything (EnhancedObservation)
    'target-2v4-0-full-obs': (['--team', 'target', '--config', 'MATE-2v4-0', '--full-observability'],
                              'targets-2v4-0-observability', 'episode_normalized_target_return',
                              'normalised target episode reward'),
    'target-4v8-0': (['--team', 'target', '--config', 'MATE-4v8-0'], ('targets-4v8-0', 'targets-4v8-0-communication'),
                     'episode_normalized_target_return', 'normalised target episode reward'),
    # the paper's Fig. 4b/5 add-ons: learned communication among the targets (TarMAC for MAPPO and IPPO, I2C for MAPPO)
    'target-4v8-0-tarmac': (['--team', 'target', '--config', 'MATE-4v8-0', '--comm', 'tarmac'],
                            'targets-4v8-0-communication', 'episode_normalized_target_return',
                            'normalised target episode reward'),
    'target-4v8-0-i2c': (['--team', 'target', '--config', 'MATE-4v8-0', '--comm', 'i2c'],
                         'targets-4v8-0-communication', 'episode_normalized_target_return',
                         'normalised target episode reward'),
}
# HRL-MAPPO: the recipe of the shipped policy (pretrained/hrl-mappo-camera-4v8-9.pt), a higher entropy bonus
RECIPE = ['--entropy-schedule', '[[0, 0.03], [2000000, 0.01], [4000000, 0]]']
PPO_ARGUMENTS = {'hrl-camera-4v8-9': RECIPE, 'hrl-tarmac-camera-4v8-9': RECIPE}
COMMUNICATION = {'tarmac': '+TarMAC', 'i2c': '+I2C'}      # experiment name part -> legend suffix
FIGURE_SETTINGS = {'cameras-4v8-9': ('camera', 'MATE-4v8-9-v0'), 'targets-2v4-0': ('target', 'MATE-2v4-0-v0'),
                   'targets-4v8-0': ('target', 'MATE-4v8-0-v0'),
                   'targets-4v8-0-communication': ('target', 'MATE-4v8-0-v0'),
                   'cameras-4v8-9-communication': ('camera', 'MATE-4v8-9-v0'),
                   'cameras-4v8-9-hrl': ('camera', 'MATE-4v8-9-v0'),
                   'targets-2v4-0-observability': ('target', 'MATE-2v4-0-v0')}


@functools.lru_cache(maxsize=None)
def greedy_reference(team: str, env_id: str, num_envs: int = 64, seed: int = 0) -> float:
    """The greedy agent of `team` in the learner's setting: greedy cameras vs greedy targets (`mate.teams`),
    one training episode per env (the 500-decision horizon in raw steps), scored with the curve's metric:
    step-mean coverage rate (cameras) or normalised target episode reward (targets)."""
    import mate
    from mate.learn.envs import PAPER_SETTINGS
    from mate.teams import GreedyTeam

    horizon = 500 * PAPER_SETTINGS[team]['frame_skip']
    vec = mate.make_vec(env_id, num_envs=num_envs, max_episode_steps=horizon)
    (camera_obs, target_obs), _ = vec.reset(seed=seed)
    counts = (vec.num_cameras, vec.num_targets, vec.num_obstacles)
    cameras, targets = GreedyTeam('camera', num_envs, counts, seed=seed), GreedyTeam('target', num_envs, counts, seed=seed)
    everyone = np.ones(num_envs, dtype=bool)
    cameras.reset(camera_obs, everyone)
    targets.reset(target_obs, everyone)
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


def trainer_arguments(algo: str, arguments: list[str]) -> list[str]:
    """`mate train` arguments of an experiment for `algo`: a communicating experiment (`--comm tarmac|i2c`) runs the
    trainer of that name (`tarmac` with `--critic local` for IPPO)."""
    arguments = list(arguments)
    if '--comm' not in arguments:
        return [algo, *arguments]
    at = arguments.index('--comm')
    comm = arguments[at + 1]
    del arguments[at:at + 2]
    return [comm, *(['--critic', 'local'] if algo == 'ippo' else []), *arguments]


def run_one(out: Path, name: str, algo: str, seed: int, steps: float, extra: list[str]) -> int:
    run_dir = out / 'runs' / f'{algo}-{name}-seed{seed}'
    ppo = PPO_ARGUMENTS.get(name, []) if algo in PPO_ALGOS else []
    command = [sys.executable, '-m', 'mate.cli', 'train', *trainer_arguments(algo, EXPERIMENTS[name][0]), *ppo,
               '--steps', str(int(float(steps))), '--seed', str(seed), '--run-dir', str(run_dir), '--no-progress',
               *extra]
    print(' '.join(command), flush=True)
    return subprocess.call(command, stdout=subprocess.DEVNULL)


def read_curve(path: Path, column: str):
    """(decision steps, `column`) of a progress CSV, as float arrays (NaN where the log has none)."""
    with open(path, newline='') as f:
        rows = list(csv.DictReader(f))
    x = np.array([float(r['env_steps']) for r in rows])
    y = np.array([float(r[column] or 'nan') for r in rows])     # an empty cell: nothing logged
    return x, y


def find_log(logs: Path, run: str) -> Path | None:
    """The progress CSV of `run` (ALGO-NAME-seedS) under `logs`: a `train` run directory's, else a thinned copy."""
    for path in (logs / 'runs' / run / 'progress.csv', logs / f'{run}.csv'):
        if path.is_file():
            return path
    return None


def seed_curves(logs: Path, run: str, seeds: list[int], column: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """The logged points (steps, `column`) of each seed's run RUN-seedS under `logs` that has one (NaN rows left
    out; a curve with fewer than two points is left out)."""
    curves = [read_curve(path, column) for seed in seeds if (path := find_log(logs, f'{run}-seed{seed}')) is not None]
    return [(x[~np.isnan(y)], y[~np.isnan(y)]) for x, y in curves if (~np.isnan(y)).sum() > 1]


def plot(logs: Path, out: Path, algos: list[str], seeds: list[int], experiments: list[str]) -> list[Path]:
    """Draw every figure with at least one curve of `experiments` from the logs under `logs` into `out`;
    returns the PNGs written."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    figures = {}
    for name in experiments:
        _, names, column, label = EXPERIMENTS[name]
        for figure in (names,) if isinstance(names, str) else names:
            figures.setdefault(figure, []).append((name, column, label))
    written = []
    for figure, members in figures.items():
        fig, ax = plt.subplots(figsize=(6, 4))
        drawn = False
        for name, column, label in members:
            for algo in algos:
                if figure.endswith('-communication') and algo not in PPO_ALGOS:
                    continue        # the add-ons are PPO's: their figures compare PPO learners only
                curves = seed_curves(logs, f'{algo}-{name}', seeds, column)
                if not curves:
                    continue
                grid = np.geomspace(max(x[0] for x, _ in curves), min(x[-1] for x, _ in curves), 200)
                ys = np.array([np.interp(grid, x, y) for x, y in curves])
                mean, std = ys.mean(0), ys.std(0)
                prefix = 'HRL-' if name.startswith('hrl') else ''
                suffix = (', full obs.' if name.endswith('full-obs') else ', partial obs.') if 'observability' in figure else ''
                suffix += ', per-target heads' if 'per-target' in name else ''
                suffix += ', difference reward' if 'difference' in name.split('-') else ''
                suffix = ''.join(tag for part, tag in COMMUNICATION.items() if part in name.split('-')) + suffix
                ax.plot(grid, mean, label=f'{prefix}{algo.upper()}{suffix} ({len(ys)} seed{"s" * (len(ys) > 1)})')
                ax.fill_between(grid, mean - std, mean + std, alpha=0.25)
                drawn = True
        if not drawn:
            plt.close(fig)
            continue
        team, env_id = FIGURE_SETTINGS[figure]
        ax.axhline(greedy_reference(team, env_id), color='black', linestyle='--',     # black: no curve's colour
                   label=f'greedy {team}s (same setting)')
        ax.set_xscale('log')      # off-policy runs of minutes beside PPO runs of millions of steps
        ax.set_xlabel('decision steps (log scale)')
        ax.set_ylabel(label)
        ax.set_title(figure)
        if len(ax.lines) > 8:      # a long legend goes beside the axes, not over the curves
            fig.set_size_inches(9, 4)
            ax.legend(fontsize='small', loc='center left', bbox_to_anchor=(1.01, 0.5))
        else:
            ax.legend(fontsize='small')
        fig.tight_layout()
        out.mkdir(parents=True, exist_ok=True)
        fig.savefig(out / f'{figure}.png', dpi=120)
        plt.close(fig)
        written.append(out / f'{figure}.png')
        print(f'wrote {out / f"{figure}.png"}')
    return written


def table(logs: Path, algos: list[str], seeds: list[int], experiments: list[str], budgets: list[float]) -> str:
    """A markdown table of each (experiment, algorithm) curve at each budget (decision steps): mean ± std over the
    seeds whose log reaches it (the value interpolated between logged points, as drawn), '-' where none does."""
    lines = ['| experiment | algorithm | seeds | ' + ' | '.join(f'{b:,.0f} decisions' for b in budgets) + ' |',
             '|---|---|---|' + '---|' * len(budgets)]
    for name in experiments:
        column = EXPERIMENTS[name][2]
        for algo in algos:
            curves = seed_curves(logs, f'{algo}-{name}', seeds, column)
            if not curves:
                continue
            cells = []
            for budget in budgets:
                values = [np.interp(budget, x, y) for x, y in curves if x[0] <= budget <= x[-1]]
                cells.append(f'{np.mean(values):.3f} ± {np.std(values):.3f} ({len(values)})' if values else '-')
            lines.append(f'| {name} | {algo} | {len(curves)} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


SHIPPED_LOGS = Path(__file__).resolve().parent / 'results'
COMMANDS = ('plot', 'train', 'table')


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest='command', required=True, metavar='{plot,train,table}')
    selection = argparse.ArgumentParser(add_help=False)
    selection.add_argument('--algos', nargs='+', default=list(ALGOS), choices=ALGOS,
                           help='algorithms (default all; `train` skips MADDPG on HRL experiments)')
    selection.add_argument('--seeds', nargs='+', type=int, default=[0, 1, 2])
    selection.add_argument('--experiments', nargs='+', default=list(EXPERIMENTS), choices=list(EXPERIMENTS))

    draw = commands.add_parser('plot', parents=[selection], help='draw the figures from existing logs (the default)')
    draw.add_argument('--logs', type=Path, default=SHIPPED_LOGS,
                      help=f'where the logs are (default: the shipped ones, {SHIPPED_LOGS})')
    draw.add_argument('--out', type=Path, default=None, help='where the PNGs go (default: the --logs directory)')
    draw.add_argument('--plot-only', action='store_true', help=argparse.SUPPRESS)   # the former spelling of `plot`

    at = commands.add_parser('table', parents=[selection], help='print each curve at given budgets (markdown)')
    at.add_argument('--logs', type=Path, default=SHIPPED_LOGS, help=f'where the logs are (default {SHIPPED_LOGS})')
    at.add_argument('--at', type=float, nargs='+', required=True, metavar='STEPS', help='budgets in decision steps')

    train = commands.add_parser('train', parents=[selection], help='train every run with `mate train`, then draw')
    train.add_argument('--out', type=Path, default=Path('results'), help='runs go to OUT/runs/, PNGs to OUT (default results)')
    train.add_argument('--steps', type=float, default=2e6, help='decision steps per run (default 2e6)')
    train.add_argument('--jobs', type=int, default=1, help='trainings at a time (default 1)')
    train.add_argument('--train-args', default='', help='extra `mate train` arguments, one string')
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in (*COMMANDS, '-h', '--help'):
        argv.insert(0, 'plot')      # no command: redraw
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command == 'train':
        if importlib.util.find_spec('mate') is None:     # found now, not after hours of training when plotting
            parser.error('the mate package is not importable by this Python: install it (pip install -e .) first')
        args.out.mkdir(parents=True, exist_ok=True)
        tasks = [(name, algo, seed) for name in args.experiments for algo in args.algos for seed in args.seeds
                 if not (algo == 'maddpg' and name.startswith('hrl'))      # HRL selects targets: no continuous form
                 and not (algo not in ('iql', 'qmix') and 'per-target' in name)
                 and not (algo != 'iql' and 'difference' in name.split('-'))      # the difference reward: IQL's
                 and not (algo not in PPO_ALGOS and any(part in name.split('-') for part in COMMUNICATION))
                 and not (algo == 'ippo' and 'i2c' in name.split('-'))]      # I2C is a MAPPO add-on
        with ThreadPoolExecutor(args.jobs) as pool:
            codes = list(pool.map(lambda t: run_one(args.out, *t, args.steps, args.train_args.split()), tasks))
        if any(codes):
            print(f'{sum(c != 0 for c in codes)} runs failed', file=sys.stderr)
        logs = out = args.out
    elif args.command == 'table':
        print(table(args.logs, args.algos, args.seeds, args.experiments, args.at))
        return 0
    else:
        logs, out = args.logs, args.out or args.logs
    if not plot(logs, out, args.algos, args.seeds, args.experiments):
        print(f'nothing to plot: no log in {logs} of {", ".join(args.experiments)} with algos {" ".join(args.algos)} '
              f'and seeds {" ".join(map(str, args.seeds))} (looked for ALGO-NAME-seedS.csv and '
              'runs/ALGO-NAME-seedS/progress.csv)', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
