"""`mate train ALGORITHM [OPTIONS]`: one command per trainer, its options generated from the trainer's config.

`mate train -h` lists the trainers; `mate train ALGORITHM -h` its options, each with its default and help, read
from the config dataclass of the algorithm's file (`mate.cli.options`). An option of another trainer is not on the
parser, so it is refused. The trainer's module (and torch) is imported only once a trainer is named.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from ..cli.arguments import ArgumentParser, CommandError, resolving_arguments
from .run_config import default_run_dir, run_name  # (no torch: `mate train -h` works without it)

__all__ = ['TRAINERS', 'add_arguments', 'run', 'trainer_config']


@dataclass(frozen=True)
class Trainer:
    """A `mate train` command: the module with `train(config)` and its config class, and the fields it fixes."""

    module: str
    config: str
    help: str
    fixed: dict = field(default_factory=dict)


TRAINERS = {
    'mappo': Trainer('mate.learn.mappo', 'MAPPOConfig', 'MAPPO: feed-forward actor, critic on the global state',
                     dict(critic='state')),
    'ippo': Trainer('mate.learn.mappo', 'MAPPOConfig', "IPPO: feed-forward actor, critic on each agent's observation",
                    dict(critic='local')),
    'mappo-as': Trainer('mate.learn.mappo', 'MAPPOConfig', 'MAPPO-AS: MAPPO whose critic reads the global state with '
                                                           "each agent's observation appended (one value per agent)",
                        dict(critic='agent')),
    'mappo-lstm': Trainer('mate.learn.mappo_lstm', 'RecurrentConfig',
                          "recurrent MAPPO / IPPO (--critic local): MLP -> LSTM -> head, the paper's actor"),
    'tarmac': Trainer('mate.learn.tarmac', 'TarMACConfig', 'TarMAC: learned messages read through attention one '
                                                          'decision later (MAPPO or IPPO base)'),
    'i2c': Trainer('mate.learn.i2c', 'I2CConfig', "I2C: each agent asks the teammates its prior selects for their "
                                                  'current observations (MAPPO base)'),
    'iql': Trainer('mate.learn.iql', 'IQLConfig',
                   'independent Q-learning: a dueling double-Q network shared by the team'),
    'qmix': Trainer('mate.learn.qmix', 'QMIXConfig', 'QMIX: recurrent agent network, monotonic mixer on the state'),
    'matd3': Trainer('mate.learn.matd3', 'MATD3Config', 'MADDPG as MA-TD3: one actor and twin centralised critics per '
                                                        'agent, continuous actions'),
}
"""The trainers of `mate train`: name -> `Trainer` (the algorithm's module, its config class, a line of help, and
the config fields the name fixes, as `critic='local'` for `ippo`). A new algorithm is a file with a config
dataclass, `policy_spec` and `train`, and a line here; 'maddpg' is another name for 'matd3'."""
TRAINERS['maddpg'] = TRAINERS['matd3']       # the paper's name for it


def add_arguments(parser: argparse.ArgumentParser) -> None:
    listing = '; '.join(f'{name}: {trainer.help}' for name, trainer in TRAINERS.items() if name != 'maddpg')
    parser.add_argument('algo', choices=list(TRAINERS), metavar='ALGORITHM',
                        help=f'the trainer ({listing}; maddpg: matd3). `mate train ALGORITHM -h` lists its options')
    parser.add_argument('options', nargs=argparse.REMAINDER, help='the trainer\'s options')


def trainer_parser(name: str):
    """(parser, module, config class) of `mate train NAME` (imports the trainer's module, and torch)."""
    from ..cli.options import add_options

    trainer = TRAINERS[name]
    try:
        module = importlib.import_module(trainer.module)
    except ImportError as exc:
        raise CommandError(f"needs PyTorch ({exc}); install the train extra: pip install -e '.[train]'") from None
    config_class = getattr(module, trainer.config)
    parser = ArgumentParser(prog=f'mate train {name}', description=f'{trainer.help}. {config_class.__doc__}')
    parser.add_argument('--config-file', default=None, metavar='FILE',
                        help='a YAML or JSON file of these options by field name (num_envs: 16, hidden: [64, 64], '
                             'paper: true); the command line overrides it')
    add_options(parser, config_class, exclude=tuple(trainer.fixed))
    return parser, module, config_class


def trainer_config(name: str, options: list[str]):
    """(module, config) of the command line `mate train NAME OPTIONS...`: the options (over a `--config-file`'s)
    parsed by the trainer's parser into its config, every field resolved (`run_dir` None when not given). A mistake
    exits as the command would (CommandError, or argparse's SystemExit)."""
    from ..cli.options import config_from, file_arguments

    parser, module, config_class = trainer_parser(name)
    parsed = parser.parse_args(options)
    if parsed.config_file:
        with resolving_arguments():
            parsed = parser.parse_args([*file_arguments(parser, parsed.config_file), *options])
    return module, config_from(parser, config_class, parsed, **TRAINERS[name].fixed)


def run(args: argparse.Namespace, console) -> int:
    """Train as `args` say; 0 when done (or already done), 130 when stopped by a signal (resumable)."""
    from ..policies.checkpoint import CheckpointError, load_checkpoint

    module, config = trainer_config(args.algo, args.options)
    if config.run_dir is None:
        config = dataclasses.replace(config, run_dir=default_run_dir(args.algo, config))
    if config.wandb:
        from ..cli.extras import require

        require('wandb', '--wandb')
    resuming = resumes(config, console)
    if resuming is None:
        return 0
    if not resuming and getattr(config, 'init_from', None):   # a bad file fails now, before the envs are built
        try:
            load_checkpoint(config.init_from)
        except CheckpointError as exc:
            raise CommandError(f'--init-from: {exc}') from None
    with resolving_arguments():
        spec = module.policy_spec(config)
        from ..policies.device import resolve_device

        device = resolve_device(config.device)
        games = config.resolved_game_device(spec) if hasattr(config, 'resolved_game_device') else 'cpu'
    _write_command(config.run_dir, ['mate', 'train', args.algo, *args.options])
    name = run_name(args.algo, config)
    console.print(f'training {name.upper()} {config.team}s on {spec.env_id} ({spec.network} network'
                  f'{f", LSTM {spec.lstm}" if spec.lstm else ""}, {spec.action} actions, frame skip {spec.frame_skip}, '
                  f'{config.num_envs} envs, {config.steps:,} decision steps, {device}, games on {games}) -> '
                  f'{config.run_dir}',
                  soft_wrap=True, highlight=False)
    return train_and_report(module.train, config, console, resuming)


def train_and_report(train: Callable, config, console, resuming: bool) -> int:
    """Run `train(config, console=console)` (a trainer's `train`, or RLlib's for `mate rllib-train`) and say how it
    ended; the command's exit status: 0 when done (or stopped by `--iterations`), 130 when stopped by a signal."""
    from ..policies.checkpoint import CheckpointError

    checkpoint_path = Path(config.run_dir) / 'checkpoint.pt'
    if resuming:
        console.print(f'resuming from {checkpoint_path}', soft_wrap=True)
    try:
        result = train(config, console=console)
    except CheckpointError as exc:   # the run directory's checkpoint belongs to another experiment
        raise CommandError(f'{exc} (use --fresh or another --run-dir to start over)') from None
    row = result.last_row
    if result.interrupted:
        console.print(f'stopped at iteration {result.iteration} ({result.env_steps:,} decision steps), checkpoint '
                      f'written; run the same command again to continue from {checkpoint_path}', soft_wrap=True)
        return 130
    if not result.complete:         # `mate rllib-train --iterations`
        console.print(f'stopped after --iterations {config.iterations} ({result.env_steps:,} of {config.steps:,} '
                      'decision steps); run the command again with more --iterations (or without) to continue',
                      soft_wrap=True)
        return 0
    if config.minutes and result.env_steps < config.steps:
        console.print(f'stopped at the time limit of {config.minutes:g} minutes')
    from .run import episode_reward_phrase

    rounded = f' (--steps {config.steps:,} rounded up to whole iterations)' if result.env_steps > config.steps else ''
    console.print(f"done: {result.env_steps:,} decision steps{rounded}, rollout coverage "
                  f"{row.get('rollout_coverage', float('nan')):.3f}, {episode_reward_phrase(row)}; final policy "
                  f"{Path(config.run_dir) / 'final.pt'} (the learner's reward is what it trains on: for cameras the "
                  "summed coverage rate; mate evaluate reports the env's raw team return)", soft_wrap=True,
                  highlight=False)
    return 0


def already_done(saved: dict, config) -> tuple[str, str] | None:
    """Why the run of checkpoint `saved` needs no more training under `config`, and the flag to raise to train on;
    None if it does need more."""
    counters = saved.get('run', {})
    steps, seconds = int(counters.get('env_steps', 0)), float(counters.get('wall_seconds', 0.0))
    if steps >= config.steps:
        return f'{steps:,} decision steps >= --steps {config.steps:,}', '--steps'
    if config.minutes and seconds >= config.time_limit:
        return f'{seconds / 60:.3g} minutes of training >= --minutes {config.minutes:g}', '--minutes'
    return None


def resumes(config, console) -> bool | None:
    """Whether the run of `config` (its `run_dir` set) goes on from its checkpoint; None when the checkpoint's run is
    already done (said on `console`, and a missing absolute metric played). CommandError for an unreadable
    checkpoint."""
    from ..policies.checkpoint import CheckpointError, load_checkpoint

    checkpoint_path = Path(config.run_dir) / 'checkpoint.pt'
    if not checkpoint_path.exists() or config.fresh:
        return False
    try:
        done = already_done(load_checkpoint(checkpoint_path), config)
    except CheckpointError as exc:
        raise CommandError(f'{exc} (use --fresh or another --run-dir to start over)') from None
    if done is None:
        return True
    reason, flag = done
    console.print(f'run already done: {reason} (use --fresh to start over or raise {flag})', soft_wrap=True)
    _absolute_metric(config, console)
    return None


def _absolute_metric(config, console) -> None:
    """A complete run with an evaluation protocol whose absolute metric is missing (the process stopped between its
    last checkpoint and the end): play it now."""
    run_dir = Path(config.run_dir)
    if not config.eval_every or (run_dir / 'absolute.json').exists() or not (run_dir / 'best-eval.pt').exists():
        return
    from ..policies.checkpoint import load_checkpoint, read_spec
    from .evaluation import Evaluator

    path = run_dir / 'best-eval.pt'
    evaluator = Evaluator(run_dir, read_spec(load_checkpoint(path), path), config.eval_every, config.eval_episodes,
                          config.resolved_horizon)
    record = evaluator.absolute()
    console.print(f'absolute metric (best evaluated policy, {len(record["episodes"])} held-out episodes): '
                  f'{record["metric"]} {record["mean"]:.3f} -> {run_dir / "absolute.json"}', soft_wrap=True)


def _write_command(run_dir, argv: list[str]) -> None:
    """`RUN_DIR/command.txt`: the command line that ran (or resumed) the run, beside its checkpoints and
    `config.json`."""
    import shlex

    path = Path(run_dir)
    path.mkdir(parents=True, exist_ok=True)
    (path / 'command.txt').write_text(shlex.join(argv) + '\n')
