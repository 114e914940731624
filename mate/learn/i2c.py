"""I2C on MAPPO for MATE: each agent asks the teammates its prior selects, in one file (`mate train i2c`).

    config  ->  PolicySpec (network 'i2c': one network per agent, an LSTM of `lstm` cells; flat grid actions)
            ->  `TrainingEnv`, and the channel requests and replies go through in training (`Channel`: ideal by
                default)
            ->  networks: the `I2CActor`s, a feed-forward critic on the global state (MAPPO), and I2C's training
                signals (`I2CTraining`: a joint action-value network per agent and the labels' KL buffer)
            ->  loop: collect T decisions x B envs x N agents, the actors carrying (h, c) from decision to decision;
                GAE; the prior's labels on a sample of the rollout; K epochs on minibatches of whole env sequences
            ->  `Run`: logs, checkpoints, best.pt, final.pt

I2C ("individually inferred communication", Ding et al. 2020; docs/training.md, "I2C"): at every decision each
agent's prior network decides, from its own observation, which teammates to ask; it attends to the current
observations of those it asked, and the message joins its observation in an MLP -> LSTM -> head (`mate.policies.comm`
has the computation). No delay, peer to peer, no shared weights. The memory rules are `mappo_lstm.py`'s: zeroed where
an episode starts (`starting`), the rollout's first memory and start flags kept so that the update unrolls each env
sequence again.

One optimiser minimises, besides PPO's clipped loss, value loss and entropy bonus:
* the joint action-value networks' regression Q_i(s, a) onto the value targets (normalised returns);
* the prior's binary cross-entropy on causal-influence labels: for `influence_samples` random decisions of the
  rollout, once per iteration and without gradient, whether teammate j's action moved agent i's best response more
  than the median of the recent KL values (`I2CTraining.labels`; they cost N (N - 1) A^2 joint action-value
  evaluations each: 0.5 s of a 3.5-5 s iteration of 4 targets at 32 samples on 2 cores, docs/performance.md);
* 0.01 x the policy-correlation regulariser KL(pi_i || softmax(Q_i(s, ., a_-i) / tau)), its Q targets computed once
  per iteration, before the epochs (as PPO takes its old log-probabilities).

The action-value networks read the global state, hence MAPPO only; the actions are the flat grid moves (the
labels enumerate them); a deployed agent asks its teammates for their raw observations, hence no `--memory` or
`--velocity` columns. The lossy channel of training (`message_dropout`, `communication_range`): at every decision a
mask (B, N askers, N teammates) of the replies that arrive (a reply needs its request and itself to get through,
each lost with the dropout's probability; or the two agents are farther apart than the range); a lost reply is a
zero observation in its slot, as at deployment. The masks are stored with the rollout and replayed by the update;
they come from a generator of their own (on the CPU). A reply later than its decision is never read: there is no
delay option (a delay of one decision is `message_dropout` 1).
"""

from __future__ import annotations

import dataclasses

import torch

from ..cli.options import option
from . import ppo_loop
from ..policies.comm import I2C_REGULARISER, Channel, I2CTraining, check_channel
from .envs import TrainingEnv
from .ppo import PPOConfig
from .run import Run
from ..policies.spec import PolicySpec

__all__ = ['I2CConfig', 'I2CSignals', 'policy_spec', 'train']


@dataclasses.dataclass
class I2CConfig(PPOConfig):
    """Settings of an I2C run (`train(config)`, `mate train i2c`; MAPPO's critic, flat grid actions)."""

    lstm: int = option(256, "LSTM cells of each agent's actor (the paper's 256)", minimum=1)
    influence_samples: int = option(32, "decisions per iteration whose causal-influence labels are computed (each "
                                        "costs N_agents x (N_agents - 1) x 25 x 25 joint action-value evaluations: "
                                        'at 32, 4 targets spend about a tenth of an iteration on them)', minimum=1,
                                   metavar='N')
    message_dropout: float = option(0.0, 'train under a lossy channel: each request and each reply lost with this '
                                         'probability in [0, 1] (as RandomMessageDropout)', metavar='P')
    communication_range: float | None = option(None, 'requests and replies get through only between agents at most '
                                                     'this many world units apart (as RestrictedCommunicationRange); '
                                                     'None: any distance', metavar='R')

    def __post_init__(self) -> None:
        super().__post_init__()
        for flag, given, reason in (('--hrl', self.hrl, 'needs the flat discrete actions'),
                                    ('--memory', self.memory, 'exchanges raw observations'),
                                    ('--velocity', self.velocity, 'exchanges raw observations')):
            if given:
                raise ValueError(f'I2C {reason}; {flag} does not combine with it')
        check_channel(self.message_dropout, self.communication_range, 'i2c', as_flags=True)

    @property
    def algo(self) -> str:
        return 'mappo-i2c'

    @property
    def channel(self) -> dict:
        """The settings of the channel the team trains under (a resume must keep them)."""
        return dict(message_dropout=float(self.message_dropout), communication_range=self.communication_range)


