"""RLlib PPO policy -> `mate` policy file: the actor of RLlib's default PPO module as `mate.learn`'s MLP actor.

    from mate.integrations.rllib_export import export_module, export_run_checkpoint
    export_module(algo.get_module('camera'), spec, 'camera.pt')                  # a live module
    export_run_checkpoint('runs/rllib-ppo-camera-seed0/checkpoint.pt', 'camera.pt')       # a run's checkpoint

The policy file is the one `mate train` writes (`mate.policies.checkpoint`, format `mate.learn/2`: the spec, the actor's
weights, the config, the step count, a note), so `load_policy(path)`, `mate evaluate --camera-agent checkpoint:PATH`
and `mate.learn.evaluation.Evaluator` play it.

What is converted. RLlib's default PPO module (new API stack, `DefaultPPOTorchRLModule` with a `DefaultModelConfig`
of `fcnet_hiddens` H and `fcnet_activation` a, and no `head_fcnet_hiddens`) computes its action logits as
`pi(encoder(obs))`: the encoder is Linear(D, H1), a, Linear(H1, H2), a, ... (its actor tower, `actor_encoder`, when
the value function has its own layers, `vf_share_layers=False`; the shared `encoder` otherwise) and `pi` is one
Linear(H_last, A). `mate.policies.networks.Actor(D, A, H, a)` is the same computation: `body` = the Linear/activation
stack, `head` = the last Linear. Its softmax is the policy RLlib samples from (a `TorchCategorical` over the same
logits), so the exported policy acts as the RLlib policy does, given the same observations: the env of the run shows
RLlib `spec.features(raw)` and decodes its actions with `spec.decode` (`MateMultiAgentEnv` with a `'spec'`), which
`PolicyTeam` and the policy agents do too. The value function is not exported (a policy file holds the actor only).

Refused with one line (`SpecError`): a module whose layers do not match the spec (input width `spec.obs_dim`, widths
`spec.hidden`, `spec.num_actions` logits), a pi head with hidden layers, or other parameters in the actor tower
(layer norms).
"""

from __future__ import annotations

import re
from pathlib import Path

import torch

from ..policies.checkpoint import save_checkpoint
from ..policies.spec import PolicySpec, SpecError

__all__ = ['ENCODER_PREFIXES', 'actor_state', 'actor_state_of_module', 'export_module', 'export_run_checkpoint',
           'module_state_of']

ENCODER_PREFIXES = ('encoder.actor_encoder.net.mlp.', 'encoder.encoder.net.mlp.')
"""Where the policy's layers sit in the module's state dict: its own tower (`vf_share_layers=False`), or the tower
it shares with the value function."""
PI_PREFIX = 'pi.net.mlp.'
_LAYER = re.compile(r'^(\d+)\.(weight|bias)$')


def _linears(state: dict, prefix: str, what: str) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """The (weight, bias) pairs of the Linear layers under `prefix`, in order; SpecError for anything else there."""
    layers: dict[int, dict[str, torch.Tensor]] = {}
    for key, value in state.items():
        if not key.startswith(prefix):
            continue
        match = _LAYER.match(key[len(prefix):])
        if match is None:
            raise SpecError(f'the RLlib module has a parameter {key!r} in its {what} that mate\'s MLP actor does not '
                            'have; it has Linear layers and activations only')
        layers.setdefault(int(match.group(1)), {})[match.group(2)] = torch.as_tensor(value).detach().cpu()
    pairs = []
    for index in sorted(layers):
        parts = layers[index]
        if set(parts) != {'weight', 'bias'} or parts['weight'].dim() != 2:
            raise SpecError(f"the RLlib module's {what} layer {index} is not a Linear layer with a bias (a layer "
                            "norm? mate's MLP actor has Linear layers and activations only: fcnet_use_layernorm=False)")
        pairs.append((parts['weight'], parts['bias']))
    return pairs


