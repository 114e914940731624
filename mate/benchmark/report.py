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
* `<experiment>-curves.png`: the periodic evaluations against decision steps, IQM with its 95 % CI band per
  setting, the references as horizontal lines; population experiments: `<experiment>-exploitability.png` (Fig. 7)
  and `<experiment>-meta-strategies.png` (Fig. 8: every run's meta-strategies, iteration x policy heat maps).
* `marl_eval.json`: every training run's evaluations and absolute metric in marl-eval's layout (environment: the
  experiment, task: '<preset> <team>s', algorithm: the setting, run: `seed_<k>`; `mate.benchmark.marl_eval`); a
  population run's exploitability per iteration, negated (`negative_exploitability`: higher is better), and as its
  absolute metric the last iteration's exploitability on fresh seeds, negated (task: the preset).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from ..learn.evaluation import read_evaluations
from ..learn.population.solvers import effective_policies
from .experiments import Experiment, experiment_of
from .marl_eval import AbsoluteRecord, StepRecord, write_marl_eval
from .directory import read_manifest
from .jobs import by_setting, job_name
from .stats import curve_intervals, improvement_intervals, interval_estimates, normalised
from .verdicts import decide, weigh

__all__ = ['Results', 'TrainingRun', 'claim_rows', 'collect', 'exploitability_histories', 'format_each',
           'format_interval', 'summarise', 'write_report']

REPS = 50_000
"""Bootstrap replications of every interval."""


@dataclasses.dataclass
class TrainingRun:
    """One complete training run: its periodic evaluations and its absolute metric (per-episode values)."""

    label: str
    preset: str
    seed: int
    steps: list[int]                    # decision steps at each evaluation
    evaluations: list[list[float]]      # per evaluation, the metric of each episode
    absolute: list[float]               # the absolute metric of each episode

    @property
    def score(self) -> float:
        """The run's score: the mean absolute metric."""
        return float(np.mean(self.absolute))


@dataclasses.dataclass
class Results:
    """Everything read for one experiment."""

    experiment: Experiment
    steps: int                                           # decision steps per run (the budget run)
    runs: list[TrainingRun] = dataclasses.field(default_factory=list)
    incomplete: list[tuple] = dataclasses.field(default_factory=list)     # (label, preset, seed) of jobs not complete
    references: dict = dataclasses.field(default_factory=dict)           # (agent, preset) -> {evaluation, absolute}
    populations: dict = dataclasses.field(default_factory=dict)          # (label, preset, seed) -> state.json

    def settings(self, preset: str) -> list[str]:
        """The labels of the settings with complete runs on `preset`, in the experiment's order."""
        present = {run.label for run in self.runs if run.preset == preset}
        present |= {label for label, p, _ in self.populations if p == preset}
        return [s.label for s in self.experiment.settings if s.label in present]

    def runs_of(self, label: str, preset: str) -> list[TrainingRun]:
        return sorted((r for r in self.runs if r.label == label and r.preset == preset), key=lambda r: r.seed)


# ============================================================================ reading


def collect(directories: Iterable) -> dict[str, Results]:
    """The results of the benchmark directories, merged by experiment (same budget and protocol required);
    ValueError for a directory that is not a benchmark or holds a run twice."""
    merged: dict[str, Results] = {}
    for directory in directories:
        directory = Path(directory)
        manifest = read_manifest(directory)
        experiment = experiment_of(manifest)
        results = merged.setdefault(experiment.name, Results(experiment, manifest['steps']))
        if results.steps != manifest['steps']:
            raise ValueError(f'{directory}: {experiment.name} at {manifest["steps"]:,} steps per run, another '
                             f'directory at {results.steps:,}; report them apart')
        for job in manifest['jobs']:
            _read_job(results, directory, job)
    return merged


def _read_job(results: Results, directory: Path, job: dict) -> None:
    folder = directory / job['dir']
    kind, label, preset, seed = job['kind'], job['label'], job['preset'], job['seed']
    name = job_name(label, preset, seed)
    if kind == 'reference':
        files = {part: folder / f'{part}.json' for part in ('evaluation', 'absolute')}
        if not all(path.exists() for path in files.values()):
            results.incomplete.append((label, preset, seed))
            return
        metric = _metric(results.experiment)
        results.references[(label, preset)] = {
            part: [episode[metric] for episode in json.loads(path.read_text())['episodes']]
            for part, path in files.items()}
        return
    if kind == 'psro':
        state_path = folder / 'state.json'
        state = json.loads(state_path.read_text()) if state_path.exists() else None
        if state is None or len(state['iterations']) <= int(state['settings']['iterations']):
            results.incomplete.append((label, preset, seed))
            return
        _add_once(results.populations, (label, preset, seed), state, name)
        return
    absolute_path = folder / 'absolute.json'
    if not absolute_path.exists():
        results.incomplete.append((label, preset, seed))
        return
    absolute = json.loads(absolute_path.read_text())
    evaluations = read_evaluations(folder)
    run = TrainingRun(label, preset, int(seed), [int(e['env_steps']) for e in evaluations],
                      [[ep[absolute['metric']] for ep in e['episodes']] for e in evaluations],
                      [ep[absolute['metric']] for ep in absolute['episodes']])
    if any(r.label == label and r.preset == preset and r.seed == run.seed for r in results.runs):
        raise ValueError(f'{name} is in two of the directories; report each run once')
    results.runs.append(run)


def _job_order(job: tuple) -> tuple:
    """Sort key of a (label, preset, seed) triple; a reference (seed None) before the seeds of its setting."""
    label, preset, seed = job
    return label, preset, -1 if seed is None else seed


def _add_once(table: dict, key, value, name: str) -> None:
    if key in table:
        raise ValueError(f'{name} is in two of the directories; report each run once')
    table[key] = value


def _metric(experiment: Experiment) -> str:
    from ..learn.evaluation import TEAM_METRIC

    return TEAM_METRIC[experiment.team]


# ============================================================================ statistics


def _interval(point_low_high) -> dict:
    point, low, high = point_low_high
    return dict(point=point, low=low, high=high)


def _reference_means(results: Results, preset: str, part: str) -> dict[str, float]:
    return {agent: float(np.mean(values[part])) for (agent, p), values in results.references.items() if p == preset}


def summarise(results: Results, reps: int = REPS) -> dict:
    """The numbers of `results.md` (module docstring) as a JSON-ready dict."""
    experiment = results.experiment
    source = {} if experiment.source == 'paper' else dict(source=experiment.source)   # (the paper's reports: as before)
    summary = dict(experiment=experiment.name, figure=experiment.figure, claim=experiment.claim, **source,
                   team=experiment.team, steps=results.steps, paper_steps=experiment.steps,
                   eval_every=experiment.eval_interval(results.steps), eval_episodes=experiment.eval_episodes,
                   iterations=experiment.iterations,
                   incomplete=by_setting(sorted(results.incomplete, key=_job_order)), tasks={})
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
                histories = exploitability_histories(results, label, preset)
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
        references = _reference_means(results, preset, 'absolute')
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


# ============================================================================ figures


def plot_curves(results: Results, path, reps: int = REPS) -> Path | None:
    """Periodic evaluations against decision steps: IQM with its 95 % CI band per setting, one panel per task, the
    references' evaluation scores as dashed lines. None when no run has an evaluation."""
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
        for agent, value in _reference_means(results, preset, 'evaluation').items():
            ax.axhline(value, linestyle='--', linewidth=1, color='gray' if agent != 'upper-bound' else 'black')
            ax.annotate(agent, (1.0, value), xycoords=('axes fraction', 'data'), fontsize=7, ha='right', va='bottom')
        ax.set_title(experiment.task(preset))
        ax.set_xlabel('decision steps')
        ax.set_ylabel(f'{_metric(experiment).replace("_", " ")} (IQM, 95 % CI)')
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return save_figure(figure, path)


def exploitability_histories(results: Results, label: str, preset: str) -> np.ndarray:
    """(runs, iterations): each population run's exploitability (mean of both terms) at iterations 1, 2, ... of the
    setting `label` on `preset`, cut to the shortest run."""
    histories = [[r['exploitability']['mean'] for r in state['iterations'] if r.get('exploitability')]
                 for (lab, p, _), state in sorted(results.populations.items()) if lab == label and p == preset]
    length = min(len(h) for h in histories)
    return np.array([h[:length] for h in histories], dtype=float).reshape(len(histories), length)


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
    """The markdown table of the claims' verdicts (`summarise`'s 'claims'), header included."""
    rows = ['| claim | task | verdict | evidence [95 % CI] | test: p (Holm) |', '|---|---|---|---|---|']
    for claim in claims:
        evidence = '-' if 'point' not in claim else f'{claim["statistic"]}: {format_interval(claim)}'
        test = '-' if 'p' not in claim else f'{claim["test"]}: {_p_value(claim["p"])} ({_p_value(claim["p_holm"])})'
        rows.append(f'| {claim["text"]} | {claim["task"]} | **{claim["verdict"]}** | {evidence} | {test} |')
    return rows


def _p_value(p: float) -> str:
    """'0.0079', '0.10', '<0.0001': two significant digits."""
    return '<0.0001' if p < 1e-4 else f'{p:.2g}' if p < 0.1 else f'{p:.2f}'


VERDICT_RULE = ('a verdict is decisive only where the 95 % interval and a test agree at 5 % after Holm\'s correction '
                'over these claims: between two settings, the interval of P(better > worse) against 1/2 and the exact '
                'Mann-Whitney permutation test (3 runs a side can never be decisive: its smallest p is 0.1); against a '
                'reference, the interval of the difference paired by episode against 0 and a t-test counting the '
                "runs' and the episodes' spread. confirmed: on the claim's side; refuted: on the other; unresolved: "
                'not decisive. For two settings that should agree: equivalent (two one-sided tests within a declared '
                'margin), differ, or no difference detected (which is not evidence that they agree)')
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
    metric = _metric(results.experiment)
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
    out.mkdir(parents=True, exist_ok=True)
    merged = collect(directories)
    files: dict[str, Path] = {}
    sections, summaries, records = list(REPORT_HEADER), {}, []
    for name, results in merged.items():
        summary = summarise(results, reps)
        summaries[name] = summary
        if results.experiment.population:
            figures = [plot_exploitability(results, summary, out / f'{name}-exploitability.png'),
                       plot_meta_strategies(results, out / f'{name}-meta-strategies.png')]
        else:
            figures = [plot_curves(results, out / f'{name}-curves.png', reps)]
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
