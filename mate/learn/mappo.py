"""MAPPO and IPPO for MATE, feed-forward, in one file that reads top to bottom (`mate train mappo|ippo`).

    config  ->  PolicySpec (what the policy sees and does)  ->  batched training envs (`TrainingEnv`: B games,
                the other team a batched opponent, the greedy rules by default)
            ->  networks: one actor shared by every agent of the team (full parameter sharing, as in the paper),
                a critic on the global state (MAPPO, `critic='state'`), on each agent's observation (IPPO,
                `critic='local'`) or on both (MAPPO with the agent-specific global state, `critic='agent'`)
            ->  loop: collect T decisions x B envs x N agents, GAE, K epochs of clipped PPO on minibatches
            ->  `Run`: logs (progress line, CSV, TensorBoard when installed), checkpoints, best.pt, final.pt

The actor's output is one or more independent categorical choices (`action_distribution`): one of 25 grid moves, or
one keep/ignore bit per target slot for HRL cameras (`--hrl`, the paper's hierarchical cameras), whose rule executor
runs inside the env. Rewards are team rewards, repeated to every agent, or each camera's own share of the coverage
(`--credit difference`; MAPPO's critic then gives one value per agent). Values are learned on normalised returns
(running mean/std, "value normalisation"). The recurrent variant is `mappo_lstm.py`; with learned messages,
`tarmac.py` and `i2c.py`.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar, Literal

from ..cli.options import option
from . import ppo_loop
from .envs import TrainingEnv
from .ppo import PAPER_HELP, PAPER_HYPERPARAMETERS, PPOConfig
from .run import Run
from ..policies.spec import PolicySpec

__all__ = ['HRL_CAMERA_HIDDEN', 'MAPPOConfig', 'policy_spec', 'train']


HRL_CAMERA_HIDDEN = (64, 64)
"""The default widths of HRL cameras: at 1 M decisions on MATE-4v8-9 (3 seeds each) hidden layers of 64, 128 and
256 units cover alike on held-out episodes (0.605 / 0.607 / 0.604), and 64 trains 1.6x faster than 256 on 2 cores;
the targets learn faster with 256 (docs/training.md, "Network width")."""


@dataclasses.dataclass
class MAPPOConfig(PPOConfig):
    """Settings of a feed-forward MAPPO / IPPO / MAPPO-AS run (`train(config)`, `mate train mappo|ippo|mappo-as`)."""

    PRESETS: ClassVar[dict] = {'paper': (PAPER_HELP + "; the paper's MLP actor",
                                         dict(PAPER_HYPERPARAMETERS, actor='mlp'))}

    critic: Literal['state', 'local', 'agent'] = option('state', "the critic's input: the global state (MAPPO), each "
                                                                 "agent's observation (IPPO), or the global state with "
                                                                 "each agent's observation appended (MAPPO-AS)")
    actor: Literal['mlp', 'per-target'] | None = option(None, "policy network: 'mlp' (the paper's) or, for cameras, "
                                                              "'per-target' (one shared scorer per target slot); None: "
                                                              'per-target for cameras, mlp for targets')

    hidden: tuple[int, ...] | None = option(None, 'hidden layer widths of the actor and the critic; None: 64 64 for '
                                                  'HRL cameras, 256 256 otherwise (the width study, docs/training.md)',
                                            minimum=1)

    def __post_init__(self) -> None:
        if self.hidden is None:
            self.hidden = HRL_CAMERA_HIDDEN if self.hrl and self.team == 'camera' else (256, 256)
        super().__post_init__()
        if self.actor == 'per-target' and self.team != 'camera':
            raise ValueError("--actor per-target reads a camera's target slots; it needs --team camera")

    @property
    def algo(self) -> str:
        return {'state': 'mappo', 'local': 'ippo', 'agent': 'mappo-as'}[self.critic]




def policy_spec(config: MAPPOConfig, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains; with `envs` given, what they say the policy sees and does (their
    `spec`: PSRO's envs, the tests' toy tasks) with this config's network."""
    actor = config.actor or ('per-target' if config.team == 'camera' else 'mlp')
    return config.policy_spec(action='hrl' if config.hrl else 'grid', envs=envs, network=actor, hidden=config.hidden,
                              activation=config.activation, lstm=0, algo=config.algo)


# ============================================================================ training

def train(config: MAPPOConfig, envs: TrainingEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/ALGO-TEAM-seedN); resume from its checkpoint
    unless `config.fresh`. `envs` replaces the training envs (anything with `TrainingEnv`'s attributes, `spec`
    and reset/step: PSRO's mixtures, tests' toy tasks); `callback(row)` sees every log row. Returns the `Run`
    (`last_row`, `interrupted`, counters). The loop is `mate.learn.ppo_loop`'s."""
    return ppo_loop.train(config, policy_spec(config, envs), envs, callback, console, critic=config.critic)
