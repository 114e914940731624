"""Learned communication between the agents of a team: TarMAC (Das et al. 2019) and I2C
(Ding et al. 2020, after the TarMAC part below).

TarMAC. Every agent broadcasts a message at each decision; every agent (the sender included) reads all N
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

At deployment the batched `mate.policies.policy.PolicyTeam` steps the whole team at once, exactly as here;
single agents (`mate.policies.policy`) step one receiver on the N messages they got through the env's channel
(`mate.Message`s, so the communication wrappers act on them; a message that did not arrive reads as zeros).

I2C ("individually inferred communication"): independent networks per agent, no delay, peer to peer.

    decision t, for each agent i of an env (N agents, each with its own weights), K = N - 1 teammate slots
    k = 0..K-1 holding teammate j = (i + 1 + k) mod N (`cyclic_teammates`):
        r_ik  = prior_i([obs_i, one_hot(k)])                  request logit; i asks j iff r_ik >= 0
        q_i   = Q_i obs_i,  k_ij = K_i obs_j,  v_ij = V_i obs_j   (learned projections, bias, obs dim wide)
        w_i   = softmax over [q_i . k_ij / sqrt(D) for the asked j, 0 for an all-zero key]
        m_i   = M_i O_i (sum_j w_ij v_ij)                     the message (64), O_i the attention's output layer
        x_i   = MLP_i([obs_i, m_i]);  (h_i, c_i) = LSTM_i(x_i, (h_i, c_i));  logits_i = head_i([x_i, h_i])

`I2CActor.step` computes it for the whole team from the N current observations (the ideal channel of
training); a deployment agent computes its own row from its observation and the replies of the teammates it
asked (zeros for a reply that did not arrive), `step(obs, state, teammates=..., agents=...)`.
Its training signals (`I2CTraining`): a joint action-value network per agent Q_i(s, a_i, a_-i) regressed onto
the PPO value targets; causal-influence labels for the prior (`causal_influence`, `InfluenceThreshold`); the
policy-correlation regulariser KL(pi_i || softmax(Q_i(s, ., a_-i) / tau)) over the actions
(`policy_correlation`).

Training under a perturbed channel (`Channel`, `PPOConfig.message_dropout` / `communication_range`): at each
decision a mask (B, N receivers, N senders) of the deliveries that happen, passed to `step` / `forward` as
`delivered`; a lost delivery reads as zeros (TarMAC: the sender's key and value in that receiver's attention;
I2C: the asked teammate's slot), which is what the deployment agents read when a message does not arrive.

Units: observations are the processed ones of `TrainingEnv` (rescaled to [-1, 1]); messages are in [-1, 1]
(TarMAC) or unbounded (I2C); Q-values are in the critic's normalised return units.
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from .networks import AgentwiseLSTMCell, AgentwiseMLP, linear, mlp, restarted

__all__ = ['COMMUNICATION', 'Channel', 'I2C_MESSAGE', 'I2C_REGULARISER', 'I2C_TEMPERATURE', 'I2CActor', 'I2CTraining',
           'InfluenceThreshold', 'JointActionValue', 'TARMAC_LSTM', 'TarMACActor', 'causal_influence',
           'channel_difference', 'check_channel', 'cyclic_teammates', 'policy_correlation', 'teammate_slots']

COMMUNICATION = ('none', 'tarmac', 'i2c')
"""Values of `PPOConfig.comm` (`mate train --comm`)."""
TARMAC_LSTM = 256
"""LSTM cells of a TarMAC actor when the run asks for none (`lstm` 0): the paper's size."""


