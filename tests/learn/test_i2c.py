"""I2C (mate.policies.comm, mate.learn.i2c): causal-influence labels and their median threshold on hand-made Q-values,
the prior's mask, the regulariser over actions, training, checkpoints and what the trainer refuses, the command
line, and deployed agents (batched, and single agents that ask and answer through the env's channel computing what
the training network computes)."""

from __future__ import annotations

import math

import pytest
import torch

import mate
from mate.learn import tarmac
from mate.policies.checkpoint import CheckpointError, load_checkpoint
from mate.policies.comm import (I2CActor, I2CTraining, InfluenceThreshold, JointActionValue, causal_influence,
                             cyclic_teammates, policy_correlation)
from mate.learn.i2c import I2CConfig, policy_spec, train
from mate.policies.policy import make_actor
from mate.policies.spec import PolicySpec


# ---------------------------------------------------------------------------- labels and threshold

def test_causal_influence_on_a_hand_made_q():
    """One agent, one teammate, two actions each, tau 0.1. Case 1: Q = 0.1 [[1, 0], [0, 1]] (my best action
    copies the teammate's), teammate played 0: p_full = softmax(1, 0) = (e, 1) / (e + 1); marginalising the
    teammate gives log(e + 1) for both of my actions: p_marg = (1/2, 1/2). Case 2: Q = 0.1 [[1, 1], [0, 0]]
    (the teammate does not matter): p_marg = p_full, KL 0."""
    tables = torch.tensor([[[1.0, 0.0], [0.0, 1.0]], [[1.0, 1.0], [0.0, 0.0]]]) * 0.1     # [case, a_i, a_j]
    own = tables[:, :, 0]                                                                # the teammate played 0
    kl = causal_influence(own[:, None, :], tables[:, None, None], temperature=0.1)       # (case, N=1, K=1)
    p = math.e / (math.e + 1)
    by_hand = p * math.log(2 * p) + (1 - p) * math.log(2 * (1 - p))
    assert kl.shape == (2, 1, 1)
    assert kl[0, 0, 0].item() == pytest.approx(by_hand, rel=1e-5) and by_hand > 0.05
    assert kl[1, 0, 0].item() == pytest.approx(0.0, abs=1e-7)


def _table_q(signals: I2CTraining) -> None:
    """Make the joint action-value networks of N = 2 agents, 2 actions, state dim 1 compute Q_i = 0.1 [a_i = a_j]
    exactly: ReLU units h_x = relu(teammate one-hot_x + own one-hot_x - 1) on [s, teammate one-hot, own one-hot],
    Q = 0.1 (h_0 + h_1)."""
    net = signals.value.net
    with torch.no_grad():
        net.weights[0].copy_(torch.tensor([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 0.0], [0.0, 1.0]]).expand(2, 5, 2))
        net.biases[0].fill_(-1.0)
        net.weights[1].fill_(0.1)
        net.biases[1].zero_()


def test_labels_from_the_joint_action_values_and_the_median_of_the_buffer():
    signals = I2CTraining(2, 1, 2, hidden=(2,), activation='relu', temperature=0.1, capacity=4, chunk=2)
    _table_q(signals)
    # three decisions; agent 0 is influenced by agent 1 as in case 1 above (KL by hand), and so is agent 1
    state, actions = torch.zeros(3, 1), torch.tensor([[0, 0], [1, 0], [1, 1]])
    labels, kl = signals.labels(state, actions)
    p = math.e / (math.e + 1)
    by_hand = p * math.log(2 * p) + (1 - p) * math.log(2 * (1 - p))
    torch.testing.assert_close(kl, torch.full((3, 2, 1), by_hand))
    assert labels.all()                                                    # all equal to their median

    # the FIFO keeps the last `capacity` values; the threshold is their median (mean of the middle two)
    buffer = InfluenceThreshold(capacity=4)
    assert buffer.labels(torch.tensor([0.1, 0.5, 0.2])).tolist() == [False, True, True]     # median 0.2
    assert buffer.threshold() == pytest.approx(0.2)
    assert buffer.labels(torch.tensor([0.9, 0.05, 0.3])).tolist() == [True, False, True]    # of 0.2 0.9 0.05 0.3
    assert buffer.threshold() == pytest.approx(0.25)
    assert int(buffer.count) == 4 and sorted(buffer.values.tolist()) == pytest.approx([0.05, 0.2, 0.3, 0.9])


