"""RescaledObservation: map every box-bounded observation field onto [-1, 1] and rescale the spaces to match.

The map is `mate.agents.utils.rescale_observation` (per field `2 (v - low) / (high - low) - 1` over the
team's standard observation space; fields bounded only below are shifted, counts and goal bits stay as
they are), which accepts any leading batch axes. Coordinates scale as v / 2000, so this wrapper commutes
with RelativeCoordinates.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from mate.agents.utils import rescale_observation
from mate.messages import Team
from mate.spaces import observation_space_of

from .base import has_wrapper
from .relative_coordinates import PerTeamObservation

__all__ = ['RescaledObservation', 'rescaled_space']


def rescaled_space(team: Team, num_cameras: int, num_targets: int, num_obstacles: int) -> spaces.Box:
    """The team's standard observation Box with `low` and `high` rescaled (bounded fields become [-1, 1])."""
    counts = (num_cameras, num_targets, num_obstacles)
    space = observation_space_of(team, *counts)
    low = rescale_observation(space.low, team, *counts)
    high = rescale_observation(space.high, team, *counts)
    return spaces.Box(low=low, high=high, dtype=np.float64)


class RescaledObservation(PerTeamObservation):
    """Observations rescaled to [-1, 1] field by field, with matching observation spaces.

    Two-team env: sets `camera_observation_space`, `target_observation_space`, the two joint spaces and
    `observation_space`. Single-team env: the own team's spaces, `teammate_observation_space`,
    `teammate_joint_observation_space`, and `observation_space` (the joint Tuple for MultiCamera/MultiTarget,
    the single Box for SingleCamera/SingleTarget). The opponent's spaces are left as they are (the
    opponents are built-in agents that see raw observations).

    Order: anywhere (once), but outside any single-team wrapper (built-in opponents expect raw values);
    EnhancedObservation and SharedFieldOfView must come before it.
    """

    ROLES = frozenset({'converted'})

    def __init__(self, env) -> None:
        super().__init__(env)
        counts = self._counts
        camera_space = rescaled_space(Team.CAMERA, *counts)
        target_space = rescaled_space(Team.TARGET, *counts)
        camera_joint = spaces.Tuple((camera_space,) * counts[0])
        target_joint = spaces.Tuple((target_space,) * counts[1])
        if not self.single_team:
            self.camera_observation_space, self.target_observation_space = camera_space, target_space
            self.camera_joint_observation_space, self.target_joint_observation_space = camera_joint, target_joint
            self.observation_space = spaces.Tuple((camera_joint, target_joint))
            return
        own, own_joint = (camera_space, camera_joint) if self._own_team is Team.CAMERA else (target_space, target_joint)
        prefix = self._own_team.name.lower()
        setattr(self, f'{prefix}_observation_space', own)
        setattr(self, f'{prefix}_joint_observation_space', own_joint)
        self.teammate_observation_space, self.teammate_joint_observation_space = own, own_joint
        self.observation_space = own if has_wrapper(self.env, 'single-agent') else own_joint

    def transform(self, observation, team: Team):
        return rescale_observation(observation, team, *self._counts)
