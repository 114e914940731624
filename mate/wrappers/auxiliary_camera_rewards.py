"""AuxiliaryCameraRewards: shape each camera's reward as a weighted sum of team and individual components."""

from __future__ import annotations

import numpy as np

from mate.messages import Team

from .auxiliary_rewards import AuxiliaryRewards

__all__ = ['AuxiliaryCameraRewards', 'camera_soft_coverage_scores']


def camera_soft_coverage_scores(scores: np.ndarray, view_mask: np.ndarray) -> np.ndarray:
    """(..., Nc): per camera, the sum of S[c, t] over the targets it sees, or tanh(max_t S[c, t]) (in (-1, 0])
    when it sees none (0 with no targets). scores, view_mask: (..., Nc, Nt)."""
    view_mask = np.asarray(view_mask, dtype=bool)
    seen = np.where(view_mask, scores, 0.0).sum(axis=-1)
    if scores.shape[-1] == 0:
        return seen
    return np.where(view_mask.any(axis=-1), seen, np.tanh(scores.max(axis=-1)))


class AuxiliaryCameraRewards(AuxiliaryRewards):
    """Camera reward = sum over `coefficients` of coefficient * component, per camera.

    Components: `raw_reward` (the team reward), `coverage_rate`, `real_coverage_rate`, `mean_transport_rate`
    (lower is better for cameras), `soft_coverage_score` (individual, see `mate.wrappers.soft_coverage`),
    `num_tracked` (targets this camera sees), `baseline` (1). `reduction` in {'mean', 'sum', 'max', 'min',
    'none'}. Info keys per camera: `<key>` (if absent), `auxiliary_reward_<key>`, `reward_coefficient_<key>`,
    `reward`, and `shared_reward` when reduced.

    Order: RepeatedRewardIndividualDone before it; not behind MultiTarget or SingleCamera/SingleTarget; once.
    """

    TEAM = Team.CAMERA
    ACCEPTABLE_KEYS = ('raw_reward', 'coverage_rate', 'real_coverage_rate', 'mean_transport_rate',
                       'soft_coverage_score', 'num_tracked', 'baseline')

    @classmethod
    def _forbidden_inside(cls) -> type:
        from .single_team import MultiTarget
        return MultiTarget

    def components(self, raw_rewards: np.ndarray) -> dict:
        base = self.env.unwrapped
        count = base.num_cameras
        mask = base.camera_target_view_mask
        soft = np.zeros(count)
        if 'soft_coverage_score' in self.coefficients:
            soft = camera_soft_coverage_scores(self._soft_coverage_matrix(), mask)
        return {
            'raw_reward': raw_rewards,
            'coverage_rate': np.full(count, base.coverage_rate),
            'real_coverage_rate': np.full(count, base.real_coverage_rate),
            'mean_transport_rate': np.full(count, base.mean_transport_rate),
            'soft_coverage_score': soft,
            'num_tracked': mask.sum(axis=-1),
            'baseline': np.ones(count),
        }