def test_joint_action_values_enumerate_own_and_paired_actions_consistently():
    torch.manual_seed(0)
    q = JointActionValue(3, 6, 4, hidden=(8,))
    state, actions = torch.randn(5, 6), torch.randint(0, 4, (5, 3))
    own = q.own_action_values(state, actions)                                    # (5, N, A)
    torch.testing.assert_close(own.gather(-1, actions[..., None])[..., 0], q(state, actions))
    paired = q.paired_action_values(state, actions)                              # (5, N, K, A own, A mate)
    mates = cyclic_teammates(actions[..., None])[..., 0]                         # (5, N, K) teammates' actions
    observed = paired.gather(-1, mates[..., None, None].expand(5, 3, 2, 4, 1))[..., 0]
    torch.testing.assert_close(observed, own[:, :, None, :].expand(5, 3, 2, 4))
    assert cyclic_teammates(torch.arange(3)[:, None])[..., 0].tolist() == [[1, 2], [2, 0], [0, 1]]


# ---------------------------------------------------------------------------- the prior's mask

def _actor(agents=3, obs_dim=5, seed=0) -> I2CActor:
    torch.manual_seed(seed)
    actor = I2CActor(agents, obs_dim, 4, hidden=(8,), lstm=6, message=7)
    with torch.no_grad():       # non-zero biases: attending to the zero key alone gives a message of its own
        for layer in (actor.query, actor.key, actor.value, actor.attended, actor.message):
            layer.biases[0].normal_()
    return actor


def test_the_prior_mask_removes_unselected_teammates():
    actor = _actor()
    obs = torch.randn(2, 3, 5)                                                   # B=2, N=3
    teammates = cyclic_teammates(obs)                                            # (2, 3, K=2, 5)
    selected = torch.tensor([[True, False], [True, True], [False, False]]).expand(2, 3, 2)
    message = actor.messages(obs, teammates, selected)
    moved = teammates.clone()
    moved[:, 0, 1] += 3.0                                                        # agent 0's unselected slot
    moved[:, 2] += 3.0                                                           # everything agent 2 could read
    again = actor.messages(obs, moved, selected)
    torch.testing.assert_close(again[:, 0], message[:, 0])
    torch.testing.assert_close(again[:, 2], message[:, 2])
    moved[:, 0, 0] += 3.0                                                        # agent 0's selected slot
    assert (actor.messages(obs, moved, selected)[:, 0] - message[:, 0]).abs().max() > 1e-3
    # none selected: all the weight on the zero key, whose value is zero after the projections
    weights = actor.attention_weights(obs, teammates, selected)
    torch.testing.assert_close(weights[:, 2], torch.tensor([0.0, 0.0, 1.0]).expand(2, 3))
    torch.testing.assert_close(weights.sum(-1), torch.ones(2, 3))
    alone = actor.message(actor.attended(torch.zeros(2, 3, 5)))[:, 2]
    torch.testing.assert_close(message[:, 2], alone)
    assert alone.abs().max() > 1e-3


def test_the_actor_reads_only_the_teammates_its_prior_asks():
    """Agent 0's prior asks nobody, agent 1's asks everyone: agent 0's decision does not depend on its
    teammates' observations, agent 1's does; the prior decides from the agent's own observation."""
    actor = _actor()
    with torch.no_grad():
        actor.prior.weights[-1].zero_()
        actor.prior.biases[-1][:] = torch.tensor([[-1.0], [1.0], [1.0]])
    obs = torch.randn(1, 3, 5, requires_grad=True)
    assert (actor.request_logits(obs) >= 0).tolist() == [[[False, False], [True, True], [True, True]]]
    logits, _ = actor.step(obs, actor.initial_state(1, 3))
    grad_0 = torch.autograd.grad(logits[0, 0].sum(), obs, retain_graph=True)[0]
    grad_1 = torch.autograd.grad(logits[0, 1].sum(), obs)[0]
    assert grad_0[0, 1:].abs().max() == 0 and grad_0[0, 0].abs().max() > 0
    assert grad_1[0, 0].abs().max() > 0 and grad_1[0, 2].abs().max() > 0
    # one agent's row with its own replies equals its row of the team computation (deployment)
    row, _ = actor.step(obs[:, 1:2].detach(), actor.initial_state(1, 1),
                        teammates=cyclic_teammates(obs.detach())[:, 1:2], agents=torch.tensor([1]))
    torch.testing.assert_close(row[:, 0], logits[:, 1].detach())


