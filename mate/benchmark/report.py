"""`mate benchmark report DIR... --out DIR`: an experiment's results with the field's statistics.

What a report holds, for every experiment found in the benchmark directories (`mate benchmark run` outputs; an
experiment's seeds may be spread over several directories, e.g. run on several machines):

* `results.md`: per task, one row per setting: the runs (complete runs only; the others are named), the absolute
  metric (each run's best evaluated policy re-played on 10 x E held-out episodes) as IQM and mean with 95 %
  stratified-bootstrap confidence intervals over the runs, the last periodic evaluation's IQM, and the absolute
  IQM normalised as (score - random) / (reference - random) with the greedy rules and, for cameras, the upper-bound
  controller as reference; the references' own scores on the same episodes; the probability of improvement between
  every two settings. Population experiments: the final exploitability (IQM and mean with CIs over the runs), from
  the payoff matrix and with the best responses re-played on fresh seeds (`mate psro`'s `exploitability_fresh`),
  and how many policies each team's last meta-strategy spreads over (`effective_policies`, IQM with CIs).
* `results.json`: the same numbers, machine-readable (what README and docs quote).
* `<experiment>-intervals.png`: per task, each setting's absolute metric (population experiments: its final
  exploitability) as a dot at the IQM with its 95 % CI as a bar and each run's score as a tick, the references as
  marked rows, and the task's claims with their verdicts (`mate.benchmark.figures.plot_intervals`, drawn from the
  summary alone: a committed report's picture is drawn again from its `results.json`).
* `<experiment>-curves.png`: the periodic evaluations against decision steps, IQM with its 95 % CI band per
  setting, the references as horizontal lines; population experiments: `<experiment>-exploitability.png` (Fig. 7)
  and `<experiment>-meta-strategies.png` (Fig. 8: every run's meta-strategies, iteration x policy heat maps).
* `marl_eval.json`: every training run's evaluations and absolute metric in marl-eval's layout (environment: the
  experiment, task: '<preset> <team>s', algorithm: the setting, run: `seed_<k>`; `mate.benchmark.marl_eval`); a
  population run's exploitability per iteration, negated (`negative_exploitability`: higher is better), and as its
  absolute metric the last iteration's exploitability on fresh seeds, negated (task: the preset).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from ..learn.population.solvers import effective_policies
from .experiments import Experiment
from .figures import plot_curves, plot_exploitability, plot_intervals, plot_meta_strategies
from .jobs import by_setting
from .marl_eval import AbsoluteRecord, StepRecord, write_marl_eval
from .results import Results, TrainingRun, collect, job_order
from .stats import curve_intervals, improvement_intervals, interval_estimates, normalised
from .verdicts import decide, p_value, weigh

__all__ = ['Results', 'TrainingRun', 'claim_rows', 'collect', 'format_each', 'p_value',
           'format_interval', 'summarise', 'write_report']

REPS = 50_000
"""Bootstrap replications of every interval."""


def _interval(point_low_high) -> dict:
    point, low, high = point_low_high
    return dict(point=point, low=low, high=high)


def summarise(results: Results, reps: int = REPS) -> dict:
    """The numbers of `results.md` (module docstring) as a JSON-ready dict."""
    experiment = results.experiment
    source = {} if experiment.source == 'paper' else dict(source=experiment.source)   # (the paper's reports: as before)
    summary = dict(experiment=experiment.name, figure=experiment.figure, claim=experiment.claim, **source,
                   team=experiment.team, steps=results.steps, paper_steps=experiment.steps,
                   eval_every=experiment.eval_interval(results.steps), eval_episodes=experiment.eval_episodes,
                   iterations=experiment.iterations,
                   incomplete=by_setting(sorted(results.incomplete, key=job_order)), tasks={})
    claims: list[dict] = []
    for preset in experiment.presets:
        task = dict(settings={}, references={}, improvement={})
        scores: dict[str, np.ndarray] = {}
        if experiment.population:
            for label in results.settings(preset):
                states = [state for (lab, p, _), state in sorted(results.populations.items())
                          if lab == label and p == preset]
                lasts = [state['iterations'][-1] for state in states]
                entry = dict(runs=len(lasts))
                for key in ('exploitability', 'exploitability_fresh'):
                    if all(last.get(key) for last in lasts):
                        finals = np.array([last[key]['mean'] for last in lasts])
                        estimates = interval_estimates({label: finals}, reps=reps)[label]
                        entry[f'final_{key}'] = {name: _interval(value) for name, value in estimates.items()}
                        entry[f'final_{key}_values'] = finals.tolist()
                entry['final_effective_policies'], entry['mean_effective_policies'] = {}, {}
                for team in ('camera', 'target'):    # how many policies each last meta-strategy spreads over
                    spread = np.array([effective_policies(last[f'{team}_strategy']) for last in lasts])
                    estimates = interval_estimates({label: spread}, reps=reps)[label]
                    entry['final_effective_policies'][team] = dict(
                        {name: _interval(value) for name, value in estimates.items()}, values=spread.tolist(),
                        pool=[len(last[f'{team}_strategy']) for last in lasts])
                    # ... and on average over the iterations 1..N of each run (iteration 0's pool has one policy)
                    spread = np.array([np.mean([effective_policies(record[f'{team}_strategy'])
                                                for record in state['iterations'][1:]]) for state in states])
                    estimates = interval_estimates({label: spread}, reps=reps)[label]
                    entry['mean_effective_policies'][team] = dict(
                        {name: _interval(value) for name, value in estimates.items()}, values=spread.tolist())
                histories = results.exploitability_histories(label, preset)
                if histories.shape[1]:        # the curve of the exploitability figure, IQM per iteration 1, 2, ...
                    points, lows, highs = curve_intervals({label: histories}, reps=reps)[label]['IQM']
                    entry['exploitability_by_iteration'] = [dict(point=float(a), low=float(b), high=float(c))
                                                            for a, b, c in zip(points, lows, highs)]
                task['settings'][label] = entry
                key = 'exploitability_fresh' if 'final_exploitability_fresh_values' in entry else 'exploitability'
                if f'final_{key}_values' in entry:       # lower is better: scored negated
                    scores[label] = -np.array(entry[f'final_{key}_values'])
            summary['tasks'][experiment.task(preset)] = task
            claims += _weigh(experiment, preset, scores, {}, {}, {}, reps)
            continue
        references = results.reference_means(preset, 'absolute')
        task['references'] = {agent: dict(absolute=value, episodes=len(results.references[(agent, preset)]['absolute']),
                                          evaluation=float(np.mean(results.references[(agent, preset)]['evaluation'])))
                              for agent, value in references.items()}
        for label in results.settings(preset):
            runs = results.runs_of(label, preset)
            scores[label] = np.array([run.score for run in runs])
            estimates = interval_estimates({label: scores[label]}, reps=reps)[label]
            last = np.array([np.mean(run.evaluations[-1]) for run in runs if run.evaluations])
            entry = dict(runs=len(runs), seeds=[run.seed for run in runs], values=scores[label].tolist(),
                         absolute={name: _interval(value) for name, value in estimates.items()})
            if len(last):
                entry['last_evaluation'] = _interval(interval_estimates({label: last}, reps=reps)[label]['IQM'])
            if 'random' in references:
                for reference in ('greedy', 'upper-bound'):
                    if reference in references and references[reference] != references['random']:
                        scaled = normalised(scores[label], references['random'], references[reference])
                        entry[f'normalised_{reference}'] = _interval(
                            interval_estimates({label: scaled}, reps=reps)[label]['IQM'])
            task['settings'][label] = entry
        if len(scores) > 1:
            for (x, y), value in improvement_intervals(scores, reps=reps).items():
                task['improvement'][f'{x} > {y}'] = _interval(value)
        summary['tasks'][experiment.task(preset)] = task
        episodes = {label: np.array([run.absolute for run in results.runs_of(label, preset)]) for label in scores}
        reference_episodes = {agent: np.array(values['absolute'])
                              for (agent, p), values in results.references.items() if p == preset}
        claims += _weigh(experiment, preset, scores, references, episodes, reference_episodes, reps)
    summary['claims'] = decide(claims)
    return summary


def _weigh(experiment: Experiment, preset: str, scores: dict, references: dict, episodes: dict,
           reference_episodes: dict, reps: int) -> list[dict]:
    """The evidence on the experiment's claims about `preset` (`mate.benchmark.verdicts.weigh`)."""
    return [weigh(claim, experiment.task(preset), scores, references, episodes, reference_episodes, reps)
            for claim in experiment.claims if claim.preset in (None, preset)]


