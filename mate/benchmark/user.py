"""Your own experiments: an experiment file outside the package, and the jobs of its own kinds of settings.

    mate benchmark run my_experiment.py --out runs/mine       # or my_experiment.yaml
    mate benchmark report runs/mine --out runs/mine-report

**A Python file** defines `EXPERIMENT`, a `mate.benchmark.Experiment` (its settings, games, budget, claims). **A
YAML or JSON file** holds the same fields as a mapping (settings and claims as lists of mappings). A setting is one
of three kinds:

* a mate trainer: `Setting('MAPPO', 'mappo', ('--hidden', '64', '64'))` (`mate train` and its options; 'rllib-ppo'
  for `mate rllib-train`);
* any command line: `Setting('mine', argv=('{python}', '{here}/train.py', '--seed', '{seed}', '--out',
  '{run_dir}'))`, run as it is (not through `python -m mate`) with the placeholders `{run_dir}` (absolute),
  `{seed}`, `{steps}`, `{team}`, `{config}` (the preset), `{horizon}`, `{eval_episodes}`, `{eval_every}`,
  `{threads}` and `{python}` (the interpreter running mate) filled in, and the same values in its environment as
  `MATE_BENCHMARK_RUN_DIR`, `MATE_BENCHMARK_SEED`, ... (`environment`); `{here}` is the experiment file's folder,
  filled in when the file is read. It must leave the run files of the protocol in `{run_dir}`: `absolute.json` (and
  `evaluations.jsonl` for a curve), as `mate.score_policy(..., run_dir=...)` writes them;
* a Python function that trains and returns a policy: `Setting('my PPO', call=train)` in a Python file (or
  `call='path/to/file.py:train'`, a path relative to the experiment file). The benchmark calls
  `train(team=..., config=..., steps=..., seed=..., run_dir=...)` in a job of its own and scores what it returns
  with `mate.score_policy` (a callable from observations (B, N, D) to actions (B, N, 2), a batched agent name, or
  a factory `f(num_envs, counts, seed)` of a batched team), on the experiment's evaluation episodes, writing the run
  files. A function with a `protocol` parameter also gets the experiment's protocol (`RunProtocol`: the horizon,
  the evaluation schedule and episodes, and `protocol.evaluate(policy, env_steps)`, one point of the learning
  curve on the benchmark's evaluation games); `train(team, config, steps, seed, run_dir, protocol)`:

      def train(team, config, steps, seed, run_dir, protocol):
          for before, after in ...:                      # decision steps before and after an update
              ...
              if protocol.due(before, after):
                  protocol.evaluate(policy, env_steps=after)
          return policy                                  # evaluated at `steps` and scored by the benchmark

A reference of the user's (`mate.benchmark.experiments.Reference`: a policy or team factory, no training) is played
by a job of its own too (`run_user_reference`), once per game, on the evaluation and absolute games.

The seed a run gets is what a mate trainer gets (`seed x SEED_STRIDE`, rows below the evaluation seeds); its
training games must stay in seed .. seed + SEED_STRIDE - 1 (its run seed's block: the next run seed trains from
there), below `EVALUATION_SEEDS` (`mate.evaluation.protocol`). The benchmark directory's manifest keeps the
whole experiment, so `mate benchmark report` and `status` need nothing but the directory.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import os
import subprocess
import sys
import warnings
from importlib import import_module
from pathlib import Path

from .experiments import Experiment, Reference, Setting, UndecidableClaimWarning

__all__ = ['ENVIRONMENT_PREFIX', 'EXPERIMENT_SUFFIXES', 'PLACEHOLDERS', 'RunProtocol', 'environment',
           'is_experiment_file', 'load_experiment', 'run_user_job', 'run_user_reference', 'user_job']

EXPERIMENT_SUFFIXES = ('.py', '.yaml', '.yml', '.json')
"""The files `mate benchmark run FILE` reads as an experiment."""
PLACEHOLDERS = ('run_dir', 'seed', 'steps', 'team', 'config', 'horizon', 'eval_episodes', 'eval_every', 'threads',
                'python')
"""What `{name}` in a command-line setting is replaced with (module docstring; `{here}` is filled in earlier, when
the experiment file is read)."""
ENVIRONMENT_PREFIX = 'MATE_BENCHMARK_'
"""A command-line setting's process also finds the `PLACEHOLDERS` in its environment: `MATE_BENCHMARK_RUN_DIR`, ..."""