def test_sequences_equal_steps_with_episode_starts_inside():
    actor = _actor(seed=1)
    obs = torch.randn(5, 2, 3, 5)
    starts = torch.zeros(5, 2, dtype=torch.bool)
    starts[2, 1] = True
    state = tuple(torch.randn_like(part) for part in actor.initial_state(2, 3))
    logits = actor(obs, state, starts)
    stepped, memory = [], state
    for t in range(5):
        keep = (~starts[t]).float()[:, None, None]
        out, memory = actor.step(obs[t], tuple(part * keep for part in memory))
        stepped.append(out)
    torch.testing.assert_close(logits, torch.stack(stepped))


def test_the_unrolled_lstm_computes_what_indexing_each_decision_computes_forward_and_backward():
    """`I2CActor.forward` takes the sequence's input gates apart with `unbind` (one gradient stacked at the end);
    its logits and every parameter's gradient are bitwise those of the unroll that indexed `gates[t]` at each
    decision (whose backward added T zero-padded gradients of the whole sequence)."""
    from mate.policies.networks import restarted

    actor = _actor(seed=2)
    obs = torch.randn(6, 3, 3, 5)
    starts = torch.zeros(6, 3, dtype=torch.bool)
    starts[3, 0] = True
    state = tuple(torch.randn_like(part) for part in actor.initial_state(3, 3))

    def indexed():
        features = actor.features(obs)
        gates, hidden, memory = actor.cell.input_gates(features), [], state
        for t in range(obs.shape[0]):
            memory = actor.cell.recur(gates[t], restarted(memory, starts[t]))
            hidden.append(memory[0])
        return actor.head(torch.cat([features, torch.stack(hidden)], dim=-1))

    results = []
    for run in (lambda: actor(obs, state, starts), indexed):
        actor.zero_grad()
        logits = run()
        (logits * torch.linspace(-1, 1, logits.numel()).reshape(logits.shape)).sum().backward()
        results.append((logits.detach(), [p.grad for p in actor.parameters()]))   # (the prior's: None, no path)
    (logits, grads), (expected, expected_grads) = results
    assert torch.equal(logits, expected)
    assert actor.cell.input_weight.grad is not None and sum(g is not None for g in grads) > 10
    assert all((g is None and e is None) or torch.equal(g, e) for g, e in zip(grads, expected_grads))


# ---------------------------------------------------------------------------- the regulariser

def test_the_regulariser_is_a_kl_over_the_actions():
    torch.manual_seed(0)
    values = torch.randn(6, 2, 4)                                                # (T, N, A)
    shifts = torch.randn(6, 2, 1) * 5                                            # per (time, agent) constants
    matched = policy_correlation(values / 0.1 + shifts, values, temperature=0.1)
    assert matched.shape == (6, 2) and matched.abs().max() < 1e-5               # pi = softmax(Q / tau): KL 0
    logits = torch.randn(6, 2, 4)
    by_hand = (torch.softmax(logits, -1) * (torch.log_softmax(logits, -1)
                                            - torch.log_softmax(values / 0.1, -1))).sum(-1)
    torch.testing.assert_close(policy_correlation(logits, values, 0.1), by_hand)
    # the original's axis (time) would not vanish on a matched policy
    over_time = (torch.softmax(values / 0.1 + shifts, 0) * (torch.log_softmax(values / 0.1 + shifts, 0)
                                                             - torch.log_softmax(values / 0.1, 0))).sum(0)
    assert over_time.abs().max() > 1e-2
    # in the loss: it moves the policy, not the Q-networks (they learn from the regression only)
    signals = I2CTraining(2, 3, 4, hidden=(8,))
    logits.requires_grad_(True)
    _, regulariser = signals.losses(logits, torch.randn(6, 3), torch.randint(0, 4, (6, 2)), torch.randn(6, 2))
    regulariser.backward()
    assert logits.grad.abs().max() > 0
    assert all(p.grad is None for p in signals.parameters())


