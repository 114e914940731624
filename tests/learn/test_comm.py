"""TarMAC (mate.policies.comm, mate.learn.tarmac): attention over the team's messages, one-decision delay, gradients
through the messages, sequences equal to steps, a toy task that needs communication, the critic reading the
messages, checkpoints, the command line, and deployed agents (batched and single, through the env's channel)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import mate
from mate.learn import mappo_lstm, tarmac
from mate.policies.checkpoint import CheckpointError, load_checkpoint
from mate.policies.comm import TarMACActor
from mate.policies.policy import make_actor
from mate.policies.spec import PolicySpec, SpecError

from .toy import CueExchange


def _actor(obs_dim=5, num_actions=3, seed=0) -> TarMACActor:
    torch.manual_seed(seed)
    return TarMACActor(obs_dim, num_actions, hidden=(16,), lstm=16, key=8, value=8)


def _random_state(actor: TarMACActor, *shape: int):
    h, c, messages = actor.initial_state(*shape)
    return torch.randn_like(h), torch.randn_like(c), torch.rand_like(messages) * 2 - 1


def test_attention_weights_sum_to_one_over_senders_and_equal_keys_are_uniform():
    actor = _actor()
    weights = actor.attention_weights(_random_state(actor, 4, 3))              # (B=4, receivers 3, senders 3)
    assert weights.shape == (4, 3, 3)
    torch.testing.assert_close(weights.sum(-1), torch.ones(4, 3))
    assert weights.std() > 0.01                                                # random keys: not uniform
    h, c, messages = _random_state(actor, 4, 3)
    messages[..., :actor.key_size] = messages[:, :1, :actor.key_size]          # every sender of a row: the same key
    torch.testing.assert_close(actor.attention_weights((h, c, messages)), torch.full((4, 3, 3), 1 / 3))
    # the spec's init: every output row (logits and message units alike) of norm 1
    torch.testing.assert_close(actor.head.weight.norm(dim=1), torch.ones(3 + 16))


def test_a_message_reaches_its_receivers_one_decision_later_and_carries_gradient():
    actor = _actor()
    obs = torch.randn(2, 1, 3, 5, requires_grad=True)                          # T=2 decisions, 1 env, N=3 agents
    logits = actor(obs, actor.initial_state(1, 3), torch.zeros(2, 1, dtype=torch.bool))
    sender, receiver = 0, 2

    def gradient(output, wrt):
        return torch.autograd.grad(output.sum(), wrt, retain_graph=True)[0]

    assert gradient(logits[0, 0, receiver], obs)[0, 0, sender].abs().max() == 0      # same decision: not heard yet
    assert gradient(logits[1, 0, receiver], obs)[0, 0, sender].abs().max() > 0       # heard at the next one
    # the receiver's loss reaches the message units of the head (they feed nothing else at decision 0 -> 1)
    head = gradient(logits[1, 0, receiver], actor.head.weight)
    assert head[actor.num_actions:].abs().sum() > 0
    # an episode start in between: nothing of decision 0 reaches decision 1
    restarted = actor(obs, actor.initial_state(1, 3), torch.tensor([[False], [True]]))
    assert gradient(restarted[1], obs)[0].abs().max() == 0


def test_sequences_equal_steps_with_episode_starts_inside():
    actor = _actor(seed=1)
    obs = torch.randn(6, 3, 2, 5)                                              # T=6, B=3 envs, N=2 agents
    state = _random_state(actor, 3, 2)
    starts = torch.zeros(6, 3, dtype=torch.bool)                               # one flag per env
    starts[0, 1] = True
    starts[2, 2] = starts[4, 2] = True                                         # env 2: two starts in the window
    logits = actor(obs, state, starts)
    stepped, memory = [], state
    for t in range(6):
        keep = (~starts[t]).float()[:, None, None]
        out, memory = actor.step(obs[t], tuple(part * keep for part in memory))
        stepped.append(out)
    torch.testing.assert_close(logits, torch.stack(stepped))
    fresh = actor(obs[4:, 2:], actor.initial_state(1, 2), torch.zeros(2, 1, dtype=torch.bool))
    torch.testing.assert_close(logits[4:, 2:], fresh)                          # env 2 forgot everything at t = 4
    assert len(memory) == 3 and memory[2].shape == (3, 2, 16) and memory[2].abs().max() <= 1


@pytest.mark.slow
@pytest.mark.parametrize('seed', [0, 1])
def test_only_a_communicating_team_solves_cue_exchange(tmp_path, seed):
    """Each agent's own cue is shown only to its teammate: chance (1/4) without messages, at best
    (1/4 + 7) / 8 = 0.91 with them. A recurrent MAPPO actor without messages and a TarMAC actor, same budget."""
    results = {}
    for name, (module, config_class, options) in dict(
            none=(mappo_lstm, mappo_lstm.RecurrentConfig, dict(actor='mlp')),
            tarmac=(tarmac, tarmac.TarMACConfig, {})).items():
        rows = []
        config = config_class(steps=16 * 16 * 25, num_envs=16, rollout_length=16, epochs=4, hidden=(32,), lstm=32,
                              lr_schedule=((0, 3e-3),), entropy_schedule=((0, 0.0),), seed=seed, threads=1,
                              run_dir=str(tmp_path / name), progress=False, **options)
        module.train(config, CueExchange(num_envs=16, num_agents=2, num_actions=4, length=8, seed=seed),
                     callback=rows.append)
        results[name] = [round(r['rollout_coverage'], 3) for r in rows]
    assert np.mean(results['none'][-10:]) < 0.35, results                   # chance: 0.25
    # with the critic reading the messages: 0.75 and 0.59 (seeds 2-5: 0.66-0.83); its critic without them: 0.70-0.77
    assert np.mean(results['tarmac'][-5:]) > 0.55, results


def _targets(run_dir, **changes) -> tarmac.TarMACConfig:
    """A tiny TarMAC run of the 4 targets of MATE-2v4-0."""
    return tarmac.TarMACConfig(**{**dict(team='target', config='MATE-2v4-0', num_envs=4, rollout_length=4,
                                         steps=2 * 4 * 4, epochs=1, hidden=(16,), lstm=16, seed=0, threads=1,
                                         run_dir=str(run_dir), progress=False), **changes})


def test_tarmac_checkpoints_resume_and_refuse_another_trainer(tmp_path):
    assert tarmac.train(_targets(tmp_path)).last_row['env_steps'] == 32
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert saved['algo'] == 'mappo-tarmac' and saved['spec']['network'] == 'tarmac'
    h, c, messages = saved['state']['memory']                          # the memory carried into the next iteration
    assert h.shape == c.shape == (4, 4, 16) and messages.shape == (4, 4, 64)
    resumed = tarmac.train(_targets(tmp_path, steps=3 * 4 * 4))
    assert resumed.last_row['env_steps'] == 48 and resumed.iteration == 3
    with pytest.raises(CheckpointError, match='trained by mappo-tarmac; this run is mappo-lstm'):
        mappo_lstm.train(mappo_lstm.RecurrentConfig(team='target', config='MATE-2v4-0', num_envs=4, rollout_length=4,
                                                    steps=4 * 4 * 4, epochs=1, hidden=(16,), lstm=16,
                                                    run_dir=str(tmp_path), progress=False))
    with pytest.raises(CheckpointError, match='trained by mappo-tarmac; this run is ippo-tarmac'):
        tarmac.train(_targets(tmp_path, critic='local', steps=4 * 4 * 4))
    policy = load_checkpoint(tmp_path / 'final.pt')                    # a policy file: its spec builds the actor
    actor = make_actor(PolicySpec.from_dict(policy['spec']))
    actor.load_state_dict(policy['actor'])
    assert isinstance(actor, TarMACActor) and actor.lstm_size == 16


def test_tarmac_policies_play_batched_and_as_agents(tmp_path):
    from mate.policies.policy import PolicyTargetAgent, PolicyTeam, load_agent, load_policy
    from mate.teams import make_team, play_batch

    tarmac.train(_targets(tmp_path))
    policy = load_policy(tmp_path / 'final.pt', 'target')
    assert isinstance(policy.actor, TarMACActor) and policy.recurrent and policy.communicates
    targets = PolicyTeam(policy, 'target', 2, (2, 4, 0), seed=0)
    results, _ = play_batch('MATE-2v4-0', lambda b, c: make_team('greedy', 'camera', b, c, seed=0), targets,
                            episodes=2, max_episode_steps=30)
    assert [r.episode_length for r in results] == [30, 30]
    messages = targets.memory[2]                                   # the whole team of a row decides together
    assert messages.shape == (2, 4, 64) and messages.abs().sum() > 0

    # single agents play it too (their messages go through the env's channel: the tests below)
    assert PolicyTargetAgent(policy, seed=0).policy is policy
    assert load_agent(f'checkpoint:{tmp_path / "final.pt"}', 'target')(seed=0).policy.communicates


def test_the_spec_builds_tarmac_and_the_config_defaults():
    spec = tarmac.policy_spec(tarmac.TarMACConfig(lstm=8))
    assert (spec.network, spec.lstm, spec.action, spec.algo) == ('tarmac', 8, 'grid', 'mappo-tarmac')  # not per-target
    actor = make_actor(spec)
    assert isinstance(actor, TarMACActor) and actor.lstm_size == 8 and actor.key_size + actor.value_size == 64
    with pytest.raises(SpecError, match="network 'tarmac' needs an LSTM"):
        spec.replace(lstm=0)
    with pytest.raises(SpecError, match='network must be one of'):
        spec.replace(network='commnet')
    assert tarmac.TarMACConfig().lstm == 256 and tarmac.TarMACConfig(lstm=64).lstm == 64
    assert tarmac.policy_spec(tarmac.TarMACConfig(hrl=True)).action == 'hrl'          # HRL selections combine
    with pytest.raises(ValueError, match='--lstm must be an integer >= 1, got 0'):
        tarmac.TarMACConfig(lstm=0)


def _command_error(capsys, *arguments) -> str:
    """The first line of what `mate train ARGUMENTS` says on stderr when it refuses them (exit status 2)."""
    from mate.cli.main import main

    with pytest.raises(SystemExit) as exit_info:
        main(['train', *arguments])
    assert exit_info.value.code == 2
    return capsys.readouterr().err.splitlines()[0]


@pytest.mark.parametrize('algo', ['mappo', 'ippo', 'mappo-lstm'])
def test_tarmac_is_a_trainer_of_its_own(algo, capsys):
    assert 'unrecognized arguments: --comm tarmac' in _command_error(capsys, algo, '--comm', 'tarmac')


def test_mate_train_tarmac(tmp_path, capsys):
    from mate.learn.command import trainer_parser
    from mate.cli.options import config_from

    parser, _, config_class = trainer_parser('tarmac')
    config = config_from(parser, config_class, parser.parse_args(['--team', 'target', '--critic', 'local']))
    assert (config.algo, config.critic, config.lstm) == ('ippo-tarmac', 'local', 256)
    assert 'unrecognized arguments: --actor per-target' in _command_error(capsys, 'tarmac', '--actor', 'per-target')
    from mate.cli.main import main

    run_dir = tmp_path / 'run'
    assert main(['train', 'tarmac', '--team', 'target', '--config', 'MATE-2v4-0', '--lstm', '8', '--steps', '8',
                 '--num-envs', '2', '--rollout-length', '4', '--epochs', '1', '--threads', '1', '--run-dir',
                 str(run_dir), '--no-progress']) == 0
    assert 'tarmac network, LSTM 8' in ' '.join(capsys.readouterr().out.split())
    spec = load_checkpoint(run_dir / 'final.pt')['spec']
    assert (spec['network'], spec['lstm'], spec['algo']) == ('tarmac', 8, 'mappo-tarmac')


# ---------------------------------------------------------------------------- single agents through the channel

@pytest.fixture(scope='module')
def target_policy(tmp_path_factory):
    """A small, nearly untrained TarMAC policy of the 4 targets of MATE-2v4-0 (one iteration), as a checkpoint."""
    run = tmp_path_factory.mktemp('tarmac-targets')
    tarmac.train(_targets(run, num_envs=2, rollout_length=2, steps=2 * 2))
    return run / 'final.pt'


def _reference_step(actor, processed, memory, read):
    """Each receiver's own step with the messages `read` (N receivers, N senders, M): obs (N, 1, D),
    (h, c) (N, 1, lstm); returns logits (N, A) and the new (h, c, messages (N, 1, M))."""
    h, c, _ = memory
    logits, memory = actor.step(processed[:, None], (h, c, read))
    return logits[:, 0], memory


def _play_targets(path, wrappers=(), lag=0, steps=22, frame_skip=3):
    """Single policy targets (argmax) driven by `mate.group_step` against greedy cameras, checked at every
    decision against the network fed the same processed observations of the whole team.

    `lag`: teammates' messages read at decision k are those of decision k - 1 - lag (None: never any;
    'arrived': those that the channel delivered to the receiver since its last decision, by sender).
    lag 0 is the training computation: one `TarMACActor.step` on the team (1, N, D)."""
    from .deployment import policy_targets_against_greedy

    env, policy, targets, cameras, (camera_obs, target_obs), (camera_infos, target_infos) = \
        policy_targets_against_greedy(path, wrappers, frame_skip)
    actor = policy.actor
    N, M = env.num_targets, actor.key_size + actor.value_size
    team_memory = actor.initial_state(1, N)                                # the training computation (lag 0)
    own_memory = actor.initial_state(N, 1)                                 # one receiver per row
    sent, silent, delivered, decisions = [], actor.initial_state(N, 1), 0, 0
    arrived = torch.zeros(N, N, M)                                         # [receiver, sender] this window
    for step in range(steps):
        camera_action = mate.group_step(env, cameras, camera_obs, camera_infos)
        target_action = mate.group_step(env, targets, target_obs, target_infos)
        for i, agent in enumerate(targets):
            for message in agent.last_requests + agent.last_responses:
                if 'tarmac' in message.content:
                    delivered += 1
                    arrived[i, message.sender] = torch.from_numpy(message.content['tarmac'])
        if step % frame_skip == 0:
            processed = torch.as_tensor(policy.features(target_obs), dtype=torch.float32)      # (N, D)
            with torch.no_grad():
                if lag == 0:
                    logits, team_memory = actor.step(processed[None], team_memory)
                    logits, (h, c, messages) = logits[0], tuple(part[0] for part in team_memory)
                else:
                    read = torch.zeros(N, N, M)
                    if lag == 'arrived':
                        read = arrived.clone()
                    elif lag is not None and len(sent) > lag:
                        read[:] = sent[-1 - lag]                            # every receiver: the same senders
                    eye = torch.eye(N, dtype=torch.bool)
                    read[eye] = own_memory[2][:, 0]                         # its own last message, never lost
                    logits, own_memory = _reference_step(actor, processed, own_memory, read)
                    h, c, messages = (part[:, 0] for part in own_memory)
                # what the agents would do without any teammate's message (zeros), from their own state
                read = torch.zeros(N, N, M)
                read[torch.eye(N, dtype=torch.bool)] = silent[2][:, 0]
                _, silent = _reference_step(actor, processed, silent, read)
            sent.append(messages)
            arrived.zero_()
            assert [int(a._held[0]) for a in targets] == logits.argmax(-1).tolist(), step
            for i, agent in enumerate(targets):
                torch.testing.assert_close(agent._memory[0][0], h[i], rtol=0, atol=1e-5)
                torch.testing.assert_close(agent._memory[1][0], c[i], rtol=0, atol=1e-5)
                torch.testing.assert_close(agent._memory[2][0], messages[i], rtol=0, atol=1e-5)
            decisions += 1
            gap = (h - silent[0][:, 0]).abs().max().item()           # > 0 once teammates' messages arrived
        (camera_obs, target_obs), _, _, _, (camera_infos, target_infos) = env.step((camera_action, target_action))
    assert decisions == len(range(0, steps, frame_skip))
    return delivered, gap


def test_single_agents_exchange_messages_through_the_env_channel_as_in_training(target_policy):
    """Targets driven by `group_step` (one broadcast per decision, in the next step's response round)
    compute what one `TarMACActor.step` on the whole team computes, decision after decision."""
    delivered, gap = _play_targets(target_policy, frame_skip=3)
    assert delivered == 4 * 4 * 7            # 7 broadcasts (decisions 0..6 then step 19) of 4 agents to 4 agents
    assert gap > 1e-3                        # the messages matter: zeros instead would give other states
    delivered, gap = _play_targets(target_policy, frame_skip=1, steps=8)
    assert delivered == 4 * 4 * 7 and gap > 1e-3


@pytest.mark.parametrize('wrapper', [mate.NoCommunication, lambda env: mate.RandomMessageDropout(env, 1.0)])
def test_lost_messages_read_as_zeros(target_policy, wrapper):
    delivered, gap = _play_targets(target_policy, wrappers=[wrapper], lag=None)
    assert delivered == 0 and gap == 0


def test_each_teammate_that_was_not_heard_reads_as_zeros(target_policy):
    """Half the copies dropped: every receiver reads exactly the messages that reached it, zeros for the rest."""
    delivered, _ = _play_targets(target_policy, wrappers=[lambda env: mate.RandomMessageDropout(env, 0.5)],
                                 lag='arrived')
    assert 4 * 4 * 7 * 0.25 < delivered < 4 * 4 * 7 * 0.75


def test_a_late_message_is_read_at_the_first_decision_after_it_arrives(target_policy):
    """Sent in the response round of step s + 1 and held 3 steps, a message of decision s reaches its
    teammates at step s + 4, after their decision at s + 3: they read it at s + 6, one decision late."""
    delivered, _ = _play_targets(target_policy, wrappers=[lambda env: mate.ExtraCommunicationDelays(env, 3)],
                                 lag=1, frame_skip=3)
    assert delivered == 4 * 4 * 6            # the 7th broadcast (step 19) is still held at step 21


def test_tarmac_messages_compare_by_value(target_policy):
    from mate.policies.policy import load_agent

    agent = load_agent(f'checkpoint:{target_policy}', 'target')(seed=0)
    env = mate.make('MATE-2v4-0-v0')
    (_, target_obs), _ = env.reset(seed=0)
    agent.reset(target_obs[1])
    agent.act(target_obs[1])
    [message] = agent.send_responses()
    assert agent.send_responses() == ()                                     # once per decision
    vector = message.content['tarmac']
    assert vector.dtype == np.float32 and vector.shape == (64,) and message.recipient is None
    assert vector is not agent._memory[2][0].numpy()                        # a copy, by value
    twin = mate.Message(sender=1, recipient=None, content={'tarmac': vector.copy()}, team=mate.Team.TARGET,
                        broadcasting=True)
    assert message == twin
    twin.content['tarmac'][0] += 0.5
    assert message != twin


# ---------------------------------------------------------------------------- the critic reads the messages

def test_critic_inputs_append_the_messages():
    from mate.learn.ppo_loop import critic_input_dim, critic_inputs

    obs, state, messages = torch.randn(5, 3, 7), torch.randn(5, 11), torch.randn(5, 3, 4)
    mappo = critic_inputs('state', obs, state, messages)
    assert mappo.shape == (5, 11 + 12) and torch.equal(mappo[:, 11:], messages.reshape(5, 12))
    ippo = critic_inputs('local', obs, state, messages)
    assert ippo.shape == (5, 3, 7 + 12) and torch.equal(ippo[:, 2, 7:], messages.reshape(5, 12))
    assert critic_input_dim('state', 7, 11, 12) == 23 and critic_input_dim('local', 7, 11, 12) == 19
    agent = critic_inputs('agent', obs, state, messages)                  # MAPPO-AS: state, own observation, messages
    assert agent.shape == (5, 3, 11 + 7 + 12) and critic_input_dim('agent', 7, 11, 12) == 30
    assert torch.equal(agent[:, 1, :11], state) and torch.equal(agent[:, 1, 11:18], obs[:, 1])
    assert torch.equal(agent[:, 1, 18:], messages.reshape(5, 12))


@pytest.mark.parametrize('critic', ['state', 'local', 'agent'])
def test_tarmac_critic_reads_the_messages(tmp_path, critic):
    tarmac.train(_targets(tmp_path, critic=critic, num_envs=2, rollout_length=3, steps=2 * 3))
    data = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert data['algo'] == {'state': 'mappo-tarmac', 'local': 'ippo-tarmac', 'agent': 'mappo-as-tarmac'}[critic]
    spec = data['spec']
    base = {'state': spec['state_dim'], 'local': spec['obs_dim'], 'agent': spec['state_dim'] + spec['obs_dim']}[critic]
    first = next(v for k, v in data['state']['networks']['critic'].items() if k.endswith('weight'))
    assert first.shape[1] == base + 4 * 64