def is_experiment_file(name: str) -> bool:
    """Whether `mate benchmark run NAME` names a file of the user's rather than one of the package's experiments."""
    return Path(name).suffix.lower() in EXPERIMENT_SUFFIXES or Path(name).is_file()


def load_experiment(path) -> Experiment:
    """The experiment of a user's file (module docstring); ValueError naming the problem otherwise."""
    path = Path(path).resolve()
    if not path.is_file():
        raise ValueError(f'{path}: no such experiment file')
    if path.suffix.lower() == '.py':
        experiment = _from_python(path)
    elif path.suffix.lower() in ('.yaml', '.yml', '.json'):
        import yaml

        try:
            data = yaml.safe_load(path.read_text())
        except yaml.YAMLError as exc:
            raise ValueError(f'{path}: not valid YAML/JSON: {str(exc).splitlines()[0]}') from None
        if not isinstance(data, dict):
            raise ValueError(f'{path}: an experiment file holds a mapping of the Experiment fields')
        experiment = Experiment.from_dict(data)
    else:
        raise ValueError(f'{path}: an experiment file ends with {", ".join(EXPERIMENT_SUFFIXES)}')
    with warnings.catch_warnings():             # said when the file built it
        warnings.simplefilter('ignore', UndecidableClaimWarning)
        return dataclasses.replace(experiment.resolved_from(path), source='user')


def _module_of(path: Path, name: str, keep_path: bool = False):
    """Run the Python file `path` as the module `name`: registered in `sys.modules` as an import would (dataclasses
    of the file look their module up), with the file's folder first on `sys.path` for its own imports, as `python
    FILE` finds them; the folder stays there with `keep_path` (a job's function imports more when it is called)."""
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    sys.path.insert(0, str(path.parent))
    try:
        spec.loader.exec_module(module)
    finally:
        if not keep_path:
            sys.path.remove(str(path.parent))
    return module


def _from_python(path: Path) -> Experiment:
    module = _module_of(path, f'mate_user_experiment_{abs(hash(str(path)))}')
    experiment = getattr(module, 'EXPERIMENT', None)
    if not isinstance(experiment, Experiment):
        hint = ' (one experiment per file: EXPERIMENTS is not read)' if hasattr(module, 'EXPERIMENTS') else ''
        raise ValueError(f'{path}: defines no EXPERIMENT = mate.benchmark.Experiment(...){hint}')
    return experiment


def _function(reference: str):
    """The function of 'path/to/file.py:name' (imported from its file, whose folder stays on `sys.path` for the
    imports the function makes when called: a job's process calls one function) or 'module:name'."""
    where, _, name = reference.rpartition(':')
    if not where or not name:
        raise ValueError(f"a call setting names 'path/to/file.py:function', got {reference!r}")
    if where.endswith('.py'):
        file = Path(where)
        if not file.is_file():
            raise ValueError(f'{reference}: no such file {file}')
        module = _module_of(file, f'mate_user_setting_{file.stem}', keep_path=True)
    else:
        module = import_module(where)
    function = getattr(module, name, None)
    if not callable(function):
        raise ValueError(f'{reference}: {name!r} is not a function of {where}')
    return function


@dataclasses.dataclass(frozen=True)
class RunProtocol:
    """What the benchmark gives a training function with a `protocol` parameter: the experiment's protocol for this
    run, and `evaluate` to log the points of its learning curve as a mate trainer does.

    Attributes:
        team, config: the trained team ('camera', 'target') and the game (a preset's name).
        steps: the run's budget in decision steps (summed over the games played at once).
        seed: the training seed (run seed k: k x 1,000; the training games stay in seed .. seed + 999).
        run_dir: the run's directory (absolute), where `evaluations.jsonl` goes.
        horizon: env steps per episode of the experiment, evaluation and (if the function wants) training.
        eval_every: decision steps between evaluations (the experiment's `eval_interval` at this budget).
        eval_episodes: episodes per evaluation (the absolute metric plays ten times as many).
        threads: the torch threads the run may use (already set for torch).
    """

    team: str
    config: str
    steps: int
    seed: int
    run_dir: str
    horizon: int
    eval_every: int
    eval_episodes: int
    threads: int = 1

    @classmethod
    def of(cls, values: dict) -> RunProtocol:
        """The protocol of a job's `values` (`jobs.job_values`)."""
        return cls(team=str(values['team']), config=str(values['config']), steps=int(values['steps']),
                   seed=int(values['seed']), run_dir=str(values['run_dir']), horizon=int(values['horizon']),
                   eval_every=int(values['eval_every']), eval_episodes=int(values['eval_episodes']),
                   threads=int(values['threads']))

    def due(self, before: int, after: int) -> bool:
        """Whether an evaluation falls due between `before` and `after` decision steps (the steps done before and
        after an update): a multiple of `eval_every` passed in (before, after], as `mate train` evaluates; False once
        `after` reaches `steps`, where the benchmark evaluates the returned policy itself (the curve's last point)."""
        return after < self.steps and after // self.eval_every > before // self.eval_every

    def evaluate(self, policy=None, env_steps: int = 0, *, team_factory=None) -> list[dict]:
        """One periodic evaluation at `env_steps` decision steps, appended to the run's `evaluations.jsonl`: the
        policy (observations (B, N, D) -> actions (B, N, 2), or a team factory `f(num_envs, counts, seed)` as
        `team_factory`) on the benchmark's `eval_episodes` evaluation games cut at `horizon` env steps, against the
        greedy opponent (`mate.evaluation.protocol.evaluate`). Returns one dict per episode."""
        from ..evaluation.protocol import evaluate

        return evaluate(policy, self.team, self.config, team_factory=team_factory, episodes=self.eval_episodes,
                        max_episode_steps=self.horizon, run_dir=self.run_dir, env_steps=int(env_steps))