# ---------------------------------------------------------------------------- training, checkpoints, play

def _config(run_dir, **changes) -> I2CConfig:
    """A tiny I2C run of the 4 targets of MATE-2v4-0."""
    return I2CConfig(**{**dict(team='target', config='MATE-2v4-0', num_envs=4, rollout_length=4, steps=2 * 4 * 4,
                               epochs=1, hidden=(16,), lstm=16, seed=0, threads=1, influence_samples=6,
                               run_dir=str(run_dir), progress=False), **changes})


def test_i2c_checkpoints_resume_and_refuse_another_trainer(tmp_path):
    rows = []
    assert train(_config(tmp_path), callback=rows.append).last_row['env_steps'] == 32
    assert {'q_loss', 'prior_loss', 'regulariser', 'edges', 'influence_threshold'} <= set(rows[-1])
    assert 0 <= rows[-1]['edges'] <= 3 and rows[-1]['q_loss'] > 0
    data = load_checkpoint(tmp_path / 'checkpoint.pt')
    networks = data['state']['networks']
    assert data['algo'] == 'mappo-i2c' and data['spec']['network'] == 'i2c'
    assert set(networks) == {'actor', 'critic', 'value_norm', 'comm_training'}
    first = next(v for k, v in networks['critic'].items() if k.endswith('weight'))
    assert first.shape[1] == data['spec']['state_dim']                         # no messages in its critic
    assert int(networks['comm_training']['threshold.count']) == 2 * 6 * 4 * 3   # iterations x rows x N x K
    resumed = train(_config(tmp_path, steps=3 * 4 * 4))
    assert resumed.iteration == 3
    networks = load_checkpoint(tmp_path / 'checkpoint.pt')['state']['networks']
    assert int(networks['comm_training']['threshold.count']) == 3 * 6 * 4 * 3
    with pytest.raises(CheckpointError, match='trained by mappo-i2c; this run is mappo-tarmac'):
        tarmac.train(tarmac.TarMACConfig(team='target', config='MATE-2v4-0', num_envs=4, rollout_length=4,
                                         steps=4 * 4 * 4, epochs=1, hidden=(16,), lstm=16, run_dir=str(tmp_path),
                                         progress=False))
    policy = load_checkpoint(tmp_path / 'final.pt')                            # a policy file: the spec's actor
    actor = make_actor(PolicySpec.from_dict(policy['spec']))
    actor.load_state_dict(policy['actor'])
    assert isinstance(actor, I2CActor) and actor.num_agents == 4


def test_i2c_policies_play_batched_and_as_agents(tmp_path):
    from mate.policies.policy import PolicyTeam, load_policy
    from mate.teams import make_team, play_batch

    train(_config(tmp_path))
    policy = load_policy(tmp_path / 'final.pt', 'target')
    assert isinstance(policy.actor, I2CActor) and policy.comm == 'i2c' and policy.recurrent
    torch.testing.assert_close(policy.actor.state_dict()['head.weights.0'],
                               load_checkpoint(tmp_path / 'final.pt')['actor']['head.weights.0'])
    targets = PolicyTeam(policy, 'target', 2, (2, 4, 0), seed=0)
    results, _ = play_batch('MATE-2v4-0', lambda b, c: make_team('greedy', 'camera', b, c, seed=0), targets,
                            episodes=2, max_episode_steps=30)
    assert [r.episode_length for r in results] == [30, 30]
    assert targets.memory[0].shape == (2, 4, 16) and targets.memory[0].abs().sum() > 0

    from mate.cli.main import main      # `mate evaluate` plays it: single agents through the channel, and batched
    for batched in ([], ['--batched']):
        assert main(['evaluate', '--config', 'MATE-2v4-0', '--target-agent', f'checkpoint:{tmp_path / "final.pt"}',
                     '--episodes', '1', '--max-episode-steps', '12', '--no-render', *batched]) == 0


