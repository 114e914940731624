import pytest
import torch

from mate.learn.checkpoint import load_checkpoint
from mate.learn.networks import Actor, RecurrentActor
from mate.learn.ppo import (
    PPOConfig,
    ValueNormalizer,
    adapt_kl_coeff,
    compute_gae,
    critic_inputs,
    minibatch_rows,
    per_agent,
    ppo_policy_loss,
    sampled_kl,
    train,
)
from mate.learn.schedules import piecewise

from .toy import CueMatching, CueRecall


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


def test_value_normalizer_round_trip():
    norm = ValueNormalizer()
    x = torch.randn(1000) * 7 + 3
    norm.update(x)
    assert float(norm.mean) == pytest.approx(float(x.mean()), rel=1e-3)
    assert torch.allclose(norm.denormalize(norm.normalize(x)), x, atol=1e-4)


def test_actor_head_starts_near_uniform_and_critic_inputs():
    actor = Actor(10, 25)
    logits = actor(torch.randn(5, 10))
    assert logits.abs().max() < 0.1
    obs, state = torch.zeros(3, 4, 10), torch.ones(3, 7)
    assert critic_inputs('mappo', obs, state) is state      # one value per env: the reward is shared
    assert critic_inputs('ippo', obs, state) is obs
    values, local = torch.arange(3.0), torch.randn(3, 4)
    assert torch.equal(per_agent('mappo', values, 4), values[:, None].expand(3, 4))
    assert per_agent('ippo', local, 4) is local


@pytest.mark.parametrize('algo', ['mappo', 'ippo'])
def test_tiny_run_improves_return(tmp_path, algo):
    rows = []
    config = PPOConfig(algo=algo, actor='mlp', total_steps=16 * 16 * 12, num_envs=16, rollout_length=16, epochs=4,
                       hidden=(32,), lr_schedule=((0, 3e-3),), entropy_schedule=((0, 0.0),), seed=1)
    train(config, tmp_path, progress=False, callback=rows.append,
          envs=CueMatching(num_envs=16, num_agents=2, num_actions=4))
    first, last = rows[0]['rollout_coverage'], rows[-1]['rollout_coverage']
    assert first < 0.45                  # random: 0.25 of the agents match their cue
    assert last > 0.8, [round(r['rollout_coverage'], 3) for r in rows]
    assert (tmp_path / 'progress.csv').read_text().count('\n') == len(rows) + 1


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


def test_kl_penalty_adapts_during_training_and_is_logged(tmp_path):
    """With a tiny target the measured KL stays above it, so the coefficient grows by 1.5 every
    iteration; the row reports the coefficient the iteration used, the checkpoint the next one."""
    rows = []
    config = PPOConfig(actor='mlp', total_steps=8 * 8 * 4, num_envs=8, rollout_length=8, epochs=2,
                       hidden=(16,), lr_schedule=((0, 3e-3),), kl_coeff=0.2, kl_target=1e-9, seed=0)
    train(config, tmp_path, progress=False, callback=rows.append,
          envs=CueMatching(num_envs=8, num_agents=2, num_actions=4))
    assert [round(r['kl_coeff'], 6) for r in rows] == [round(0.2 * 1.5 ** i, 6) for i in range(4)]
    assert all(r['approx_kl'] > 0 for r in rows)
    from mate.learn import load_checkpoint
    assert load_checkpoint(tmp_path / 'checkpoint.pt')['kl_coeff'] == pytest.approx(0.2 * 1.5 ** 4)
    off = []
    train(PPOConfig(actor='mlp', total_steps=8 * 8, num_envs=8, rollout_length=8, hidden=(16,), seed=0),
          tmp_path / 'off', progress=False, callback=off.append, envs=CueMatching(num_envs=8, num_agents=2, num_actions=4))
    assert off[0]['kl_coeff'] == 0.0


def test_minibatch_rows_cover_the_rollout_once():
    generator = torch.Generator().manual_seed(0)
    for sequences in (False, True):
        batches = minibatch_rows(5, 8, 4, sequences, generator)
        assert sorted(torch.cat(batches).tolist()) == list(range(40))
    for rows in minibatch_rows(5, 8, 4, True, generator):     # whole sequences, t-major
        envs = rows[:2]
        assert rows.tolist() == [t * 8 + int(e) for t in range(5) for e in envs]