def policy_spec(config: I2CConfig, envs=None) -> PolicySpec:
    """The spec of the policy `config` trains; with `envs` given, what they say the policy sees and does (their
    `spec`) with this config's network."""
    return config.policy_spec(action='grid', envs=envs, network='i2c', hidden=config.hidden,
                              activation=config.activation, lstm=config.lstm, algo=config.algo)


# ============================================================================ I2C's own terms

class I2CSignals(I2CTraining):
    """I2C's training signals as the PPO loop's `Auxiliary`: per iteration, the prior's causal-influence labels on
    `influence_samples` random decisions of the rollout and the regulariser's Q targets, once and without gradient;
    per minibatch the joint action-value regression, the prior's loss and the policy-correlation regulariser; the
    log's `edges` (teammates asked per agent), the labels' mean KL and threshold."""

    name = 'comm_training'
    stats = ('q_loss', 'prior_loss', 'regulariser')

    def __init__(self, agents: int, state_dim: int, num_actions: int, hidden, activation: str,
                 influence_samples: int) -> None:
        super().__init__(agents, state_dim, num_actions, hidden, activation)
        self.influence_samples = influence_samples

    def prepare(self, rollout: ppo_loop.Rollout) -> None:
        self.rollout = rollout
        rows = torch.randperm(len(rollout.state), generator=rollout.generator,
                              device=rollout.state.device)[:self.influence_samples]
        # the prior's labels (R, N, N - 1) on R sampled decisions, and the KL values they were cut from
        self.label_labels, self.influence = self.labels(rollout.state[rows], rollout.actions[rows, :, 0])
        self.label_obs = rollout.obs[rows]
        self.own_values = self.own_action_values(rollout.state, rollout.actions[..., 0])      # (T B, N, A)

    def terms(self, actor, logits: torch.Tensor, rows: torch.Tensor) -> tuple[tuple, dict]:
        rollout = self.rollout
        q_loss, regulariser = self.losses(logits, rollout.state[rows], rollout.actions[rows][..., 0],
                                          rollout.returns[rows], self.own_values[rows])
        prior_loss = self.prior_loss(actor, self.label_obs, self.label_labels)
        return ((q_loss, prior_loss, I2C_REGULARISER * regulariser),
                dict(q_loss=q_loss.item(), prior_loss=prior_loss.item(), regulariser=regulariser.item()))

    def log(self, actor) -> dict:
        with torch.no_grad():
            edges = (actor.request_logits(self.label_obs) >= 0).float().sum(-1).mean()
        return dict(edges=float(edges), influence_kl=float(self.influence.mean()),
                    influence_threshold=self.threshold.threshold())


# ============================================================================ training

def train(config: I2CConfig, envs: TrainingEnv | None = None, callback=None, console=None) -> Run:
    """Train as `config` says (in `config.run_dir`, default runs/ALGO-TEAM-seedN); resume from its checkpoint
    unless `config.fresh` (a checkpoint trained under another channel is refused). `envs` replaces the training envs
    (anything with `TrainingEnv`'s attributes, `spec` and reset/step; `positions()` with a `communication_range`);
    `callback(row)` sees every log row. Returns the `Run`. The loop is `mate.learn.ppo_loop`'s, with I2C's
    signals (`I2CSignals`) and the channel of the requests and replies."""
    channel = Channel(config.message_dropout, config.communication_range, legs=2)   # the request, then the reply

    def signals(agents: int, state_dim: int, num_actions: int) -> I2CSignals:
        return I2CSignals(agents, state_dim, num_actions, config.hidden, config.activation, config.influence_samples)

    return ppo_loop.train(config, policy_spec(config, envs), envs, callback, console, critic='state',   # MAPPO's
                          channel=channel, auxiliary=signals)
