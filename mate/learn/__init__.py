"""`mate.learn`: MAPPO / IPPO on the batched vector env against batched greedy opponents (PyTorch, CPU).

    from mate.learn import PPOConfig, train
    train(PPOConfig(algo='mappo', team='camera', total_steps=2_000_000), 'runs/mappo-camera')
    agent = mate.learn.PolicyCameraAgent.from_checkpoint('runs/mappo-camera/final.pt')

Torch is imported on first use of a torch-backed name, so `import mate` stays light.
See docs/training.md.
"""

from __future__ import annotations

import importlib

from .envs import (
    PAPER_SETTINGS,
    TeamVecEnv,
    discrete_to_continuous,
    preprocess_observation,
)
from .opponents import VecGreedyCamera, VecGreedyTarget

_LAZY = {
    'PPOConfig': 'ppo', 'train': 'ppo', 'compute_gae': 'ppo', 'ppo_policy_loss': 'ppo', 'Actor': 'networks',
    'Critic': 'networks', 'ValueNormalizer': 'ppo', 'piecewise': 'schedules', 'PAPER_HYPERPARAMETERS': 'ppo',
    'CheckpointError': 'checkpoint', 'save_checkpoint': 'checkpoint', 'load_checkpoint': 'checkpoint',
    'PolicyCameraAgent': 'agents', 'PolicyTargetAgent': 'agents', 'load_agent': 'agents',
    'load_policy': 'agents', 'pretrained_path': 'agents', 'export_policy': 'agents', 'TarMACActor': 'comm',
    'I2CActor': 'comm',
}

__all__ = ['PAPER_SETTINGS', 'TeamVecEnv', 'VecGreedyCamera', 'VecGreedyTarget', 'discrete_to_continuous',  # noqa: PLE0604
           'preprocess_observation', *_LAZY]


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(f'{__name__}.{module}'), name)
    globals()[name] = value
    return value
