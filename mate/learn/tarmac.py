"""TarMAC on MAPPO or IPPO for MATE: learned messages read through attention, in one file (`mate train tarmac`).

    config  ->  PolicySpec (network 'tarmac': the MLP body, an LSTM of `lstm` cells, a head of [logits | message])
            ->  `TrainingEnv`, and the channel the messages go through in training (`Channel`: ideal by default)
            ->  networks: one `TarMACActor` shared by the team; a feed-forward critic on the global state (MAPPO,
                `critic='state'`), on each agent's observation (IPPO, `critic='local'`) or on both (MAPPO-AS,
                `critic='agent'`, as `mappo.py`), the messages appended
            ->  loop: collect T decisions x B envs x N agents, the actor carrying (h, c, messages) from decision to
                decision; GAE; K epochs of clipped PPO on minibatches of whole env sequences, unrolled through the
                messages
            ->  `Run`: logs, checkpoints, best.pt, final.pt

At every decision each agent sends a message (key 32 + value 32) and every agent of the env, the sender included,
reads all N messages at the next decision through soft attention (`mate.policies.comm` has the computation). The
messages are part of the state the actor carries, `(h, c, messages)`, so the memory rules are `mappo_lstm.py`'s:
zeroed where an episode starts (`starting`; nothing is heard at an episode's first decision), the rollout's first
memory and its start flags kept so that the update unrolls each env sequence again, bitwise as in the rollout. The
messages stay in the graph of that unroll: the loss of a receiver's action at t + 1 trains the sender's message
head at t (within a rollout; the memory carried in from the previous one is a constant).

The critic reads the N messages of the decision too (docs/training.md, "TarMAC"): those the agents read at it (the
previous decision's; zeros at an episode's first), stored with the rollout as data (T, B, N, 64) and appended flat
(N x 64) to the global state or to each agent's critic input. A horizon cut's bootstrap value reads the messages just
sent (those the episode's next decision would read); the rollout's last value those the next decision reads.

The lossy channel of training (`message_dropout`, `communication_range`): at every decision of the rollout a mask
(B, N receivers, N senders) of the deliveries that happen (each lost with the dropout's probability, or between
agents farther apart than the range, read from `TrainingEnv.positions`); a lost message reads as zeros in the
receiver's attention, as at deployment. The masks are stored with the rollout and the update's unroll replays them;
they are drawn from a generator of their own (on the CPU), so the actions drawn are those of an unperturbed run. The
critic still reads every message sent (centralised, like the state). `message_delay` K: teammates' messages are read
K decisions later than without (an agent's own: the last), the memory carrying a queue of the K message sets before
the last (`TarMACActor.delay`).
"""

from __future__ import annotations

import dataclasses
from typing import Literal

from ..cli.options import option
from . import ppo_loop
from ..policies.comm import Channel, TarMACActor, check_channel
from .envs import TrainingEnv
from ..policies.policy import make_actor
from .ppo import PPOConfig
from .run import Run
from ..policies.spec import PolicySpec

__all__ = ['TarMACConfig', 'policy_spec', 'train']


@dataclasses.dataclass
class TarMACConfig(PPOConfig):
    """Settings of a TarMAC run (`train(config)`, `mate train tarmac`)."""

    critic: Literal['state', 'local', 'agent'] = option('state', "the critic's input, the messages appended: the "
                                                                 "global state (MAPPO), each agent's observation "
                                                                 "(IPPO) or the state with each agent's observation "
                                                                 "appended (MAPPO-AS)")
    lstm: int = option(256, "LSTM cells of the actor (the paper's 256)", minimum=1)
    message_dropout: float = option(0.0, 'train under a lossy channel: each sender -> receiver delivery lost with '
                                         'this probability in [0, 1] (as RandomMessageDropout)', metavar='P')
    communication_range: float | None = option(None, 'deliver a message only between agents at most this many world '
                                                     'units apart (as RestrictedCommunicationRange); None: any '
                                                     'distance', metavar='R')
    message_delay: int = option(0, "teammates' messages arrive this many decisions late, on top of TarMAC's one (as "
                                   'ExtraCommunicationDelays of K x frame-skip steps)', metavar='K')

    def __post_init__(self) -> None:
        super().__post_init__()
        check_channel(self.message_dropout, self.communication_range, 'tarmac', self.message_delay, as_flags=True)

    @property
    def algo(self) -> str:
        return {'state': 'mappo-tarmac', 'local': 'ippo-tarmac', 'agent': 'mappo-as-tarmac'}[self.critic]

    @property
    def channel(self) -> dict:
        """The settings of the channel the team trains under (a resume must keep them)."""
        return dict(message_dropout=float(self.message_dropout), communication_range=self.communication_range,
                    message_delay=int(self.message_delay))


def policy_spec(config: TarMACConfig, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains; with `envs` given, what they say the policy sees and does (their
    `spec`) with this config's network."""
    return config.policy_spec(action='hrl' if config.hrl else 'grid', envs=envs, network='tarmac', hidden=config.hidden,
                              activation=config.activation, lstm=config.lstm, algo=config.algo)


# ============================================================================ training

def train(config: TarMACConfig, envs: TrainingEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/ALGO-TEAM-seedN); resume from its checkpoint
    unless `config.fresh` (a checkpoint trained under another channel is refused). `envs` replaces the training envs
    (anything with `TrainingEnv`'s attributes, `spec` and reset/step; `positions()` with a `communication_range`);
    `callback(row)` sees every log row. Returns the `Run`. The loop is `mate.learn.ppo_loop`'s: it carries the
    actor's (h, c, messages), replays the channel's deliveries and gives the critic the messages (`heard`)."""

    def actor_of(spec: PolicySpec) -> TarMACActor:
        actor = make_actor(spec)
        actor.delay = config.message_delay             # training's delay: a queue in the memory
        return actor

    channel = Channel(config.message_dropout, config.communication_range)       # a broadcast: one leg
    return ppo_loop.train(config, policy_spec(config, envs), envs, callback, console, critic=config.critic,
                          channel=channel, build_actor=actor_of)
