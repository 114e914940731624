"""The figures of a benchmark report: every setting's score with its interval beside the references and the claims'
verdicts (`plot_intervals`), learning curves with IQM bands (`plot_curves`), population experiments' exploitability
per iteration (`plot_exploitability`, the paper's Fig. 7) and meta-strategies (`plot_meta_strategies`, Fig. 8). Each
returns the PNG written, or None when there is nothing to draw; the legends sit outside the axes, off the data."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .results import Results
from .stats import curve_intervals

__all__ = ['VERDICT_COLOURS', 'plot_curves', 'plot_exploitability', 'plot_intervals', 'plot_meta_strategies']

VERDICT_COLOURS = {'confirmed': '#1a7f37', 'equivalent': '#1a7f37', 'refuted': '#cf222e', 'differ': '#cf222e'}
"""The colour of a decisive verdict in `plot_intervals` (the others, not decisive, are grey)."""
UNDECIDED = '#6e7781'
PALETTE = 256
"""The colours of a report figure's PNG (an adaptive palette: a third to a quarter of the bytes of full colour, each
pixel within 10 of 255 of it; the repository carries the committed reports' figures)."""
REFERENCE = '#24292f'


def _scored(summary: dict, entry: dict) -> tuple[dict | None, list]:
    """A setting's interval and each run's score in an interval plot: the absolute metric's IQM; population
    experiments: the final exploitability's, on fresh seeds when measured."""
    if summary['team'] != 'both':
        return entry['absolute']['IQM'], entry.get('values', [])
    key = 'exploitability_fresh' if 'final_exploitability_fresh' in entry else 'exploitability'
    scores = entry.get(f'final_{key}')
    return (scores and scores['IQM']), entry.get(f'final_{key}_values', [])


def plot_intervals(summary: dict, path, width: float = 8.0, dpi: int = 90) -> Path | None:
    """One experiment's scores as an interval plot (the kind rliable and marl-eval draw): a panel per task, a row
    per setting with a dot at the IQM of its absolute metric, its 95 % CI as a bar and each run's score as a tick
    (population experiments: the final exploitability, on fresh seeds when measured; lower is better), the
    references as marked rows with a dotted line across the panel, and under the panel the task's claims that have
    a test, each with its verdict (decisive ones in colour) and its p after Holm's correction. Drawn from `summary`
    alone (an entry of `results.json`), so a committed report's picture is drawn again from the report; the
    settings' colours are those of the curves. None when no task has a run."""
    import textwrap

    from ..tools.plotting import pyplot, save_figure
    from ..evaluation.protocol import TEAM_METRIC
    from .verdicts import p_value

    population = summary['team'] == 'both'
    tested = [claim for claim in summary.get('claims', ()) if 'p' in claim]
    indent = 0.45 + 0.062 * max((len(claim['verdict']) for claim in tested), default=0)
    panels = []
    for task, data in summary['tasks'].items():
        settings = [(label, *_scored(summary, entry), entry['runs']) for label, entry in data['settings'].items()]
        settings = [row for row in settings if row[1]]
        if settings:          # each claim: its verdict and its words, wrapped to the width left of the verdicts
            claims = [(claim['verdict'], textwrap.wrap(f'{claim["text"]}  (p after Holm: {p_value(claim["p_holm"])})',
                                                       int((width - indent - 0.2) / 0.058)))
                      for claim in tested if claim['task'] == task]
            panels.append((task, settings, data.get('references', {}), claims))
    if not panels:
        return None
    inch = dict(top=0.75, title=0.32, row=0.27, axis=0.5, claim=0.19, gap=0.2)
    heights = [inch['title'] + inch['row'] * (len(settings) + len(references) + 0.4) + inch['axis']
               + inch['claim'] * sum(len(words) for _, words in claims) + inch['gap']
               for _, settings, references, claims in panels]
    height = inch['top'] + sum(heights)
    labels = [f'{label} ({runs} run{"s" * (runs != 1)})' for _, settings, _, _ in panels
              for label, *_, runs in settings]
    labels += [f'{agent} (reference)' for _, _, references, _ in panels for agent in references]
    left = min(0.45 * width, 0.25 + 0.068 * max(map(len, labels)))
    plt = pyplot()
    figure = plt.figure(figsize=(width, height))
    unit = 'per best response' if population else 'per run'
    title = f'{summary["experiment"]}: {summary["figure"]}'
    figure.text(0.5, 1 - 0.16 / height, title, ha='center', va='top', weight='bold',
                fontsize=min(11.0, 72 * (width - 0.3) / (0.62 * len(title))))
    figure.text(0.5, 1 - 0.40 / height, f'{summary["steps"]:,} decision steps {unit}; 95 % stratified-bootstrap '
                'intervals over the runs', ha='center', va='top', fontsize=8.5, color=UNDECIDED)
    metric = ('final exploitability' + (' on fresh seeds' if any('final_exploitability_fresh' in entry
                                                                  for data in summary['tasks'].values()
                                                                  for entry in data['settings'].values()) else '')
              + ' (lower is better)') if population else \
        f'{TEAM_METRIC[summary["team"]].replace("_", " ")} on the held-out episodes (absolute metric)'
    top = inch['top']
    for (task, settings, references, claims), panel in zip(panels, heights):
        rows = len(settings) + len(references)
        axes_top = top + inch['title']
        axes_height = inch['row'] * (rows + 0.4)
        ax = figure.add_axes((left / width, 1 - (axes_top + axes_height) / height, 1 - (left + 0.3) / width,
                              axes_height / height))
        values = []
        for row, (label, interval, runs_scores, runs) in enumerate(settings):
            colour = f'C{row}'
            ax.plot([interval['low'], interval['high']], [row, row], color=colour, linewidth=7, alpha=0.35,
                    solid_capstyle='butt')
            ax.plot(list(runs_scores), [row] * len(runs_scores), linestyle='none', marker='|', markersize=9,
                    color=colour, alpha=0.9)
            ax.plot(interval['point'], row, marker='o', markersize=6.5, color=colour, markeredgecolor='white')
            values += [interval['low'], interval['high'], *runs_scores]
        for row, (agent, reference) in enumerate(references.items(), len(settings)):
            ax.axvline(reference['absolute'], color=REFERENCE, linestyle=':', linewidth=1, alpha=0.7)
            ax.plot(reference['absolute'], row, marker='D', markersize=5.5, color=REFERENCE)
            values.append(reference['absolute'])
        ax.set_yticks(range(rows), [f'{label} ({runs} run{"s" * (runs != 1)})' for label, *_, runs in settings]
                      + [f'{agent} (reference)' for agent in references], fontsize=8.5)
        for tick in ax.get_yticklabels()[len(settings):]:
            tick.set_fontstyle('italic')
        ax.set_ylim(rows - 0.5, -0.7)
        low, high = min(values), max(values)
        margin = 0.06 * (high - low) or 0.05 * max(abs(high), 1e-3)
        ax.set_xlim(low - margin, high + margin)
        ax.set_title(task, loc='left', fontsize=9.5)
        ax.set_xlabel(metric, fontsize=8.5)
        ax.tick_params(axis='x', labelsize=8)
        ax.tick_params(axis='y', length=0)
        ax.grid(axis='x', alpha=0.3)
        for side in ('top', 'right', 'left'):
            ax.spines[side].set_visible(False)
        line = axes_top + axes_height + inch['axis']
        for verdict, words in claims:
            y = 1 - (line + inch['claim'] / 2) / height
            figure.text(0.2 / width, y, verdict, color=VERDICT_COLOURS.get(verdict, UNDECIDED), weight='bold',
                        fontsize=8, va='center')
            for text in words:
                figure.text(indent / width, 1 - (line + inch['claim'] / 2) / height, text, fontsize=8, va='center')
                line += inch['claim']
        top += panel
    handles = [plt.Line2D([], [], linestyle='none', marker='o', color='0.35', markersize=6, label='IQM'),
               plt.Line2D([], [], color='0.35', linewidth=7, alpha=0.35, label='95 % CI'),
               plt.Line2D([], [], linestyle='none', marker='|', color='0.35', markersize=9, label='each run')]
    if any(references for _, _, references, _ in panels):
        handles.append(plt.Line2D([], [], linestyle=':', marker='D', color=REFERENCE, markersize=5, label='reference'))
    figure.legend(handles=handles, loc='upper center', bbox_to_anchor=(0.5, 1 - 0.52 / height), ncol=len(handles),
                  frameon=False, fontsize=8)
    return save_figure(figure, path, dpi=dpi, layout=False, palette=PALETTE)


