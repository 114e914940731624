"""An experiment's jobs: `plan` turns an experiment, run seeds and a budget into `Job`s, each a list of command
lines of the package (`python -m mate ...`) with the files that mark it done.

    from mate.benchmark.experiments import experiment
    from mate.benchmark.jobs import plan

    jobs = plan(experiment('fig4a-cameras'), seeds=range(5), out='bench/fig4a')
    print(len(jobs), jobs[-1].name)        # 38 MA-TD3 on MATE-4v8-9 seed 4

A job is one command line of the package (`python -m mate ...`) whose output goes to a log file:

* a training run (`mate train COMMAND ... --seed S --eval-every K --eval-episodes E --run-dir OUT/runs/...`) per
  (setting, preset, seed), done when its `absolute.json` exists (the run completed and its best policy was
  re-evaluated);
* a population run (`mate psro ... --out OUT/runs/...`) per (setting, preset, seed), done when its `state.json`
  holds every iteration;
* a reference (`mate evaluate` of a rule team against the greedy rules) per (preset, reference): the evaluation
  episodes (seeds `EVALUATION_SEEDS`, ..., E episodes) and the absolute ones (seeds `ABSOLUTE_SEEDS`, ..., 10 E),
  each cut at the training horizon, the same episodes the learners are scored on; done when both JSON files exist.
  A team of the user's (`mate.benchmark.experiments.Reference`) is played the same way by `mate benchmark job DIR
  LABEL PRESET` (no seed), which writes the same two files.

Run seeds: seed k trains with `mate train --seed k * SEED_STRIDE`, so no two runs share a training env (the rows
of a run are seeded `seed + row`, at most SEED_STRIDE of them: `plan` refuses a setting with more; a session resumed
without its batch's state resets inside the run's block, `mate.evaluation.protocol.training_reset_seed`) and every run
stays below the evaluation seeds; a population run with `mate psro --seed k`, which spaces its best responses' seeds by
1,000 itself (`PSROSettings.best_response_seed`: seed k x 1,000 + 2 x iteration + side, each with its envs' rows,
which `plan` keeps within the 1,000).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from collections.abc import Iterable
from pathlib import Path

from ..cli.arguments import positive_int
from ..learn.envs import PAPER_SETTINGS
from ..learn.evaluation import ABSOLUTE_FACTOR, ABSOLUTE_SEEDS, EVALUATION_SEEDS, TEAM_METRIC
from ..evaluation.protocol import SEED_BLOCK
from .experiments import Experiment, Reference, Setting

__all__ = ['MAX_SEED', 'PSRO_ENVS', 'SEED_STRIDE', 'Job', 'add_job_arguments', 'by_setting', 'check_run_seeds',
           'horizon_of', 'job_name', 'job_values', 'parse_presets', 'parse_seeds', 'parse_settings', 'plan']

SEED_STRIDE = SEED_BLOCK
"""Run seed k trains with `--seed k * SEED_STRIDE` (1,000; `mate.evaluation.protocol.SEED_BLOCK`) on at most
SEED_STRIDE envs: the training env rows of different runs never share a seed."""
PSRO_ENVS = 16
"""`mate psro`'s envs per best response when a setting does not say (`--num-envs`)."""
MAX_SEED = EVALUATION_SEEDS // SEED_STRIDE - 1
"""The largest run seed: its training envs (up to SEED_STRIDE rows) stay below the evaluation seeds."""


def job_name(label: str, preset: str, seed: int | None) -> str:
    """How a job is named in progress lines and errors: 'MAPPO on MATE-4v8-0 seed 3' ('greedy on MATE-4v8-0' for a
    reference, which has no seed)."""
    return f'{label} on {preset}' + ('' if seed is None else f' seed {seed}')


def by_setting(jobs: Iterable[tuple[str, str, int | None]]) -> list[str]:
    """(label, preset, seed) triples grouped by setting, in order of first appearance: ['MAPPO on MATE-4v8-0 (seeds 3,
    4)', 'greedy on MATE-4v8-0'] (a reference has no seed)."""
    seeds: dict[tuple[str, str], list[int]] = {}
    for label, preset, seed in jobs:
        seeds.setdefault((label, preset), []).extend([] if seed is None else [seed])
    return [job_name(label, preset, None) + (f' (seed{"s" * (len(numbers) > 1)} {", ".join(map(str, numbers))})'
                                             if numbers else '')
            for (label, preset), numbers in seeds.items()]


