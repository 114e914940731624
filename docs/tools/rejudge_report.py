"""Give a committed report whose runs' data were not kept the current verdict rule (`mate.benchmark.verdicts`).

    python docs/tools/rejudge_report.py docs/results/fig5-targets-comm [...]

A report committed without its `benchmark/` directory still holds what the verdicts need: each run's score
(`results.json`) and each run's absolute metric per held-out episode (`marl_eval.json`). The reference teams'
episodes are taken from a report that kept them (`docs/results/*/benchmark/references/AGENT-PRESET/absolute.json`):
the same rule team on the same held-out seeds, checked by its mean, which must equal the report's to the last digit
(a shorter protocol, e.g. 160 episodes, uses the first ones). Every number but the claims' is left as it was;
the figures are drawn again (`EXPERIMENT-intervals.png` from the summary, `EXPERIMENT-curves.png` from every run's
evaluations in `marl_eval.json`, which holds them all, and the references' evaluation means in `results.json`) and
`results.md` is written again from the updated summary, with them.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from mate.benchmark.experiments import experiment
from mate.benchmark.figures import plot_curves, plot_intervals
from mate.benchmark.report import REPORT_HEADER, _jsonable, _weigh, markdown
from mate.benchmark.results import Results, TrainingRun
from mate.benchmark.verdicts import decide
from mate.evaluation.protocol import ABSOLUTE_SEEDS, TEAM_METRIC

ROOT = Path(__file__).resolve().parents[2]


def run_episodes(marl_eval: dict, name: str, task: str, label: str, metric: str, values: list) -> np.ndarray:
    """(runs, E): the runs' absolute metric per episode from marl_eval.json, checked against their scores."""
    runs = marl_eval[name][task][label]
    seeds = sorted(runs, key=lambda key: int(key.split('_')[1]))
    episodes = np.array([runs[seed]['absolute_metrics'][metric] for seed in seeds], dtype=float)
    if not np.allclose(episodes.mean(axis=1), values, rtol=0, atol=1e-12):
        raise SystemExit(f'{name} {task} {label}: marl_eval.json does not hold the runs of results.json')
    return episodes


def reference_episodes(agent: str, preset: str, metric: str, mean: float, count: int) -> np.ndarray:
    """(E,): a kept reference's first `count` episodes whose mean is the report's `mean` exactly."""
    for path in sorted(ROOT.glob(f'docs/results/*/benchmark/references/{agent}-{preset}/absolute.json')):
        episodes = json.loads(path.read_text())['episodes'][:count]
        values = np.array([episode[metric] for episode in episodes])
        if len(values) == count and episodes[0]['seed'] == ABSOLUTE_SEEDS and float(values.mean()) == mean:
            return values
    raise SystemExit(f'no kept reference {agent} on {preset} with {count} episodes of mean {mean!r}')


def curve_results(name: str, summary: dict, marl_eval: dict) -> Results:
    """What `plot_curves` draws, read back from a report: every run's evaluations (per episode) and their decision
    steps from marl_eval.json, the references' evaluation means from results.json; the runs must be those of
    results.json, each with every evaluation of the budget."""
    exp = experiment(name)
    metric = TEAM_METRIC[exp.team]
    results = Results(exp, summary['steps'])
    for preset in exp.presets:
        task = summary['tasks'][exp.task(preset)]
        for label, entry in task['settings'].items():
            runs = marl_eval[name][exp.task(preset)][label]
            if sorted(int(run.split('_')[1]) for run in runs) != entry['seeds']:
                raise SystemExit(f'{name} {exp.task(preset)} {label}: marl_eval.json does not hold every run')
            for run, record in runs.items():
                steps = [record[f'step_{index}'] for index in range(len(record) - 1)]
                if len(steps) != summary['steps'] // summary['eval_every']:
                    raise SystemExit(f'{name} {exp.task(preset)} {label} {run}: marl_eval.json holds {len(steps)} '
                                     'evaluations, not every one of the budget')
                results.runs.append(TrainingRun(label, preset, int(run.split('_')[1]),
                                                [step['step_count'] for step in steps],
                                                [step[metric] for step in steps], record['absolute_metrics'][metric]))
        for agent, entry in task['references'].items():       # (the mean of one value: the value itself)
            results.references[(agent, preset)] = dict(evaluation=[entry['evaluation']], absolute=[entry['absolute']])
    return results


def rejudge(folder: Path, reps: int) -> None:
    summaries = json.loads((folder / 'results.json').read_text())
    marl_eval = json.loads((folder / 'marl_eval.json').read_text())
    sections = list(REPORT_HEADER)
    for name, summary in summaries.items():
        exp = experiment(name)
        metric = TEAM_METRIC[exp.team]
        claims = []
        for preset in exp.presets:
            task = summary['tasks'][exp.task(preset)]
            scores = {label: np.array(entry['values']) for label, entry in task['settings'].items()}
            references = {agent: entry['absolute'] for agent, entry in task['references'].items()}
            episodes = {label: run_episodes(marl_eval, name, exp.task(preset), label, metric, entry['values'])
                        for label, entry in task['settings'].items()}
            played = {agent: reference_episodes(agent, preset, metric, entry['absolute'], entry['episodes'])
                      for agent, entry in task['references'].items()}
            claims += _weigh(exp, preset, scores, references, episodes, played, reps)
        summary['claims'] = decide(claims)
        figures = [plot_intervals(summary, folder / f'{name}-intervals.png'),
                   plot_curves(curve_results(name, summary, marl_eval), folder / f'{name}-curves.png', reps)]
        sections.append(markdown(summary, [figure.name for figure in figures if figure is not None]))
        for claim in summary['claims']:
            print(f'{name}: {claim["verdict"]:>24} | {claim["text"]} | p {claim.get("p", "-")}')
    (folder / 'results.json').write_text(json.dumps(summaries, indent=1, default=_jsonable))
    (folder / 'results.md').write_text('\n'.join(sections))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('reports', nargs='+', type=Path, help='report folders (results.json, marl_eval.json)')
    parser.add_argument('--reps', type=int, default=50_000, help='bootstrap replications (default 50,000)')
    args = parser.parse_args(argv)
    for folder in args.reports:
        rejudge(folder, args.reps)
    return 0


if __name__ == '__main__':
    sys.exit(main())
