"""MateWrapper attribute forwarding, chain inspection, WrapperSpec / mate.make, and the ordering rules
(spec §8.1-8.2, §9)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from wrapper_scene import NC, NT, make_env

import mate
from mate.wrappers import WrapperOrderError, find_wrapper, has_wrapper, iter_env_chain


class Foreign(gym.Wrapper):
    """A plain Gymnasium wrapper (no attribute forwarding of its own)."""


def test_forwarding_reaches_the_base_env_through_foreign_wrappers():
    env = make_env()
    wrapped = mate.RepeatedRewardIndividualDone(Foreign(mate.MoreTrainingInformation(env)))
    base = env.unwrapped
    assert wrapped.num_cameras == NC and wrapped.num_targets == NT
    np.testing.assert_array_equal(wrapped.camera_target_view_mask, base.camera_target_view_mask)
    assert wrapped.send_messages.__self__ is base
    assert wrapped.episode_step == base.episode_step
    with pytest.raises(AttributeError):
        getattr(wrapped, '_world')  # noqa: B009  (private names are never forwarded)
    with pytest.raises(AttributeError, match='no attribute'):
        getattr(wrapped, 'no_such_attribute')  # noqa: B009


def test_wrapper_attributes_shadow_inner_ones():
    env = make_env(wrappers=[mate.WrapperSpec(mate.DiscreteCamera, levels=3)])
    outer = mate.RepeatedRewardIndividualDone(env)
    assert outer.camera_action_space == gym.spaces.Discrete(9)        # from DiscreteCamera, not the base env
    assert outer.levels == 3


def test_chain_helpers_and_str():
    env = make_env(wrappers=[mate.EnhancedObservation, mate.WrapperSpec(mate.DiscreteCamera, levels=5)])
    chain = list(iter_env_chain(env))
    assert [type(e).__name__ for e in chain] == ['DiscreteCamera', 'EnhancedObservation', 'MultiAgentTracking']
    assert has_wrapper(env, mate.EnhancedObservation) and not has_wrapper(env, mate.MultiCamera)
    assert find_wrapper(env, mate.EnhancedObservation) is env.env
    assert str(env) == ('<DiscreteCamera(levels=5)<EnhancedObservation(team=both)<MultiAgentTracking>'
                        '(2 cameras, 3 targets, 2 obstacles)>>')


def test_wrapper_spec_and_make_apply_innermost_first():
    spec = mate.WrapperSpec(mate.NoCommunication, team='camera')
    env = make_env(wrappers=[mate.MoreTrainingInformation, spec, mate.RepeatedRewardIndividualDone])
    assert isinstance(env, mate.RepeatedRewardIndividualDone)
    assert isinstance(env.env, mate.NoCommunication) and env.env.team == 'camera'
    assert isinstance(env.env.env, mate.MoreTrainingInformation)
    with pytest.raises(TypeError):
        mate.WrapperSpec(42)


# (wrappers, error type, text the message must contain)
WRONG_ORDERS = [
    (lambda: [mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyTargetAgent(seed=0)),
              mate.EnhancedObservation], WrapperOrderError, 'EnhancedObservation must be applied before MultiCamera'),
    (lambda: [mate.RelativeCoordinates, mate.EnhancedObservation], WrapperOrderError,
     'EnhancedObservation must be applied before RelativeCoordinates'),
    (lambda: [mate.RescaledObservation, mate.SharedFieldOfView], WrapperOrderError,
     'SharedFieldOfView must be applied before RescaledObservation'),
    (lambda: [mate.WrapperSpec(mate.MultiTarget, camera_agent=mate.GreedyCameraAgent(seed=0)),
              mate.MoreTrainingInformation], WrapperOrderError,
     'MoreTrainingInformation must be applied before MultiTarget'),
    (lambda: [mate.MoreTrainingInformation, mate.MoreTrainingInformation], WrapperOrderError, 'only once'),
    (lambda: [mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyTargetAgent(seed=0)), mate.DiscreteCamera],
     WrapperOrderError, 'DiscreteCamera must be applied before MultiCamera'),
    (lambda: [mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyTargetAgent(seed=0)), mate.DiscreteTarget],
     WrapperOrderError, 'DiscreteTarget must be applied before MultiCamera'),
    (lambda: [mate.DiscreteCamera, mate.DiscreteCamera], WrapperOrderError, 'only once'),
    (lambda: [mate.DiscreteTarget, mate.DiscreteTarget], WrapperOrderError, 'only once'),
    (lambda: [mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyTargetAgent(seed=0)),
              mate.WrapperSpec(mate.MultiTarget, camera_agent=mate.GreedyCameraAgent(seed=0))],
     WrapperOrderError, 'MultiTarget must be applied before MultiCamera'),
    (lambda: [mate.WrapperSpec(mate.SingleCamera, other_camera_agent=mate.GreedyCameraAgent(seed=0),
                               target_agent=mate.GreedyTargetAgent(seed=0)), mate.RepeatedRewardIndividualDone],
     WrapperOrderError, 'RepeatedRewardIndividualDone must be applied before SingleCamera'),
    (lambda: [mate.RepeatedRewardIndividualDone, mate.RepeatedRewardIndividualDone], WrapperOrderError, 'only once'),
    (lambda: [mate.WrapperSpec(mate.AuxiliaryCameraRewards, coefficients={'baseline': 1})], WrapperOrderError,
     'AuxiliaryCameraRewards needs RepeatedRewardIndividualDone to be applied before it'),
    (lambda: [mate.WrapperSpec(mate.AuxiliaryTargetRewards, coefficients={'baseline': 1})], WrapperOrderError,
     'AuxiliaryTargetRewards needs RepeatedRewardIndividualDone to be applied before it'),
    (lambda: [mate.WrapperSpec(mate.MultiTarget, camera_agent=mate.GreedyCameraAgent(seed=0)),
              mate.RepeatedRewardIndividualDone, mate.WrapperSpec(mate.AuxiliaryCameraRewards, coefficients={})],
     WrapperOrderError, 'AuxiliaryCameraRewards must be applied before MultiTarget'),
    (lambda: [mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyTargetAgent(seed=0)),
              mate.RepeatedRewardIndividualDone, mate.WrapperSpec(mate.AuxiliaryTargetRewards, coefficients={})],
     WrapperOrderError, 'AuxiliaryTargetRewards must be applied before MultiCamera'),
    (lambda: [mate.RepeatedRewardIndividualDone, mate.WrapperSpec(mate.AuxiliaryCameraRewards, coefficients={}),
              mate.WrapperSpec(mate.AuxiliaryCameraRewards, coefficients={})], WrapperOrderError, 'only once'),
    (lambda: [mate.RelativeCoordinates, mate.RelativeCoordinates], WrapperOrderError, 'only once'),
    (lambda: [mate.RescaledObservation, mate.RescaledObservation], WrapperOrderError, 'only once'),
    (lambda: [mate.WrapperSpec(mate.EnhancedObservation, team='cameras')], ValueError, "invalid team 'cameras'"),
    (lambda: [mate.WrapperSpec(mate.DiscreteCamera, levels=4)], ValueError, 'odd integer >= 3'),
    (lambda: [mate.WrapperSpec(mate.DiscreteTarget, levels=1)], ValueError, 'odd integer >= 3'),
    (lambda: [mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyCameraAgent(seed=0))], TypeError,
     'target_agent must be a TargetAgentBase'),
    (lambda: [mate.WrapperSpec(mate.SingleTarget, other_target_agent=mate.GreedyCameraAgent(seed=0),
                               camera_agent=mate.GreedyCameraAgent(seed=0))], TypeError,
     'other_target_agent must be a TargetAgentBase'),
    (lambda: [mate.RepeatedRewardIndividualDone,
              mate.WrapperSpec(mate.AuxiliaryCameraRewards, coefficients={'bounty': 1.0})], ValueError, 'unknown keys'),
    (lambda: [mate.RepeatedRewardIndividualDone,
              mate.WrapperSpec(mate.AuxiliaryCameraRewards, coefficients={}, reduction='median')], ValueError,
     'invalid reduction'),
    (lambda: [mate.WrapperSpec(mate.MessageFilter, filter=None)], TypeError, 'filter must be callable'),
    (lambda: [mate.WrapperSpec(mate.RandomMessageDropout, dropout_rate=1.5)], ValueError, 'dropout_rate'),
    (lambda: [mate.WrapperSpec(mate.ExtraCommunicationDelays, delay=0)], ValueError, 'delay must be'),
    (lambda: [mate.WrapperSpec(mate.RenderCommunication, duration=0)], ValueError, 'duration'),
    (lambda: [mate.WrapperSpec(mate.NoCommunication, team='all')], ValueError, "invalid team 'all'"),
]


@pytest.mark.parametrize('wrappers, error, text', WRONG_ORDERS)
def test_wrong_orders_and_arguments_raise(wrappers, error, text):
    with pytest.raises(error, match=text.replace('(', r'\(').replace(')', r'\)')):
        make_env(wrappers=wrappers())


def test_order_error_says_how_to_fix():
    with pytest.raises(WrapperOrderError) as info:
        make_env(wrappers=[mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyTargetAgent(seed=0)),
                           mate.SharedFieldOfView])
    message = str(info.value)
    assert 'put SharedFieldOfView earlier in the wrappers list' in message and 'than MultiCamera' in message


def test_allowed_orders():
    greedy = mate.GreedyTargetAgent(seed=0)
    for wrappers in (
        [mate.WrapperSpec(mate.MultiCamera, target_agent=greedy), mate.RepeatedRewardIndividualDone],
        [mate.RepeatedRewardIndividualDone, mate.WrapperSpec(mate.MultiCamera, target_agent=greedy)],
        [mate.RepeatedRewardIndividualDone, mate.WrapperSpec(mate.MultiCamera, target_agent=greedy),
         mate.WrapperSpec(mate.AuxiliaryCameraRewards, coefficients={'baseline': 1.0})],
        [mate.WrapperSpec(mate.MultiCamera, target_agent=greedy), mate.RelativeCoordinates, mate.RescaledObservation],
        [mate.NoCommunication, mate.WrapperSpec(mate.MultiCamera, target_agent=greedy), mate.NoCommunication],
    ):
        make_env(wrappers=wrappers)


def test_non_mate_environment_is_rejected():
    with pytest.raises(TypeError, match='wraps a MATE environment'):
        mate.EnhancedObservation(gym.make('CartPole-v1'))


def test_gymnasium_make_accepts_wrappers():
    env = gym.make('MATE-2v2-9-v0', wrappers=[mate.RepeatedRewardIndividualDone,
                                               mate.WrapperSpec(mate.DiscreteCamera, levels=3)])
    env.reset(seed=0)
    _, (camera_rewards, target_rewards), *_ = env.step(env.action_space.sample())
    assert len(camera_rewards) == 2 and camera_rewards[0] == -target_rewards[0]
