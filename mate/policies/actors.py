"""The registry of policy networks: what a `PolicySpec.network` name builds and what it means for the spec.

    register_network('my-actor', 'my_package.my_module:build')      # build(spec) -> torch.nn.Module

Trainers build the network of their spec (`mate.policies.policy.make_actor`), checkpoints and policy files name it, and
the loaders build it again from the name: a network kind is one entry here. An entry says how to build it (a
callable taking the `PolicySpec`, or 'module:function' imported on first use, so that this module and `PolicySpec`
need no torch) and what the spec needs to know of it: the communication scheme its deployment agents speak, whether
it always carries a memory, whether its outputs are Q-values, and which team and action kind it works with.

A network that the PPO loop (`mate.learn.ppo_loop`) trains is a feed-forward actor (`actor(obs (..., N, D))` ->
logits (..., N, A)) or a recurrent one (`recurrent = True`; `initial_state(B, N)`, `step(obs, memory)` -> (logits,
memory), `forward(obs (T, B, N, D), memory, starts (T, B))` -> logits (T, B, N, A)); see docs/training.md, "Adding an
algorithm".
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable
from typing import Any

__all__ = ['NETWORK_KINDS', 'NetworkKind', 'network_kind', 'register_network']


@dataclasses.dataclass(frozen=True)
class NetworkKind:
    """One registered network.

    Args:
        build: `build(spec) -> nn.Module`, or 'module:function' naming it (imported on first use).
        comm: the scheme its agents communicate with at deployment: 'none', 'tarmac' or 'i2c'.
        recurrent: it carries a memory whatever the spec's `lstm` (TarMAC, I2C, QMIX's GRU); otherwise it is
            recurrent when `lstm` > 0.
        needs_lstm: the spec must give it LSTM cells (`lstm` > 0).
        value_based: its outputs are Q-values, acted on greedily.
        team: the only team it plays ('camera'), or None for both.
        action: the only action kind it acts with, or None for any.
        team_input: it reads the whole team's input (N, D), one network per agent row: a deployment agent fills
            its own row (MA-TD3's actors).
    """

    build: Callable[[Any], Any] | str
    comm: str = 'none'
    recurrent: bool = False
    needs_lstm: bool = False
    value_based: bool = False
    team: str | None = None
    action: str | None = None
    team_input: bool = False

    def builder(self) -> Callable[[Any], Any]:
        """The build function (imported from its 'module:function' name on first use)."""
        if callable(self.build):
            return self.build
        module, _, name = self.build.partition(':')
        return getattr(importlib.import_module(module), name)


NETWORK_KINDS: dict[str, NetworkKind] = {
    'mlp': NetworkKind('mate.policies.networks:build_mlp_actor'),
    'per-target': NetworkKind('mate.policies.networks:build_per_target_actor', team='camera'),
    'tarmac': NetworkKind('mate.policies.comm:build_tarmac_actor', comm='tarmac', recurrent=True, needs_lstm=True),
    'i2c': NetworkKind('mate.policies.comm:build_i2c_actor', comm='i2c', recurrent=True, needs_lstm=True),
    'dueling': NetworkKind('mate.policies.networks:build_dueling_network', value_based=True),
    'recurrent-q': NetworkKind('mate.policies.networks:build_recurrent_q_network', recurrent=True, value_based=True),
    'independent': NetworkKind('mate.policies.networks:build_independent_actors', action='continuous', team_input=True),
}
"""Every network a spec may name: a shared MLP, the camera per-target scorer (either with an LSTM when `lstm` > 0),
the TarMAC and I2C communicating actors, IQL's dueling Q-network, QMIX's GRU agent network, MA-TD3's independent
deterministic actors, and those added by `register_network`."""


def register_network(name: str, build: Callable[[Any], Any] | str, **kind: Any) -> NetworkKind:
    """Add a network kind under `name` (`NetworkKind`'s fields as keywords); ValueError for a name already taken by
    another network (registering the same entry again is allowed: a module imported twice)."""
    entry = NetworkKind(build, **kind)
    if not isinstance(name, str) or not name:
        raise ValueError(f'a network name is a non-empty string, got {name!r}')
    if name in NETWORK_KINDS and NETWORK_KINDS[name] != entry:
        raise ValueError(f'network {name!r} is registered already ({NETWORK_KINDS[name].build!r})')
    NETWORK_KINDS[name] = entry
    return entry


def network_kind(name: str) -> NetworkKind:
    """The registered network `name`; ValueError naming the registered ones."""
    try:
        return NETWORK_KINDS[name]
    except KeyError:
        raise ValueError(f'network must be one of {", ".join(NETWORK_KINDS)}, got {name!r}') from None
