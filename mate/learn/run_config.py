"""`RunConfig`: a training run's budget, machine and files, the options every trainer takes (no torch here, so that
command-line parsers and configs load without it)."""

from __future__ import annotations

import dataclasses

from ..cli.options import check_ranges, option
from ..evaluation.protocol import MAX_EVAL_EPISODES

__all__ = ['RunConfig', 'default_run_dir', 'run_name']


@dataclasses.dataclass
class RunConfig:
    """A training run's budget, machine and files: options every trainer takes."""

    steps: int = option(2_000_000, 'decision steps in total (summed over the envs), as RLlib counts', minimum=1)
    minutes: float = option(0.0, 'also stop after this many minutes of training (resumed sessions included); '
                                 '0: no time limit', minimum=0)
    threads: int = option(1, 'torch threads of the updates; 0: every core (collection always uses 1). Measured on 2 '
                             'cores, MAPPO cameras: 1 thread 1,760 decisions/s alone and 1,520 beside a busy process, '
                             'every core 2,070 alone but 705 beside it', minimum=0)
    device: str = option('auto', "where networks, rollouts and updates run: auto (a GPU when there is one), cpu, "
                                 'cuda or cuda:N (where the games run: --game-device of mate train)')
    run_dir: str | None = option(None, 'output directory; None: runs/NAME-TEAM-seedN')
    fresh: bool = option(False, 'start over, ignoring (and replacing) a checkpoint in the run directory')
    progress: bool = option(True, 'the progress bar (plain lines every 30 s when the output is not a terminal)')
    checkpoint_every: int = option(20, 'iterations between checkpoints', minimum=1)
    snapshot_every: int = option(0, 'keep the policy every N iterations as RUN_DIR/snapshots/policy-STEPS.pt; 0: off',
                                 minimum=0)
    eval_every: int = option(0, 'decision steps between evaluations of the policy on held-out seeds '
                                '(evaluations.jsonl, best-eval.pt, and at the end the absolute metric); 0: none',
                             minimum=0)
    eval_episodes: int = option(32, 'episodes per evaluation (the absolute metric plays 10 times as many)', minimum=1,
                                maximum=MAX_EVAL_EPISODES)
    wandb: bool = option(False, 'also log every row to Weights & Biases (pip install wandb; WANDB_MODE=offline works '
                                'without an account)')
    wandb_project: str = option('mate', 'the Weights & Biases project of --wandb')

    def __post_init__(self) -> None:
        from ..policies.device import parse_device

        parse_device(self.device)          # a bad name is refused now, with the valid forms
        check_ranges(self)                 # the options' ranges, as the command line checks them

    def cuts_its_last_iteration(self) -> bool:
        """Whether a run of this config ends its last iteration early at its budget `steps`, logging a row (and
        from there on, iterations) a run of a larger budget does not have. The rollout trainers' iterations all have
        one size and the last goes past the budget: never. A trainer that logs a row every so many decision steps
        and one at the budget (IQL, QMIX, MA-TD3) says so by overriding this."""
        return False

    @property
    def time_limit(self) -> float:
        """The time budget in seconds (0: none)."""
        return 60.0 * self.minutes

    def to_dict(self) -> dict:
        return {k: (list(map(list, v)) if k.endswith('schedule') else list(v) if isinstance(v, tuple) else v)
                for k, v in dataclasses.asdict(self).items()}


def run_name(algo: str, config) -> str:
    """The run's name in its default directory: the algorithm (its config's `algo` when it has one: 'ippo-tarmac'
    for `mate train tarmac --critic local`), 'hrl-' first for HRL cameras, the observability and the channel's
    perturbations after."""
    algo = getattr(config, 'algo', algo)
    name = ('hrl-' if config.hrl else '') + algo + ('-full-obs' if config.full_observability else '')
    tags = (('message_dropout', 'dropout'), ('communication_range', 'range'), ('message_delay', 'delay'))
    for attribute, tag in tags:
        value = getattr(config, attribute, None)
        if value:
            name += f'-{tag}{value:g}'
    return name


def default_run_dir(algo: str, config) -> str:
    """The directory of a run whose config names none: runs/NAME-TEAM-seedN (`run_name`), the one default of
    `mate train` and of `Run.of`."""
    return f'runs/{run_name(algo, config)}-{config.team}-seed{config.seed}'