# ============================================================================ files


def format_number(value: float, digits: int = 3) -> str:
    """`value` with `digits` decimals; one that rounds to zero is '0.000', never '-0.000'."""
    text = f'{value:.{digits}f}'
    return text[1:] if text.startswith('-') and float(text) == 0 else text


def format_each(values, digits: int = 3) -> str:
    """'0.366, 0.444, 0.049' (each run's score), or '-' without them."""
    return ', '.join(format_number(value, digits) for value in values) if values else '-'


def format_interval(interval: dict | None, digits: int = 3) -> str:
    """'point [low, high]' of an interval of `results.json` ('-' for none)."""
    if not interval:
        return '-'
    point, low, high = (format_number(interval[key], digits) for key in ('point', 'low', 'high'))
    return f'{point} [{low}, {high}]'


def claim_rows(claims: list[dict]) -> list[str]:
    """The markdown table of the claims' verdicts (`summarise`'s 'claims'), header included; where a verdict with a
    test is not decisive, a last column says why in its row (`mate.benchmark.verdicts.decide`'s `reason`)."""
    why = any('reason' in claim for claim in claims)
    rows = ['| claim | task | verdict | evidence [95 % CI] | test: p (Holm) |' + (' why not decisive |' * why),
            '|---|---|---|---|---|' + '---|' * why]
    for claim in claims:
        evidence = '-' if 'point' not in claim else f'{claim["statistic"]}: {format_interval(claim)}'
        test = '-' if 'p' not in claim else f'{claim["test"]}: {p_value(claim["p"])} ({p_value(claim["p_holm"])})'
        rows.append(f'| {claim["text"]} | {claim["task"]} | **{claim["verdict"]}** | {evidence} | {test} |'
                    + (f' {claim.get("reason", "-")} |' * why))
    return rows