def user_job(manifest: dict, folder, label: str, preset: str, seed: int | None,
             threads: int) -> tuple[Setting | Reference, dict]:
    """(setting, values) of a user's setting's job (`mate benchmark job FOLDER LABEL PRESET SEED`) in the benchmark
    directory `folder` of `manifest`: the command-line or function setting `label` of its experiment and what the
    benchmark gives it (`jobs.job_values`); without a seed, (reference, values) of the user's reference team `label`.
    ValueError when `label` is no such setting or reference."""
    from .experiments import experiment_of
    from .jobs import job_values

    experiment = experiment_of(manifest)
    if seed is None:
        reference = next((r for r in experiment.own_references if r.label == label), None)
        if reference is None:
            raise ValueError(f'{label!r} is no reference team of yours in {experiment.name} (its own: '
                             f'{", ".join(r.label for r in experiment.own_references) or "none"}); a setting\'s job '
                             'names a run seed')
        return reference, job_values(experiment, preset, None, manifest['steps'], folder, threads, reference)
    setting = next((s for s in experiment.settings if s.label == label), None)
    if setting is None or setting.kind not in ('argv', 'call'):
        raise ValueError(f'{label!r} is no command-line or function setting of {experiment.name}')
    return setting, job_values(experiment, preset, seed, manifest['steps'], folder, threads, setting)


def run_user_job(setting: Setting | Reference, values: dict, episodes: int, say=print) -> int:
    """Run one job of a command-line or function setting with the job's `values` (the `PLACEHOLDERS`), then check
    (command line) or write (function: `mate.score_policy`) the run files; a reference team's job
    (`run_user_reference`). Returns the exit status."""
    run_dir = Path(values['run_dir'])
    run_dir.mkdir(parents=True, exist_ok=True)
    _limit_threads(int(values['threads']))      # the job's share of the cores (a command line inherits it)
    if isinstance(setting, Reference):
        return run_user_reference(setting, values, episodes, say)
    if setting.argv:
        values = dict(values, python=sys.executable)
        try:
            argv = [part.format(**values) for part in setting.argv]
        except (KeyError, IndexError, ValueError) as exc:
            say(f'the command line of {setting.label} has a placeholder mate does not fill in ({exc}); they are '
                f'{", ".join("{%s}" % name for name in PLACEHOLDERS)} ({{{{ and }}}} for braces)')
            return 2
        say(f'$ {" ".join(argv)}')
        try:
            status = subprocess.call(argv, env={**os.environ, **environment(values)})
        except OSError as exc:
            say(f'the command of {setting.label} could not start: {exc}')
            return 1
        if status == 0 and not (run_dir / 'absolute.json').exists():
            say(f'the command of {setting.label} ended without writing {run_dir / "absolute.json"} (the protocol\'s '
                'run files: mate.score_policy(..., run_dir=...) writes them)')
            return 1
        return status
    from ..evaluation.protocol import score_policy

    try:
        train = _function(setting.call)
    except (ValueError, ImportError) as exc:
        say(f'the function of {setting.label} could not be imported: {exc}')
        return 2
    given = dict(team=values['team'], config=values['config'], steps=int(values['steps']), seed=int(values['seed']),
                 run_dir=str(run_dir))
    if _takes(train, 'protocol'):               # the experiment's protocol, for a function that asks for it
        given['protocol'] = RunProtocol.of(values)
    policy = train(**given)
    arguments = dict(team=values['team'], config=values['config'], episodes=episodes,
                     max_episode_steps=int(values['horizon']), references=(), run_dir=run_dir,
                     env_steps=int(values['steps']))
    if callable(policy) and not isinstance(policy, str) and _is_factory(policy):
        score = score_policy(team_factory=policy, **arguments)
    else:
        score = score_policy(policy, **arguments)
    say(f'{setting.label}: absolute {score.metric} {score.absolute_mean:.3f} ({len(score.absolute)} episodes) '
        f'-> {run_dir / "absolute.json"}')
    (run_dir / 'job.json').write_text(json.dumps(dict(setting=setting.to_dict(), values=values), indent=1))
    return 0