@dataclasses.dataclass(frozen=True)
class Job:
    """One command of an experiment.

    Args:
        kind: 'train', 'psro' or 'reference'.
        label: the setting's label (training, population) or the reference's agent name.
        preset: the game.
        seed: the run seed (None for a reference).
        dir: the job's directory (the run directory, or the reference's).
        commands: the command lines after `python -m mate`, run in order.
        outputs: the files whose existence marks the job done.
        metric: the per-episode metric the job is scored by (the trained team's: `TEAM_METRIC`; '' for PSRO).
    """

    kind: str
    label: str
    preset: str
    seed: int | None
    dir: Path
    commands: tuple[tuple[str, ...], ...]
    outputs: tuple[Path, ...]
    metric: str = ''

    @property
    def name(self) -> str:
        return job_name(self.label, self.preset, self.seed)

    def done(self) -> bool:
        """Whether the job has completed (its result files written; for PSRO, every iteration)."""
        if self.kind == 'psro':
            return _psro_complete(self.outputs[0])
        return all(path.exists() for path in self.outputs)

    def measured(self) -> str:
        """What the finished job measured, for its lines ('; absolute coverage_rate 0.612 (320 episodes)')."""
        if self.kind == 'train':
            absolute = json.loads(self.outputs[0].read_text())
            return f'; absolute {absolute["metric"]} {absolute["mean"]:.3f} ({len(absolute["episodes"])} episodes)'
        if self.kind == 'psro':
            state = json.loads(self.outputs[0].read_text())
            gains = state['iterations'][-1].get('exploitability')
            return '' if gains is None else f'; last exploitability {gains["mean"]:.4f}'
        values = [episode[self.metric] for episode in json.loads(self.outputs[-1].read_text())['episodes']]
        return f'; {self.metric} {sum(values) / len(values):.3f} ({len(values)} episodes)'


def _psro_complete(state_path: Path) -> bool:
    if not state_path.exists():
        return False
    state = json.loads(state_path.read_text())
    return len(state['iterations']) > int(state['settings']['iterations'])


def parse_seeds(text: str) -> list[int]:
    """Run seeds from '0-4', '0,2,5' or '3' (ranges inclusive); ValueError naming the valid form otherwise."""
    seeds: list[int] = []
    try:
        for part in str(text).split(','):
            first, _, last = part.strip().partition('-')
            seeds.extend(range(int(first), int(last or first) + 1))
    except ValueError:
        raise ValueError(f"--seeds: seeds as '0-4', '0,2,5' or '3', got {text!r}") from None
    if not seeds:
        raise ValueError(f'--seeds: no seeds in {text!r}')
    bad = [s for s in seeds if not 0 <= s <= MAX_SEED]
    if bad:
        raise ValueError(f'--seeds: run seeds are 0..{MAX_SEED}, got {bad[0]}')
    return sorted(set(seeds))


def parse_presets(text: str, experiment: Experiment) -> list[str]:
    """Games of `experiment` from 'MATE-4v8-0' or 'MATE-2v4-0,MATE-4v8-0' (`mate benchmark run --presets`), in the
    experiment's order; ValueError naming the experiment's games otherwise."""
    return _subset('--presets', 'games', text, experiment, list(experiment.presets))


def parse_settings(text: str, experiment: Experiment) -> list[str]:
    """Labels of `experiment`'s settings from their labels or file-name slugs, comma-separated ('IPPO,MAPPO+TarMAC'
    or 'ippo,mappo-tarmac'; `mate benchmark run --settings`), in the experiment's order; ValueError naming the
    experiment's settings otherwise."""
    slugs = {setting.slug: setting.label for setting in experiment.settings}
    return _subset('--settings', 'settings', text, experiment, [s.label for s in experiment.settings], slugs)


def _subset(option: str, what: str, text: str, experiment: Experiment, names: list[str],
            aliases: dict[str, str] | None = None) -> list[str]:
    """The names of `names` listed in `text` (comma-separated; `aliases` maps other spellings to names), in the
    order of `names`."""
    aliases = aliases or {}
    given = [part.strip() for part in str(text).split(',') if part.strip()]
    unknown = [part for part in given if part not in names and part not in aliases]
    if not given or unknown:
        problem = f'{unknown[0]!r} is not one of them' if unknown else f'none given in {text!r}'
        raise ValueError(f'{option}: the {what} of {experiment.name} are {", ".join(names)}; {problem}')
    chosen = {aliases.get(part, part) for part in given}
    return [name for name in names if name in chosen]


