"""The pure pieces the PPO trainers share (mate.learn.ppo): GAE, the clipped loss, the sampled KL and its adaptive
coefficient, value normalisation, schedules, minibatches. The trainers themselves: test_mappo.py and the files
of the recurrent and communicating variants."""

import re

import pytest
import torch

from mate.policies.networks import Actor
from mate.learn.ppo import (
    ValueNormalizer,
    adapt_kl_coeff,
    compute_gae,
    learning_targets,
    minibatch_rows,
    ppo_policy_loss,
    sampled_kl,
)
from mate.learn.schedules import piecewise


def test_gae_matches_hand_computation():
    gamma, lam = 0.9, 0.8
    rewards = torch.tensor([1.0, 2.0, 3.0])
    values = torch.tensor([0.5, 1.0, 1.5])
    dones = torch.tensor([0.0, 1.0, 0.0])      # the episode ends after step 1
    last = torch.tensor(2.0)
    # step 2: delta = 3 + 0.9 * 2 - 1.5 = 3.3;            A2 = 3.3
    # step 1: delta = 2 + 0 - 1.0 = 1.0 (terminal);       A1 = 1.0
    # step 0: delta = 1 + 0.9 * 1.0 - 0.5 = 1.4;          A0 = 1.4 + 0.9 * 0.8 * 1.0 = 2.12
    adv, ret = compute_gae(rewards, values, dones, last, gamma, lam)
    assert adv.tolist() == pytest.approx([2.12, 1.0, 3.3])
    assert ret.tolist() == pytest.approx([2.62, 2.0, 4.8])


def test_gae_lambda_one_is_discounted_return_minus_value():
    rewards = torch.ones(4, 3)
    values = torch.zeros(4, 3)
    adv, _ = compute_gae(rewards, values, torch.zeros(4, 3), torch.zeros(3), 0.5, 1.0)
    assert adv[:, 0].tolist() == pytest.approx([1 + 0.5 + 0.25 + 0.125, 1.75, 1.5, 1.0])


def test_policy_loss_sign_and_clipping():
    old = torch.zeros(2)
    adv = torch.tensor([1.0, -1.0])
    # unchanged policy: loss = -mean(A)
    assert float(ppo_policy_loss(old, old, adv, 0.2)) == pytest.approx(0.0)
    assert float(ppo_policy_loss(old[:1], old[:1], adv[:1], 0.2)) == pytest.approx(-1.0)
    # raising the probability of a positive-advantage action lowers the loss, until the clip at 1 + eps
    up = torch.log(torch.tensor([1.1]))
    assert float(ppo_policy_loss(up, old[:1], adv[:1], 0.2)) == pytest.approx(-1.1)
    far = torch.log(torch.tensor([2.0])).requires_grad_()
    loss = ppo_policy_loss(far, old[:1], adv[:1], 0.2)
    assert float(loss.detach()) == pytest.approx(-1.2)
    loss.backward()
    assert float(far.grad) == 0.0            # clipped: no gradient pushes further
    # negative advantage: a lower ratio is clipped at 1 - eps, a higher one is not
    low = torch.log(torch.tensor([0.5]))
    assert float(ppo_policy_loss(low, old[:1], adv[1:], 0.2)) == pytest.approx(0.8)
    high = torch.log(torch.tensor([1.5]))
    assert float(ppo_policy_loss(high, old[:1], adv[1:], 0.2)) == pytest.approx(1.5)


def test_schedules():
    sched = ((0, 0.05), (100, 0.01), (200, 0.0))
    assert piecewise(sched, 50, True) == pytest.approx(0.03)
    assert piecewise(sched, 50, False) == pytest.approx(0.05)
    assert piecewise(sched, 1000, True) == 0.0


@pytest.mark.parametrize('config, flag, value, message', [
    ('ppo', 'lr_schedule', ((0, 5e-4), (1000, -1e-5)),
     'a learning rate >= 0 (0: the weights stay), got -1e-05 (at step 1000)'),
    ('ppo', 'lr_schedule', ((0, float('nan')),), 'a learning rate >= 0 (0: the weights stay), got nan'),
    ('ppo', 'entropy_schedule', ((0, -0.01),), 'an entropy coefficient >= 0, got -0.01'),
    ('ppo', 'lr_schedule', ((-5, 5e-4),),
     "a step is a decision-step count >= 0 or a share of --steps from '0%' to '100%', got -5"),
    ('ppo', 'lr_schedule', ((0, 5e-4, 3),), 'each point is [step, value], got [0, 0.0005, 3]'),
    ('ppo', 'entropy_schedule', (), 'needs at least one [step, value] point'),
    ('iql', 'epsilon_schedule', ((0, 1.5),), 'an exploration rate in [0, 1], got 1.5'),
    ('iql', 'lr_schedule', ((0, -1e-4),), 'a learning rate >= 0 (0: the weights stay), got -0.0001'),
    ('qmix', 'lr_schedule', ((0, -1e-4),), 'a learning rate >= 0 (0: the weights stay), got -0.0001'),
])
def test_a_schedule_out_of_range_is_refused_naming_the_option_and_the_range(config, flag, value, message):
    from mate.learn.iql import IQLConfig
    from mate.learn.ppo import PPOConfig
    from mate.learn.qmix import QMIXConfig
    make = dict(ppo=PPOConfig, iql=IQLConfig, qmix=QMIXConfig)[config]
    with pytest.raises(ValueError, match='^' + re.escape(f'--{flag.replace("_", "-")}')) as error:
        make(**{flag: value})
    assert message in str(error.value)