def run_user_reference(reference: Reference, values: dict, episodes: int, say=print) -> int:
    """Play a user's reference team (`values`: `jobs.job_values` of it) as the benchmark plays a rule team: the
    evaluation games (`episodes` from `EVALUATION_SEEDS`) and the absolute ones (10 x as many from
    `ABSOLUTE_SEEDS`), cut at the horizon, against the greedy opponent; writes `evaluation.json` and
    `absolute.json` (`{'metric', 'mean', 'seeds', 'episodes'}`: the episodes as `mate evaluate --json` writes those
    of a rule team), each replaced whole. Returns the exit status."""
    from ..evaluation.protocol import (ABSOLUTE_FACTOR, ABSOLUTE_SEEDS, EVALUATION_SEEDS, TEAM_METRIC,
                                       play_policy_episodes)

    try:
        team = _function(reference.call)
    except (ValueError, ImportError) as exc:
        say(f'the team of the reference {reference.label} could not be imported: {exc}')
        return 2
    factory = team if _is_factory(team) else None
    policy = None if factory is not None else team
    run_dir, metric = Path(values['run_dir']), TEAM_METRIC[values['team']]
    for part, count, first in (('evaluation', episodes, EVALUATION_SEEDS),
                               ('absolute', ABSOLUTE_FACTOR * episodes, ABSOLUTE_SEEDS)):
        played = play_policy_episodes(policy, factory, values['team'], values['config'], count, first, int(values['horizon']),
                       'greedy', 'cpu')
        record = dict(metric=metric, mean=sum(e[metric] for e in played) / count, seeds=[first, first + count - 1],
                      episodes=played)
        tmp = run_dir / f'{part}.json.tmp'          # a job killed while writing leaves no half file that looks done
        tmp.write_text(json.dumps(record, indent=1))
        os.replace(tmp, run_dir / f'{part}.json')
        say(f'{reference.label} ({part}): {metric} {record["mean"]:.3f} ({count} episodes) -> {run_dir}/{part}.json')
    return 0


def environment(values: dict) -> dict[str, str]:
    """A command-line setting's environment variables: each of `values` (the `PLACEHOLDERS`) as
    `MATE_BENCHMARK_<NAME>` ('MATE_BENCHMARK_RUN_DIR', 'MATE_BENCHMARK_SEED', ...)."""
    return {f'{ENVIRONMENT_PREFIX}{name.upper()}': str(value) for name, value in values.items()}


def _limit_threads(threads: int) -> None:
    """Torch threads of a job: the runner's share of the cores (`OMP_NUM_THREADS` for a command line's process and a
    torch imported later, `torch.set_num_threads` for one the experiment file imported already)."""
    os.environ.setdefault('OMP_NUM_THREADS', str(threads))
    if 'torch' in sys.modules:
        sys.modules['torch'].set_num_threads(threads)


def _takes(function, name: str) -> bool:
    """Whether `function` has a parameter `name` (one it can be given by keyword)."""
    import inspect

    try:
        parameter = inspect.signature(function).parameters.get(name)
    except (TypeError, ValueError):
        return False
    return parameter is not None and parameter.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD,
                                                        inspect.Parameter.KEYWORD_ONLY)


def _is_factory(function) -> bool:
    """Whether a returned callable is a team factory f(num_envs, counts, seed) rather than a policy f(observations):
    it takes three arguments without defaults."""
    import inspect

    try:
        parameters = inspect.signature(function).parameters.values()
    except (TypeError, ValueError):
        return False
    positional = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    return sum(p.kind in positional and p.default is inspect.Parameter.empty for p in parameters) == 3

