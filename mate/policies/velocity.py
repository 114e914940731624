"""How fast the targets a camera sees are moving (`--velocity`), for learners and their agents.

A camera that holds its decision for k env steps (the paper's frame skip) should aim where a target
will be, not where it is: the greedy rule, snapped to the learner's grid and held for 5 steps, covers
0.584 of the targets; aiming at the target's predicted position at the end of the hold brings it to
0.600 (docs/training.md). A feed-forward policy sees positions only, so this module gives it the motion.

Features per camera and target slot, appended to the processed observation (2 per slot, slot-major):
`[dx, dy]`, the target's displacement over one held decision at its current velocity, `(position now
- position one env step before) * k / scale`, in the units of the rescaled target records (divided by
`scale`, so that `offset + displacement` is where the target will be). Zero when the camera does not
see the target now and one step before (its own observations; no messages needed).
"""

from __future__ import annotations

from ..core.arrays import array_namespace
from .memory import camera_sightings, target_record_scale

__all__ = ['VELOCITY_FEATURES', 'target_displacements']

VELOCITY_FEATURES = 2
"""Columns per target slot: the displacement over one held decision, dx and dy."""


def target_displacements(current, previous, counts, steps: int):
    """(..., N, Nt * 2) float32 features from raw camera observations now and one env step before
    (both (..., N, D), numpy or tensors) of a game with `counts` = (Nc, Nt, No): each seen target's displacement over
    `steps` env steps at its current velocity, rescaled like the target records; 0 where not seen twice."""
    counts = tuple(int(n) for n in counts)
    xp = array_namespace(current)
    scale = target_record_scale(*counts)
    _, seen_now, where_now = camera_sightings(current, *counts)
    _, seen_before, where_before = camera_sightings(previous, *counts)
    both = (seen_now & seen_before)[..., None]
    moved = xp.where(both, (where_now - where_before) * (steps / scale), 0.0)
    return xp.astype(xp.reshape(moved, (*moved.shape[:-2], -1)), xp.float32)