VERDICT_RULE = ('a verdict is decisive only where the 95 % interval and a test agree at 5 % after Holm\'s correction '
                'over these claims: between two settings, the interval of P(better > worse) against 1/2 and the exact '
                'Mann-Whitney permutation test (3 runs a side can never be decisive: its smallest p is 0.1); against a '
                'reference, the interval of the difference paired by episode against 0 and a t-test of the mean '
                "difference counting the runs' and the episodes' spread once each; and the tested statistic on the "
                "interval's side. confirmed: on the claim's side; refuted: on the other; unresolved: not decisive. "
                'For two settings that should agree: equivalent (two one-sided tests within a declared margin), '
                'differ, or no difference detected (which is not evidence that they agree)')
"""How a report's verdicts are reached, in words (`mate.benchmark.verdicts`)."""


def markdown(summary: dict, figures: list[str]) -> str:
    """One experiment's section of `results.md`, showing the report's `figures` (file names)."""
    lines = [f'## {summary["experiment"]}: {summary["figure"]}', '']
    population = summary['team'] == 'both'
    unit = 'per best response' if population else 'per run'
    budget = f'{summary["steps"]:,} decision steps {unit}'
    if summary['steps'] != summary['paper_steps']:
        budget += f' (the experiment\'s budget: {summary["paper_steps"]:,})'
    iterations = summary['iterations']
    protocol = (f'{iterations} iteration{"s" * (iterations != 1)}; the exploitability of the last, from the payoff '
                'matrix and with the best responses re-played on fresh seeds' if population else
                f'evaluation every {summary["eval_every"]:,} decision steps on {summary["eval_episodes"]} held-out '
                f'episodes; absolute metric on {10 * summary["eval_episodes"]} other held-out episodes')
    lines += [f'Claim tested: {summary["claim"]}.', '', f'Budget: {budget}; {protocol}. Intervals: 95 % stratified '
              'bootstrap over runs.', '']
    for figure in figures:
        lines += [f'![{summary["experiment"]}]({figure})', '']
    for task, data in summary['tasks'].items():
        lines += [f'### {task}', '']
        if not data['settings'] and not data['references']:
            lines += ['No runs of this game in the benchmark directories (`mate benchmark run --presets` ran '
                      'others).', '']
            continue
        if population:
            lines += ['| setting | runs | final exploitability IQM [95 % CI] | mean [95 % CI] | on fresh seeds: IQM '
                      '[95 % CI] |', '|---|---|---|---|---|']
            for label, entry in data['settings'].items():
                values, fresh = entry.get('final_exploitability'), entry.get('final_exploitability_fresh')
                lines.append(f'| {label} | {entry["runs"]} | {format_interval(values and values["IQM"], 4)} | '
                             f'{format_interval(values and values["mean"], 4)} | '
                             f'{format_interval(fresh and fresh["IQM"], 4)} |')
            lines += ['', 'The exploitability by iteration (the figure\'s curve), IQM [95 % CI]:', '']
            for label, entry in data['settings'].items():
                curve = entry.get('exploitability_by_iteration', [])
                lines.append(f'* {label}: ' + ('; '.join(f'{i}: {format_interval(point, 4)}'
                                                         for i, point in enumerate(curve, 1)) or '-'))
            lines += ['', 'How many policies the meta-strategies spread over (exp of their entropy: 1 for a pure '
                      'strategy, the pool size for a uniform one), the last and the mean over iterations 1 to the '
                      'last of each run; the heat maps show every iteration, colour from 0, dark, to 1, yellow:', '',
                      '| setting | team | pool | last: IQM [95 % CI] | each run | mean over iterations: IQM [95 % CI] '
                      '| each run |', '|---|---|---|---|---|---|---|']
            for label, entry in data['settings'].items():
                last, mean = entry['final_effective_policies'], entry['mean_effective_policies']
                for team in ('camera', 'target'):
                    lines.append(f'| {label} | {team}s | {", ".join(map(str, sorted(set(last[team]["pool"]))))} | '
                                 f'{format_interval(last[team]["IQM"], 2)} | {format_each(last[team]["values"], 2)} | '
                                 f'{format_interval(mean[team]["IQM"], 2)} | {format_each(mean[team]["values"], 2)} |')
            lines.append('')
            continue
        camera = summary['team'] == 'camera'
        header = '| setting | runs | absolute IQM [95 % CI] | absolute mean [95 % CI] | last evaluation IQM | ' \
                 'normalised, greedy = 1 |' + (' normalised, upper bound = 1 |' if camera else '')
        lines += [header, '|' + '---|' * (header.count('|') - 1)]
        for label, entry in data['settings'].items():
            row = (f'| {label} | {entry["runs"]} | {format_interval(entry["absolute"]["IQM"])} | '
                   f'{format_interval(entry["absolute"]["mean"])} | {format_interval(entry.get("last_evaluation"))} | '
                   f'{format_interval(entry.get("normalised_greedy"), 2)} |')
            if camera:
                row += f' {format_interval(entry.get("normalised_upper-bound"), 2)} |'
            lines.append(row)
        for agent, reference in data['references'].items():
            row = (f'| *{agent}* (reference) | - | {format_number(reference["absolute"])} | | '
                   f'{format_number(reference["evaluation"])} | | ')
            lines.append(row + (' |' if camera else ''))
        lines.append('')
        if data['improvement']:
            lines += ['Probability of improvement (absolute metric):', '', '| comparison | P [95 % CI] |', '|---|---|']
            lines += [f'| {pair} | {format_interval(value, 2)} |' for pair, value in data['improvement'].items()]
            lines.append('')
    if summary.get('claims'):
        whose = 'Claims of the paper' if summary.get('source', 'paper') == 'paper' else 'Claims of this experiment'
        lines += [f'{whose} at this budget ({VERDICT_RULE}):', '', *claim_rows(summary['claims']), '']
    if summary['incomplete']:
        lines += [f'Not complete (left out): {", ".join(summary["incomplete"])}.', '']
    return '\n'.join(lines)


