"""Network blocks shared by every trainer of `mate.learn` (docs/training.md, "Network options").

* `linear`, `mlp`: orthogonally initialised layers (each output row rescaled to a given norm), tanh or ReLU;
* `Actor`: observation -> MLP -> logits (`num_actions` per agent);
* `PerTargetActor`: cameras; the same small network applied to every target slot (HRL: one keep/ignore
  pair per slot; flat: pooled into 25 moves), see its docstring;
* `RecurrentActor`: MLP -> LSTM -> head, with per-row episode starts (`restarted` zeroes a state's rows);
* `DuelingQNetwork`: IQL's action values (value and advantage streams), one or several heads;
* `RecurrentQNetwork`: QMIX's agent network (embedding -> GRU -> action values), one or several heads;
* `AgentwiseMLP`, `AgentwiseLSTMCell`, `IndependentActors`: N MLPs (LSTM cells) with their own weights
  evaluated at once (MADDPG's actors and critics, I2C's networks, one per agent);
* `Critic`: a value MLP with one or more outputs.

Shapes: inputs (..., D) float32, outputs (..., A); the recurrent actor's sequences are (T, B, N, D).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from ..messages import Team
from ..spaces import observation_indices_of, observation_space_of
from .memory import MEMORY_FEATURES
from .velocity import VELOCITY_FEATURES

__all__ = ['ACTIVATIONS', 'Actor', 'AgentwiseLSTMCell', 'AgentwiseMLP', 'agentwise_matmul',
           'Critic', 'DuelingQNetwork', 'IndependentActors', 'PerTargetActor',
           'RecurrentActor', 'RecurrentQNetwork',
           'linear', 'mlp', 'restarted']


ACTIVATIONS = {'tanh': (nn.Tanh, 5.0 / 3.0), 'relu': (nn.ReLU, math.sqrt(2.0))}
IN_PLACE = {'tanh': torch.tanh_, 'relu': torch.relu_}
"""The activations applied in place (the same kernels as `ACTIVATIONS`' modules: the same values), for the
agentwise layers' fresh outputs: no second tensor of the layer's size per layer."""


def linear(inputs: int, outputs: int, scale: float, gain: float, bias: bool = True) -> nn.Linear:
    """Orthogonal weights with every output row rescaled to L2 norm `scale * gain`; zero bias, or none."""
    layer = nn.Linear(inputs, outputs, bias=bias)
    with torch.no_grad():
        nn.init.orthogonal_(layer.weight)
        layer.weight.mul_(scale * gain / layer.weight.norm(dim=1, keepdim=True).clamp_min(1e-8))
        if bias:
            layer.bias.zero_()
    return layer


def mlp(inputs: int, hidden, activation: str) -> tuple[nn.Sequential, int]:
    act, gain = ACTIVATIONS[activation]
    layers = []
    for width in hidden:
        layers += [linear(inputs, width, 1.0, gain), act()]
        inputs = width
    return nn.Sequential(*layers), inputs


class Actor(nn.Module):
    """Shared policy: preprocessed local observation -> logits over the discrete actions.

    `body` (MLP) embeds the observation; `logits_from(obs, context)` is the head on that embedding,
    widened by `context_extra` inputs when a `RecurrentActor` appends its LSTM output to it.
    """

    def __init__(self, obs_dim: int, num_actions: int, hidden=(256, 256), activation: str = 'tanh',
                 context_extra: int = 0) -> None:
        super().__init__()
        self.body, self.width = mlp(obs_dim, hidden, activation)
        self.head = linear(self.width + context_extra, num_actions, 0.01, 1.0)

    def logits_from(self, obs: torch.Tensor, context: torch.Tensor) -> torch.Tensor:
        return self.head(context)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.logits_from(obs, self.body(obs))


class PerTargetActor(nn.Module):
    """Camera policy that reads the target slots with one shared scorer (`--actor per-target`).

    Each of the Nt target slots gives 13 features: its 5 observed values (relative location, sight
    range, loaded, visibility flag) and 8 computed from the observation (zero when the slot is not
    visible): the offset along and across the camera's heading, the distance, the cosine and sine of
    the bearing relative to the heading, how far inside the camera's own sector the target is (angle
    margin cos(bearing) - cos(theta / 2), range margin 1 - distance / sight range), and whether the
    sector of a teammate this camera sees contains the target too. A context MLP embeds the whole
    observation; one scorer maps [slot features, context] to a slot embedding. Slots carry no
    identity (`shuffle_entities`), so sharing the scorer lets one sample teach all of them.

    Output (..., A): HRL cameras (`num_actions` None or 2 Nt) get keep/ignore logits per slot (the
    layout of `Actor` with `action_distribution`); flat cameras get `num_actions` logits: a head on the
    context and the mean and max of the visible slots' embeddings, plus the attention-weighted sum of
    per-slot action logits (each visible slot proposes logits for "aim at this target", one shared layer,
    softmax attention over the visible slots).
    Input: camera observations processed as in training (relative coordinates, rescaled to [-1, 1]) of a
    game with `counts` = (Nc, Nt, No) entities.

    With `memory` (the team's sighting memory of `mate.policies.memory` appended to the observation, 4
    columns per slot), a slot is *present* when this camera sees the target or the team remembers it
    within this camera's maximum sight range (a target out of reach cannot be aimed at): the geometric
    features are computed at the remembered location, two more features give the memory's freshness and
    whether a teammate sees the target now (15 in all, zero for absent slots), and pooling and attention
    run over the present slots.

    With `velocity` (each seen target's displacement over one held decision, `mate.policies.velocity`, 2
    columns per slot after the memory's), 4 more features: the displacement along and across the line
    of sight divided by the distance (the change of range and of bearing in radians over the hold,
    clipped to [-2, 2]), and the cosine and sine of the bearing of the predicted position (offset plus
    displacement) relative to the heading.
    """

    SLOT_FEATURES = 13
    VELOCITY_SLOT_FEATURES = 4

    def __init__(self, obs_dim: int, counts: tuple[int, int, int], hidden=(256, 256), activation: str = 'tanh',
                 head_width: int = 64, num_actions: int | None = None, context_extra: int = 0,
                 memory: bool = False, velocity: bool = False) -> None:
        super().__init__()
        nc, nt, no = (int(n) for n in counts)
        starts = observation_indices_of(Team.CAMERA, nc, nt, no)
        self.own, self.begin, self.teammates = int(starts[1]), int(starts[2]), int(starts[4])
        self.memory = int(starts[-1]) if memory else None       # first memory column
        first_velocity = int(starts[-1]) + (MEMORY_FEATURES * nt if memory else 0)
        self.velocity = first_velocity if velocity else None     # first velocity column
        expected = first_velocity + (VELOCITY_FEATURES * nt if velocity else 0)
        if obs_dim != expected:
            extras = ' with sighting memory' * bool(memory) + ' with target velocities' * bool(velocity)
            raise ValueError(f'a camera observation{extras} of a game with counts {tuple(counts)} has '
                             f'{expected} columns, got obs_dim {obs_dim}')
        self.slot_features_dim = (self.SLOT_FEATURES + (2 if memory else 0)
                                  + (self.VELOCITY_SLOT_FEATURES if velocity else 0))
        self.num_cameras, self.num_targets = nc, nt
        space = observation_space_of(Team.CAMERA, nc, nt, no)
        # rescaled viewing angles v in [-1, 1] -> degrees: low + (v + 1) (high - low) / 2 (own state: index 5)
        self.angle_low = float(space.low[self.own + 5])
        self.angle_span = float(space.high[self.own + 5] - space.low[self.own + 5])
        # rescaled maximum sight range (own state index 6) -> the rescaled offsets' units (divided by the offset scale)
        scale = float(space.high[self.begin])
        self.reach_low = float(space.low[self.own + 6]) / scale
        self.reach_span = float(space.high[self.own + 6] - space.low[self.own + 6]) / scale
        # offsets and sight vectors share one scale, so the geometry below works on rescaled values
        assert space.high[self.begin] == space.high[self.own + 3] == space.high[self.teammates + 3]
        self.hrl = num_actions is None or num_actions == 2 * nt
        self.body, self.width = mlp(obs_dim, hidden, activation)
        width = self.width + context_extra
        act, gain = ACTIVATIONS[activation]
        # the scorer's first layer on [slot features, context], split so that the context part runs once per agent
        joint = linear(width + self.slot_features_dim, head_width, 1.0, gain)
        self.slot_in = nn.Linear(self.slot_features_dim, head_width)
        self.context_in = nn.Linear(width, head_width, bias=False)
        with torch.no_grad():
            self.slot_in.weight.copy_(joint.weight[:, width:])
            self.slot_in.bias.copy_(joint.bias)
            self.context_in.weight.copy_(joint.weight[:, :width])
        self.activation = act()
        if self.hrl:
            self.head = linear(head_width, 2, 0.01, 1.0)
        else:
            self.head = nn.Sequential(linear(width + 2 * head_width, head_width, 1.0, gain), act(),
                                      linear(head_width, num_actions, 0.01, 1.0))
            # per-slot action logits ("aim at this target") and an attention score over the visible slots
            self.aim = linear(head_width, num_actions + 1, 0.01, 1.0)

    def _half_angle_cosine(self, rescaled_angle: torch.Tensor) -> torch.Tensor:
        degrees = self.angle_low + (rescaled_angle + 1.0) * 0.5 * self.angle_span
        return torch.cos(torch.deg2rad(0.5 * degrees))

    def slot_features(self, obs: torch.Tensor) -> torch.Tensor:
        """(..., D) processed observations -> (..., Nt, F) slot features (F = 13, + 4 with velocity, + 2
        with memory; see the class docstring). Column 4 is the visibility flag; with memory, the last but
        one is the memory's freshness."""
        lead, nt, nc = obs.shape[:-1], self.num_targets, self.num_cameras
        records = obs[..., self.begin:self.begin + 5 * nt].reshape(*lead, nt, 5)
        if self.memory is None:
            dx, dy, visible = records[..., 0], records[..., 1], records[..., 4]
        else:
            remembered = obs[..., self.memory:self.memory + MEMORY_FEATURES * nt].reshape(*lead, nt, MEMORY_FEATURES)
            dx, dy = remembered[..., 0], remembered[..., 1]
            # present: seen now, or remembered within this camera's maximum sight range
            max_reach = self.reach_low + (obs[..., self.own + 6:self.own + 7] + 1.0) * 0.5 * self.reach_span
            within = (dx * dx + dy * dy <= max_reach * max_reach) & (remembered[..., 2] > 0)
            visible = (within | (records[..., 4] > 0.5)).to(obs.dtype)
        sight = obs[..., self.own + 3:self.own + 5]                       # own (R cos phi, R sin phi)
        reach = sight.norm(dim=-1, keepdim=True).clamp_min(1e-6)
        ux, uy = sight[..., 0:1] / reach, sight[..., 1:2] / reach
        along, across = dx * ux + dy * uy, dy * ux - dx * uy
        distance = torch.sqrt(dx * dx + dy * dy + 1e-12)
        cos_bearing = along / distance
        angle_margin = cos_bearing - self._half_angle_cosine(obs[..., self.own + 5:self.own + 6])
        range_margin = 1.0 - distance / reach
        # teammates this camera sees (flag 1, not itself: its own record sits at offset 0)
        mates = obs[..., self.teammates:self.teammates + 7 * nc].reshape(*lead, nc, 7)
        seen = (mates[..., 6] > 0.5) & (mates[..., :2].abs().sum(-1) > 1e-9)                  # (..., Nc)
        to_target = torch.stack([dx, dy], dim=-1)[..., None, :, :] - mates[..., :, None, :2]    # (..., Nc, Nt, 2)
        gap = to_target.norm(dim=-1)
        mate_reach = mates[..., 3:5].norm(dim=-1, keepdim=True)                                # (..., Nc, 1)
        mate_cos = (to_target * mates[..., None, 3:5]).sum(-1) / (gap * mate_reach).clamp_min(1e-9)
        inside = (gap <= mate_reach) & (mate_cos >= self._half_angle_cosine(mates[..., 5:6]))
        covered = (inside & seen[..., None]).any(dim=-2).to(obs.dtype)
        ego = torch.stack([along, across, distance, cos_bearing, across / distance, angle_margin, range_margin,
                           covered], dim=-1)
        features = [records, ego * visible[..., None]]
        if self.velocity is not None:
            moved = obs[..., self.velocity:self.velocity + VELOCITY_FEATURES * nt].reshape(*lead, nt, VELOCITY_FEATURES)
            moved_along = moved[..., 0] * ux + moved[..., 1] * uy
            moved_across = moved[..., 1] * ux - moved[..., 0] * uy
            ahead_along, ahead_across = along + moved_along, across + moved_across
            ahead = torch.sqrt(ahead_along * ahead_along + ahead_across * ahead_across + 1e-12)
            motion = torch.stack([(moved_along / distance).clamp(-2.0, 2.0), (moved_across / distance).clamp(-2.0, 2.0),
                                  ahead_along / ahead, ahead_across / ahead], dim=-1)
            features.append(motion * visible[..., None])
        if self.memory is not None:
            features.append(remembered[..., 2:4] * visible[..., None])     # freshness > 0: a present slot
        return torch.cat(features, dim=-1)

    def present(self, slots: torch.Tensor) -> torch.Tensor:
        """(..., Nt, 1) 1.0 for the slots pooling and attention run over: seen, or with memory remembered
        within reach (their freshness column is then > 0)."""
        return slots[..., 4:5] if self.memory is None else (slots[..., -2:-1] > 0).to(slots.dtype)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.logits_from(obs, self.body(obs))

    def logits_from(self, obs: torch.Tensor, context: torch.Tensor) -> torch.Tensor:
        slots = self.slot_features(obs)
        embedded = self.activation(self.slot_in(slots) + self.context_in(context).unsqueeze(-2))
        if self.hrl:
            return self.head(embedded).reshape(*obs.shape[:-1], 2 * self.num_targets)
        visible = self.present(slots)
        mean = (embedded * visible).sum(-2) / visible.sum(-2).clamp_min(1.0)
        largest = torch.where(visible > 0.5, embedded, torch.full_like(embedded, -1.0)).amax(-2)
        pooled = self.head(torch.cat([context, mean, largest], dim=-1))
        aim = self.aim(embedded)                                                     # (..., Nt, A + 1)
        score = aim[..., -1:].masked_fill(visible < 0.5, -1e9)
        weights = torch.softmax(score, dim=-2) * visible                             # zero when nothing is seen
        return pooled + (weights * aim[..., :-1]).sum(-2)


def restarted(state: tuple, starts: torch.Tensor) -> tuple:
    """A recurrent state tuple with the rows where `starts` is true zeroed (an episode begins there).
    `starts` (E...) bool covers the leading axes of every part (..., X): one flag per env, shared by its agents."""
    return tuple(part * (~starts).to(part.dtype).reshape(*starts.shape, *[1] * (part.dim() - starts.dim()))
                 for part in state)


class RecurrentActor(nn.Module):
    """The paper's recurrent policy around a feed-forward actor: its MLP body -> LSTM -> its head on
    [MLP features, LSTM output] (skip-concat). The inner actor is built with `context_extra = lstm`.

    `step(obs (..., D), state)` -> (logits (..., A), state); `state` is a pair (h, c) of (..., L).
    `forward(obs (T, ..., D), state, starts (T, E))` runs sequences, zeroing the state of the rows where
    `starts[t]` (an episode begins at t) before step t; returns logits (T, ..., A). `starts` may cover
    only the leading axes of `obs` after T (one flag per env, shared by its agents).
    """

    recurrent = True

    def __init__(self, inner: nn.Module, lstm: int = 256) -> None:
        super().__init__()
        self.inner = inner
        self.lstm = nn.LSTM(inner.width, lstm)
        self.lstm_size = lstm

    def initial_state(self, *shape: int) -> tuple[torch.Tensor, torch.Tensor]:
        return torch.zeros(*shape, self.lstm_size), torch.zeros(*shape, self.lstm_size)

    def step(self, obs: torch.Tensor, state):
        features = self.inner.body(obs)
        lead = features.shape[:-1]
        h0, c0 = (x.reshape(1, -1, self.lstm_size) for x in state)
        out, (h, c) = self.lstm(features.reshape(1, -1, features.shape[-1]), (h0, c0))
        h, c = h.reshape(*lead, self.lstm_size), c.reshape(*lead, self.lstm_size)
        return self.inner.logits_from(obs, torch.cat([features, h], dim=-1)), (h, c)

    def forward(self, obs: torch.Tensor, state, starts: torch.Tensor) -> torch.Tensor:
        """One fused LSTM call over all sequences: each sequence is cut where an episode starts, and every
        piece becomes a row of its own (zero initial state, or `state` for a piece that continues the
        rollout's first step), left-aligned and padded; padding only follows a piece, so it cannot leak."""
        T, lead = obs.shape[0], obs.shape[1:-1]
        features = self.inner.body(obs)                                               # (T, ..., F)
        flags = starts.reshape(T, *starts.shape[1:], *([1] * (len(lead) - starts.dim() + 1))).expand(T, *lead)
        flags = flags.reshape(T, -1)                                                  # (T, S)
        rows = flags.shape[1]
        begins = flags.clone()
        begins[0] = True                                                              # every sequence opens a piece
        piece = torch.cumsum(begins.long(), dim=0) - 1                                # piece number within its sequence
        counts = begins.sum(0)
        piece = piece + (torch.cumsum(counts, 0) - counts)[None]                      # global piece index (T, S)
        time = torch.arange(T, device=obs.device)[:, None].expand(T, rows)
        opened = torch.cummax(torch.where(begins, time, torch.zeros_like(time)), dim=0).values
        position = time - opened                                                      # step within its piece
        h0 = torch.zeros(1, int(counts.sum()), self.lstm_size, device=obs.device)
        c0 = torch.zeros_like(h0)
        carried = ~flags[0]                                                           # first pieces that continue
        first = piece[0]
        h0[0, first] = state[0].reshape(rows, -1) * carried[:, None].to(h0.dtype)
        c0[0, first] = state[1].reshape(rows, -1) * carried[:, None].to(c0.dtype)
        packed = features.new_zeros(T, h0.shape[1], features.shape[-1])
        packed = packed.index_put((position.reshape(-1), piece.reshape(-1)), features.reshape(T * rows, -1))
        out, _ = self.lstm(packed, (h0, c0))
        hidden = out[position.reshape(-1), piece.reshape(-1)].reshape(T, *lead, self.lstm_size)
        return self.inner.logits_from(obs, torch.cat([features, hidden], dim=-1))


class DuelingQNetwork(nn.Module):
    """Action values of a dueling network (IQL's, docs/training.md): observation -> MLP trunk -> a value
    stream and an advantage stream (one hidden ReLU layer of `stream` units each) -> Q = V + A - mean(A).

    The action may be `heads` independent choices among `choices` each (HRL cameras: keep/ignore per target
    slot); the joint value is then the sum of the heads' values, Q(s, a) = V(s) + sum_h (A_h(s, a_h) -
    mean_c A_h(s, c)), and the network returns each head's share, V / heads + A_h - mean A_h, shape
    (..., heads * choices). The argmax of the joint value is each head's own argmax, which is what the
    policy agents take from these outputs (they read them as logits, deterministically).
    """

    def __init__(self, obs_dim: int, heads: int, choices: int, hidden=(512, 512, 256), activation: str = 'tanh',
                 stream: int = 256) -> None:
        super().__init__()
        self.heads, self.choices = int(heads), int(choices)
        self.trunk, width = mlp(obs_dim, hidden, activation)
        relu_gain = ACTIVATIONS['relu'][1]
        self.value = nn.Sequential(linear(width, stream, 1.0, relu_gain), nn.ReLU(), linear(stream, 1, 1.0, 1.0))
        self.advantage = nn.Sequential(linear(width, stream, 1.0, relu_gain), nn.ReLU(),
                                       linear(stream, self.heads * self.choices, 0.01, 1.0))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        features = self.trunk(obs)
        advantage = self.advantage(features).unflatten(-1, (self.heads, self.choices))
        q = self.value(features).unsqueeze(-1) / self.heads + advantage - advantage.mean(-1, keepdim=True)
        return q.flatten(-2)


class RecurrentQNetwork(nn.Module):
    """QMIX's agent network (docs/training.md, "QMIX"): observation -> Linear(width) + ReLU -> GRU(width) ->
    Linear -> action values (..., heads * choices); with several heads (HRL cameras) the value of a joint
    choice is the sum of the heads' values, as in `DuelingQNetwork`. PyTorch's default initialisation.

    `step(obs (..., D), state)` -> (values (..., A), state), `state` a 1-tuple (h (..., width),) as the
    deployment agents carry it; `forward(obs (T, ..., D), h0 (..., width))` unrolls sequences that never
    cross an episode start (the replay's chunks) and returns values (T, ..., A).
    """

    recurrent = True

    def __init__(self, obs_dim: int, heads: int, choices: int, width: int = 256) -> None:
        super().__init__()
        self.heads, self.choices, self.width = int(heads), int(choices), int(width)
        self.embed = nn.Sequential(nn.Linear(obs_dim, self.width), nn.ReLU())
        self.gru = nn.GRU(self.width, self.width)
        self.head = nn.Linear(self.width, self.heads * self.choices)

    def initial_state(self, *shape: int) -> tuple[torch.Tensor]:
        return (torch.zeros(*shape, self.width),)

    def step(self, obs: torch.Tensor, state):
        values, h = self.unroll(obs[None], state[0])
        return values[0], (h,)

    def forward(self, obs: torch.Tensor, h0: torch.Tensor) -> torch.Tensor:
        return self.unroll(obs, h0)[0]

    def unroll(self, obs: torch.Tensor, h0: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Values (T, ..., A) of sequences obs (T, ..., D) from the states h0 (..., width), and the last state."""
        T, lead = obs.shape[0], obs.shape[1:-1]
        out, h = self.gru(self.embed(obs).reshape(T, -1, self.width), h0.reshape(1, -1, self.width))
        return self.head(out).reshape(T, *lead, -1), h.reshape(*lead, self.width)


def agentwise_matmul(x: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """x (..., n, i) @ weight (n, i, o) per agent -> (..., n, o), as one `bmm` (torch.einsum took up to 10x
    longer on small batches, forward and backward)."""
    lead, n = x.shape[:-2], x.shape[-2]
    rows = x.reshape(-1, n, x.shape[-1]).transpose(0, 1)                                # (n, R, i)
    return torch.bmm(rows, weight).transpose(0, 1).reshape(*lead, n, weight.shape[-1])


class AgentwiseMLP(nn.Module):
    """N independent MLPs (one per agent, no shared weights) evaluated in one batched call:
    (..., N, inputs) -> (..., N, outputs). Each agent's layers are initialised as `linear` does:
    hidden rows to norm gain(activation), output rows to `out_scale`; zero biases.

    `outputs=None`: no output layer, the last hidden layer (activated) is the output, width `self.width`.
    `forward(x, agents)`: with `agents` (n,) long, the rows of x (..., n, inputs) are those agents (the
    networks of a subset of the team, e.g. a single deployment agent)."""

    def __init__(self, agents: int, inputs: int, hidden, outputs: int | None, activation: str = 'tanh',
                 out_scale: float = 1.0) -> None:
        super().__init__()
        act, gain = ACTIVATIONS[activation]
        self.activation = act()
        self.activate_ = IN_PLACE[activation]
        sizes = [inputs, *hidden] + ([] if outputs is None else [outputs])
        self.width, self.activated = sizes[-1], outputs is None        # (no layers at all: the identity)
        self.weights, self.biases = nn.ParameterList(), nn.ParameterList()
        for layer, (n_in, n_out) in enumerate(zip(sizes[:-1], sizes[1:])):
            last = layer == len(sizes) - 2 and outputs is not None
            scale, layer_gain = (out_scale, 1.0) if last else (1.0, gain)
            weight = torch.stack([linear(n_in, n_out, scale, layer_gain).weight.T for _ in range(agents)])
            self.weights.append(nn.Parameter(weight.detach().clone()))               # (N, in, out)
            self.biases.append(nn.Parameter(torch.zeros(agents, n_out)))

    def forward(self, x: torch.Tensor, agents: torch.Tensor | None = None) -> torch.Tensor:
        lead, n = x.shape[:-2], x.shape[-2]
        rows = x.reshape(-1, n, x.shape[-1]).transpose(0, 1)                                # (n, R, inputs)
        return self.agent_major(rows, agents=agents).transpose(0, 1).reshape(*lead, n, -1)

    def agent_major(self, x: torch.Tensor, start: int = 0, agents: torch.Tensor | None = None) -> torch.Tensor:
        """`forward` on rows already grouped by agent, from layer `start` on: x (n, R, inputs of that layer; for
        `start` k > 0 the activated output of layer k - 1, computed by the caller, e.g. from a factorised first
        layer) -> (n, R, outputs), every agent's layers as one `bmm` each, the bias added and the activation
        applied in place on its product (I2C's A x A pairs come this way)."""
        layers = len(self.weights)
        for layer in range(start, layers):
            weight, bias = self.weights[layer], self.biases[layer]
            if agents is not None:
                weight, bias = weight[agents], bias[agents]
            x = torch.bmm(x, weight).add_(bias.unsqueeze(1))      # in place on the product: the values of `+`
            if layer < layers - 1 or self.activated:
                x = self.activate_(x)
        return x


class AgentwiseLSTMCell(nn.Module):
    """N independent LSTM cells (one per agent) stepped at once, PyTorch's gate order (i, f, g, o) and
    default init (uniform in +-1/sqrt(hidden)). `forward(x (..., n, inputs), (h, c) (..., n, hidden), agents)`
    -> (h, c); `agents` (n,) long as in `AgentwiseMLP` (None: all N, in order). A sequence computes the input
    part of its gates at once (`input_gates` (T, ..., n, 4 hidden)) and then `recur`s step by step."""

    def __init__(self, agents: int, inputs: int, hidden: int) -> None:
        super().__init__()
        bound = 1.0 / math.sqrt(hidden)
        self.hidden = int(hidden)
        self.input_weight = nn.Parameter(torch.empty(agents, inputs, 4 * hidden).uniform_(-bound, bound))
        self.hidden_weight = nn.Parameter(torch.empty(agents, hidden, 4 * hidden).uniform_(-bound, bound))
        self.bias = nn.Parameter(torch.empty(agents, 4 * hidden).uniform_(-bound, bound))

    def input_gates(self, x: torch.Tensor, agents: torch.Tensor | None = None) -> torch.Tensor:
        w_in, bias = self.input_weight, self.bias
        if agents is not None:
            w_in, bias = w_in[agents], bias[agents]
        return agentwise_matmul(x, w_in) + bias

    def forward(self, x: torch.Tensor, state, agents: torch.Tensor | None = None):
        return self.recur(self.input_gates(x, agents), state, agents)

    def recur(self, input_gates: torch.Tensor, state, agents: torch.Tensor | None = None):
        """(h, c) after one step from the input part of the gates (..., n, 4 hidden) and the state."""
        h, c = state
        w_h = self.hidden_weight if agents is None else self.hidden_weight[agents]
        i, f, g, o = (input_gates + agentwise_matmul(h, w_h)).chunk(4, dim=-1)
        c = torch.sigmoid(f) * c + torch.sigmoid(i) * torch.tanh(g)
        return torch.sigmoid(o) * torch.tanh(c), c


class IndependentActors(nn.Module):
    """MADDPG's deterministic actors, one per agent (docs/training.md, "MADDPG as MA-TD3"): each agent's observation
    (..., N, D) -> its own MLP -> tanh -> actions (..., N, A) in [-1, 1], the share of the agent's action bounds (the
    original's low + (high - low) sigmoid(2x) on the same box). Deployment reads the outputs as the actions."""

    continuous = True

    def __init__(self, agents: int, obs_dim: int, action_dim: int = 2, hidden=(512, 256),
                 activation: str = 'tanh') -> None:
        super().__init__()
        self.agents = int(agents)
        self.body = AgentwiseMLP(agents, obs_dim, hidden, action_dim, activation, out_scale=0.01)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return torch.tanh(self.body(obs))


class Critic(nn.Module):
    """Value in normalised units of the global state (MAPPO) or of a local observation (IPPO):
    (..., input_dim) -> (...,), or (..., outputs) with `outputs` > 1 (MAPPO with per-agent rewards:
    one value per agent, in the agents' order in the state)."""

    def __init__(self, input_dim: int, hidden=(256, 256), activation: str = 'tanh', outputs: int = 1) -> None:
        super().__init__()
        self.body, width = mlp(input_dim, hidden, activation)
        self.head = linear(width, outputs, 1.0, 1.0)
        self.outputs = outputs

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        values = self.head(self.body(x))
        return values.squeeze(-1) if self.outputs == 1 else values


# ============================================================================ builders (`mate.policies.actors`)

def build_mlp_actor(spec) -> nn.Module:
    """The shared MLP actor of `spec` (network 'mlp'), inside a `RecurrentActor` when `spec.lstm` > 0."""
    actor = Actor(spec.obs_dim, spec.num_actions, spec.hidden, spec.activation, context_extra=spec.lstm)
    return RecurrentActor(actor, spec.lstm) if spec.lstm else actor


def build_per_target_actor(spec) -> nn.Module:
    """The camera per-target scorer of `spec` (network 'per-target'), inside a `RecurrentActor` when `spec.lstm` > 0."""
    actor = PerTargetActor(spec.obs_dim, spec.counts, spec.hidden, spec.activation, num_actions=spec.num_actions,
                           context_extra=spec.lstm, memory=bool(spec.memory), velocity=spec.velocity)
    return RecurrentActor(actor, spec.lstm) if spec.lstm else actor


def build_dueling_network(spec) -> nn.Module:
    """IQL's dueling Q-network of `spec` (network 'dueling')."""
    return DuelingQNetwork(spec.obs_dim, spec.heads, spec.choices, spec.hidden, spec.activation)


def build_recurrent_q_network(spec) -> nn.Module:
    """QMIX's GRU agent network of `spec` (network 'recurrent-q'; its width is the last hidden width)."""
    return RecurrentQNetwork(spec.obs_dim, spec.heads, spec.choices, spec.hidden[-1])


def build_independent_actors(spec) -> nn.Module:
    """MA-TD3's deterministic actors of `spec`, one per agent (network 'independent')."""
    return IndependentActors(spec.num_agents, spec.obs_dim, spec.num_actions, spec.hidden, spec.activation)