def test_value_normalizer_round_trip():
    norm = ValueNormalizer()
    x = torch.randn(1000) * 7 + 3
    norm.update(x)
    assert float(norm.mean) == pytest.approx(float(x.mean()), rel=1e-3)
    assert torch.allclose(norm.denormalize(norm.normalize(x)), x, atol=1e-4)


def test_sampled_kl_estimates_the_exact_kl_and_is_zero_for_the_same_policy():
    old = torch.distributions.Categorical(logits=torch.tensor([2.0, 0.0, -1.0, 0.5]))
    new = torch.distributions.Categorical(logits=torch.tensor([1.0, 0.5, -0.5, 0.0]))
    actions = old.sample((200_000,), )
    estimate = sampled_kl(new.log_prob(actions), old.log_prob(actions))
    exact = torch.distributions.kl_divergence(old, new)
    assert abs(float(estimate) - float(exact)) < 0.01 * float(exact) + 1e-3
    logp = old.log_prob(actions[:10])
    assert float(sampled_kl(logp, logp)) == 0.0
    # differentiable in the new log-probabilities, and pushing them towards the old ones lowers it
    new_logp = new.log_prob(actions[:1000]).clone().requires_grad_()
    loss = sampled_kl(new_logp, old.log_prob(actions[:1000]))
    loss.backward()
    stepped = sampled_kl(new_logp.detach() - 0.1 * new_logp.grad / new_logp.grad.norm(), old.log_prob(actions[:1000]))
    assert float(stepped) < loss.item()


def test_adaptive_kl_rule():
    assert adapt_kl_coeff(0.2, 0.03, 0.01) == pytest.approx(0.3)     # above 2 x target: x1.5
    assert adapt_kl_coeff(0.2, 0.004, 0.01) == pytest.approx(0.1)    # below target / 2: x0.5
    assert adapt_kl_coeff(0.2, 0.01, 0.01) == 0.2
    assert adapt_kl_coeff(0.2, 0.02, 0.01) == 0.2 and adapt_kl_coeff(0.2, 0.005, 0.01) == 0.2


def test_minibatch_rows_cover_the_rollout_once():
    generator = torch.Generator().manual_seed(0)
    for sequences in (False, True):
        batches = minibatch_rows(5, 8, 4, sequences, generator)
        assert sorted(torch.cat(batches).tolist()) == list(range(40))
    for rows in minibatch_rows(5, 8, 4, True, generator):     # whole sequences, t-major
        envs = rows[:2]
        assert rows.tolist() == [t * 8 + int(e) for t in range(5) for e in envs]


def test_actor_head_starts_near_uniform():
    assert Actor(10, 25)(torch.randn(5, 10)).abs().max() < 0.1


def test_learning_targets_are_rows_of_decision_major_gae_standardised_and_normalised():
    """One row per (decision, env), t-major as the update's flattened buffers; the episode end of an env stops its
    bootstrap for every agent; advantages standardised over the rollout; returns in the updated normaliser's units."""
    generator = torch.Generator().manual_seed(0)
    T, B, N = 3, 2, 2
    rewards, values = torch.randn(T, B, N, generator=generator), torch.randn(T, B, N, generator=generator)
    last_values = torch.randn(B, N, generator=generator)
    episode_ends = torch.tensor([[0.0, 1.0], [0.0, 0.0], [1.0, 0.0]])
    norm = ValueNormalizer()
    advantages, returns = learning_targets(rewards, values, episode_ends, last_values, norm, 0.9, 0.8)
    assert advantages.shape == returns.shape == (T * B, N)
    assert float(norm.count) > 1                                                  # updated with this rollout
    assert float(advantages.mean()) == pytest.approx(0.0, abs=1e-6)
    assert float(advantages.std()) == pytest.approx(1.0, abs=1e-5)
    # env 1's episode ended after decision 0: that decision's advantage is its own one-step TD error, for each agent
    raw, raw_returns = compute_gae(rewards, values, episode_ends.unsqueeze(-1).expand(T, B, N), last_values, 0.9, 0.8)
    assert torch.allclose(raw[0, 1], rewards[0, 1] - values[0, 1])
    row = 0 * B + 1                                                               # (t = 0, env 1)
    standardised = (raw - raw.mean()) / (raw.std() + 1e-8)
    assert torch.allclose(advantages[row], standardised[0, 1])
    assert torch.allclose(returns[2 * B + 0], norm.normalize(raw_returns[2, 0]))  # (t = 2, env 0)