def horizon_of(experiment: Experiment) -> int | None:
    """Env steps per training (and evaluation) episode: the experiment's, or the trainer's default of 500 decisions
    at the paper's frame skip of the team (None for a population experiment: `mate psro` sets its own)."""
    if experiment.population:
        return experiment.horizon
    return experiment.horizon or 500 * PAPER_SETTINGS[experiment.team]['frame_skip']


def _training(experiment: Experiment, setting: Setting, preset: str, seed: int, steps: int, out: Path,
              threads: int) -> Job:
    folder = out / 'runs' / f'{setting.slug}-{preset}-seed{seed}'
    if setting.kind in ('argv', 'call'):       # a user's command line or function: `mate benchmark job` runs it
        command = ('benchmark', 'job', str(out), setting.label, preset, str(seed), '--threads', str(threads))
        return Job('train', setting.label, preset, seed, folder, (command,), (folder / 'absolute.json',),
                   TEAM_METRIC[experiment.team])
    trainer = ('rllib-train',) if setting.command == 'rllib-ppo' else ('train', setting.command)
    command = (*trainer, *setting.options, '--team', experiment.team, '--config', preset,
               '--steps', str(steps), '--seed', str(seed * SEED_STRIDE), '--horizon', str(horizon_of(experiment)),
               '--eval-every', str(experiment.eval_interval(steps)), '--eval-episodes', str(experiment.eval_episodes),
               '--threads', str(threads), '--run-dir', str(folder), '--no-progress')
    return Job('train', setting.label, preset, seed, folder, (command,), (folder / 'absolute.json',),
               TEAM_METRIC[experiment.team])


def _population(experiment: Experiment, setting: Setting, preset: str, seed: int, steps: int, out: Path) -> Job:
    folder = out / 'runs' / f'{setting.slug}-{preset}-seed{seed}'
    command = ('psro', *setting.options, '--config', preset, '--iterations', str(experiment.iterations),
               '--br-steps', str(steps), '--seed', str(seed), '--workers', '1', '--out', str(folder))
    return Job('psro', setting.label, preset, seed, folder, (command,), (folder / 'state.json',))


def _reference(experiment: Experiment, agent: str | Reference, preset: str, out: Path, threads: int = 1) -> Job:
    if isinstance(agent, Reference):            # a team of the user's: `mate benchmark job` plays it
        folder = out / 'references' / f'{agent.slug}-{preset}'
        command = ('benchmark', 'job', str(out), agent.label, preset, '--threads', str(threads))
        return Job('reference', agent.label, preset, None, folder, (command,),
                   tuple(folder / f'{name}.json' for name in ('evaluation', 'absolute')), TEAM_METRIC[experiment.team])
    folder = out / 'references' / f'{agent}-{preset}'
    own, other = ('--camera-agent', '--target-agent') if experiment.team == 'camera' else \
        ('--target-agent', '--camera-agent')
    commands, outputs = [], []
    for name, seed, episodes in (('evaluation', EVALUATION_SEEDS, experiment.eval_episodes),
                                 ('absolute', ABSOLUTE_SEEDS, ABSOLUTE_FACTOR * experiment.eval_episodes)):
        path = folder / f'{name}.json'
        commands.append(('evaluate', '--config', preset, own, agent, other, 'greedy', '--episodes', str(episodes),
                         '--seed', str(seed), '--max-episode-steps', str(horizon_of(experiment)), '--no-render',
                         '--json', str(path)))
        outputs.append(path)
    return Job('reference', agent, preset, None, folder, tuple(commands), tuple(outputs), TEAM_METRIC[experiment.team])


