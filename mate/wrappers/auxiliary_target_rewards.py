"""AuxiliaryTargetRewards: shape each target's reward as a weighted sum of team and individual components."""

from __future__ import annotations

import numpy as np

from mate.constants import TERRAIN_SIZE, TERRAIN_WIDTH
from mate.messages import Team

from .auxiliary_rewards import AuxiliaryRewards
from .base import private_states
from .more_training_information import warehouse_distances

__all__ = ['AuxiliaryTargetRewards', 'normalized_goal_distances', 'target_soft_coverage_scores']

_EMPTY_BITS = slice(10, 14)


def normalized_goal_distances(centre_distances: np.ndarray, goals: np.ndarray, empty_bits: np.ndarray) -> np.ndarray:
    """(..., Nt) distance to where each target should head, divided by 2000.

    Loaded target: the distance to its destination warehouse; unloaded: the nearest warehouse it does not
    believe empty (its own `empty_bits`), or 1000 when it believes all are empty. Distances are
    `max(centre distance - 75, 0)`. centre_distances, empty_bits: (..., Nt, 4); goals: (..., Nt), -1 unloaded.
    """
    distances = warehouse_distances(centre_distances)
    goals = np.asarray(goals)
    believed = ~np.asarray(empty_bits, dtype=bool)
    nearest = np.where(believed, distances, np.inf).min(axis=-1)
    nearest = np.where(believed.any(axis=-1), nearest, TERRAIN_SIZE)
    loaded = np.take_along_axis(distances, np.maximum(goals, 0)[..., None], axis=-1)[..., 0]
    return np.where(goals >= 0, loaded, nearest) / TERRAIN_WIDTH


def target_soft_coverage_scores(scores: np.ndarray, view_mask: np.ndarray) -> np.ndarray:
    """(..., Nt): per target, the sum of S[c, t] over the cameras that see it, or tanh(max_c S[c, t]) when
    none does; -1 (the limit of "no camera anywhere near") when there are no cameras.
    scores, view_mask: (..., Nc, Nt)."""
    view_mask = np.asarray(view_mask, dtype=bool)
    seen = np.where(view_mask, scores, 0.0).sum(axis=-2)
    if scores.shape[-2] == 0:
        return np.full(seen.shape, -1.0)
    return np.where(view_mask.any(axis=-2), seen, np.tanh(scores.max(axis=-2)))


class AuxiliaryTargetRewards(AuxiliaryRewards):
    """Target reward = sum over `coefficients` of coefficient * component, per target.

    Components: `raw_reward`, `coverage_rate`, `real_coverage_rate`, `mean_transport_rate`,
    `normalized_goal_distance` (see `normalized_goal_distances`), `sparse_delivery` (1 on the step the
    target delivers), `soft_coverage_score` (see `mate.wrappers.soft_coverage`), `is_tracked`, `is_colliding`,
    `baseline` (1). `reduction` in {'mean', 'sum', 'max', 'min', 'none'} ('min' is accepted here too; the
    original rejected it). Info keys as for AuxiliaryCameraRewards.

    Order: RepeatedRewardIndividualDone before it; not behind MultiCamera or SingleCamera/SingleTarget; once.
    """

    TEAM = Team.TARGET
    ACCEPTABLE_KEYS = ('raw_reward', 'coverage_rate', 'real_coverage_rate', 'mean_transport_rate',
                       'normalized_goal_distance', 'sparse_delivery', 'soft_coverage_score', 'is_tracked',
                       'is_colliding', 'baseline')

    @classmethod
    def _forbidden_inside(cls) -> type:
        from .single_team import MultiCamera
        return MultiCamera

    def components(self, raw_rewards: np.ndarray) -> dict:
        base = self.env.unwrapped
        count = base.num_targets
        components = {
            'raw_reward': raw_rewards,
            'coverage_rate': np.full(count, base.coverage_rate),
            'real_coverage_rate': np.full(count, base.real_coverage_rate),
            'mean_transport_rate': np.full(count, base.mean_transport_rate),
            'sparse_delivery': base.target_dones.astype(np.float64),
            'soft_coverage_score': np.zeros(count),
            'is_tracked': base.tracked_bits,
            'is_colliding': np.array(base.target_is_colliding),
            'baseline': np.ones(count),
        }
        if 'normalized_goal_distance' in self.coefficients:
            _, targets = private_states(self.env)
            components['normalized_goal_distance'] = normalized_goal_distances(
                base.target_warehouse_distances, base.target_goals, targets[:, _EMPTY_BITS])
        if 'soft_coverage_score' in self.coefficients:
            components['soft_coverage_score'] = target_soft_coverage_scores(
                self._soft_coverage_matrix(), base.camera_target_view_mask)
        return components
