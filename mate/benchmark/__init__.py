"""The paper's experiments, and yours, as a benchmark (`mate benchmark`).

- `mate.benchmark.experiments`: the paper's figures as data (`Experiment`, `Setting`, `Claim`, `Reference`,
  `EXPERIMENTS`; the first four also here, for an experiment file of yours: `EXPERIMENT =
  mate.benchmark.Experiment(...)`);
- `mate.benchmark.user`: experiments of the user's files (.py, .yaml, .json) and the jobs of their command-line and
  function settings;
- `mate.benchmark.jobs`: an experiment's jobs (references, training runs, PSRO runs) for run seeds and a budget;
- `mate.benchmark.runner`: the jobs run, resumable, in local processes or on Ray (`mate.tools.runners`);
- `mate.benchmark.directory`: a benchmark directory's manifest, the reuse of another's jobs, each job's status;
- `mate.benchmark.report`: `results.md`, `results.json`, figures and `marl_eval.json` from benchmark directories
  (`results` reads the runs, `verdicts` judges the claims, `figures` draws);
- `mate.benchmark.identity`: a job's resolved config (`job.json`), what `--reuse` and `--extend` compare;
- `mate.benchmark.stats`: IQM, mean and probability of improvement with stratified-bootstrap confidence
  intervals (rliable's definitions, in numpy), curves with bands, normalised scores;
- `mate.benchmark.marl_eval`: results in marl-eval's JSON layout.

None imports torch (the training runs are `mate train` or `mate benchmark job` processes) but `identity`, which
reads a `mate train` command line with the trainer's own parser when a job starts or is compared.
"""

from .experiments import Claim, Experiment, Reference, Setting
from .marl_eval import AbsoluteRecord, StepRecord, marl_eval_json, write_marl_eval
from .stats import (Interval, curve_intervals, improvement_intervals, interval_estimates, iqm, mean, normalised,
                    probability_of_improvement, stratified_bootstrap)

__all__ = ['Experiment', 'Setting', 'Claim', 'Reference', 'iqm', 'mean', 'stratified_bootstrap', 'interval_estimates',
           'probability_of_improvement', 'improvement_intervals', 'curve_intervals', 'normalised', 'Interval',
           'StepRecord', 'AbsoluteRecord', 'marl_eval_json', 'write_marl_eval']
