"""`mate.learn`: trainers for MATE's teams (PyTorch), one file per algorithm, and trained policies as agents.

    from mate.learn.mappo import MAPPOConfig, train
    train(MAPPOConfig(team='camera', steps=2_000_000, run_dir='runs/mappo-camera'))
    agent = mate.learn.PolicyCameraAgent.from_checkpoint('runs/mappo-camera/final.pt')

The pieces: `spec` (`PolicySpec`, a policy's contract and its observation/action pipeline), `envs` (the team's
training envs), `run` (`Run`: run directory, resume, checkpoints, logs, budget, signals), `networks`, `ppo` (what
the PPO trainers share), one file per algorithm (`mappo`, `mappo_lstm`, `tarmac`, `i2c`, `iql`, `qmix`, `matd3`),
`policy` (trained policies as batched teams and as agents) and `population` (PSRO). Torch is imported on first use
of a torch-backed name, so `import mate` stays light. See docs/training.md.
"""

from __future__ import annotations

import importlib

_LAZY = {
    'PolicySpec': 'spec', 'TeamEnvConfig': 'envs', 'TrainingEnv': 'envs', 'TeamVecEnv': 'envs', 'Run': 'run',
    'CheckpointError': 'checkpoint', 'save_checkpoint': 'checkpoint', 'load_checkpoint': 'checkpoint',
    'PolicyCameraAgent': 'policy', 'PolicyTargetAgent': 'policy', 'PolicyTeam': 'policy', 'load_agent': 'policy',
    'load_policy': 'policy', 'pretrained_path': 'policy', 'export_policy': 'policy',
}

__all__ = list(_LAZY)  # noqa: PLE0604


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(f'{__name__}.{module}'), name)
    globals()[name] = value
    return value
