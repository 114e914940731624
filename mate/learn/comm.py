"""Learned communication between the agents of a team: TarMAC (spec training.md §2.6, §4.1).

Every agent broadcasts a message at each decision; every agent (the sender included) reads all N
messages at the next decision through soft attention, one round per decision:

    decision t, for each receiver i of an env (N agents, shared weights):
        q_i   = Q [h_i, c_i]                                  its query, from its LSTM state before t (key)
        w_ij  = softmax_j(q_i . k_j / sqrt(key))              over all N senders j, i included
        u_i   = sum_j w_ij v_j                                what it hears (value)
        x_i   = MLP([obs_i, u_i]);  (h_i, c_i) = LSTM(x_i, (h_i, c_i))
        [logits_i | k_i, v_i] = head([x_i, h_i]), the message (k_i, v_i) squashed by tanh into [-1, 1]

    where (k_j, v_j) is the message agent j sent at decision t - 1 (zeros after a reset).

The state an actor carries from decision to decision is (h, c, messages), shapes (..., N, lstm),
(..., N, lstm), (..., N, key + value): the messages of the last decision are part of it, so a message
sent at t is read at t + 1 (a one-decision delay). `TarMACActor.forward` unrolls whole sequences with
an explicit time loop (the query depends on the recurrent state), and the messages stay in the graph:
the loss of a receiver's action at t + 1 reaches the sender's message head at t. This is our documented
deviation (docs/differences.md): the original's messages were deterministic action outputs that got no
gradient, so its message head kept its initial weights. All outputs (logits included) are initialised
with orthogonal rows of norm 1, as the spec says for TarMAC.

The PPO critic of a TarMAC run (`mate.learn.ppo`) reads the N messages the agents read at each decision,
appended to the global state (MAPPO) or to each agent's observation (IPPO), as the spec's critic does.

At deployment the batched `mate.learn.evaluate.PolicyTeam` steps the whole team at once, exactly as here;
single agents (`mate.learn.agents`) step one receiver on the N messages they got through the env's channel
(`mate.Message`s, so the communication wrappers act on them; a message that did not arrive reads as zeros).

Units: observations are the processed ones of `TeamVecEnv` (rescaled to [-1, 1]); messages are in [-1, 1].
"""

from __future__ import annotations

import math

import torch
from torch import nn

from .networks import linear, mlp, restarted

__all__ = ['COMMUNICATION', 'TARMAC_LSTM', 'TarMACActor', 'make_communicating_actor']

COMMUNICATION = ('none', 'tarmac')
"""Values of `PPOConfig.comm` (`mate train --comm`)."""
TARMAC_LSTM = 256
"""LSTM cells of a TarMAC actor when the run asks for none (`lstm` 0): the paper's size."""


class TarMACActor(nn.Module):
    """Shared TarMAC policy of a team; see the module docstring for the computation.

    `step(obs (B, N, D), state)` -> (logits (B, N, A), new state); the N agents of a row talk to each other.
    The receivers may be fewer than the senders: with obs (..., M, D), (h, c) (..., M, lstm) and messages
    (..., N, key + value), M receivers read the N messages and the new state's messages are the M receivers'
    own (a single deployment agent: M = 1, `mate.learn.agents`).
    `forward(obs (T, B, N, D), state, starts (T, B) bool)` -> logits (T, B, N, A): zeroes the state of the envs
    where `starts[t]` before decision t, then steps; differentiable through the messages.
    """

    recurrent = True
    communicates = True

    def __init__(self, obs_dim: int, num_actions: int, hidden=(256, 256), activation: str = 'tanh', lstm: int = 256,
                 key: int = 32, value: int = 32) -> None:
        super().__init__()
        self.num_actions, self.lstm_size = int(num_actions), int(lstm)
        self.key_size, self.value_size = int(key), int(value)
        self.body, self.width = mlp(obs_dim + self.value_size, hidden, activation)
        self.cell = nn.LSTMCell(self.width, self.lstm_size)                                  # PyTorch's default init
        self.query = linear(2 * self.lstm_size, self.key_size, 1.0, 1.0, bias=False)
        self.head = linear(self.width + self.lstm_size, self.num_actions + self.key_size + self.value_size, 1.0, 1.0)

    def initial_state(self, *shape: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Zero (h, c, messages) for `shape` = (B, N) agents."""
        return (torch.zeros(*shape, self.lstm_size), torch.zeros(*shape, self.lstm_size),
                torch.zeros(*shape, self.key_size + self.value_size))

    def attention_weights(self, state) -> torch.Tensor:
        """(..., N receivers, N senders): each receiver's softmax over the senders, from its query (its h, c in
        `state`) and the keys of the messages in `state`. Rows sum to one."""
        h, c, messages = state
        query = self.query(torch.cat([h, c], dim=-1))                                   # (..., N, key)
        keys = messages[..., :self.key_size]                                            # (..., N, key)
        return torch.softmax(query @ keys.transpose(-1, -2) / math.sqrt(self.key_size), dim=-1)

    def step(self, obs: torch.Tensor, state):
        h, c, messages = state
        heard = self.attention_weights(state) @ messages[..., self.key_size:]           # (..., N, value)
        features = self.body(torch.cat([obs, heard], dim=-1))                           # (..., N, width)
        lead = features.shape[:-1]
        h, c = self.cell(features.reshape(-1, self.width),
                         (h.reshape(-1, self.lstm_size), c.reshape(-1, self.lstm_size)))
        h, c = h.reshape(*lead, self.lstm_size), c.reshape(*lead, self.lstm_size)
        out = self.head(torch.cat([features, h], dim=-1))
        logits, message = out[..., :self.num_actions], torch.tanh(out[..., self.num_actions:])
        return logits, (h, c, message)

    def forward(self, obs: torch.Tensor, state, starts: torch.Tensor) -> torch.Tensor:
        logits = []
        for t in range(obs.shape[0]):
            step_logits, state = self.step(obs[t], restarted(state, starts[t]))
            logits.append(step_logits)
        return torch.stack(logits)


def make_communicating_actor(comm: str, kind: str, obs_dim: int, num_actions: int, hidden, activation: str,
                             lstm: int) -> nn.Module:
    """The actor of `comm` ('tarmac'): ValueError for another scheme, a body other than 'mlp' or no LSTM."""
    if comm != 'tarmac':
        raise ValueError(f'unknown comm {comm!r}; valid: {", ".join(map(repr, COMMUNICATION))}')
    if kind != 'mlp':
        raise ValueError(f"comm 'tarmac' builds its actor on the MLP body; actor {kind!r} does not combine with it")
    if lstm <= 0:
        raise ValueError(f"comm 'tarmac' needs a recurrent actor (lstm > 0), got lstm {lstm}")
    return TarMACActor(obs_dim, num_actions, hidden, activation, lstm)