def add_job_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments of `mate benchmark job DIR LABEL PRESET [SEED] [--threads N]`, the command line of a job of a
    user's command-line or function setting (`_training`), or without SEED of a user's reference team
    (`_reference`)."""
    parser.add_argument('dir', metavar='DIR', help='the benchmark directory (its manifest defines the experiment)')
    parser.add_argument('label', metavar='LABEL', help='the setting, or a reference of yours')
    parser.add_argument('preset', metavar='PRESET', help='the game')
    parser.add_argument('seed', type=int, nargs='?', default=None, metavar='SEED',
                        help='the run seed (none for a reference)')
    parser.add_argument('--threads', type=positive_int, default=1, help='torch threads (default 1)')


def plan(experiment: Experiment, seeds: Iterable[int], out, steps: int | None = None, threads: int = 1,
         presets: Iterable[str] | None = None, settings: Iterable[str] | None = None) -> list[Job]:
    """Every job of `experiment` for the run seeds `seeds` in the directory `out`: the references first, then each
    (setting, preset) for each seed. `steps`: decision steps per training run (None: the experiment's budget);
    `threads`: torch threads per training run; `presets`: only these of the experiment's games, `settings` only the
    settings of these labels (None: all)."""
    check_run_seeds(experiment)
    out = Path(out)
    steps = int(steps or experiment.steps)
    wanted = set(experiment.presets if presets is None else presets)
    games = [preset for preset in experiment.presets if preset in wanted]
    labels = {setting.label for setting in experiment.settings} if settings is None else set(settings)
    chosen = [setting for setting in experiment.settings if setting.label in labels]
    jobs = [] if experiment.population else [
        _reference(experiment, agent, preset, out, threads) for preset in games for agent in experiment.references]
    for seed in seeds:
        for preset in games:
            for setting in chosen:
                jobs.append(_population(experiment, setting, preset, seed, steps, out) if setting.kind == 'psro'
                            else _training(experiment, setting, preset, seed, steps, out, threads))
    return jobs


def _option(options: tuple[str, ...], name: str) -> str | None:
    """The value of `--name V` or `--name=V` among a setting's options (the last one given), else None."""
    value = None
    for index, option in enumerate(options):
        if option == name and index + 1 < len(options):
            value = options[index + 1]
        elif option.startswith(name + '='):
            value = option[len(name) + 1:]
    return value


def check_run_seeds(experiment: Experiment) -> None:
    """ValueError (one line, naming the setting and the valid range) for a setting whose runs would play another run
    seed's training games: a trainer's `--num-envs` above SEED_STRIDE, or a population run whose best responses'
    rows (seed k x 1,000 + 2 x iteration + side + row) leave its 1,000 seeds. A user's command line or function picks
    its own envs (`mate.benchmark.user` says how to keep them in the run's seeds)."""
    for setting in experiment.settings:
        if setting.kind not in ('trainer', 'psro'):
            continue
        given = _option(setting.options, '--num-envs')
        try:
            envs = PSRO_ENVS if given is None and setting.kind == 'psro' else None if given is None else int(given)
        except ValueError:
            continue                    # not a number: the trainer's own parser says so
        if envs is None:
            continue
        if setting.kind == 'trainer' and envs > SEED_STRIDE:
            raise ValueError(f'experiment {experiment.name!r}, setting {setting.label!r}: --num-envs {envs:,} would '
                             f'play another run\'s training games; a benchmark run has 1..{SEED_STRIDE:,} envs (run '
                             f'seed k trains on seeds k x {SEED_STRIDE:,} to k x {SEED_STRIDE:,} + {SEED_STRIDE - 1})')
        rows = 2 * experiment.iterations + 1 + envs       # best responses' first seeds after the run's own, + rows
        if setting.kind == 'psro' and rows > SEED_STRIDE:
            raise ValueError(f'experiment {experiment.name!r}, setting {setting.label!r}: {experiment.iterations} '
                             f'iterations with --num-envs {envs:,} play seeds up to k x 1,000 + {rows - 1:,}, another '
                             f'run\'s; 2 x iterations + 1 + num_envs must be at most {SEED_STRIDE:,}')


def job_values(experiment: Experiment, preset: str, seed: int | None, steps: int, out, threads: int,
               setting: Setting | Reference) -> dict:
    """What a user's command-line or function setting is given for the run (`mate.benchmark.user.PLACEHOLDERS`): its
    run directory (absolute, from the current one), training seed (`seed x SEED_STRIDE`, as a mate trainer's),
    budget, team, game, episode cut, evaluation episodes and interval, and torch threads. For a user's reference
    team (`Reference`, seed None): its directory under `references/`, the team, game, episode cut, evaluation
    episodes and threads."""
    if isinstance(setting, Reference):
        return dict(run_dir=str(Path(out).resolve() / 'references' / f'{setting.slug}-{preset}'),
                    team=experiment.team, config=preset, horizon=horizon_of(experiment),
                    eval_episodes=experiment.eval_episodes, threads=int(threads))
    run_dir = Path(out).resolve() / 'runs' / f'{setting.slug}-{preset}-seed{seed}'
    return dict(run_dir=str(run_dir), seed=seed * SEED_STRIDE, steps=int(steps), team=experiment.team, config=preset,
                horizon=horizon_of(experiment), eval_episodes=experiment.eval_episodes,
                eval_every=experiment.eval_interval(steps), threads=int(threads))
