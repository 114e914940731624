"""Agents for MATE: base classes, group helpers and the built-in camera and target agents.

    cameras = mate.GreedyCameraAgent(seed=0).spawn(env.num_cameras)
    targets = mate.GreedyTargetAgent(seed=0).spawn(env.num_targets)

Modules: `base` (life cycle, seeding, decoders), `group` (drive a team through a step),
`utils` (observation helpers, state views), `geometry` (degrees, Vector2D) and one module per
built-in family: `random`, `naive`, `greedy`, `heuristic`, `mixture`, and `upper_bound` (a reference
camera that sees the true state). The greedy rules (and the targets' noisy walk) are compiled functions
of `mate.teams.rules`, which the batched teams of `mate.teams` run on B games at once; the upper-bound
rule is `mate.teams.upper_bound.plan`.
"""

from .base import AgentBase, CameraAgentBase, TargetAgentBase
from .geometry import Vector2D
from .greedy import GreedyCameraAgent, GreedyTargetAgent
from .group import group_act, group_communicate, group_observe, group_reset, group_step
from .heuristic import HeuristicCameraAgent, HeuristicTargetAgent
from .mixture import MixtureCameraAgent, MixtureTargetAgent
from .naive import NaiveCameraAgent, NaiveTargetAgent
from .random import RandomCameraAgent, RandomTargetAgent
from .upper_bound import UpperBoundCameraAgent
from .utils import (
    CameraStatePrivate,
    CameraStatePublic,
    ObstacleState,
    StateBase,
    TargetStatePrivate,
    TargetStatePublic,
    convert_coordinates,
    normalize_observation,
    rescale_observation,
    split_observation,
)

__all__ = [
    'AgentBase', 'CameraAgentBase', 'TargetAgentBase',
    'RandomCameraAgent', 'RandomTargetAgent', 'NaiveCameraAgent', 'NaiveTargetAgent',
    'GreedyCameraAgent', 'GreedyTargetAgent', 'HeuristicCameraAgent', 'HeuristicTargetAgent',
    'MixtureCameraAgent', 'MixtureTargetAgent', 'UpperBoundCameraAgent',
    'group_reset', 'group_observe', 'group_communicate', 'group_act', 'group_step',
    'convert_coordinates', 'normalize_observation', 'rescale_observation', 'split_observation',
    'StateBase', 'CameraStatePublic', 'CameraStatePrivate', 'TargetStatePublic', 'TargetStatePrivate',
    'ObstacleState', 'Vector2D',
]
