"""Recurrent MAPPO and IPPO for MATE: the paper's actor, MLP -> LSTM -> head, in one file (`mate train mappo-lstm`).

    config  ->  PolicySpec (the 'mlp' or 'per-target' network with an LSTM of `lstm` cells)  ->  `TrainingEnv`
            ->  networks: one recurrent actor shared by the team (`RecurrentActor`: the feed-forward actor's body, an
                LSTM, the head on [body features, LSTM output]), a feed-forward critic on the global state (MAPPO,
                `critic='state'`), on each agent's observation (IPPO, `critic='local'`) or on both (MAPPO-AS,
                `critic='agent'`, as `mappo.py`)
            ->  loop: collect T decisions x B envs x N agents, the actor carrying its memory from decision to decision
                (and from iteration to iteration), GAE, K epochs of clipped PPO on minibatches of whole env sequences
            ->  `Run`: logs, checkpoints, best.pt, final.pt

The actor's memory (h, c) (B, N, lstm) starts at zero where an episode starts: `starting` (B,) flags the envs whose
next decision opens an episode (every env at a run's start, then those that were done), and each decision first
zeroes their memory (`restarted`). The rollout keeps the memory it began with (before that zeroing) and the flags of
every decision (`start_buf`); a minibatch is a group of envs with all their T decisions, and the update unrolls each
sequence again from its first memory, zeroing the same rows at the same decisions (`RecurrentActor.forward`), so that
its log-probabilities are those of the rollout before the first step (KL 0). The gradient flows through the T
decisions of the rollout, not into the iterations before it (truncated backpropagation through time). The memory and
the flags outlive the iteration: the next rollout continues the episodes where this one stopped.

Everything else is feed-forward MAPPO's (`mappo.py`; the loop is `ppo_loop.py`): the action distribution (grid
moves or HRL keep/ignore bits), team or per-agent rewards, value normalisation, horizon cuts bootstrapped from the
critic.
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

__all__ = ['RecurrentConfig', 'policy_spec', 'train']


@dataclasses.dataclass
class RecurrentConfig(PPOConfig):
    """Settings of a recurrent MAPPO / IPPO run (`train(config)`, `mate train mappo-lstm`)."""

    PRESETS: ClassVar[dict] = {'paper': (PAPER_HELP + "; the paper's MLP actor",
                                         dict(PAPER_HYPERPARAMETERS, actor='mlp'))}

    critic: Literal['state', 'local', 'agent'] = option('state', "the critic's input: the global state (MAPPO), each "
                                                                 "agent's observation (IPPO) or the state with each "
                                                                 "agent's observation appended (MAPPO-AS)")
    actor: Literal['mlp', 'per-target'] | None = option(None, "the body and head around the LSTM: 'mlp' (the paper's) "
                                                              "or, for cameras, 'per-target' (one shared scorer per "
                                                              'target slot); None: per-target for cameras, mlp for '
                                                              'targets')
    lstm: int = option(256, "LSTM cells of the actor (the paper's 256)", minimum=1)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.actor == 'per-target' and self.team != 'camera':
            raise ValueError("--actor per-target reads a camera's target slots; it needs --team camera")

    @property
    def algo(self) -> str:
        return {'state': 'mappo-lstm', 'local': 'ippo-lstm', 'agent': 'mappo-as-lstm'}[self.critic]




def policy_spec(config: RecurrentConfig, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains; with `envs` given, what they say the policy sees and does (their
    `spec`) with this config's network."""
    actor = config.actor or ('per-target' if config.team == 'camera' else 'mlp')
    return config.policy_spec(action='hrl' if config.hrl else 'grid', envs=envs, network=actor, hidden=config.hidden,
                              activation=config.activation, lstm=config.lstm, algo=config.algo)


# ============================================================================ training

def train(config: RecurrentConfig, envs: TrainingEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/ALGO-TEAM-seedN); resume from its checkpoint
    unless `config.fresh`. `envs` replaces the training envs (anything with `TrainingEnv`'s attributes, `spec`
    and reset/step); `callback(row)` sees every log row. Returns the `Run`. The loop is `mate.learn.ppo_loop`'s,
    which reads from the actor (`RecurrentActor.recurrent`) that it carries a memory."""
    return ppo_loop.train(config, policy_spec(config, envs), envs, callback, console, critic=config.critic)
