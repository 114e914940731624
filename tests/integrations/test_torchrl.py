"""`mate.integrations.torchrl.MateTorchRLEnv`: TorchRL's own spec checks pass, and its games are those of
`mate.make_team_vec` with the same seed and actions, episode ends and partial resets included."""

from __future__ import annotations

import numpy as np
import pytest

import mate   # before torch: MATE_REPRODUCIBLE pins torch's kernels as torch loads
from conftest import needs_extra, run_simulated

torch = needs_extra('torch')
needs_extra('torchrl')

from torchrl.envs.utils import check_env_specs  # noqa: E402

from mate.integrations.torchrl import MateTorchRLEnv  # noqa: E402


@pytest.mark.parametrize('config, team, reward', [('MATE-4v8-9', 'camera', 'team'), ('MATE-2v4-0', 'target', 'own')])
def test_torchrls_checks_pass(config, team, reward):
    env = MateTorchRLEnv(config, team=team, num_envs=3, reward=reward, max_episode_steps=6)
    check_env_specs(env)
    n = env.envs.num_agents
    assert env.full_observation_spec[team, 'observation'].shape[-2] == n
    assert env.full_reward_spec[team, 'reward'].shape == (3, n, 1)


def test_the_rollout_is_the_single_team_envs_games():
    B, steps, horizon = 3, 20, 7
    env = MateTorchRLEnv('MATE-2v4-0', team='target', num_envs=B, max_episode_steps=horizon)
    env.set_seed(11)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-20, 20, (steps, B, env.envs.num_agents, 2)).astype(np.float32)
    td = env.reset()
    reference = mate.make_team_vec('MATE-2v4-0', team='target', num_envs=B, max_episode_steps=horizon,
                                   autoreset_mode='same_step', observation_dtype=np.float32)
    expected, _ = reference.reset(seed=11)
    assert np.array_equal(td['target', 'observation'].numpy(), expected)
    ended_any = False
    for step in range(steps):
        td.set(('target', 'action'), torch.from_numpy(actions[step]))
        td = env.step(td)
        observations, rewards, terminated, truncated, infos = reference.step(actions[step].astype(np.float64))
        done = terminated | truncated
        shown = observations.copy()
        for i in np.flatnonzero(done):
            shown[i] = infos['final_obs'][i]
        assert np.array_equal(td['next', 'target', 'observation'].numpy(), shown)
        assert np.array_equal(td['next', 'target', 'reward'].numpy()[..., 0], np.broadcast_to(
            rewards[:, None], shown.shape[:2]).astype(np.float32))
        assert np.array_equal(td['next', 'done'].numpy()[:, 0], done)
        td = env.step_mdp(td)
        if done.any():
            ended_any = True
            td = env.reset(td.set('_reset', torch.from_numpy(done[:, None])))
            assert np.array_equal(td['target', 'observation'].numpy(), observations)   # the next episodes' first
    assert ended_any


def test_a_rollout_keeps_every_steps_observation():
    """Each step's tensors are the adapter's own: the env's buffers, overwritten at its next step, are copied."""
    B, steps = 2, 6
    env = MateTorchRLEnv('MATE-2v4-0', team='target', num_envs=B, max_episode_steps=50)
    env.set_seed(3)
    rollout = env.rollout(steps)
    reference = mate.make_team_vec('MATE-2v4-0', team='target', num_envs=B, max_episode_steps=50,
                                   autoreset_mode='same_step', observation_dtype=np.float32)
    expected = [reference.reset(seed=3)[0].copy()]
    for step in range(steps):
        actions = rollout['target', 'action'][:, step].to(torch.float64).numpy()
        expected.append(reference.step(actions)[0].copy())
    for step in range(steps):
        assert np.array_equal(rollout['target', 'observation'][:, step].numpy(), expected[step])
        assert np.array_equal(rollout['next', 'target', 'observation'][:, step].numpy(), expected[step + 1])


def test_autoreset_is_the_adapters_own():
    with pytest.raises(ValueError, match='autoreset_mode'):
        MateTorchRLEnv('MATE-2v4-0', team='target', num_envs=2, autoreset_mode='next_step')


ON_DEVICE = """
import json
import numpy as np
import torch
from mate.integrations.torchrl import MateTorchRLEnv
from mate.teams.device import HostTeam

B, steps, horizon = 3, 20, 7
host_greedy = lambda n, c, seed: HostTeam('greedy', 'camera', n, c, seed=seed)
envs = [MateTorchRLEnv('MATE-2v4-0', team='target', num_envs=B, max_episode_steps=horizon, reward='own',
                       game_device='cuda', block=2),
        MateTorchRLEnv('MATE-2v4-0', team='target', num_envs=B, max_episode_steps=horizon, reward='own',
                       opponent=host_greedy)]
for env in envs:
    env.set_seed(11)
tds = [env.reset() for env in envs]
actions = np.random.default_rng(0).uniform(-20, 20, (steps, B, 4, 2)).astype(np.float32)
differing, ends = [], 0
if not torch.equal(tds[0]['target', 'observation'], tds[1]['target', 'observation']):
    differing.append('reset')
for step in range(steps):
    for i, env in enumerate(envs):
        tds[i].set(('target', 'action'), torch.from_numpy(actions[step]))
        tds[i] = env.step(tds[i])
    for key in (('next', 'target', 'observation'), ('next', 'target', 'reward'), ('next', 'done'),
                ('next', 'terminated'), ('next', 'truncated')):
        if not torch.equal(tds[0][key], tds[1][key]):
            differing.append(f'{step}: {key}')
    done = tds[1]['next', 'done']
    tds = [env.step_mdp(td) for env, td in zip(envs, tds)]
    if done.any():
        ends += int(done.sum())
        tds = [env.reset(td.set('_reset', done.clone())) for env, td in zip(envs, tds)]
        if not torch.equal(tds[0]['target', 'observation'][done[:, 0]], tds[1]['target', 'observation'][done[:, 0]]):
            differing.append(f'{step}: partial reset')
print(json.dumps(dict(differing=differing[:5], ends=ends)))
"""


@pytest.mark.slow
def test_the_games_on_a_simulated_device_are_the_cpu_adapters():
    """`game_device='cuda'` under numba's CUDA simulator against the CPU adapter whose opponent is the device
    team's host twin: the same rollout, partial resets included."""
    import json

    needs_extra('numba_cuda')
    done = run_simulated(ON_DEVICE)
    assert done.returncode == 0, done.stderr[-3000:]
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert found['differing'] == [] and found['ends'] >= 3, found
