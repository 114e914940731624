"""`mate rllib-train`: RLlib's PPO training a team of MATE as a `mate train` run (the witness beside mate's IPPO).

    mate rllib-train --team camera --steps 10000000 --eval-every 500000 --eval-episodes 32 --seed 1000

The run is `mate train`'s in everything but the learner: the same game and view (`TeamEnvConfig`: the paper's
preset, frame skip and horizon of the team; the policy's observations are `PolicySpec.features`, its actions the
25 grid moves), the same opponent (the greedy rules, batched), the same decision count (`--steps`: decisions summed
over the games, which is what RLlib counts as env steps, one RLlib step being one decision of the team), the same
run directory and files (`mate.learn.Run`: `progress.csv`, `best.pt`, `final.pt`, `checkpoint.pt`) and the same
evaluation protocol (`mate.learn.evaluation`: `evaluations.jsonl`, `best-eval.pt`, `absolute.json`), the policies
exported from the RLlib module to `mate` policy files (`mate.integrations.rllib_export`). The learner is RLlib's PPO
(new API stack) with one policy shared by the team's agents, its value function per agent (of the agent's own
observation, as IPPO's), and by default the paper's RLlib hyper-parameters (its appendix;
`mate.learn.ppo.PAPER_HYPERPARAMETERS`).

This module imports nothing from Ray or torch until the command runs, so `mate --help` works without the optional
extra. The training itself is `mate.integrations.rllib.train_run`.
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Literal

from ..cli.arguments import CommandError, resolving_arguments
from ..learn.envs import TeamEnvConfig
from ..learn.evaluation import EVALUATION_SEEDS
from ..learn.run_config import RunConfig
from ..learn.schedules import check_network_options
from ..cli.options import add_options, option
from ..evaluation.protocol import check_eval_episodes

__all__ = ['ALGO', 'RLlibPPOConfig', 'add_arguments', 'config_of', 'run']

ALGO = 'rllib-ppo'
"""The algorithm name of `mate rllib-train` runs (their spec's `algo`; their default directory runs/rllib-ppo-...)."""

EXCLUDED = ('hrl', 'memory', 'velocity', 'full_observability', 'credit', 'device')
"""`TeamEnvConfig` and `RunConfig` options that the RLlib run does not offer (flat grid moves of an MLP policy, team
rewards, the learner on the CPU)."""


@dataclasses.dataclass
class RLlibPPOConfig(RunConfig, TeamEnvConfig):
    """Settings of a `mate rllib-train` run: the team env's options and the run's (as `mate train`'s: `TeamEnvConfig`,
    `RunConfig`), Ray's, then RLlib PPO's hyper-parameters (defaults: the paper's RLlib settings, as
    `mate.learn.ppo.PAPER_HYPERPARAMETERS`, with mate's MLP actor of 256 256)."""

    # ---- the run (mate.learn.run.RunConfig), where it differs
    threads: int = option(0, 'torch threads of the driver (the learner, and the env runner when '
                             '--num-env-runners is 0); 0: torch\'s default', minimum=0)
    device: str = option('cpu', 'where the evaluations\' forward passes run (the RLlib learner runs on the CPU)')
    run_dir: str | None = option(None, 'output directory; None: runs/rllib-ppo-TEAM-seedN')
    iterations: int | None = option(None, 'also stop after this many iterations in all (the run is then not '
                                          'complete: no final.pt or absolute.json until it goes on)', minimum=1)
    # ---- Ray
    address: str | None = option(None, "an existing Ray cluster ('auto', 'ray://host:10001'); None: start a local Ray")
    num_cpus: int | None = option(None, 'CPUs of the local Ray instance (None: all)', minimum=1)
    num_env_runners: int = option(0, 'remote rollout workers, each playing num_envs / num_env_runners games '
                                     '(0: sample on the driver)', minimum=0)
    # ---- RLlib PPO
    rollout_length: int = option(25, 'decisions per env per iteration (RLlib rollout_fragment_length; the batch is '
                                     'num_envs x rollout_length decisions)', minimum=1)
    epochs: int = option(16, 'passes over each batch (RLlib num_epochs; the paper: 16)', minimum=1)
    minibatch_size: int = option(256, "agent steps per minibatch (RLlib's minibatch_size, counted in the shared "
                                      "policy's rows: decisions x agents; the paper: 256)", minimum=1)
    gamma: float = option(0.99, 'discount per decision', minimum=0, maximum=1)
    gae_lambda: float = option(1.0, 'GAE lambda (RLlib and the paper: 1.0)', minimum=0, maximum=1)
    clip: float = option(0.3, 'PPO clip range of the probability ratio', above=0)
    value_coef: float = option(1.0, 'weight of the value loss (RLlib vf_loss_coeff)', minimum=0)
    vf_clip: float = option(10_000.0, 'clip of the squared value error (RLlib vf_clip_param; the paper: 10000, '
                                      'effectively off)', above=0)
    kl_coeff: float = option(0.2, 'initial coefficient of the adaptive KL penalty (RLlib and the paper: 0.2); 0: off',
                             minimum=0)
    kl_target: float = option(0.01, 'KL the penalty adapts towards', above=0)
    max_grad_norm: float = option(0.0, 'gradient clipping by global norm (RLlib grad_clip); 0: none (the paper)',
                                  minimum=0)
    hidden: tuple[int, ...] = option((256, 256), 'hidden layer widths of the policy (and of the value function)',
                                     minimum=1)
    activation: Literal['tanh', 'relu'] = option('tanh', 'hidden activation')
    vf_share_layers: bool = option(False, "the value function shares the policy's layers (RLlib's default) instead "
                                          "of its own MLP (mate's IPPO critic)")
    lr_schedule: tuple[tuple[float, float], ...] = option(
        ((0, 5e-4), (4_000_000, 1e-4), (8_000_000, 5e-5)), 'learning rate [[step, lr], ...] in decision steps, '
        'RLlib interpolating linearly between the points (the paper\'s points)')
    entropy_schedule: tuple[tuple[float, float], ...] = option(
        ((0, 0.05), (2_000_000, 0.01), (4_000_000, 0.001), (10_000_000, 0.0)),
        'entropy coefficient [[step, coefficient], ...], piecewise linear in decision steps (the paper\'s)')

    def __post_init__(self) -> None:
        TeamEnvConfig.__post_init__(self)
        RunConfig.__post_init__(self)
        check_network_options(self, ('lr_schedule', 'entropy_schedule'))
        for name in ('lr_schedule', 'entropy_schedule'):
            points = getattr(self, name)
            if points[0][0] != 0:
                raise ValueError(f'--{name.replace("_", "-")} must start at step 0 (RLlib schedules do), '
                                 f'got {points[0][0]:g}')
        if self.seed + self.num_envs > EVALUATION_SEEDS:       # rows play seed + row (mate.integrations.rllib)
            raise ValueError(f'--seed {self.seed} with --num-envs {self.num_envs} would train on evaluation seeds: '
                             f'seed + num_envs must be at most {EVALUATION_SEEDS:,} '
                             '(mate.evaluation.protocol.SEED_RANGES)')
        check_eval_episodes(self.eval_episodes, '--eval-episodes')
        if self.num_env_runners and self.num_envs % self.num_env_runners:
            raise ValueError(f'--num-envs {self.num_envs} must be a multiple of --num-env-runners '
                             f'{self.num_env_runners} (each runner plays the same number of games)')
        if self.minibatch_size > self.num_envs * self.rollout_length:
            raise ValueError(f'--minibatch-size {self.minibatch_size} must be at most the batch, num_envs x '
                             f'rollout_length = {self.num_envs * self.rollout_length} (RLlib checks it against the '
                             'decisions of the batch)')
        object.__setattr__(self, 'hidden', tuple(self.hidden))

    @property
    def envs_per_runner(self) -> int:
        """Games each env runner plays (RLlib num_envs_per_env_runner)."""
        return self.num_envs // max(self.num_env_runners, 1)

    def to_dict(self) -> dict:
        return {k: v for k, v in super().to_dict().items() if k not in EXCLUDED}

    def witness_spec(self):
        """The `PolicySpec` of the run's policies: the team's view, 25 grid moves, the MLP of `hidden`, algo ALGO."""
        return self.policy_spec(action='grid', network='mlp', hidden=self.hidden, activation=self.activation, algo=ALGO)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The command's options, one per field of `RLlibPPOConfig` (see docs/rllib.md)."""
    add_options(parser, RLlibPPOConfig, exclude=EXCLUDED)


def config_of(args: argparse.Namespace) -> RLlibPPOConfig:
    """The config of parsed arguments; CommandError (one line) for values that do not fit together."""
    given = {f.name: getattr(args, f.name) for f in dataclasses.fields(RLlibPPOConfig)
             if f.init and f.name not in EXCLUDED and hasattr(args, f.name)}
    given = {name: tuple(value) if isinstance(value, list) else value for name, value in given.items()}
    with resolving_arguments():
        return RLlibPPOConfig(**given)


def run(args: argparse.Namespace, console) -> int:
    """Train as `args` say; 0 when done (or already done), 130 when stopped by a signal (resumable). The config,
    the game and the run directory's checkpoint are checked before Ray starts; without Ray, CommandError says how
    to install it."""
    config = config_of(args)
    with resolving_arguments():   # the game: a bad --config lists the presets
        spec = config.witness_spec()
    try:
        from . import rllib
    except ImportError as exc:
        raise CommandError(f"needs Ray RLlib ({exc}); install the optional extra: pip install 'mate[rllib]' "
                           '(see docs/rllib.md for the versions)') from None
    from ..learn.command import resumes, train_and_report

    if config.run_dir is None:
        config.run_dir = f'runs/{ALGO}-{config.team}-seed{config.seed}'
    resuming = resumes(config, console)
    if resuming is None:
        return 0
    where = f'Ray cluster at {config.address}' if config.address else 'a local Ray instance'
    console.print(f'training RLlib PPO {config.team}s on {spec.env_id} (MLP {" ".join(map(str, spec.hidden))}, '
                  f'{spec.choices} grid moves, frame skip {spec.frame_skip}, {config.num_envs} envs, {config.steps:,} '
                  f'decision steps, {where}) -> {config.run_dir}', soft_wrap=True, highlight=False)
    return train_and_report(rllib.train_run, config, console, resuming)