class TarMACActor(nn.Module):
    """Shared TarMAC policy of a team; see the module docstring for the computation.

    `step(obs (B, N, D), state)` -> (logits (B, N, A), new state); the N agents of a row talk to each other.
    The receivers may be fewer than the senders: with obs (..., M, D), (h, c) (..., M, lstm) and messages
    (..., N, key + value), M receivers read the N messages and the new state's messages are the M receivers'
    own (a single deployment agent: M = 1, `mate.policies.policy`).
    `forward(obs (T, B, N, D), state, starts (T, B) bool)` -> logits (T, B, N, A): zeroes the state of the envs
    where `starts[t]` before decision t, then steps; differentiable through the messages.
    Both take `delivered` ((..., M, N) bool, (T, B, N, N) for `forward`; None: every message arrives): the
    perturbed channel of training (`Channel`); receiver i reads sender j's message as zeros where it is false,
    as a deployment agent reads a message that did not reach it. With `delay` K > 0 (training only, the whole
    team: M = N) every receiver reads its own last message but its teammates' messages of K decisions earlier
    (sent at t - 1 - K, read at t), kept in the state's queue, which episode starts zero like the rest.
    """

    recurrent = True
    communicates = True
    scheme = 'tarmac'

    def __init__(self, obs_dim: int, num_actions: int, hidden=(256, 256), activation: str = 'tanh', lstm: int = 256,
                 key: int = 32, value: int = 32, delay: int = 0) -> None:
        super().__init__()
        self.num_actions, self.lstm_size = int(num_actions), int(lstm)
        # training's channel delay in decisions (not in the weights: at deployment the env's channel delays)
        self.delay = int(delay)
        self.key_size, self.value_size = int(key), int(value)
        self.body, self.width = mlp(obs_dim + self.value_size, hidden, activation)
        self.cell = nn.LSTMCell(self.width, self.lstm_size)                                  # PyTorch's default init
        self.query = linear(2 * self.lstm_size, self.key_size, 1.0, 1.0, bias=False)
        self.head = linear(self.width + self.lstm_size, self.num_actions + self.key_size + self.value_size, 1.0, 1.0)

    @property
    def heard_size(self) -> int:
        """The size of each message the agents read (key + value): its memory's third part, (..., N, size), which
        the PPO loop's critic reads too (`mate.learn.ppo_loop.heard`)."""
        return self.key_size + self.value_size

    def initial_state(self, *shape: int) -> tuple[torch.Tensor, ...]:
        """Zero (h, c, messages) for `shape` = (B, N) agents; with a `delay` K, also the queue (B, K, N, key +
        value) of the messages of the K decisions before the last, oldest first."""
        size = self.key_size + self.value_size
        state = (torch.zeros(*shape, self.lstm_size), torch.zeros(*shape, self.lstm_size), torch.zeros(*shape, size))
        return state + ((torch.zeros(*shape[:-1], self.delay, shape[-1], size),) if self.delay else ())

    def _late(self, state) -> torch.Tensor | None:
        """With a delay: (..., N, N) bool, true where receiver i reads sender j's message from the queue's oldest
        decision (every teammate), false on the diagonal (an agent's own last message is kept locally)."""
        if not self.delay:
            return None
        n = state[2].shape[-2]
        return ~torch.eye(n, dtype=torch.bool, device=state[2].device)

    def attention_weights(self, state, delivered: torch.Tensor | None = None) -> torch.Tensor:
        """(..., N receivers, N senders): each receiver's softmax over the senders, from its query (its h, c in
        `state`) and the keys of the messages in `state`. Rows sum to one. `delivered` (..., N receivers,
        N senders) bool: a message that did not reach a receiver reads as zeros (its score is 0)."""
        h, c, messages = state[:3]
        query = self.query(torch.cat([h, c], dim=-1))                                   # (..., N, key)
        keys = messages[..., :self.key_size]                                            # (..., N, key)
        scores = query @ keys.transpose(-1, -2) / math.sqrt(self.key_size)
        late = self._late(state)
        if late is not None:                           # teammates' keys of `delay` decisions earlier
            old_keys = state[3][..., 0, :, :self.key_size]
            scores = torch.where(late, query @ old_keys.transpose(-1, -2) / math.sqrt(self.key_size), scores)
        if delivered is not None:
            scores = scores * delivered
        return torch.softmax(scores, dim=-1)

    def step(self, obs: torch.Tensor, state, delivered: torch.Tensor | None = None):
        h, c, messages = state[:3]
        weights = self.attention_weights(state, delivered)
        if delivered is not None:                       # a lost message's value reads as zeros too
            weights = weights * delivered
        late = self._late(state)
        if late is None:
            heard = weights @ messages[..., self.key_size:]                             # (..., N, value)
        else:                                           # own value: the last; teammates': the queue's oldest
            heard = ((weights * ~late) @ messages[..., self.key_size:]
                     + (weights * late) @ state[3][..., 0, :, self.key_size:])
        features = self.body(torch.cat([obs, heard], dim=-1))                           # (..., N, width)
        lead = features.shape[:-1]
        h, c = self.cell(features.reshape(-1, self.width),
                         (h.reshape(-1, self.lstm_size), c.reshape(-1, self.lstm_size)))
        h, c = h.reshape(*lead, self.lstm_size), c.reshape(*lead, self.lstm_size)
        out = self.head(torch.cat([features, h], dim=-1))
        logits, message = out[..., :self.num_actions], torch.tanh(out[..., self.num_actions:])
        if self.delay:                                  # the queue moves on: the last messages join it
            queue = torch.cat([state[3][..., 1:, :, :], messages.unsqueeze(-3)], dim=-3)
            return logits, (h, c, message, queue)
        return logits, (h, c, message)

    def forward(self, obs: torch.Tensor, state, starts: torch.Tensor,
                delivered: torch.Tensor | None = None) -> torch.Tensor:
        logits = []
        for t in range(obs.shape[0]):
            step_logits, state = self.step(obs[t], restarted(state, starts[t]),
                                           None if delivered is None else delivered[t])
            logits.append(step_logits)
        return torch.stack(logits)


