"""The exporter RLlib PPO module -> mate policy file (`mate.integrations.rllib_export`): the exported policy's action
probabilities are the RLlib module's on the same observations, and it plays the same episode in mate's evaluation
as the RLlib policy in the RLlib env. Builds RLlib modules locally (no Ray instance); skipped without ray.rllib."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from conftest import needs_extra

needs_extra('ray.rllib')

from mate.integrations import rllib as mate_rllib  # noqa: E402
from mate.integrations import rllib_train  # noqa: E402
from mate.integrations.rllib_export import actor_state, export_module, export_run_checkpoint  # noqa: E402
from mate.policies.checkpoint import load_checkpoint, save_checkpoint  # noqa: E402
from mate.learn.evaluation import evaluate_policy  # noqa: E402
from mate.policies.policy import load_policy  # noqa: E402
from mate.policies.spec import SpecError  # noqa: E402

HORIZON = 60


def witness(team: str, *options: str) -> tuple:
    """(config, spec, PPOConfig) of `mate rllib-train --team TEAM` on MATE-2v4-0 with a small MLP."""
    from mate.cli import main as cli

    args = cli.build_parser().parse_args(['rllib-train', '--team', team, '--config', 'MATE-2v4-0', '--hidden', '32',
                                          '16', '--horizon', str(HORIZON), '--num-envs', '2', '--minibatch-size', '25',
                                          *options])
    config = rllib_train.config_of(args)
    spec = config.policy_spec(action='grid', network='mlp', hidden=config.hidden, activation=config.activation,
                              algo=rllib_train.ALGO)
    return config, spec, mate_rllib.witness_ppo_config(config, spec)


def module_of(ppo_config, env, team: str, seed: int = 0):
    """The team's RLModule as the PPO config builds it, its weights perturbed (RLlib's pi head starts near zero,
    which would make every policy nearly uniform)."""
    spaces = {team: (env.observation_spaces[f'{team}_0'], env.action_spaces[f'{team}_0'])}
    module = ppo_config.get_multi_rl_module_spec(spaces=spaces).build()[team]
    generator = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for parameter in module.parameters():
            parameter.add_(0.5 * torch.randn(parameter.shape, generator=generator))
    return module.eval()


def rllib_logits(module, observations: np.ndarray) -> np.ndarray:
    with torch.no_grad():
        out = module.forward_inference({'obs': torch.as_tensor(observations, dtype=torch.float32)})
    return out['action_dist_inputs'].numpy()


def softmax(logits: np.ndarray) -> np.ndarray:
    p = np.exp(logits - logits.max(axis=-1, keepdims=True))
    return p / p.sum(axis=-1, keepdims=True)


@pytest.mark.parametrize('team, share', [('camera', False), ('camera', True), ('target', False)],
                         ids=['cameras', 'cameras-shared-value-layers', 'targets'])
def test_exported_probabilities_are_the_rllib_modules(tmp_path, team, share):
    config, spec, ppo = witness(team, *(['--vf-share-layers'] if share else []))
    env = mate_rllib.MateMultiAgentEnv(mate_rllib.witness_env_config(config, spec))
    module = module_of(ppo, env, team)
    path = export_module(module, spec, tmp_path / 'policy.pt', env_steps=123)
    policy = load_policy(path)
    assert policy.spec == spec and path.stat().st_size > 0
    raw_team = 0 if team == 'camera' else 1
    observations, _ = env.reset(seed=5)
    compared, distinct = 0, 0
    for _ in range(8):
        agents = sorted(observations)
        rllib_obs = np.stack([observations[agent] for agent in agents])
        # mate's pipeline from the raw observations (what PolicyTeam and the agents do), RLlib's from the env's
        raw = np.asarray(env.raw_observations[raw_team], dtype=np.float64)
        mate_probs = softmax(policy.outputs(policy.features(raw)))
        rllib_probs = softmax(rllib_logits(module, rllib_obs))
        np.testing.assert_allclose(mate_probs, rllib_probs, atol=1e-6, rtol=0)
        compared += len(agents)
        distinct += int((rllib_probs.max(-1) > 2.0 / spec.choices).sum())   # not a uniform policy
        actions = {agent: int(np.argmax(rllib_probs[i])) for i, agent in enumerate(agents)}
        observations, *_ = env.step(actions)
    assert compared >= 16 and distinct >= compared // 2


@pytest.mark.parametrize('team', ['camera', 'target'])
def test_the_exported_policy_plays_the_rllib_policys_episode(tmp_path, team):
    """Greedy (argmax) actions: the RLlib module in the RLlib env of the run, and the exported policy in mate's
    evaluation (`evaluate_policy`: a PolicyTeam against the batched greedy team, the protocol's episodes), play the
    same game from the same seed: the same coverage and target return, env step for env step."""
    config, spec, ppo = witness(team)
    env = mate_rllib.MateMultiAgentEnv(mate_rllib.witness_env_config(config, spec))
    module = module_of(ppo, env, team, seed=1)
    policy = load_policy(export_module(module, spec, tmp_path / 'policy.pt', deterministic=True))
    seed = 1_000_003
    observations, _ = env.reset(seed=seed)
    done = False
    while not done:
        agents = sorted(observations)
        logits = rllib_logits(module, np.stack([observations[agent] for agent in agents]))
        observations, _, terminateds, truncateds, infos = env.step(
            {agent: int(np.argmax(logits[i])) for i, agent in enumerate(agents)})
        done = terminateds['__all__'] or truncateds['__all__']
    info = infos[f'{team}_0']
    (episode,) = evaluate_policy(policy, 1, seed, HORIZON)
    assert info['episode_length'] == episode['episode_length'] == HORIZON
    assert info['episode_coverage_rate'] == pytest.approx(episode['coverage_rate'], abs=1e-12)
    assert info['episode_normalized_target_return'] == pytest.approx(episode['normalized_target_return'], abs=1e-12)


def test_a_run_checkpoint_exports_as_the_live_module(tmp_path):
    """`checkpoint.pt` of a `mate rllib-train` run keeps the RLlib algorithm's state as plain data (read with the
    weights-only loader); its module exports as the live module does."""
    config, spec, ppo = witness('camera')
    env = mate_rllib.MateMultiAgentEnv(mate_rllib.witness_env_config(config, spec))
    module = module_of(ppo, env, 'camera', seed=2)
    weights = {name: value.numpy() for name, value in module.state_dict().items()}
    rllib_state = {'learner_group': {'learner': {'rl_module': {'camera': weights}}}}
    save_checkpoint(tmp_path / 'checkpoint.pt', dict(spec=spec.to_dict(), algo=spec.algo, config={},
                                                     run=dict(env_steps=40, iteration=2),
                                                     state=dict(rllib_state=rllib_state, kl_coeff=0.2)))
    path = export_run_checkpoint(tmp_path / 'checkpoint.pt', tmp_path / 'policy.pt')
    policy = load_policy(path)
    assert policy.spec == spec and load_checkpoint(path)['env_steps'] == 40
    state = policy.actor.state_dict()
    for name, value in actor_state(module.state_dict(), spec).items():
        torch.testing.assert_close(state[name], value)
    save_checkpoint(tmp_path / 'other.pt', dict(spec=spec.replace(team='target').to_dict(), algo=spec.algo,
                                                config={}, run=dict(env_steps=40, iteration=2),
                                                state=dict(rllib_state=rllib_state)))
    with pytest.raises(SpecError, match=r"the RLlib state has no module 'target'; it has \['camera'\]"):
        export_run_checkpoint(tmp_path / 'other.pt', tmp_path / 'x.pt')
    save_checkpoint(tmp_path / 'ippo.pt', dict(spec=spec.to_dict(), algo='ippo', config={},
                                               run=dict(env_steps=40, iteration=2), state={}))
    with pytest.raises(SpecError, match='is not a checkpoint of a mate rllib-train run'):
        export_run_checkpoint(tmp_path / 'ippo.pt', tmp_path / 'x.pt')


def test_a_module_that_does_not_fit_the_spec_is_refused(tmp_path):
    config, spec, ppo = witness('camera')
    env = mate_rllib.MateMultiAgentEnv(mate_rllib.witness_env_config(config, spec))
    state = module_of(ppo, env, 'camera').state_dict()
    with pytest.raises(SpecError) as error:
        actor_state(state, spec.replace(hidden=(64, 16)))
    assert str(error.value) == ('the RLlib module (inputs 56, hidden [32, 16], 25 logits) does not match the spec '
                                '(inputs 56, hidden [64, 16], 25 logits)')
    normed = ppo.copy(copy_frozen=False).rl_module(model_config=dict(
        ppo.model_config, fcnet_use_layernorm=True)).get_multi_rl_module_spec(
        spaces={'camera': (env.observation_spaces['camera_0'], env.action_spaces['camera_0'])}).build()['camera']
    with pytest.raises(SpecError, match='policy encoder layer 1 is not a Linear layer with a bias .a layer norm'):
        actor_state(normed.state_dict(), spec)
    with pytest.raises(SpecError, match='pi head has 2 Linear layers'):
        actor_state({**state, 'pi.net.mlp.2.weight': state['pi.net.mlp.0.weight'],
                     'pi.net.mlp.2.bias': state['pi.net.mlp.0.bias']}, spec)
    with pytest.raises(SpecError, match="network 'per-target'"):
        actor_state(state, spec.replace(network='per-target'))
