"""The optional extras of the package: which command needs which, and the one-line error when one is missing.

A plain `pip install mate` (numpy, numba, gymnasium, pyyaml, rich) plays the game: `mate evaluate` with the rule
agents, `mate bench`, `mate presets`, `mate generate-config`, the env, the vector env and the single-team env. The
extras add the rest:

| extra        | brings                                  | for                                                     |
|--------------|-----------------------------------------|---------------------------------------------------------|
| `render`     | pygame, Pillow, imageio, imageio-ffmpeg | frames, GIFs and videos (`mate evaluate` saves a GIF)   |
| `pettingzoo` | pettingzoo                              | `mate.integrations.pettingzoo`                          |
| `train`      | torch (CPU wheel), TensorBoard, matplotlib, scipy | `mate train`, `mate psro`, `mate benchmark`, trained policies (`pretrained:NAME`, `checkpoint:PATH`) |
| `rllib`      | ray[rllib]                              | `mate rllib-train`, `mate.integrations.rllib`           |
| `wandb`      | wandb                                   | `mate train --wandb` (Weights & Biases logging)         |
| `docs`       | mkdocs, mkdocs-material, mkdocstrings   | the documentation site                                  |
| `gpu`        | numba-cuda (with NVVM)                  | the core on a CUDA device (`mate.core.device`)          |
| `torchrl`    | torchrl, tensordict                     | `mate.integrations.torchrl`                             |
| `all`        | render, pettingzoo, train               |                                                         |
| `test`       | pytest, hypothesis and what the tests use |                                                       |

`require(extra, what)` is how a command asks for one: a `CommandError` (`mate COMMAND: error: ...`, exit status 2)
naming the missing module and the install line when a module of the extra cannot be found. It only looks the
modules up (`importlib.util.find_spec`), it imports nothing.
"""

from __future__ import annotations

import importlib.util

from .arguments import CommandError

__all__ = ['EXTRAS', 'missing', 'require']

EXTRAS = {
    'render': ('pygame', 'PIL', 'imageio'),
    'pettingzoo': ('pettingzoo',),
    'train': ('torch', 'scipy', 'matplotlib'),
    'rllib': ('ray',),
    'wandb': ('wandb',),
    'docs': ('mkdocs',),
    'gpu': ('numba_cuda',),
    'torchrl': ('torchrl',),
}
"""extra -> the top-level modules it installs that the package imports (the table of the module docstring)."""


def missing(extra: str) -> list[str]:
    """The modules of `extra` that cannot be imported here ([] when the extra is installed)."""
    return [module for module in EXTRAS[extra] if not _importable(module)]


def _importable(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):   # a module blocked in sys.modules (None), or a broken package
        return False


def require(extra: str, what: str) -> None:
    """Raise `CommandError` naming `what` needs (a command, an agent) when a module of `extra` is missing."""
    absent = missing(extra)
    if absent:
        raise CommandError(f"{what} needs the {extra} extra (no module {', '.join(map(repr, absent))}): "
                           f"pip install 'mate[{extra}]' (from a clone: pip install -e '.[{extra}]')")