# ============================================================================ I2C

I2C_MESSAGE = 64
"""Width of an I2C message (the attention's output projected by `Linear(obs dim -> 64)`)."""
I2C_TEMPERATURE = 0.1
"""tau of the softmaxes over Q-values (labels and regulariser)."""
I2C_REGULARISER = 0.01
"""Coefficient of the policy-correlation regulariser in the total loss."""
I2C_LABEL_BUFFER = 100_000
"""KL values kept (first in, first out) for the labels' threshold, their median."""


def _cyclic_index(n: int, device) -> torch.Tensor:
    """(N, N - 1) long: row i holds its teammates i+1, ..., i+N-1 (mod N)."""
    return (torch.arange(n, device=device)[:, None] + torch.arange(1, n, device=device)[None, :]) % n


def teammate_slots(delivered: torch.Tensor) -> torch.Tensor:
    """(..., N receivers, N senders) -> (..., N, N - 1): row i's entries for its cyclic slots (teammates i+1, ...)."""
    n = delivered.shape[-1]
    index = _cyclic_index(n, delivered.device)
    return delivered.gather(-1, index.expand(*delivered.shape[:-1], n - 1))


def cyclic_teammates(x: torch.Tensor) -> torch.Tensor:
    """(..., N, F) -> (..., N, N - 1, F): row i holds its teammates' rows in cyclic order i+1, ..., i+N-1 (mod N)."""
    n = x.shape[-2]
    index = _cyclic_index(n, x.device)
    return x[..., index, :]


