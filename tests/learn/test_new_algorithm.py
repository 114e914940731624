"""The recipe of docs/training.md, "Adding a PPO-family algorithm", followed as a user would: one file with a config
and an actor, one line registering the actor; `mate.learn.ppo_loop.train` does the rest. The toy actor learns a toy
task, its run resumes, and its policy file loads and acts through the registry like the package's own."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from torch import nn

from mate.learn import ppo_loop
from mate.policies.actors import NETWORK_KINDS, register_network
from mate.policies.policy import load_policy, make_actor
from mate.learn.ppo import PPOConfig

from .resume import assert_same_run, stopped_and_resumed
from .toy import CueMatching


# ---------------------------------------------------------------- the user's file: an actor and a config

class BiasedLinearActor(nn.Module):
    """A one-layer actor: logits = W obs + b, (..., N, D) -> (..., N, A)."""

    def __init__(self, obs_dim: int, num_actions: int) -> None:
        super().__init__()
        self.layer = nn.Linear(obs_dim, num_actions)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.layer(obs)


def build_linear_actor(spec) -> nn.Module:
    return BiasedLinearActor(spec.obs_dim, spec.num_actions)


@dataclasses.dataclass
class LinearPPOConfig(PPOConfig):
    """PPO with a one-layer actor and MAPPO's critic."""

    @property
    def algo(self) -> str:
        return 'linear-ppo'


def policy_spec(config: LinearPPOConfig, envs=None):
    network = dict(network='toy-linear', hidden=config.hidden, activation=config.activation, lstm=0, algo=config.algo)
    return envs.spec.replace(**network) if envs is not None else config.policy_spec(action='grid', **network)


def train(config: LinearPPOConfig, envs=None, callback=None):
    return ppo_loop.train(config, policy_spec(config, envs), envs, callback, critic='state')


# ---------------------------------------------------------------- the registry line

@pytest.fixture()
def registered():
    register_network('toy-linear', build_linear_actor)
    yield
    NETWORK_KINDS.pop('toy-linear')


def test_a_new_actor_trains_through_the_one_ppo_loop_and_loads_back(tmp_path, registered):
    rows = []
    config = LinearPPOConfig(steps=16 * 16 * 25, num_envs=16, rollout_length=16, epochs=4, hidden=(32,),
                             lr_schedule=((0, 1e-2),), entropy_schedule=((0, 0.0),), seed=1, run_dir=str(tmp_path),
                             progress=False)
    run = train(config, CueMatching(num_envs=16, num_agents=2, num_actions=4), rows.append)
    assert not run.interrupted
    assert rows[0]['rollout_coverage'] < 0.45 < 0.8 < rows[-1]['rollout_coverage']     # random 0.25; cues matched
    policy = load_policy(tmp_path / 'final.pt')
    assert isinstance(policy.actor, BiasedLinearActor) and policy.spec.network == 'toy-linear'
    cue = np.eye(4, dtype=np.float32)[[[2, 0]]]                                   # (1 env, 2 agents, 4)
    assert policy.outputs(cue).argmax(-1).tolist() == [[2, 0]]                    # it acts on its cue


def test_the_new_actors_run_on_a_game_resumes_exactly(tmp_path, registered):
    """On MATE-4v8-9 cameras against the greedy targets: stopped by SIGINT after iteration 3 and resumed, the same
    weights, optimiser and log rows as the run never stopped."""
    def config_of(run_dir, fresh):
        return LinearPPOConfig(seed=1, steps=240, num_envs=4, rollout_length=10, epochs=2, minibatches=2, horizon=40,
                               threads=1, progress=False, run_dir=run_dir, fresh=fresh)

    straight, stopped = stopped_and_resumed(train, config_of, 3, tmp_path)
    assert_same_run(straight, stopped)
    assert load_policy(straight / 'final.pt').spec.env_id == 'MATE-4v8-9-v0'


def test_a_registered_name_is_the_specs_and_a_taken_one_is_refused(registered):
    from mate.policies.spec import SpecError
    from .toy import toy_spec

    spec = toy_spec(CueMatching(num_envs=2, num_agents=2, num_actions=4)).replace(network='toy-linear')
    assert isinstance(make_actor(spec), BiasedLinearActor) and spec.comm == 'none' and not spec.recurrent
    with pytest.raises(ValueError, match="'toy-linear' is registered already"):
        register_network('toy-linear', lambda spec: None)
    with pytest.raises(SpecError, match='network must be one of mlp, per-target'):
        spec.replace(network='no-such-network')
