"""EnhancedObservation: every agent sees every entity (full observability), targets see the true warehouse stock.

The rule is the core's (`mate.core.observability.enhance_observations`, re-exported here with its helpers): one
array function on joint observations with any leading batch axes, `(..., Nc, D_c)` and `(..., Nt, D_t)`, numpy
arrays or tensors, so a vector env and the training envs on either device call it on `(B, N, D)` arrays.
"""

from __future__ import annotations

import numpy as np

from mate.core.observability import (
    TARGET_EMPTY_BITS,
    all_flagged_records,
    empty_warehouses,
    enhance_observations,
    flagged_records,
    public_records,
)

from .base import TeamObservationWrapper

__all__ = ['EnhancedObservation', 'TARGET_EMPTY_BITS', 'all_flagged_records', 'empty_warehouses',
           'enhance_observations', 'flagged_records', 'public_records']

TEAMS = TeamObservationWrapper.TEAMS


class EnhancedObservation(TeamObservationWrapper):
    """Full observability for one or both teams.

    Camera side: every camera sees all targets, all obstacles and all cameras (public states, flag 1).
    Target side: every target sees all cameras, obstacles and targets, and its own `empty_bits` become the
    truth (warehouse w is empty iff it has no cargo left to send). `team='none'` passes through.

    Order: before (inside) any single-team wrapper, RelativeCoordinates and RescaledObservation.
    """

    def observation(self, observation: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The enhanced joint observations (the given arrays, modified in place)."""
        if not (self.for_camera or self.for_target):
            return observation
        camera_obs, target_obs = observation
        base = self.env.unwrapped
        return enhance_observations(camera_obs, target_obs, base.obstacle_states,
                                    empty_warehouses(base.remaining_cargoes), *self._counts,
                                    camera=self.for_camera, target=self.for_target)