def actor_state(module_state: dict, spec: PolicySpec) -> dict[str, torch.Tensor]:
    """The state dict of `mate.policies.policy.make_actor(spec)` (an MLP `Actor`) holding the policy of an RLlib PPO
    module's state dict `module_state` (module docstring); SpecError (one line) when they do not match."""
    if spec.network != 'mlp' or spec.lstm:
        raise SpecError(f"an RLlib PPO module exports to an MLP actor (network 'mlp', no LSTM); the spec has network "
                        f'{spec.network!r}{f" with an LSTM of {spec.lstm}" if spec.lstm else ""}')
    prefix = next((p for p in ENCODER_PREFIXES if any(key.startswith(p) for key in module_state)), None)
    if prefix is None:
        raise SpecError("the RLlib module has no MLP encoder (expected keys 'encoder.actor_encoder.net.mlp.*' or "
                        "'encoder.encoder.net.mlp.*': RLlib's default PPO module with fcnet_hiddens)")
    body = _linears(module_state, prefix, 'policy encoder')
    head = _linears(module_state, PI_PREFIX, 'pi head')
    if len(head) != 1:
        raise SpecError(f"the RLlib module's pi head has {len(head)} Linear layers; mate's MLP actor has one "
                        '(build the module with head_fcnet_hiddens=[])')
    widths = tuple(int(weight.shape[0]) for weight, _ in body)
    inputs, outputs = int(body[0][0].shape[1]) if body else int(head[0][0].shape[1]), int(head[0][0].shape[0])
    if widths != spec.hidden or inputs != spec.obs_dim or outputs != spec.num_actions:
        raise SpecError(f'the RLlib module (inputs {inputs}, hidden {list(widths)}, {outputs} logits) does not match '
                        f'the spec (inputs {spec.obs_dim}, hidden {list(spec.hidden)}, {spec.num_actions} logits)')
    state = {}
    for i, (weight, bias) in enumerate(body):
        state[f'body.{2 * i}.weight'], state[f'body.{2 * i}.bias'] = weight.float().clone(), bias.float().clone()
    state['head.weight'], state['head.bias'] = head[0][0].float().clone(), head[0][1].float().clone()
    return state


def actor_state_of_module(module, spec: PolicySpec) -> dict[str, torch.Tensor]:
    """`actor_state` of a live RLlib module (an `RLModule` with `state_dict()`), after checking that its activation
    is the spec's (SpecError otherwise)."""
    model_config = getattr(module, 'model_config', None) or {}
    activation = model_config.get('fcnet_activation') if isinstance(model_config, dict) else \
        getattr(model_config, 'fcnet_activation', None)
    if activation is not None and str(activation).lower() != spec.activation:
        raise SpecError(f'the RLlib module uses the {activation} activation; the spec has {spec.activation!r}')
    head_hidden = model_config.get('head_fcnet_hiddens') if isinstance(model_config, dict) else \
        getattr(model_config, 'head_fcnet_hiddens', None)
    if head_hidden:
        raise SpecError(f"the RLlib module's pi head has hidden layers {list(head_hidden)}; mate's MLP actor has "
                        'a single linear head (head_fcnet_hiddens=[])')
    return actor_state(module.state_dict(), spec)


def export_module(module, spec: PolicySpec, out, *, note: str = '', env_steps: int = 0, config: dict | None = None,
                  deterministic: bool = False) -> Path:
    """Write the policy of an RLlib PPO module as a `mate` policy file `out` (module docstring); returns its path.
    `deterministic` is stored as the agents' default way of acting (argmax instead of sampling)."""
    spec = spec.replace(deterministic=bool(deterministic))
    return save_checkpoint(out, dict(spec=spec.to_dict(), algo=spec.algo, actor=actor_state_of_module(module, spec),
                                     config=dict(config or {}), env_steps=int(env_steps),
                                     note=note or 'exported from an RLlib PPO module'))


def module_state_of(algorithm_state: dict, module_id: str) -> dict:
    """The weights of the RLModule `module_id` ('camera' or 'target' in `mate rllib-train` runs) in an RLlib
    algorithm's state (`algo.get_state()`); SpecError (one line) if the state has no such module."""
    try:
        modules = algorithm_state['learner_group']['learner']['rl_module']
    except (KeyError, TypeError):
        raise SpecError("the RLlib state has no modules (expected algo.get_state()['learner_group']['learner']"
                        "['rl_module'])") from None
    if module_id not in modules:
        raise SpecError(f'the RLlib state has no module {module_id!r}; it has {sorted(modules)}')
    return modules[module_id]


def export_run_checkpoint(checkpoint, out, *, note: str = '') -> Path:
    """The policy of a `mate rllib-train` run's `checkpoint.pt` (the RLlib algorithm's state kept there) as a
    `mate` policy file `out`; returns its path. The file is read with mate's safe loader (tensors and plain data:
    RLlib's own checkpoint directories, which are pickles, are never read)."""
    from ..policies.checkpoint import load_checkpoint, read_spec

    data = load_checkpoint(checkpoint)
    spec = read_spec(data)
    state = data.get('state') or {}
    if 'rllib_state' not in state:
        raise SpecError(f'{str(checkpoint)!r} is not a checkpoint of a mate rllib-train run (no RLlib state in it)')
    actor = actor_state(module_state_of(state['rllib_state'], spec.team), spec)
    return save_checkpoint(out, dict(spec=spec.to_dict(), algo=spec.algo, actor=actor, config=data.get('config', {}),
                                     env_steps=int(data.get('run', {}).get('env_steps', 0)),
                                     note=note or f'exported from the RLlib state in {str(checkpoint)!r}'))
