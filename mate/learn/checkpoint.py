"""Checkpoint files of `mate.learn`: one `torch.save` dict, written atomically, checked on load.

Layout: {'format': 'mate.learn/1', 'actor', 'critic', 'value_norm', 'optimizer' (state dicts),
'env_steps', 'iteration', 'config' (PPOConfig as a dict), 'meta' (team, env id, frame skip, levels,
observation/state dims, agent and action counts, algo, observability, actor, LSTM size, communication and,
for TarMAC, `critic_messages` (the critic reads the messages; slice-1 TarMAC checkpoints lack it)), and for
I2C 'comm_training' (its joint action-value networks and the FIFO of KL values of its labels)}.
Loaded with `weights_only=True`.
"""

from __future__ import annotations

import os
from pathlib import Path

import torch

__all__ = ['CHECKPOINT_FORMAT', 'FLAGS', 'CheckpointError', 'describe_difference', 'load_checkpoint', 'save_checkpoint']

CHECKPOINT_FORMAT = 'mate.learn/1'
REQUIRED = ('actor', 'meta', 'config')
META_DEFAULTS = {'full_observability': False, 'memory': 0, 'velocity': False, 'credit': 'team', 'comm': 'none',
                 'critic_messages': False, 'message_dropout': 0.0, 'communication_range': None,
                 'message_delay': 0}
"""Values of meta keys added after the first checkpoints were written (files without them have these)."""


class CheckpointError(ValueError):
    """A checkpoint that cannot be read, is not a mate.learn checkpoint, or does not fit the experiment."""


def save_checkpoint(path, payload: dict) -> Path:
    """Write `payload` (+ the format tag) to `path` via a temporary file and an atomic rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + '.tmp')
    torch.save({'format': CHECKPOINT_FORMAT, **payload}, tmp)
    os.replace(tmp, path)
    return path


def load_checkpoint(path, expect: dict | None = None) -> dict:
    """Read a checkpoint; CheckpointError if it is unreadable, of another format, or if any `expect`
    entry differs from the stored `meta` (e.g. team, env id, observation size)."""
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f'checkpoint {str(path)!r} does not exist')
    if not path.is_file():
        raise CheckpointError(f'checkpoint {str(path)!r} is not a file')
    try:
        data = torch.load(path, map_location='cpu', weights_only=True)
    except Exception:  # noqa: BLE001  (truncated zip, random bytes, text, pickled objects, ...)
        # torch's own message is not passed on: it advises unsafe loading (`weights_only=False`)
        raise CheckpointError(f'checkpoint {str(path)!r} is corrupt or not a mate.learn checkpoint: it is not a '
                              'torch file of tensors and plain data (mate never unpickles other objects)') from None
    if not isinstance(data, dict) or data.get('format') != CHECKPOINT_FORMAT:
        found = data.get('format') if isinstance(data, dict) else type(data).__name__
        raise CheckpointError(f'checkpoint {str(path)!r} has format {found!r}; expected {CHECKPOINT_FORMAT!r}')
    missing = [key for key in REQUIRED if key not in data]
    if missing:
        raise CheckpointError(f'checkpoint {str(path)!r} lacks {missing}')
    meta = data['meta']
    if not isinstance(meta, dict):
        raise CheckpointError(f"checkpoint {str(path)!r} is corrupt: its 'meta' entry is a {type(meta).__name__}, not a dict")
    expect = expect or {}
    for key in sorted(expect, key=lambda k: (k not in FLAGS, list(FLAGS).index(k) if k in FLAGS else 0)):
        found, value = meta.get(key, META_DEFAULTS.get(key)), expect[key]
        if found != value:
            raise CheckpointError(f'checkpoint {str(path)!r} does not match this experiment: '
                                  f'{describe_difference(key, found, value)}')
    return data


FLAGS = {'team': '--team', 'env_id': '--config', 'algo': 'the algorithm', 'hrl': '--hrl',
         'joint_selection': '--selection', 'comm': '--comm', 'actor': '--actor', 'lstm': '--lstm',
         'full_observability': '--full-observability', 'memory': '--memory', 'velocity': '--velocity',
         'credit': '--credit', 'frame_skip': '--frame-skip', 'levels': 'levels', 'message_dropout': '--message-dropout',
         'communication_range': '--communication-range', 'message_delay': '--message-delay'}
"""Metadata a run's flags decide, in the order a mismatch is reported (the cause before derived sizes such as
`num_actions`), with the flag that sets each."""


def describe_difference(key: str, saved, wanted) -> str:
    """One phrase saying how a checkpoint's `key` (`saved`) differs from this run's (`wanted`), by the flag
    that sets it: 'trained with --hrl; this run is without it', 'trained with --memory 25; this run has
    --memory 0', 'trained for MATE-4v8-9-v0; this run plays MATE-8v8-9-v0'."""
    flag = FLAGS.get(key)
    if key == 'env_id':
        return f'trained for {saved}; this run plays {wanted} (--config)'
    if key == 'team':
        return f'trained for the {saved} team; this run trains the {wanted} team (--team)'
    if key == 'algo':
        return f'trained by {saved}; this run is {wanted}'
    if flag is None or not flag.startswith('--'):
        return f'{key} is {saved!r} in the checkpoint, {wanted!r} here'
    if isinstance(saved, bool) or isinstance(wanted, bool):
        return f'trained with {flag}; this run is without it' if saved else f'trained without {flag}; this run has it'
    trained = f'trained without {flag}' if saved is None else f'trained with {flag} {saved}'
    return trained + ('; this run is without it' if wanted is None else f'; this run has {flag} {wanted}')
