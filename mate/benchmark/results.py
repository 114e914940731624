"""What `mate benchmark report` reads of benchmark directories: every complete training run's evaluations and
absolute metric (`TrainingRun`), the references' episodes and the population runs' states, by experiment
(`Results`, `collect`); the jobs not complete are named."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..learn.evaluation import read_evaluations
from .directory import read_manifest
from .experiments import Experiment, experiment_of
from .jobs import job_name

__all__ = ['Results', 'TrainingRun', 'collect', 'job_order']


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

    @property
    def metric(self) -> str:
        """The per-episode metric the experiment's team is scored by ('coverage_rate' for cameras, ...)."""
        from ..learn.evaluation import TEAM_METRIC

        return TEAM_METRIC[self.experiment.team]

    def reference_means(self, preset: str, part: str) -> dict[str, float]:
        """agent -> the mean score of each reference on `preset` over its 'evaluation' or 'absolute' episodes."""
        return {agent: float(np.mean(values[part])) for (agent, p), values in self.references.items() if p == preset}

    def exploitability_histories(self, label: str, preset: str) -> np.ndarray:
        """(runs, iterations): each population run's exploitability (mean of both terms) at iterations 1, 2, ... of
        the setting `label` on `preset`, cut to the shortest run."""
        histories = [[r['exploitability']['mean'] for r in state['iterations'] if r.get('exploitability')]
                     for (lab, p, _), state in sorted(self.populations.items()) if lab == label and p == preset]
        length = min(len(h) for h in histories)
        return np.array([h[:length] for h in histories], dtype=float).reshape(len(histories), length)


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
        metric = results.metric
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


def job_order(job: tuple) -> tuple:
    """Sort key of a (label, preset, seed) triple; a reference (seed None) before the seeds of its setting."""
    label, preset, seed = job
    return label, preset, -1 if seed is None else seed


def _add_once(table: dict, key, value, name: str) -> None:
    if key in table:
        raise ValueError(f'{name} is in two of the directories; report each run once')
    table[key] = value