class I2CActor(nn.Module):
    """I2C policies of a team, one per agent (no shared weights); see the module docstring.

    `step(obs (..., N, D), state)` -> (logits (..., N, A), state (h, c) each (..., N, lstm)): the team, every
    agent reading its teammates' current observations. With `teammates` (..., n, N - 1, D) and `agents` (n,)
    long, the n rows of obs are those agents and read those teammates' observations instead (a deployment
    agent: its replies, zeros where none came). `forward(obs (T, B, N, D), state, starts (T, B))` unrolls
    sequences (the state of the envs where `starts[t]` zeroed before decision t). Both take `delivered`
    ((..., N, N) bool, (T, B, N, N) for `forward`), training's perturbed channel: a teammate whose reply did not
    arrive is a zero observation in its slot (the prior's mask unchanged).
    """

    recurrent = True
    communicates = True
    scheme = 'i2c'

    def __init__(self, agents: int, obs_dim: int, num_actions: int, hidden=(256, 256), activation: str = 'tanh',
                 lstm: int = 256, message: int = I2C_MESSAGE) -> None:
        super().__init__()
        if agents < 2:
            raise ValueError(f'I2C needs a team of at least 2 agents, got {agents}')
        n, d = int(agents), int(obs_dim)
        self.num_agents, self.num_actions = n, int(num_actions)
        self.lstm_size, self.message_size = int(lstm), int(message)
        self.prior = AgentwiseMLP(n, d + n - 1, hidden, 1, activation)          # one request logit per slot
        self.query, self.key, self.value, self.attended = (AgentwiseMLP(n, d, (), d) for _ in range(4))
        self.message = AgentwiseMLP(n, d, (), self.message_size)
        self.body = AgentwiseMLP(n, d + self.message_size, hidden, None, activation)
        self.cell = AgentwiseLSTMCell(n, self.body.width, self.lstm_size)
        self.head = AgentwiseMLP(n, self.body.width + self.lstm_size, (), self.num_actions, out_scale=0.01)

    def initial_state(self, *shape: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Zero (h, c) for `shape` = (B, N) agents."""
        return torch.zeros(*shape, self.lstm_size), torch.zeros(*shape, self.lstm_size)

    def request_logits(self, obs: torch.Tensor, agents: torch.Tensor | None = None) -> torch.Tensor:
        """(..., n, D) -> (..., n, N - 1): each agent's logit of asking the teammate of each cyclic slot."""
        slots = self.num_agents - 1
        one_hot = torch.eye(slots, dtype=obs.dtype, device=obs.device).expand(*obs.shape[:-1], slots, slots)
        x = torch.cat([obs.unsqueeze(-2).expand(*obs.shape[:-1], slots, obs.shape[-1]), one_hot], dim=-1)
        return self.prior(x.transpose(-2, -3), agents).squeeze(-1).transpose(-1, -2)

    @torch.no_grad()
    def requested(self, obs: torch.Tensor, agent: int) -> np.ndarray:
        """(1, D) agent `agent`'s features -> the teammates (indices in the team) it asks at a decision: those of the
        cyclic slots whose request logit is >= 0 (what a deployed agent sends its requests to)."""
        logits = self.request_logits(obs, torch.tensor([agent], device=obs.device))[0]
        return (agent + 1 + np.flatnonzero(logits.cpu().numpy() >= 0)) % self.num_agents

    def _per_slot(self, layer: AgentwiseMLP, x: torch.Tensor, agents) -> torch.Tensor:
        """An agentwise layer on (..., n, K, F): agent i's weights on each of its K slots."""
        return layer(x.transpose(-2, -3), agents).transpose(-2, -3)

    def attention_weights(self, obs: torch.Tensor, teammates: torch.Tensor, selected: torch.Tensor,
                          agents: torch.Tensor | None = None) -> torch.Tensor:
        """(..., n, N - 1 + 1): each agent's softmax over its teammate slots and the all-zero key (last),
        unselected slots (`selected` (..., n, N - 1) false) at weight 0."""
        query = self.query(obs, agents)                                              # (..., n, D)
        keys = self._per_slot(self.key, teammates, agents)                           # (..., n, K, D)
        scores = (keys @ query.unsqueeze(-1)).squeeze(-1) / math.sqrt(obs.shape[-1])
        scores = scores.masked_fill(~selected, float('-inf'))
        return torch.softmax(torch.cat([scores, scores.new_zeros(*scores.shape[:-1], 1)], dim=-1), dim=-1)

    def messages(self, obs: torch.Tensor, teammates: torch.Tensor, selected: torch.Tensor,
                 agents: torch.Tensor | None = None) -> torch.Tensor:
        """obs (..., n, D), teammates (..., n, N - 1, D), selected (..., n, N - 1) bool -> messages (..., n, 64)."""
        weights = self.attention_weights(obs, teammates, selected, agents)[..., :-1]   # the zero value adds nothing
        heard = (weights.unsqueeze(-1) * self._per_slot(self.value, teammates, agents)).sum(-2)
        return self.message(self.attended(heard, agents), agents)

    def features(self, obs: torch.Tensor, teammates: torch.Tensor | None = None,
                 agents: torch.Tensor | None = None, delivered: torch.Tensor | None = None) -> torch.Tensor:
        """The MLP body's output (..., n, width) on [obs, message], the prior choosing whom to read.
        `delivered` (..., N, N) bool (training's perturbed channel): a teammate whose reply did not reach the
        asker is read as a zero observation in its slot, the prior's mask unchanged (as a deployment agent)."""
        if teammates is None:
            teammates = cyclic_teammates(obs)
            if delivered is not None:
                teammates = teammates * teammate_slots(delivered).unsqueeze(-1)
        selected = self.request_logits(obs, agents) >= 0
        return self.body(torch.cat([obs, self.messages(obs, teammates, selected, agents)], dim=-1), agents)

    def step(self, obs: torch.Tensor, state, teammates: torch.Tensor | None = None,
             agents: torch.Tensor | None = None, delivered: torch.Tensor | None = None):
        features = self.features(obs, teammates, agents, delivered)
        h, c = self.cell(features, state, agents)
        return self.head(torch.cat([features, h], dim=-1), agents), (h, c)

    def forward(self, obs: torch.Tensor, state, starts: torch.Tensor,
                delivered: torch.Tensor | None = None) -> torch.Tensor:
        features = self.features(obs, delivered=delivered)   # no recurrence before the LSTM: all decisions at once
        hidden = []
        # unbind: one view per decision, whose backward stacks the T gradients once (indexing gates[t] T times
        # made each step's backward fill and add a zero gradient of the whole sequence: T^2 memory traffic)
        for t, gates in enumerate(self.cell.input_gates(features).unbind(0)):
            state = self.cell.recur(gates, restarted(state, starts[t]))
            hidden.append(state[0])
        return self.head(torch.cat([features, torch.stack(hidden)], dim=-1))


class JointActionValue(nn.Module):
    """Q_i(s, a_i, a_-i) of every agent i, its own network each (I2C's, Ding et al. 2020): MLP on [state, the teammates'
    one-hot actions in cyclic order ((N - 1) A), its own one-hot action (A)] -> a scalar.

    `forward(state (..., S), actions (..., N) long)` -> (..., N); `own_action_values` -> (..., N, A), every own
    action with the teammates' as given; `paired_action_values` -> (..., N, N - 1, A, A), every pair (own
    action, action of the teammate of a slot) with the others as given."""

    def __init__(self, agents: int, state_dim: int, num_actions: int, hidden=(512, 256),
                 activation: str = 'tanh') -> None:
        super().__init__()
        self.num_agents, self.num_actions, self.state_dim = int(agents), int(num_actions), int(state_dim)
        self.net = AgentwiseMLP(self.num_agents, self.state_dim + self.num_agents * self.num_actions, hidden, 1,
                                activation)

    def inputs(self, state: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """(..., S), (..., N) -> (..., N, S + N A)."""
        one_hot = F.one_hot(actions, self.num_actions).to(state.dtype)                      # (..., N, A)
        shared = state.unsqueeze(-2).expand(*one_hot.shape[:-1], state.shape[-1])
        return torch.cat([shared, cyclic_teammates(one_hot).flatten(-2), one_hot], dim=-1)

    def forward(self, state: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        return self.net(self.inputs(state, actions)).squeeze(-1)

    def _first_layer(self, state: torch.Tensor, actions: torch.Tensor):
        """The first layer's pre-activation split by input block (it is linear in the one-hot inputs, so a changed
        action only swaps one weight row): returns (base (..., N, H): state, teammates' actions and bias,
        mates (N, N - 1, A, H): the rows of each teammate slot's actions, taken (..., N, N - 1, H): the rows of
        the teammates' actual actions, own (N, A, H): the rows of the own action)."""
        n, a, s = self.num_agents, self.num_actions, self.state_dim
        weight, bias = self.net.weights[0], self.net.biases[0]                             # (N, S + N A, H), (N, H)
        mates = weight[:, s:s + (n - 1) * a].reshape(n, n - 1, a, -1)
        own = weight[:, s + (n - 1) * a:]
        slots = cyclic_teammates(actions.unsqueeze(-1)).squeeze(-1)                        # (..., N, N - 1)
        agent, slot = torch.arange(n, device=slots.device), torch.arange(n - 1, device=slots.device)
        taken = mates[agent[:, None], slot[None, :], slots]      # (..., N, N - 1, H)
        base = (state @ weight[:, :s].transpose(0, 1).flatten(1)).unflatten(-1, (n, -1)) + bias + taken.sum(-2)
        return base, mates, taken, own

    def own_action_values(self, state: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """(..., S), (..., N) -> (..., N, A): Q_i with agent i's own action replaced by each of the A."""
        base, _, _, own = self._first_layer(state, actions)
        lead, (n, a, h) = base.shape[:-2], own.shape
        pre = base.reshape(-1, n, 1, h).transpose(0, 1) + own[:, None]                   # (N, R, A own, H)
        values = self.net.agent_major(self.net.activate_(pre.reshape(n, -1, h)), start=1)   # (N, R A, 1)
        return values.reshape(n, -1, a).transpose(0, 1).reshape(*lead, n, a)

    def paired_action_values(self, state: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """(..., S), (..., N) -> (..., N, N - 1, A own, A teammate): Q_i with its own action and that of the
        teammate of each cyclic slot replaced by every pair, the other teammates' as given."""
        base, mates, taken, own = self._first_layer(state, actions)
        lead, (n, k, a, h) = base.shape[:-2], mates.shape
        others = (base.unsqueeze(-2) - taken).reshape(-1, n, k, 1, 1, h).transpose(0, 1)  # (N, R, K, 1, 1, H)
        pre = others + own[:, None, None, :, None, :] + mates[:, None, :, None, :, :]    # (N, R, K, A, A, H)
        values = self.net.agent_major(self.net.activate_(pre.reshape(n, -1, h)), start=1)   # (N, R K A A, 1)
        return values.reshape(n, -1, k, a, a).transpose(0, 1).reshape(*lead, n, k, a, a)


def causal_influence(own_values: torch.Tensor, paired_values: torch.Tensor,
                     temperature: float = I2C_TEMPERATURE) -> torch.Tensor:
    """KL_ij = KL(p_full || p_marg) (..., N, N - 1) of every agent i and teammate slot j (I2C's):
    p_full(a_i) = softmax_a_i Q(s, a_i, a_-i) / tau from `own_values` (..., N, A); p_marg(a_i) = softmax_a_i
    log sum_a_j exp(Q(s, a_i, a_j, a_-ij) / tau) from `paired_values` (..., N, N - 1, A own, A teammate)."""
    log_full = torch.log_softmax(own_values / temperature, dim=-1).unsqueeze(-2)            # (..., N, 1, A)
    log_marginal = torch.log_softmax(torch.logsumexp(paired_values / temperature, dim=-1), dim=-1)
    return (log_full.exp() * (log_full - log_marginal)).sum(-1)


def policy_correlation(logits: torch.Tensor, own_values: torch.Tensor,
                       temperature: float = I2C_TEMPERATURE) -> torch.Tensor:
    """KL(pi || softmax(Q(s, ., a_-i) / tau)) (...,) over the actions (the last axis of logits and own_values
    (..., A)); the original took its log-softmax over time, which we read as a bug (docs/differences.md)."""
    log_policy = torch.log_softmax(logits, dim=-1)
    log_target = torch.log_softmax(own_values / temperature, dim=-1)
    return (log_policy.exp() * (log_policy - log_target)).sum(-1)


class InfluenceThreshold(nn.Module):
    """The last `capacity` KL values (first in, first out; buffers, so they travel in checkpoints) and the
    label threshold, their median (`torch.quantile` 0.5: the mean of the two middle values of an even count)."""

    def __init__(self, capacity: int = I2C_LABEL_BUFFER) -> None:
        super().__init__()
        self.capacity = int(capacity)
        self.register_buffer('values', torch.zeros(self.capacity))
        self.register_buffer('count', torch.zeros((), dtype=torch.long))       # values held, <= capacity
        self.register_buffer('position', torch.zeros((), dtype=torch.long))    # next slot to write

    def push(self, kl: torch.Tensor) -> None:
        flat = kl.detach().reshape(-1).to(self.values.dtype)[-self.capacity:]
        slots = (self.position + torch.arange(len(flat), device=self.values.device)) % self.capacity
        self.values[slots] = flat
        self.position.copy_((self.position + len(flat)) % self.capacity)
        self.count.copy_(torch.clamp(self.count + len(flat), max=self.capacity))

    def threshold(self) -> float:
        if int(self.count) == 0:
            raise ValueError('no KL values yet: push some before asking for the threshold')
        return float(torch.quantile(self.values[:int(self.count)], 0.5))

    def labels(self, kl: torch.Tensor) -> torch.Tensor:
        """Push `kl`, then label it: kl >= the median of the buffer (bool, the shape of kl)."""
        self.push(kl)
        return kl >= self.threshold()


class I2CTraining(nn.Module):
    """The training-only parts of I2C: the joint action-value networks and the label buffer.

    `labels(state (R, S), actions (R, N))` -> (labels (R, N, N - 1) bool, KL (R, N, N - 1)), without gradient;
    `losses(logits (R, N, A), state, actions, returns (R, N))` -> (Q regression MSE, policy-correlation
    regulariser), both means over rows and agents; `prior_loss(actor, obs (R, N, D), labels)` -> BCE.
    """

    def __init__(self, agents: int, state_dim: int, num_actions: int, hidden=(512, 256), activation: str = 'tanh',
                 temperature: float = I2C_TEMPERATURE, capacity: int = I2C_LABEL_BUFFER, chunk: int = 1) -> None:
        super().__init__()
        self.value = JointActionValue(agents, state_dim, num_actions, hidden, activation)
        self.threshold = InfluenceThreshold(capacity)
        self.temperature, self.chunk = float(temperature), int(chunk)   # chunk: rows per pass of the A x A pairs

    @torch.no_grad()
    def labels(self, state: torch.Tensor, actions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        kl = torch.cat([causal_influence(self.value.own_action_values(s, a), self.value.paired_action_values(s, a),
                                         self.temperature)
                        for s, a in zip(state.split(self.chunk), actions.split(self.chunk))])
        return self.threshold.labels(kl), kl

    @torch.no_grad()
    def own_action_values(self, state: torch.Tensor, actions: torch.Tensor, rows: int = 256) -> torch.Tensor:
        """(R, S), (R, N) -> (R, N, A) without gradient, `rows` at a time: the regulariser's targets (the trainer
        takes them once per iteration, before its epochs, as PPO takes its old log-probabilities)."""
        return torch.cat([self.value.own_action_values(s, a) for s, a in zip(state.split(rows), actions.split(rows))])

    def losses(self, logits: torch.Tensor, state: torch.Tensor, actions: torch.Tensor, returns: torch.Tensor,
               own_values: torch.Tensor | None = None):
        """`own_values` (R, N, A): the regulariser's Q targets if already computed (else computed here, detached).
        The regression evaluates Q at the taken actions only (R x N rows with gradient, not R x N x A)."""
        regression = (self.value(state, actions) - returns).pow(2).mean()
        if own_values is None:
            own_values = self.own_action_values(state, actions)
        return regression, policy_correlation(logits, own_values, self.temperature).mean()

    @staticmethod
    def prior_loss(actor: I2CActor, obs: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
        return F.binary_cross_entropy_with_logits(actor.request_logits(obs), labels.to(obs.dtype))


# ============================================================================ the perturbed channel of training

def check_channel(dropout: float, range_limit: float | None, comm: str = 'tarmac', delay: int = 0,
                  as_flags: bool = False) -> None:
    """ValueError (one line, naming the valid range) unless `dropout` is a probability in [0, 1], `range_limit`
    None or a distance > 0 and `delay` a whole number of decisions >= 0; a perturbed channel needs a communicating
    team (`comm` 'tarmac' or 'i2c'), a delay TarMAC (an I2C reply that comes after its decision is never read).
    `as_flags`: name the settings as the command line does (`--message-dropout`), for the trainers' configs."""
    dropout_name, range_name, delay_name = (('--message-dropout', '--communication-range', '--message-delay')
                                            if as_flags else ('message_dropout', 'communication_range',
                                                              'message_delay'))
    if isinstance(dropout, bool) or not isinstance(dropout, (int, float)) or not 0.0 <= dropout <= 1.0:
        raise ValueError(f'{dropout_name} must be a probability in [0, 1], got {dropout!r}')
    if range_limit is not None and (isinstance(range_limit, bool) or not isinstance(range_limit, (int, float))
                                    or not range_limit > 0):
        raise ValueError(f'{range_name} must be a distance > 0 in world units (None: unlimited), '
                         f'got {range_limit!r}')
    if isinstance(delay, bool) or not isinstance(delay, int) or delay < 0:
        raise ValueError(f'{delay_name} must be a whole number of decisions >= 0, got {delay!r}')
    if (dropout > 0 or range_limit is not None or delay > 0) and comm not in COMMUNICATION[1:]:
        raise ValueError(f"message_dropout, communication_range and message_delay perturb learned messages; they "
                         f"need comm 'tarmac' or 'i2c', not {comm!r}")
    if delay > 0 and comm != 'tarmac':
        raise ValueError(f"message_delay is a TarMAC option: an I2C reply later than its decision is never read "
                         f"(train that with message_dropout 1), comm {comm!r}")


def channel_difference(saved: dict, wanted: dict) -> str | None:
    """How the channel settings of a run (`wanted`: {'message_dropout', 'communication_range'[, 'message_delay']})
    differ from those a checkpoint was trained under (`saved`), in the words of the command line ('trained with
    --message-dropout 0.25; this run has --message-dropout 0.0'); None when they are the same."""
    for name in [*saved, *(name for name in wanted if name not in saved)]:
        before, now = saved.get(name), wanted.get(name)
        if before == now:
            continue
        flag = '--' + name.replace('_', '-')
        if now is None:
            return f'trained with {flag} {before}; this run is without it'
        if before is None:
            return f'trained without {flag}; this run has {flag} {now}'
        return f'trained with {flag} {before}; this run has {flag} {now}'
    return None


def build_tarmac_actor(spec) -> TarMACActor:
    """The TarMAC actor of `spec` (network 'tarmac', `mate.policies.actors`)."""
    return TarMACActor(spec.obs_dim, spec.num_actions, spec.hidden, spec.activation, spec.lstm)


def build_i2c_actor(spec) -> I2CActor:
    """The I2C actors of `spec`, one network per agent (network 'i2c', `mate.policies.actors`)."""
    return I2CActor(spec.num_agents, spec.obs_dim, spec.num_actions, spec.hidden, spec.activation, spec.lstm)


class Channel:
    """Which messages of a decision arrive in training: `delivered(positions, generator)` -> (B, N receivers,
    N senders) bool, the diagonal always true (an agent always reads its own message, kept locally at
    deployment), or None when nothing is perturbed.

    * `dropout` P: each sender -> receiver delivery is lost independently with probability P, as with
      `RandomMessageDropout(P)` at deployment. A delivery takes `legs` messages, each lost on its own: 1 for
      TarMAC (a broadcast), 2 for I2C (the request, then the reply), so an I2C reply arrives with
      probability (1 - P)^2, as through the wrapper.
    * `range_limit` R: a delivery happens only if sender and receiver are at most R world units apart
      (`within_range`, the test of `RestrictedCommunicationRange`), on `positions` (B, N, 2) of the
      decision (`TrainingEnv.positions`).

    The draws come from `generator` (torch); P = 0 draws nothing.
    """

    def __init__(self, dropout: float = 0.0, range_limit: float | None = None, legs: int = 1) -> None:
        check_channel(dropout, range_limit)
        self.dropout, self.range_limit, self.legs = float(dropout), range_limit, int(legs)

    @property
    def active(self) -> bool:
        return self.dropout > 0 or self.range_limit is not None

    def delivered(self, shape: tuple[int, int], positions=None, generator: torch.Generator | None = None):
        """`shape` (B, N); `positions` (B, N, 2) array (needed with a range limit)."""
        if not self.active:
            return None
        b, n = shape
        mask = torch.ones(b, n, n, dtype=torch.bool)
        if self.dropout > 0:
            draws = torch.rand(b, n, n, self.legs, generator=generator)
            mask &= (draws >= self.dropout).all(-1)
        if self.range_limit is not None:
            from ..wrappers.restricted_communication_range import within_range

            receivers, senders = (x.reshape(-1) for x in np.meshgrid(np.arange(n), np.arange(n), indexing='ij'))
            near = within_range(np.asarray(positions, dtype=np.float64), senders, receivers, float(self.range_limit))
            mask &= torch.from_numpy(near.reshape(b, n, n))
        return mask | torch.eye(n, dtype=torch.bool)