def test_i2c_trains_flat_cameras(tmp_path):
    run = train(_config(tmp_path, team='camera', num_envs=2, rollout_length=3, steps=2 * 3))
    assert run.last_row['env_steps'] == 6 and math.isfinite(run.last_row['prior_loss'])
    spec = load_checkpoint(tmp_path / 'final.pt')['spec']
    assert (spec['team'], spec['network'], spec['action'], spec['num_agents']) == ('camera', 'i2c', 'grid', 2)


def test_i2c_refuses_what_it_does_not_support(tmp_path):
    with pytest.raises(TypeError, match='critic'):                 # MAPPO only: the critic is not an option
        I2CConfig(critic='local')
    for option, message in ((dict(team='camera', hrl=True), 'I2C needs the flat discrete actions; --hrl does not '
                                                             'combine with it'),
                            (dict(team='camera', memory=25), 'I2C exchanges raw observations; --memory does not'),
                            (dict(team='camera', velocity=True), 'I2C exchanges raw observations; --velocity does not'),
                            (dict(influence_samples=0), '--influence-samples must be an integer >= 1')):
        with pytest.raises(ValueError, match=message):
            _config(tmp_path, **option)
    assert not any(tmp_path.iterdir())                                           # refused before anything ran
    spec = policy_spec(I2CConfig())
    assert (spec.network, spec.lstm, spec.action, spec.algo) == ('i2c', 256, 'grid', 'mappo-i2c')


def _command_error(capsys, *arguments) -> str:
    """The first line of what `mate train ARGUMENTS` says on stderr when it refuses them (exit status 2)."""
    from mate.cli.main import main

    with pytest.raises(SystemExit) as exit_info:
        main(['train', *arguments])
    assert exit_info.value.code == 2
    return capsys.readouterr().err.splitlines()[0]


def test_mate_train_i2c(tmp_path, capsys):
    from mate.cli.main import main

    run_dir = tmp_path / 'run'
    assert main(['train', 'i2c', '--team', 'target', '--config', 'MATE-2v4-0', '--lstm', '8', '--steps', '8',
                 '--num-envs', '2', '--rollout-length', '4', '--epochs', '1', '--threads', '1', '--run-dir',
                 str(run_dir), '--no-progress']) == 0
    assert 'i2c network, LSTM 8' in ' '.join(capsys.readouterr().out.split())
    assert load_checkpoint(run_dir / 'final.pt')['spec']['network'] == 'i2c'
    assert 'I2C needs the flat discrete actions; --hrl does not combine with it' in _command_error(capsys, 'i2c',
                                                                                                   '--hrl')
    assert 'unrecognized arguments: --critic local' in _command_error(capsys, 'i2c', '--team', 'target', '--critic',
                                                                      'local')


# ---------------------------------------------------------------------------- deployment through the channel

@pytest.fixture(scope='module')
def target_policy(tmp_path_factory):
    """A small, nearly untrained I2C policy of the 4 targets of MATE-2v4-0 (one iteration), as a checkpoint."""
    run = tmp_path_factory.mktemp('i2c-targets')
    train(_config(run, num_envs=2, rollout_length=2, steps=2 * 2))
    return run / 'final.pt'