def marl_eval_records(results: Results, environment: str) -> list:
    """Every complete run's evaluations (per episode) and absolute metric as marl-eval records. marl-eval needs the
    same runs for every (task, algorithm) and the same steps in every run: only the seeds complete for every setting
    and task are written, each cut to the evaluations all of them have."""
    metric = results.metric
    groups = {(r.label, r.preset) for r in results.runs}
    seeds = set.intersection(*({r.seed for r in results.runs if (r.label, r.preset) == g} for g in groups)) \
        if groups else set()
    runs = [r for r in results.runs if r.seed in seeds]
    if not runs:
        return []
    length = min(len(r.evaluations) for r in runs)
    records: list = []
    for run in runs:
        task = results.experiment.task(run.preset)
        for index in range(length):
            records.append(StepRecord(environment, task, run.label, run.seed, index, run.steps[index], metric,
                                      run.evaluations[index]))
        records.append(AbsoluteRecord(environment, task, run.label, run.seed, metric, run.absolute))
    return records


POPULATION_METRIC = 'negative_exploitability'
"""The metric of a population run in `marl_eval.json`: its exploitability negated, so that higher is better as
marl-eval's aggregates (and probability of improvement) assume."""


def population_marl_eval_records(results: Results, environment: str) -> list:
    """Every complete population run as marl-eval records: one step per PSRO iteration from the first with an
    exploitability (step_count: the decisions of one side's best responses so far), its value the negated
    exploitability of the payoff matrix; the absolute metric the negated exploitability of the last iteration with
    the best responses re-played on fresh seeds. Only the seeds complete for every setting and task, each cut to the
    iterations all of them have (marl-eval needs the same runs and steps everywhere)."""
    groups = {(label, preset) for label, preset, _ in results.populations}
    seeds = set.intersection(*({seed for label, preset, seed in results.populations if (label, preset) == group}
                               for group in groups)) if groups else set()
    runs = {key: state for key, state in results.populations.items() if key[2] in seeds}
    if not runs:
        return []
    scored = {key: [it for it in state['iterations'] if it.get('exploitability')] for key, state in runs.items()}
    length = min(len(iterations) for iterations in scored.values())
    records: list = []
    for (label, preset, seed), iterations in sorted(scored.items()):
        task, steps = results.experiment.task(preset), int(runs[(label, preset, seed)]['settings']['br_steps'])
        for index, iteration in enumerate(iterations[:length]):
            records.append(StepRecord(environment, task, label, seed, index, int(iteration['iteration']) * steps,
                                      POPULATION_METRIC, [-float(iteration['exploitability']['mean'])]))
        last = iterations[length - 1]
        fresh = last.get('exploitability_fresh') or last['exploitability']
        records.append(AbsoluteRecord(environment, task, label, seed, POPULATION_METRIC, [-float(fresh['mean'])]))
    return records


