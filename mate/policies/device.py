"""Where a trainer computes: `--device auto|cpu|cuda[:N]` (networks, rollout buffers, updates) and `--threads`.

The games run on the CPU (numba) unless a trainer plays them on the GPU (`--game-device`,
`TrainingEnv(..., device='cuda')`); on the CPU a trainer moves each decision's observations to the device
once and the chosen actions back once. `auto` takes the first GPU when PyTorch sees one, else the CPU.
"""

from __future__ import annotations

import os
import re

__all__ = ['CORES', 'parse_device', 'resolve_device', 'update_threads']

CORES = max(1, len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count() or 1)
"""The cores this process may use."""

_PATTERN = re.compile(r'^(auto|cpu|cuda(:\d+)?)$')


def parse_device(name: str) -> str:
    """`name` if it is one of auto, cpu, cuda, cuda:N; ValueError (one line, the valid forms) otherwise."""
    if not isinstance(name, str) or not _PATTERN.match(name.strip()):
        raise ValueError(f"device must be auto, cpu, cuda or cuda:N (N a GPU index), got {name!r}")
    return name.strip()


def resolve_device(name: str = 'auto'):
    """The `torch.device` of `name`: auto picks cuda:0 when available, else cpu. ValueError (one line) when CUDA
    is asked for and PyTorch sees no GPU, or the index is out of range."""
    import torch

    name = parse_device(name)
    if name == 'auto':
        return torch.device('cuda:0' if torch.cuda.is_available() else 'cpu')
    if name == 'cpu':
        return torch.device('cpu')
    if not torch.cuda.is_available():
        raise ValueError(f'--device {name}: PyTorch sees no CUDA GPU here (torch {torch.__version__}, built '
                         f'{"with" if torch.version.cuda else "without"} CUDA); use --device cpu or auto')
    device = torch.device(name if ':' in name else 'cuda:0')
    if device.index >= torch.cuda.device_count():
        raise ValueError(f'--device {name}: PyTorch sees {torch.cuda.device_count()} GPU(s), indices 0..'
                         f'{torch.cuda.device_count() - 1}')
    return device


def update_threads(config) -> int:
    """Torch threads of a trainer's update phase: `config.threads`, or (0) every core this process may use."""
    return config.threads or CORES
