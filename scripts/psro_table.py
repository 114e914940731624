"""The results table of docs/population.md from `mate psro` run directories (scripts/psro_results.sh).

    python scripts/psro_table.py runs/psro-results [--json scripts/results/psro.json]

Prints, per solver, the exploitability (mean of both terms, and each term) at every iteration as
mean ± std over the seeds found, and the fixed-opponent runs (directories named fixed-*) beside them.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from mate.learn.population.plots import SOLVER_NAMES, exploitability_table
from mate.learn.population.psro import load_state


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('root', help='directory holding the run directories')
    parser.add_argument('--json', default=None, help='also write the numbers to this JSON file')
    args = parser.parse_args()
    root = Path(args.root)
    runs = {folder.name: load_state(folder) for folder in sorted(root.iterdir()) if (folder / 'state.json').exists()}
    population = [state for name, state in runs.items() if not name.startswith('fixed')]
    table = exploitability_table(population)
    summary = {}
    iterations = max(values['mean'].shape[1] for values in table.values())
    print('| solver (runs) | ' + ' | '.join(f'iteration {i}' for i in range(1, iterations + 1)) + ' |')
    print('|---|' + '---:|' * iterations)
    for solver, terms in table.items():
        values = terms['mean']
        cells = [f'{m:.4f} ± {s:.4f}' for m, s in zip(values.mean(axis=0), values.std(axis=0))]
        print(f'| {SOLVER_NAMES.get(solver, solver)} ({values.shape[0]}) | ' + ' | '.join(cells) + ' |')
        summary[solver] = {term: terms[term].tolist() for term in terms}
    print()
    print('| last iteration | runs | exploitability | camera term | target term |')
    print('|---|---:|---:|---:|---:|')
    for solver, terms in table.items():
        row = [f'{terms[t][:, -1].mean():.4f} ± {terms[t][:, -1].std():.4f}' for t in ('mean', 'camera', 'target')]
        print(f'| {SOLVER_NAMES.get(solver, solver)} | {terms["mean"].shape[0]} | ' + ' | '.join(row) + ' |')
    for name, state in runs.items():
        if name.startswith('fixed') and len(state['iterations']) > 1:
            gains = state['iterations'][1]['exploitability']
            pools = state['pools']
            print(f'| fixed: {pools["camera"][0]} cameras, {pools["target"][0]} targets | 1 | {gains["mean"]:.4f} | '
                  f'{gains["camera"]:.4f} | {gains["target"]:.4f} |')
            summary[name] = dict(gains, payoff=state['payoff'], coverage=state['coverage'],
                                 settings=state['settings'])
    for name, state in runs.items():
        summary.setdefault('runs', {})[name] = dict(settings=state['settings'], payoff=state['payoff'],
                                                    coverage=state['coverage'],
                                                    iterations=state['iterations'],
                                                    best_responses=state.get('best_responses', []))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(summary, indent=1))
        print(f'\nwrote {args.json}')


if __name__ == '__main__':
    main()