REPORT_HEADER = ('# Benchmark results', '',
                 'Written by `mate benchmark report`; every number below is in `results.json`.', '')
"""The lines `results.md` opens with, before the experiments' sections (`markdown`)."""


def write_report(directories: Iterable, out, reps: int = REPS, say: Callable[[str], None] = print) -> dict[str, Path]:
    """Write the report of the benchmark directories to `out` (module docstring); returns the files written."""
    out = Path(out)
    merged = collect(directories)           # (a directory that is no benchmark: nothing written)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    sections, summaries, records = list(REPORT_HEADER), {}, []
    for name, results in merged.items():
        summary = summarise(results, reps)
        summaries[name] = summary
        figures = [plot_intervals(summary, out / f'{name}-intervals.png')]
        if results.experiment.population:
            figures += [plot_exploitability(results, summary, out / f'{name}-exploitability.png'),
                        plot_meta_strategies(results, out / f'{name}-meta-strategies.png')]
        else:
            figures += [plot_curves(results, out / f'{name}-curves.png', reps)]
        figures = [figure for figure in figures if figure is not None]
        files.update({figure.name: figure for figure in figures})
        sections.append(markdown(summary, [figure.name for figure in figures]))
        records += (population_marl_eval_records if results.experiment.population else marl_eval_records)(results,
                                                                                                           name)
        complete = len(results.runs) + len(results.populations)
        say(f'{name}: {complete} complete run{"s" * (complete != 1)}, {len(results.incomplete)} not complete')
    files['results.md'] = out / 'results.md'
    files['results.md'].write_text('\n'.join(sections))
    files['results.json'] = out / 'results.json'
    files['results.json'].write_text(json.dumps(summaries, indent=1, default=_jsonable))
    if records:
        files['marl_eval.json'] = write_marl_eval(out / 'marl_eval.json', records)
    return files


def _jsonable(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and math.isnan(value):
        return None
    raise TypeError(f'not JSON: {type(value)}')
