"""`mate.learn`: trainers for MATE's teams (PyTorch), one file per algorithm, and trained policies as agents.

    from mate.learn.mappo import MAPPOConfig, train
    train(MAPPOConfig(team='camera', steps=2_000_000, run_dir='runs/mappo-camera'))
    agent = mate.learn.PolicyCameraAgent.from_checkpoint('runs/mappo-camera/final.pt')

The pieces: `envs` (the team's training envs), `run` (`Run`: run directory, resume, checkpoints, logs, budget,
signals), `ppo`/`ppo_loop` (what the PPO trainers share), `offpolicy_loop` (the off-policy trainers' loop), one file
per algorithm (`mappo`, `mappo_lstm`, `tarmac`, `i2c`, `iql`, `qmix`, `matd3`) and `population` (PSRO). What a
trained policy is (its spec, networks, checkpoints, the policy as a team or an agent) is `mate.policies`, below this
package; the names above are re-exported here. Torch is imported on first use of a torch-backed name, so
`import mate` stays light. See docs/training.md.
"""

from __future__ import annotations

import importlib

_LAZY = {
    'TeamEnvConfig': 'mate.learn.envs', 'TrainingEnv': 'mate.learn.envs', 'TeamVecEnv': 'mate.learn.envs',
    'Run': 'mate.learn.run', 'PolicySpec': 'mate.policies.spec', 'CheckpointError': 'mate.policies.checkpoint',
    'save_checkpoint': 'mate.policies.checkpoint', 'load_checkpoint': 'mate.policies.checkpoint',
    **dict.fromkeys(('PolicyCameraAgent', 'PolicyTargetAgent', 'PolicyTeam', 'load_agent', 'load_policy',
                     'pretrained_path', 'export_policy'), 'mate.policies.policy'),
}

__all__ = list(_LAZY)  # noqa: PLE0604


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value