def plot_curves(results: Results, path, reps: int = 50_000) -> Path | None:
    """Periodic evaluations against decision steps: IQM with its 95 % CI band (`reps` bootstrap replications) per
    setting, one panel per task, the references' evaluation scores as dashed lines. None when no run has an
    evaluation."""
    from ..tools.plotting import pyplot, save_figure

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
            ax.annotate(agent, (1.01, value), xycoords=('axes fraction', 'data'), fontsize=7, ha='left',
                        va='center', annotation_clip=False)
        ax.set_title(experiment.task(preset))
        ax.set_xlabel('decision steps')
        ax.xaxis.set_major_formatter(_steps_label)
        ax.set_ylabel(f'{results.metric.replace("_", " ")} (IQM, 95 % CI)')
        ax.grid(alpha=0.3)
        _legend_below(ax)
    return save_figure(figure, path, palette=PALETTE)


def _steps_label(steps: float, _=None) -> str:
    """A tick of decision steps: '500k', '1.5 M' ('120' below a thousand)."""
    return f'{steps / 1e6:g} M' if abs(steps) >= 1e6 else f'{steps / 1e3:g}k' if abs(steps) >= 1e3 else f'{steps:g}'


def _legend_below(ax) -> None:
    """The settings' legend under the axes' x label, off the data (two or three columns)."""
    count = len(ax.get_legend_handles_labels()[1])
    ax.legend(fontsize=8, loc='upper center', bbox_to_anchor=(0.5, -0.16), ncol=min(3, max(count, 1)),
              frameon=False)


def plot_exploitability(results: Results, summary: dict, path) -> Path | None:
    """Population experiments: the exploitability (mean of both terms) per iteration, IQM with its 95 % CI band over
    the runs of each setting (`summarise`'s `exploitability_by_iteration`, drawn from `summary`)."""
    from ..tools.plotting import pyplot, save_figure

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
        _legend_below(ax)
    return save_figure(figure, path, palette=PALETTE)


def plot_meta_strategies(results: Results, path) -> Path | None:
    """Population experiments (Fig. 8): every run's meta-strategies, iteration x policy heat maps; a row per
    (task, setting, team), a column per run."""
    from ..learn.population.plots import draw_meta_strategies
    from ..tools.plotting import pyplot, save_figure

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
    return save_figure(figure, path, palette=PALETTE)
