"""The figures of a benchmark report: learning curves with IQM bands (`plot_curves`), population experiments'
exploitability per iteration (`plot_exploitability`, the paper's Fig. 7) and meta-strategies (`plot_meta_strategies`,
Fig. 8). Each returns the PNG written, or None when there is nothing to draw."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .results import Results
from .stats import curve_intervals

__all__ = ['plot_curves', 'plot_exploitability', 'plot_meta_strategies']

def plot_curves(results: Results, path, reps: int = 50_000) -> Path | None:
    """Periodic evaluations against decision steps: IQM with its 95 % CI band (`reps` bootstrap replications) per
    setting, one panel per task, the references' evaluation scores as dashed lines. None when no run has an
    evaluation."""
    from ..plotting import pyplot, save_figure

    experiment = results.experiment
    presets = [p for p in experiment.presets if any(r.preset == p and r.evaluations for r in results.runs)]
    if not presets:
        return None
    plt = pyplot()
    figure, axes = plt.subplots(1, len(presets), figsize=(6.2 * len(presets), 4.2), squeeze=False)
    for ax, preset in zip(axes[0], presets):
        for label in results.settings(preset):
            runs = [r for r in results.runs_of(label, preset) if r.evaluations]
            length = min(len(r.evaluations) for r in runs)
            scores = np.array([[np.mean(e) for e in r.evaluations[:length]] for r in runs])
            steps = np.mean([r.steps[:length] for r in runs], axis=0)
            points, lows, highs = curve_intervals({label: scores}, reps=reps)[label]['IQM']
            line, = ax.plot(steps, points, marker='o', markersize=3,
                            label=f'{label} ({len(runs)} run{"s" * (len(runs) != 1)})')
            ax.fill_between(steps, lows, highs, alpha=0.2, color=line.get_color())
        for agent, value in results.reference_means(preset, 'evaluation').items():
            ax.axhline(value, linestyle='--', linewidth=1, color='gray' if agent != 'upper-bound' else 'black')
            ax.annotate(agent, (1.0, value), xycoords=('axes fraction', 'data'), fontsize=7, ha='right', va='bottom')
        ax.set_title(experiment.task(preset))
        ax.set_xlabel('decision steps')
        ax.set_ylabel(f'{results.metric.replace("_", " ")} (IQM, 95 % CI)')
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return save_figure(figure, path)


def plot_exploitability(results: Results, summary: dict, path) -> Path | None:
    """Population experiments: the exploitability (mean of both terms) per iteration, IQM with its 95 % CI band over
    the runs of each setting (`summarise`'s `exploitability_by_iteration`, drawn from `summary`)."""
    from ..plotting import pyplot, save_figure

    experiment = results.experiment
    if not results.populations:
        return None
    plt = pyplot()
    figure, axes = plt.subplots(1, len(experiment.presets), figsize=(6.2 * len(experiment.presets), 4.2),
                                squeeze=False)
    for ax, preset in zip(axes[0], experiment.presets):
        for label, entry in summary['tasks'][experiment.task(preset)]['settings'].items():
            curve = entry.get('exploitability_by_iteration')
            if not curve:
                continue
            points, lows, highs = ([point[key] for point in curve] for key in ('point', 'low', 'high'))
            x = np.arange(1, len(curve) + 1)
            line, = ax.plot(x, points, marker='o', markersize=3,
                            label=f'{label} ({entry["runs"]} run{"s" * (entry["runs"] != 1)})')
            ax.fill_between(x, lows, highs, alpha=0.2, color=line.get_color())
        ax.set_title(preset)
        ax.set_xlabel('iteration')
        ax.set_ylabel('exploitability (IQM, 95 % CI)')
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return save_figure(figure, path)


def plot_meta_strategies(results: Results, path) -> Path | None:
    """Population experiments (Fig. 8): every run's meta-strategies, iteration x policy heat maps; a row per
    (task, setting, team), a column per run."""
    from ..learn.population.plots import draw_meta_strategies
    from ..plotting import pyplot, save_figure

    runs = sorted((key, state) for key, state in results.populations.items() if state['iterations'])
    if not runs:
        return None
    groups = sorted({(preset, label) for (label, preset, _), _ in runs})
    columns = max(sum(1 for (lab, p, _), _ in runs if (p, lab) == group) for group in groups)
    iterations = max(len(state['iterations']) for _, state in runs)
    plt = pyplot()
    height = 0.22 * iterations + 1.4
    figure, axes = plt.subplots(2 * len(groups), columns, figsize=(3.2 * columns, height * 2 * len(groups)),
                                squeeze=False)
    for row, (preset, label) in enumerate(groups):
        members = [(seed, state) for (lab, p, seed), state in runs if (p, lab) == (preset, label)]
        for team_row, team in enumerate(('camera', 'target')):
            for column in range(columns):
                ax = axes[2 * row + team_row][column]
                if column >= len(members):
                    ax.axis('off')
                    continue
                seed, state = members[column]
                draw_meta_strategies(ax, state, team, f'{label} {team}s, {preset}, seed {seed}')
    return save_figure(figure, path)
