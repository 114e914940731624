"""Figures of population runs (PNG, matplotlib's Agg backend): the paper's Fig. 7 and Fig. 8.

* `plot_exploitability(states, path)`: exploitability per iteration, one line per solver, the mean over
  the runs (seeds) of that solver with a band of ± one standard deviation; a panel per term (mean,
  cameras, targets).
* `plot_meta_strategies(state, path)`: the meta-strategy of each iteration as a heat map (iteration x
  policy index), one panel per team (`draw_meta_strategies` draws one panel into given axes).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...tools.plotting import pyplot, save_figure

__all__ = ['SOLVER_NAMES', 'draw_meta_strategies', 'exploitability_table', 'meta_strategy_grid', 'plot_exploitability',
           'plot_meta_strategies']

SOLVER_NAMES = {'nash': 'PSRO-Nash', 'uniform': 'FSP (uniform)', 'last': 'SP (newest)'}


def exploitability_table(states: list[dict]) -> dict[str, dict[str, np.ndarray]]:
    """{solver: {'camera' | 'target' | 'mean': (runs, iterations) array}} over the iterations all runs of
    a solver have finished (iteration 1 first)."""
    grouped: dict[str, list[dict]] = {}
    for state in states:
        grouped.setdefault(state['settings']['solver'], []).append(state)
    table = {}
    for solver, runs in grouped.items():
        histories = [[r['exploitability'] for r in run['iterations'] if r.get('exploitability')] for run in runs]
        length = min(len(h) for h in histories)
        if length == 0:
            continue
        table[solver] = {term: np.array([[h[j][term] for j in range(length)] for h in histories])
                         for term in ('mean', 'camera', 'target')}
    return table


def plot_exploitability(states: list[dict], path) -> Path:
    """Fig. 7: exploitability against iteration for each solver (mean ± std over its runs)."""
    plt = pyplot()
    from matplotlib.ticker import MaxNLocator

    table = exploitability_table(states)
    if not table:
        raise ValueError('no run has finished an iteration with best responses (iteration 1) yet')
    figure, axes = plt.subplots(1, 3, figsize=(13, 3.8), sharex=True)
    for ax, term, title in zip(axes, ('mean', 'camera', 'target'),
                               ('exploitability (mean of both terms)', 'camera term', 'target term')):
        for solver, terms in table.items():
            values = terms[term]
            x = np.arange(1, values.shape[1] + 1)
            mean, std = values.mean(axis=0), values.std(axis=0)
            label = f'{SOLVER_NAMES.get(solver, solver)} ({values.shape[0]} run{"s" if values.shape[0] > 1 else ""})'
            ax.plot(x, mean, marker='o', label=label)
            ax.fill_between(x, mean - std, mean + std, alpha=0.2)
        ax.set_title(title)
        ax.set_xlabel('iteration')
        last = max(terms['mean'].shape[1] for terms in table.values())
        ax.set_xlim(0.5, last + 0.5)                              # iterations are whole numbers (one iteration too)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))
        ax.grid(alpha=0.3)
    axes[0].set_ylabel('normalised target-team return')
    axes[0].legend(fontsize=8)
    return save_figure(figure, path)


def meta_strategy_grid(state: dict, team: str) -> np.ndarray:
    """(iterations, largest pool) the meta-strategy of `team` ('camera' or 'target') at each finished iteration of a
    run's `state`, NaN beyond the pool of the time."""
    records = state['iterations']
    size = max(len(r[f'{team}_strategy']) for r in records)
    grid = np.full((len(records), size), np.nan)
    for row, record in enumerate(records):
        strategy = record[f'{team}_strategy']
        grid[row, :len(strategy)] = strategy
    return grid


def draw_meta_strategies(ax, state: dict, team: str, title: str):
    """Draw the heat map of `meta_strategy_grid(state, team)` into `ax` (row: iteration, column: policy); returns
    the image (for a colour bar)."""
    grid = meta_strategy_grid(state, team)
    image = ax.imshow(grid, cmap='viridis', vmin=0.0, vmax=1.0, aspect='auto', origin='upper')
    ax.set_title(title, fontsize=9)
    ax.set_xlabel('policy index (0: initial)')
    ax.set_ylabel('iteration')
    ax.set_xticks(range(grid.shape[1]))
    ax.set_yticks(range(grid.shape[0]))
    return image


def plot_meta_strategies(state: dict, path) -> Path:
    """Fig. 8: each iteration's meta-strategy over each pool as a heat map (row: iteration, column: policy)."""
    plt = pyplot()
    records = state['iterations']
    if not records:
        raise ValueError('the run has no finished iteration yet')
    figure, axes = plt.subplots(1, 2, figsize=(10, 0.45 * len(records) + 2.2))
    for ax, team in zip(axes, ('camera', 'target')):
        image = draw_meta_strategies(ax, state, team,
                                     f'{team} meta-strategy ({SOLVER_NAMES.get(state["settings"]["solver"], "")})')
        figure.colorbar(image, ax=ax, fraction=0.046, pad=0.04)
    return save_figure(figure, path)
