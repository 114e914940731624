"""MATE wrappers: observation, action, reward, single-team and communication layers around `MultiAgentTracking`.

A module a wrapper, except where the original MATE keeps several in one (the single-team wrappers in `single_team`,
the discrete action spaces in `discrete_action_spaces`); all are re-exported here and at package level
(`mate.MultiCamera`, ...).
Apply them with `mate.make(env_id, wrappers=[...])` (first item innermost) or by hand; see docs/wrappers.md
for what each one does and for the ordering rules (a wrong order raises `WrapperOrderError`).
"""

from .auxiliary_camera_rewards import AuxiliaryCameraRewards
from .auxiliary_target_rewards import AuxiliaryTargetRewards
from .base import (
    MateWrapper,
    WrapperOrderError,
    assert_base_environment,
    assert_mate_environment,
    assert_multi_agent_environment,
    find_wrapper,
    has_wrapper,
    iter_env_chain,
)
from .discrete_action_spaces import DiscreteCamera, DiscreteTarget
from .enhanced_observation import EnhancedObservation
from .extra_communication_delays import ExtraCommunicationDelays
from .message_filter import MessageFilter
from .more_training_information import MoreTrainingInformation
from .no_communication import NoCommunication
from .random_message_dropout import RandomMessageDropout
from .relative_coordinates import RelativeCoordinates
from .render_communication import RenderCommunication
from .repeated_reward_individual_done import RepeatedRewardIndividualDone
from .rescaled_observation import RescaledObservation
from .restricted_communication_range import RestrictedCommunicationRange
from .shared_field_of_view import SharedFieldOfView
from .single_team import (
    MultiCamera,
    MultiTarget,
    SingleCamera,
    SingleTarget,
    SingleTeamHelper,
    SingleTeamMultiAgent,
    SingleTeamSingleAgent,
    TeamInfos,
)

__all__ = [
    'AuxiliaryCameraRewards',
    'AuxiliaryTargetRewards',
    'DiscreteCamera',
    'DiscreteTarget',
    'EnhancedObservation',
    'ExtraCommunicationDelays',
    'MateWrapper',
    'MessageFilter',
    'MoreTrainingInformation',
    'MultiCamera',
    'MultiTarget',
    'NoCommunication',
    'RandomMessageDropout',
    'RelativeCoordinates',
    'RenderCommunication',
    'RepeatedRewardIndividualDone',
    'RescaledObservation',
    'RestrictedCommunicationRange',
    'SharedFieldOfView',
    'SingleCamera',
    'SingleTarget',
    'SingleTeamHelper',
    'SingleTeamMultiAgent',
    'SingleTeamSingleAgent',
    'TeamInfos',
    'WrapperOrderError',
    'assert_base_environment',
    'assert_mate_environment',
    'assert_multi_agent_environment',
    'find_wrapper',
    'has_wrapper',
    'iter_env_chain',
]
