"""mate: a fast, batch-native reimplementation of MATE, the Multi-Agent Tracking Environment.

    import mate
    env = mate.make('MultiAgentTracking-v0')           # MATE-4v8-9 by default
    (camera_obs, target_obs), infos = env.reset(seed=0)
    (camera_obs, target_obs), rewards, terminated, truncated, infos = env.step(env.action_space.sample())

Everything a user of the original MATE finds at package level is re-exported here: constants,
the environment, messages, spaces helpers, agents, group helpers and wrappers.
"""
# ruff: noqa: F401  (this module re-exports the public API)

from .tools.reproducible import pin_kernels as _pin_kernels

_pin_kernels()   # MATE_REPRODUCIBLE=1: before anything imports torch (mate.tools.reproducible)

from . import constants, spaces
from .agents import (AgentBase, CameraAgentBase, CameraStatePrivate, CameraStatePublic, GreedyCameraAgent,
                     GreedyTargetAgent, HeuristicCameraAgent, HeuristicTargetAgent, MixtureCameraAgent,
                     MixtureTargetAgent, NaiveCameraAgent, NaiveTargetAgent, ObstacleState, RandomCameraAgent,
                     RandomTargetAgent, StateBase, TargetAgentBase, TargetStatePrivate, TargetStatePublic,
                     UpperBoundCameraAgent, convert_coordinates, group_act, group_communicate, group_observe,
                     group_reset, group_step, normalize_observation, rescale_observation, split_observation)
from .config import ConfigError, list_presets, read_config
from .constants import *  # noqa: F403  (the original re-exports its constants at package level)
from .core.snapshot import SnapshotError
from .envs.multi_agent_tracking import MultiAgentTracking
from .messages import Message, MessageChannel, Team
from .evaluation.protocol import PolicyScore, score_policy
from .envs.registration import WrapperSpec, make, make_environment, registered_ids
from .envs.single_team_vector import AgentsAsEnvs, SingleTeamVecEnv, make_team_vec
from .spaces import (camera_coordinate_mask_of, camera_observation_indices_of, camera_observation_slices_of,
                     camera_observation_space_of, coordinate_mask_of, observation_indices_of, observation_slices_of,
                     observation_space_of, state_space_of, target_coordinate_mask_of, target_observation_indices_of,
                     target_observation_slices_of, target_observation_space_of)
from .envs.vector import MultiAgentTrackingVectorEnv, TeamReward, make_vec
from .wrappers import (AuxiliaryCameraRewards, AuxiliaryTargetRewards, DiscreteCamera, DiscreteTarget,
                       EnhancedObservation, ExtraCommunicationDelays, MateWrapper, MessageFilter,
                       MoreTrainingInformation, MultiCamera, MultiTarget, NoCommunication, RandomMessageDropout,
                       RelativeCoordinates, RenderCommunication, RepeatedRewardIndividualDone, RescaledObservation,
                       RestrictedCommunicationRange, SharedFieldOfView, SingleCamera, SingleTarget,
                       WrapperOrderError)

from . import learn  # last: it builds on the names above (torch is imported lazily)

from .version import __version__  # noqa: E402