def test_recurrent_actor_resets_its_memory_at_episode_starts():
    torch.manual_seed(0)
    actor = RecurrentActor(Actor(3, 4, hidden=(8,), context_extra=6), lstm=6)
    obs = torch.randn(4, 2, 3)                                   # T=4 steps, 2 rows
    state = (torch.randn(2, 6), torch.randn(2, 6))
    starts = torch.tensor([[False, False], [False, True], [False, False], [False, False]])
    logits = actor(obs, state, starts)
    fresh = actor(obs[1:, 1:], actor.initial_state(1), torch.zeros(3, 1, dtype=torch.bool))
    assert torch.allclose(logits[1:, 1:], fresh, atol=1e-6)     # row 1 restarted at t=1: old memory gone
    step_by_step, memory = [], state
    for t in range(4):
        keep = (~starts[t]).float()[:, None]
        out, memory = actor.step(obs[t], (memory[0] * keep, memory[1] * keep))
        step_by_step.append(out)
    assert torch.allclose(logits, torch.stack(step_by_step), atol=1e-6)


def test_recurrent_actor_sequences_equal_steps_with_several_episode_starts():
    torch.manual_seed(1)
    actor = RecurrentActor(Actor(5, 3, hidden=(8,), context_extra=4), lstm=4)
    obs = torch.randn(6, 3, 2, 5)                                  # T=6 steps, 3 envs x 2 agents
    state = (torch.randn(3, 2, 4), torch.randn(3, 2, 4))
    starts = torch.zeros(6, 3, dtype=torch.bool)                   # one flag per env, shared by its agents
    starts[0, 1] = True                                            # env 1 starts fresh at t = 0
    starts[2, 2] = starts[4, 2] = True                             # env 2: two short episodes inside the window
    logits = actor(obs, state, starts)
    step_by_step, memory = [], state
    for t in range(6):
        keep = (~starts[t]).float()[:, None, None]
        out, memory = actor.step(obs[t], (memory[0] * keep, memory[1] * keep))
        step_by_step.append(out)
    assert torch.allclose(logits, torch.stack(step_by_step), atol=1e-6)
    logits.sum().backward()                                        # the fused path is differentiable
    assert actor.lstm.weight_hh_l0.grad is not None and actor.lstm.weight_hh_l0.grad.abs().sum() > 0


@pytest.mark.parametrize('lstm', [0, 32])
def test_only_a_recurrent_actor_solves_cue_recall(tmp_path, lstm):
    rows = []
    config = PPOConfig(algo='mappo', actor='mlp', total_steps=16 * 16 * 30, num_envs=16, rollout_length=16, epochs=4,
                       hidden=(32,), lr_schedule=((0, 3e-3),), entropy_schedule=((0, 0.0),), seed=1, lstm=lstm)
    train(config, tmp_path, progress=False, callback=rows.append,
          envs=CueRecall(num_envs=16, num_agents=2, num_actions=4, length=8))
    best = max(r['rollout_coverage'] for r in rows[-5:])
    memoryless_bound = (1 + 7 / 4) / 8                          # 0.34: the cue is shown once per episode
    if lstm:
        assert best > 0.6, [round(r['rollout_coverage'], 3) for r in rows]
    else:
        assert best < memoryless_bound + 0.08, [round(r['rollout_coverage'], 3) for r in rows]


def test_time_limit_stops_training_early(tmp_path):
    rows = []
    config = PPOConfig(algo='mappo', actor='mlp', total_steps=10 ** 9, num_envs=4, rollout_length=4, epochs=1,
                       hidden=(8,), time_limit=0.5, seed=0)
    row = train(config, tmp_path, progress=False, callback=rows.append, envs=CueMatching(num_envs=4))
    assert row['wall_seconds'] < 30 and row['env_steps'] < config.total_steps and rows[-1] == row
    # the budget is checked before every iteration: every iteration but the last started (and so ended) before it
    # was spent (logged to 0.01 s); on a busy machine the first iteration alone may spend it (one row)
    assert all(earlier['wall_seconds'] <= 0.51 for earlier in rows[:-1])
    # the last row ends after the budget is spent, which the checkpoint records
    assert load_checkpoint(tmp_path / 'checkpoint.pt')['wall_seconds'] >= 0.5
    # resuming a run whose budget is spent trains no further
    assert train(config, tmp_path, progress=False, envs=CueMatching(num_envs=4)) == {}