def _play_targets(path, wrappers=(), steps=22, frame_skip=3):
    """Single I2C targets (argmax) driven by `mate.group_step` against greedy cameras. At every decision each
    agent must act as its row of `I2CActor.step` fed the replies that reached it (zeros for the others);
    without wrappers that is the training computation, one step of the team on its N observations.
    Returns (requests delivered, requests the priors made, replies delivered, decisions); requests and replies
    are those of the decision steps, `late` counts messages delivered at other steps (a delay wrapper)."""
    from .deployment import policy_targets_against_greedy

    env, policy, targets, cameras, (camera_obs, target_obs), (camera_infos, target_infos) = \
        policy_targets_against_greedy(path, wrappers, frame_skip)
    actor = policy.actor
    N = env.num_targets
    team_memory, rows_memory = actor.initial_state(1, N), actor.initial_state(N)
    requests = asked = replies = decisions = late = 0
    for step in range(steps):
        camera_action = mate.group_step(env, cameras, camera_obs, camera_infos)
        target_action = mate.group_step(env, targets, target_obs, target_infos)
        if step % frame_skip == 0:
            processed = torch.as_tensor(policy.features(target_obs), dtype=torch.float32)      # (N, D)
            arrived = torch.zeros(N, N - 1, processed.shape[-1])
            with torch.no_grad():
                selected = actor.request_logits(processed) >= 0                              # (N, K)
            for i, agent in enumerate(targets):
                requests += sum(1 for m in agent.last_requests if m.content == {'i2c': None})
                for message in agent.last_responses:
                    replies += 1
                    slot = (message.sender - i - 1) % N
                    if selected[i, slot]:                # (only the asked answer, unless a delay mixes steps)
                        reply = torch.as_tensor(policy.features(message.content['i2c']), dtype=torch.float32)
                        torch.testing.assert_close(reply, processed[message.sender]) if not wrappers else None
                        arrived[i, slot] = reply
            with torch.no_grad():
                asked += int(selected.sum())
                logits, rows_memory = actor.step(processed, rows_memory, teammates=arrived,
                                                 agents=torch.arange(N))
                if not wrappers:
                    team_logits, team_memory = actor.step(processed[None], team_memory)
                    torch.testing.assert_close(team_logits[0], logits, rtol=0, atol=1e-5)
            assert [int(a._held[0]) for a in targets] == logits.argmax(-1).tolist(), step
            for i, agent in enumerate(targets):
                torch.testing.assert_close(agent._memory[0][0], rows_memory[0][i], rtol=0, atol=1e-5)
                torch.testing.assert_close(agent._memory[1][0], rows_memory[1][i], rtol=0, atol=1e-5)
            decisions += 1
        else:
            late += sum(len(a.last_requests) + len(a.last_responses) for a in targets)
        (camera_obs, target_obs), _, _, _, (camera_infos, target_infos) = env.step((camera_action, target_action))
    if not wrappers:
        assert late == 0                                 # nobody asks between decisions
    return (requests, asked, replies, decisions) + ((late,) if wrappers else ())


def test_single_agents_ask_and_answer_through_the_env_channel_as_in_training(target_policy):
    requests, asked, replies, decisions = _play_targets(target_policy)
    assert decisions == 8 and asked > 0
    assert requests == asked == replies                  # every selected teammate asked, and it answered
    requests, asked, replies, decisions = _play_targets(target_policy, frame_skip=1, steps=6)
    assert decisions == 6 and requests == asked == replies > 0


@pytest.mark.parametrize('wrapper', [mate.NoCommunication, lambda env: mate.RandomMessageDropout(env, 1.0)])
def test_unanswered_requests_read_as_zeros(target_policy, wrapper):
    requests, asked, replies, _, late = _play_targets(target_policy, wrappers=[wrapper])
    assert requests == replies == late == 0 and asked > 0


def test_each_reply_that_was_lost_reads_as_zeros(target_policy):
    requests, asked, replies, _, _ = _play_targets(target_policy,
                                                   wrappers=[lambda env: mate.RandomMessageDropout(env, 0.5)])
    assert replies < requests < asked


def test_late_replies_are_not_read(target_policy):
    """Delayed by one step, a request reaches its teammate after the asker's decision and the reply comes a step
    later still: every decision reads zeros in the asked slots (the reference gets no reply at a decision)."""
    requests, asked, replies, _, late = _play_targets(target_policy,
                                                      wrappers=[lambda env: mate.ExtraCommunicationDelays(env, 1)])
    assert requests == replies == 0 and asked > 0 and late > asked
