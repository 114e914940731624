"""Checkpoint and policy files of `mate.learn`: one `torch.save` dict, written atomically, read without unpickling.

Format `mate.learn/2` (`Run`): {'format', 'spec' (`PolicySpec.to_dict()`), 'algo', 'config' (the trainer's config
as a dict), and either 'run' + 'state' (a run's checkpoint: its counters and the algorithm's whole state) or
'actor' (+ 'env_steps', 'note': a policy file: best.pt, final.pt, snapshots, the shipped policies)}.
Numpy arrays travel as tensors tagged `{'__ndarray__': tensor}` (so that the file holds tensors and plain data
only) and come back as arrays. Files are read with `torch.load(weights_only=True)`: nothing else is unpickled.

Files of the first format, `mate.learn/1` (before the policy spec), are no longer read: the error says so.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import torch

from .spec import PolicySpec, SpecError

__all__ = ['CHECKPOINT_FORMAT', 'CheckpointError', 'load_checkpoint', 'pack', 'read_spec', 'save_checkpoint', 'unpack']

CHECKPOINT_FORMAT = 'mate.learn/2'
FORMATS = (CHECKPOINT_FORMAT,)
"""Formats this version reads."""


class CheckpointError(ValueError):
    """A checkpoint that cannot be read, is not a mate.learn checkpoint, or does not fit the experiment."""


def pack(value):
    """`value` with every numpy array (at any depth of dicts, lists and tuples) replaced by a tagged tensor."""
    if isinstance(value, np.ndarray):
        return {'__ndarray__': torch.from_numpy(np.ascontiguousarray(value).copy())}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {k: pack(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [pack(v) for v in value]
    return value


def unpack(value):
    """The inverse of `pack`: tagged tensors back to numpy arrays."""
    if isinstance(value, dict):
        if set(value) == {'__ndarray__'}:
            return value['__ndarray__'].numpy()
        return {k: unpack(v) for k, v in value.items()}
    if isinstance(value, list):
        return [unpack(v) for v in value]
    return value


def save_checkpoint(path, payload: dict) -> Path:
    """Write `payload` (+ the format tag; numpy arrays packed) to `path` via a temporary file and an atomic rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + '.tmp')
    torch.save({'format': CHECKPOINT_FORMAT, **pack(payload)}, tmp)
    os.replace(tmp, path)
    return path


def load_checkpoint(path) -> dict:
    """Read a checkpoint or policy file (numpy arrays unpacked); CheckpointError if it is unreadable or of another
    format."""
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
    if not isinstance(data, dict) or data.get('format') not in FORMATS:
        found = data.get('format') if isinstance(data, dict) else type(data).__name__
        older = ' (the first format, written before policy specs, is no longer read)' if found == 'mate.learn/1' \
            else ''
        raise CheckpointError(f'checkpoint {str(path)!r} has format {found!r}; expected one of {FORMATS}{older}')
    missing = [key for key in ('spec', 'config') if key not in data]
    if missing:
        raise CheckpointError(f'checkpoint {str(path)!r} lacks {missing}')
    return unpack(data)


def read_spec(data: dict, path='') -> PolicySpec:
    """The `PolicySpec` of a loaded checkpoint; CheckpointError if invalid."""
    try:
        return PolicySpec.from_dict(data['spec'])
    except (SpecError, KeyError, TypeError, ValueError) as exc:
        raise CheckpointError(f'checkpoint {str(path)!r} has no valid policy spec: {exc}') from None
