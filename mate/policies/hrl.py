"""HRL cameras (the paper's hierarchical cameras): the policy picks a subset of targets, a rule executor aims at it.

High-level action: one keep/ignore bit per target slot, (..., Nt) in {0, 1}. The executor runs at every
raw step on the camera's fresh raw observation:

* valid = selected and currently visible (the camera's own flags);
* no valid target: the action lower bound (-rotation step, -zooming step), a clockwise sweep that
  narrows the view (and so lengthens the sight range);
* otherwise aim at the centroid of the valid targets: rotation = bearing - orientation wrapped to
  (-180, 180], zoom = the greedy camera's desired viewing angle for the centroid's distance - current
  angle; both clipped to the per-step limits.

The spec's learners pick a selection as one of 2^Nt choices (Discrete(256) for 8 targets); `selection_bits`
maps such an index to its bits (bit t of the index keeps target t) and `joint_allowed` lists the choices
that keep only visible targets.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

from ..core.arrays import array_namespace, on_device_of
from ..constants import PRESERVED_DIM
from ..messages import Team
from ..spaces import observation_indices_of
from ..teams.rules import centroid_aim_row

__all__ = ['executor_actions', 'joint_allowed', 'selection_bits', 'target_records']

_OWN = PRESERVED_DIM


def target_records(observation: np.ndarray, num_cameras: int, num_targets: int, num_obstacles: int) -> np.ndarray:
    """The target slots (..., Nt, 5) of raw camera observations (..., D): relative location (2), sight range,
    loaded flag and the visibility flag (index 4)."""
    begin = int(observation_indices_of(Team.CAMERA, num_cameras, num_targets, num_obstacles)[2])
    return observation[..., begin:begin + 5 * num_targets].reshape(observation.shape[:-1] + (num_targets, 5))


def executor_actions(observation, selection, num_cameras: int, num_targets: int, num_obstacles: int):
    """Continuous camera actions (..., 2) float64, in degrees, from raw observations (..., D) and selection bits
    (..., Nt) (1 keeps the slot's target): the module docstring's rule, `mate.teams.rules.centroid_aim_row` for
    every camera, in one compiled loop on the host (numpy arrays, CPU tensors) or one CUDA thread a camera
    (`mate.teams.device.hrl_actions`, tensors on a CUDA device)."""
    begin = int(observation_indices_of(Team.CAMERA, num_cameras, num_targets, num_obstacles)[2])
    tensor = hasattr(observation, 'detach')
    if tensor and observation.device.type == 'cuda':
        import torch

        from ..core.device import from_torch
        from ..teams.device import hrl_actions

        lead = observation.shape[:-1]
        flat = observation.reshape(-1, observation.shape[-1]).contiguous()
        keep = (torch.broadcast_to(selection, (*lead, num_targets)).reshape(-1, num_targets) > 0.5).contiguous()
        out = torch.empty((flat.shape[0], 2), dtype=torch.float64, device=observation.device)
        hrl_actions(from_torch(flat), from_torch(keep), begin, from_torch(out))
        return out.reshape(*lead, 2)
    if tensor:                                      # a CPU tensor: the host loop
        import torch

        return torch.from_numpy(executor_actions(observation.numpy(), np.asarray(selection), num_cameras,
                                                 num_targets, num_obstacles))
    observation = np.asarray(observation)
    lead = observation.shape[:-1]
    flat = np.ascontiguousarray(observation.reshape(-1, observation.shape[-1]))
    keep = np.ascontiguousarray(np.broadcast_to(selection, lead + (num_targets,)).reshape(-1, num_targets) > 0.5)
    out = np.empty((flat.shape[0], 2))
    _aim(flat, keep, begin, num_targets, out)
    return out.reshape(lead + (2,))


@njit(cache=True)
def _aim(observation, keep, begin, num_targets, out):
    """`executor_actions` on (R, D) observations and (R, Nt) bool selections into `out` (R, 2)."""
    for r in range(observation.shape[0]):
        centroid_aim_row(r, observation, keep, begin, num_targets, out)


@functools.cache
def selection_bits(num_targets: int) -> np.ndarray:
    """(2^Nt, Nt) int64, read-only: row k holds the keep bits of selection index k (bit t of k keeps target t)."""
    bits = (np.arange(2 ** num_targets)[:, None] >> np.arange(num_targets)) & 1
    bits.setflags(write=False)
    return bits


@functools.cache
def _choice_indices(num_targets: int) -> tuple[np.ndarray, np.ndarray]:
    """(the 2^Nt choice indices, the powers 2^t of the Nt slots), int64, read-only."""
    constants = (np.arange(2 ** num_targets, dtype=np.int64), np.int64(1) << np.arange(num_targets, dtype=np.int64))
    for array in constants:
        array.setflags(write=False)
    return constants


def joint_allowed(visible):
    """(..., 2^Nt) bool from visibility flags (..., Nt) (numpy, or a tensor on any device): the selections that keep
    only visible targets.

    Selection k keeps only visible targets iff its bits are a subset of the visible ones: k & ~v == 0 for the
    visibility word v = sum_t visible_t 2^t, one integer test per choice (the test of every choice's Nt bits one
    by one that it replaced took 34 ms for the 4,100 cameras of a QMIX update, this 2.7 ms)."""
    if not hasattr(visible, 'shape'):
        visible = np.asarray(visible, dtype=bool)
    xp = array_namespace(visible)
    choices, powers = (on_device_of(c, visible) for c in _choice_indices(visible.shape[-1]))
    word = xp.sum(xp.astype(visible, xp.int64) * powers, axis=-1)                               # (...,)
    return (choices & ~word[..., None]) == 0
