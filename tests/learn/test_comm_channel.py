"""Training under a perturbed channel (mate.policies.comm.Channel; the `message_dropout` / `communication_range` /
`message_delay` options of mate.learn.tarmac and mate.learn.i2c): what a receiver reads when a delivery is lost, the
masks' draws, the update's replay of the rollout's masks, the range test on positions, the settings in the
checkpoint and the command's errors."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mate.constants import PRESERVED_DIM
from mate.learn import i2c, tarmac
from mate.policies.checkpoint import CheckpointError, load_checkpoint
from mate.policies.comm import Channel, I2CActor, TarMACActor, channel_difference, check_channel, cyclic_teammates
from mate.learn.mappo import MAPPOConfig

from .toy import CueExchange


def _tarmac(seed=0) -> TarMACActor:
    torch.manual_seed(seed)
    return TarMACActor(5, 3, hidden=(16,), lstm=16, key=8, value=8)


def _tarmac_state(actor: TarMACActor, b: int, n: int):
    h, c, messages = actor.initial_state(b, n)
    return torch.randn_like(h), torch.randn_like(c), torch.rand_like(messages) * 2 - 1


def _i2c(seed=0) -> I2CActor:
    torch.manual_seed(seed)
    actor = I2CActor(3, 5, 4, hidden=(8,), lstm=6, message=7)
    with torch.no_grad():       # every agent asks both teammates (so that their replies matter)
        actor.prior.weights[-1].zero_()
        actor.prior.biases[-1].fill_(1.0)
    return actor


def _receiver_view(state, receiver: int, delivered: torch.Tensor):
    """The TarMAC state of one receiver as a deployment agent holds it: its own message, the delivered ones,
    zeros for the others (`delivered` (B, N, N))."""
    h, c, messages = state
    kept = messages * delivered[:, receiver, :, None]
    return h[:, receiver:receiver + 1], c[:, receiver:receiver + 1], kept


def _assert_rows_read_their_deliveries(actor, obs, state, delivered):
    logits, (h, c, message) = actor.step(obs, state, delivered=delivered)
    for i in range(obs.shape[1]):
        alone, (h_i, c_i, m_i) = actor.step(obs[:, i:i + 1], _receiver_view(state, i, delivered))
        torch.testing.assert_close(logits[:, i:i + 1], alone)
        torch.testing.assert_close(h[:, i:i + 1], h_i)
        torch.testing.assert_close(message[:, i:i + 1], m_i)
    return logits


# ---------------------------------------------------------------------------- what a receiver reads

def test_tarmac_dropout_one_reads_zeros_from_teammates_and_its_own_message():
    actor = _tarmac()
    obs, state = torch.randn(2, 3, 5), _tarmac_state(actor, 2, 3)
    delivered = Channel(1.0).delivered((2, 3), generator=torch.Generator().manual_seed(0))
    assert torch.equal(delivered, torch.eye(3, dtype=torch.bool).expand(2, 3, 3))       # its own message only
    logits = _assert_rows_read_their_deliveries(actor, obs, state, delivered)
    # the same as the team step on messages that are zero except on each receiver's own row
    h, c, messages = state
    for i in range(3):
        zeroed = torch.zeros_like(messages)
        zeroed[:, i] = messages[:, i]
        torch.testing.assert_close(logits[:, i], actor.step(obs, (h, c, zeroed))[0][:, i])
    # the teammates' messages did matter
    assert (logits - actor.step(obs, state)[0]).abs().max() > 1e-3
    torch.testing.assert_close(actor.attention_weights(state, delivered).sum(-1), torch.ones(2, 3))


def test_tarmac_partial_masks_read_exactly_the_delivered_messages():
    actor = _tarmac(1)
    obs, state = torch.randn(4, 3, 5), _tarmac_state(actor, 4, 3)
    delivered = Channel(0.5).delivered((4, 3), generator=torch.Generator().manual_seed(3))
    assert not delivered.all() and (delivered | torch.eye(3, dtype=torch.bool)).all(-1).any()
    _assert_rows_read_their_deliveries(actor, obs, state, delivered)
    # the unroll with masks equals the steps with the same masks, and a lost message gets no gradient
    sequence = torch.randn(3, 4, 3, 5)
    starts = torch.zeros(3, 4, dtype=torch.bool)
    masks = Channel(0.5).delivered((12, 3), generator=torch.Generator().manual_seed(4)).reshape(3, 4, 3, 3)
    stepped, memory = [], state
    for t in range(3):
        out, memory = actor.step(sequence[t], memory, delivered=masks[t])
        stepped.append(out)
    torch.testing.assert_close(actor(sequence, state, starts, delivered=masks), torch.stack(stepped))
    messages = state[2].clone().requires_grad_(True)
    only = torch.eye(3, dtype=torch.bool).expand(4, 3, 3).clone()
    only[:, 0, 1] = True                                     # receiver 0 hears sender 1; sender 2 reaches nobody
    logits, _ = actor.step(obs, (state[0], state[1], messages), delivered=only)
    grad = torch.autograd.grad(logits[:, 0].sum(), messages)[0]
    assert grad[:, 1].abs().max() > 0 and grad[:, 2].abs().max() == 0


def test_i2c_lost_replies_are_zero_observations_in_the_asked_slots():
    actor = _i2c()
    obs, state = torch.randn(2, 3, 5), actor.initial_state(2, 3)
    assert (actor.request_logits(obs) >= 0).all()
    nothing = Channel(1.0, legs=2).delivered((2, 3), generator=torch.Generator().manual_seed(0))
    lost, _ = actor.step(obs, state, delivered=nothing)
    torch.testing.assert_close(lost, actor.step(obs, state, teammates=torch.zeros(2, 3, 2, 5))[0])
    assert (lost - actor.step(obs, state)[0]).abs().max() > 1e-4                         # the replies mattered
    # a partial mask: agent i's slot k (teammate (i + 1 + k) mod 3) holds its observation iff delivered[i, j]
    delivered = torch.tensor([[True, False, True], [True, True, True], [False, True, True]]).expand(2, 3, 3)
    teammates = cyclic_teammates(obs).clone()
    for i in range(3):
        for k in range(2):
            if not delivered[0, i, (i + 1 + k) % 3]:
                teammates[:, i, k] = 0.0
    torch.testing.assert_close(actor.step(obs, state, delivered=delivered)[0],
                               actor.step(obs, state, teammates=teammates)[0])
    sequence, starts = torch.randn(3, 2, 3, 5), torch.zeros(3, 2, dtype=torch.bool)
    masks = delivered.expand(3, 2, 3, 3)
    stepped, memory = [], state
    for t in range(3):
        out, memory = actor.step(sequence[t], memory, delivered=masks[t])
        stepped.append(out)
    torch.testing.assert_close(actor(sequence, state, starts, delivered=masks), torch.stack(stepped))


# ---------------------------------------------------------------------------- the masks

def test_channel_masks_are_reproducible_by_seed_and_drop_at_the_given_rate():
    channel = Channel(0.5)
    first = channel.delivered((200, 4), generator=torch.Generator().manual_seed(7))
    again = channel.delivered((200, 4), generator=torch.Generator().manual_seed(7))
    other = channel.delivered((200, 4), generator=torch.Generator().manual_seed(8))
    assert torch.equal(first, again) and not torch.equal(first, other)
    assert first.diagonal(dim1=-2, dim2=-1).all()
    off = ~torch.eye(4, dtype=torch.bool)
    assert abs(float(first[:, off].float().mean()) - 0.5) < 0.05
    # I2C: the request and the reply each get through with probability 1 - P
    both = Channel(0.5, legs=2).delivered((200, 4), generator=torch.Generator().manual_seed(7))
    assert abs(float(both[:, off].float().mean()) - 0.25) < 0.05
    assert Channel(0.0).delivered((2, 3)) is None and not Channel().active


def test_range_delivers_within_the_limit_on_hand_placed_positions():
    positions = np.array([[[0.0, 0.0], [1.5, 0.0], [0.0, 3.0]],
                          [[0.0, 0.0], [2.0, 0.0], [9.0, 9.0]]])                 # 2 envs, 3 agents
    delivered = Channel(range_limit=2.0).delivered((2, 3), positions)
    assert delivered.tolist() == [[[True, True, False], [True, True, False], [False, False, True]],
                                  [[True, True, False], [True, True, False], [False, False, True]]]  # 2.0 apart: in
    actor = _tarmac(2)
    obs, state = torch.randn(2, 3, 5), _tarmac_state(actor, 2, 3)
    logits = _assert_rows_read_their_deliveries(actor, obs, state, delivered)
    h, c, messages = state
    far = messages.clone()
    far[:, 2] = 0.0
    torch.testing.assert_close(logits[:, 0], actor.step(obs, (h, c, far))[0][:, 0])     # 0 reads 1, not 2
    assert (logits[:, 0] - actor.step(obs, (h, c, messages.clone().index_fill_(1, torch.tensor([1]), 0.0)))[0][:, 0]
            ).abs().max() > 1e-4                                                        # 1's message mattered to 0
    # combined with dropout: never more than the range allows
    both = Channel(0.3, 2.0).delivered((2, 3), positions, torch.Generator().manual_seed(0))
    assert not (both & ~delivered).any()


@pytest.mark.parametrize('team', ['target', 'camera'])
def test_team_env_positions_are_the_agents_own_positions(team):
    from mate.learn.envs import TeamEnvConfig

    config = TeamEnvConfig(team=team, config='MATE-2v4-0', num_envs=2, seed=0)
    envs = config.make_env(config.policy_spec())
    envs.reset(seed=1)
    envs.step(np.zeros((2, envs.num_agents), dtype=np.int64) + 3)
    positions = envs.positions()
    assert positions.shape == (2, envs.num_agents, 2)
    np.testing.assert_allclose(positions, envs.raw_observations[..., PRESERVED_DIM:PRESERVED_DIM + 2], atol=1e-4)
    assert np.ptp(positions[0, :, 0]) > 1.0


# ---------------------------------------------------------------------------- in training

class PlacedCueExchange(CueExchange):
    """CueExchange with fixed agent positions on a line (x = 0, 1, 5, ...)."""

    def positions(self):
        x = np.array([0.0, 1.0, 5.0, 6.0])[:self.num_agents]
        return np.broadcast_to(np.stack([x, np.zeros_like(x)], -1), (self.num_envs, self.num_agents, 2)).copy()


TRAINERS = {'tarmac': (tarmac.train, tarmac.TarMACConfig), 'i2c': (i2c.train, i2c.I2CConfig)}


def _train(run_dir, comm='tarmac', envs=None, callback=None, **options):
    """A tiny run of `comm` on `envs` (default: `_envs()`); returns the `Run`."""
    train, config_class = TRAINERS[comm]
    config = config_class(**{**dict(steps=2 * 4 * 4, num_envs=4, rollout_length=4, epochs=1, minibatches=2,
                                    hidden=(16,), lstm=8, seed=0, threads=1, run_dir=str(run_dir), progress=False),
                             **options})
    return train(config, envs or _envs(), callback=callback)


def _envs(agents=3):
    return PlacedCueExchange(num_envs=4, num_agents=agents, num_actions=4, length=3, seed=0)


def test_dropout_zero_is_no_option_and_a_dropout_changes_training(tmp_path):
    weights = {}
    for name, extra in (('off', {}), ('zero', dict(message_dropout=0.0)), ('half', dict(message_dropout=0.5))):
        _train(tmp_path / name, **extra)
        weights[name] = load_checkpoint(tmp_path / name / 'final.pt')['actor']
    # (a dropout of 0 is the same run, bitwise; a dropout of 0.5 moves the weights by ~3e-3)
    gap = lambda other: max(float((weights['off'][k] - weights[other][k]).abs().max()) for k in weights['off'])
    assert gap('zero') == 0 and gap('half') > 1e-4, (gap('zero'), gap('half'))


@pytest.mark.parametrize('comm, extra', [('tarmac', dict(message_dropout=0.5)), ('i2c', dict(message_dropout=0.5)),
                                         ('tarmac', dict(communication_range=2.0)),
                                         ('i2c', dict(communication_range=2.0))])
def test_the_update_replays_the_rollouts_masks(tmp_path, comm, extra):
    """Learning rate 0: the log-probabilities the update recomputes equal the rollout's (KL 0, up to float32's
    rounding: a forward pass of another batch size may sum in another order, 1e-9 measured) only if the unroll reads
    the same messages as the rollout did."""
    rows = []
    _train(tmp_path, comm, callback=rows.append, lr_schedule=((0, 0.0),), **extra)
    assert len(rows) == 2 and all(row['approx_kl'] < 1e-7 and row['clip_fraction'] == 0 for row in rows), rows


def test_an_update_without_the_masks_would_be_caught(tmp_path, monkeypatch):
    forward = TarMACActor.forward
    monkeypatch.setattr(TarMACActor, 'forward', lambda self, obs, state, starts, delivered=None:
                        forward(self, obs, state, starts))
    rows = []
    _train(tmp_path, callback=rows.append, lr_schedule=((0, 0.0),), message_dropout=0.5)
    assert max(row['approx_kl'] for row in rows) > 1e-6, rows


@pytest.mark.parametrize('comm', ['tarmac', 'i2c'])
def test_channel_settings_are_in_the_checkpoint_and_a_resume_refuses_others(tmp_path, comm):
    train, config_class = TRAINERS[comm]
    config = config_class(team='target', config='MATE-2v4-0', num_envs=2, rollout_length=3, steps=2 * 3, epochs=1,
                          hidden=(16,), lstm=8, seed=0, threads=1, message_dropout=0.25, communication_range=400.0,
                          run_dir=str(tmp_path), progress=False)
    assert train(config).last_row['env_steps'] == 6
    saved = load_checkpoint(tmp_path / 'checkpoint.pt')
    assert (saved['config']['message_dropout'], saved['config']['communication_range']) == (0.25, 400.0)
    assert saved['state']['channel']['message_dropout'] == 0.25
    longer = config_class(**{**config.__dict__, 'steps': 2 * 2 * 3})
    assert train(longer).last_row['env_steps'] == 12
    with pytest.raises(CheckpointError,
                       match='trained with --message-dropout 0.25; this run has --message-dropout 0.0'):
        train(config_class(**{**longer.__dict__, 'message_dropout': 0.0}))
    with pytest.raises(CheckpointError, match='trained with --communication-range 400.0; this run is without it'):
        train(config_class(**{**longer.__dict__, 'communication_range': None}))
    assert channel_difference(dict(communication_range=None), dict(communication_range=5.0)) == \
        'trained without --communication-range; this run has --communication-range 5.0'


def test_bad_settings_are_refused(tmp_path):
    with pytest.raises(ValueError, match=r'message_dropout must be a probability in \[0, 1\], got 1.5'):
        check_channel(1.5, None)
    with pytest.raises(ValueError, match=r'communication_range must be a distance > 0'):
        check_channel(0.0, -1.0)
    check_channel(1.0, 0.5)                                                  # the edges are valid
    for config_class in (tarmac.TarMACConfig, i2c.I2CConfig):
        with pytest.raises(ValueError, match=r'--message-dropout must be a probability in \[0, 1\], got 1.5'):
            config_class(message_dropout=1.5)
        with pytest.raises(ValueError, match=r'--communication-range must be a distance > 0'):
            config_class(communication_range=0.0)
        config_class(message_dropout=1.0, communication_range=0.5)          # the edges are valid
    with pytest.raises(TypeError, match='message_dropout'):                 # only the communicating trainers have it
        MAPPOConfig(message_dropout=0.5)
    with pytest.raises(ValueError, match=r"--communication-range needs the agents' positions"):
        _train(tmp_path, envs=CueExchange(num_envs=4, num_agents=3, num_actions=4, length=3, seed=0),
               communication_range=1.0)


def _command_error(capsys, *arguments) -> str:
    """The first line of what `mate train ARGUMENTS` says on stderr when it refuses them (exit status 2)."""
    from mate.cli.main import main

    with pytest.raises(SystemExit) as exit_info:
        main(['train', *arguments])
    assert exit_info.value.code == 2
    return capsys.readouterr().err.splitlines()[0]


@pytest.mark.parametrize('arguments, message', [
    (['tarmac', '--message-dropout', '1.5'], '--message-dropout must be a probability in [0, 1], got 1.5'),
    (['i2c', '--message-dropout', 'nan'], "argument --message-dropout: expected a number, got 'nan'"),
    (['tarmac', '--communication-range', '0'], '--communication-range must be a distance > 0'),
    (['mappo', '--message-dropout', '0.5'], 'unrecognized arguments: --message-dropout 0.5'),
    (['mappo-lstm', '--communication-range', '100'], 'unrecognized arguments: --communication-range 100'),
])
def test_command_errors(arguments, message, capsys):
    assert message in _command_error(capsys, *arguments)


def test_command_options_reach_the_config():
    from mate.learn.command import trainer_parser
    from mate.cli.options import config_from

    def config_of(algo, argv):
        parser, _, config_class = trainer_parser(algo)
        return config_from(parser, config_class, parser.parse_args(argv))

    config = config_of('i2c', ['--team', 'target', '--message-dropout', '0.25', '--communication-range', '300'])
    assert (config.message_dropout, config.communication_range) == (0.25, 300.0)
    default = config_of('tarmac', [])
    assert (default.message_dropout, default.communication_range, default.message_delay) == (0.0, None, 0)


def test_mate_train_under_a_perturbed_channel(tmp_path, capsys):
    from mate.cli.main import main

    run_dir = tmp_path / 'run'
    assert main(['train', 'tarmac', '--team', 'target', '--config', 'MATE-2v4-0', '--lstm', '8', '--steps', '8',
                 '--num-envs', '2', '--rollout-length', '4', '--epochs', '1', '--threads', '1',
                 '--message-dropout', '0.5', '--communication-range', '300', '--run-dir', str(run_dir),
                 '--no-progress']) == 0
    out = ' '.join(capsys.readouterr().out.split())
    assert 'TARMAC-DROPOUT0.5-RANGE300 targets' in out
    config = load_checkpoint(run_dir / 'final.pt')['config']
    assert (config['message_dropout'], config['communication_range']) == (0.5, 300.0)


# ---------------------------------------------------------------------------- delay (TarMAC)

def _delayed(delay: int, seed=5) -> TarMACActor:
    actor = _tarmac(seed)
    actor.delay = delay
    return actor


def test_a_delay_makes_teammates_read_older_messages_and_the_own_message_the_last():
    actor, plain = _delayed(1), _tarmac(5)
    obs = torch.randn(4, 2, 3, 5)                                            # T=4, B=2, N=3
    state = actor.initial_state(2, 3)
    assert len(state) == 4 and state[3].shape == (2, 1, 3, 16)
    sent, memories = [], []
    for t in range(4):
        memories.append(state)
        logits, state = actor.step(obs[t], state)
        sent.append(state[2])
    # at t = 3: receiver i reads its own message of t = 2 and its teammates' of t = 1
    h, c = memories[3][0], memories[3][1]
    for i in range(3):
        read = sent[1].clone()
        read[:, i] = sent[2][:, i]
        torch.testing.assert_close(logits[:, i], plain.step(obs[3], (h, c, read))[0][:, i])
    # a teammate's observation at t reaches a receiver's logits at t + 2, not at t + 1 (its own: at t + 1)
    x = obs.clone().requires_grad_(True)
    out = actor(x, actor.initial_state(2, 3), torch.zeros(4, 2, dtype=torch.bool))
    grad = lambda t, receiver: torch.autograd.grad(out[t, :, receiver].sum(), x, retain_graph=True)[0]
    assert grad(1, 0)[0, :, 1].abs().max() == 0 and grad(2, 0)[0, :, 1].abs().max() > 0
    assert grad(1, 0)[0, :, 0].abs().max() > 0
    # delay 0 is the plain actor; sequences with episode starts inside equal the steps (the queue restarts too)
    torch.testing.assert_close(_delayed(0)(obs, plain.initial_state(2, 3), torch.zeros(4, 2, dtype=torch.bool)),
                               plain(obs, plain.initial_state(2, 3), torch.zeros(4, 2, dtype=torch.bool)))
    from mate.policies.networks import restarted

    starts = torch.tensor([[False, False], [False, True], [True, False], [False, False]])
    start_state = tuple(torch.randn_like(part) for part in actor.initial_state(2, 3))
    stepped, memory = [], start_state
    for t in range(4):
        step_logits, memory = actor.step(obs[t], restarted(memory, starts[t]))
        stepped.append(step_logits)
    torch.testing.assert_close(actor(obs, start_state, starts), torch.stack(stepped))


def test_delay_in_training_replays_and_is_in_the_checkpoint(tmp_path):
    rows = []
    _train(tmp_path, callback=rows.append, lr_schedule=((0, 0.0),), message_delay=2, message_dropout=0.3)
    assert all(row['approx_kl'] < 1e-9 for row in rows), rows
    assert load_checkpoint(tmp_path / 'final.pt')['config']['message_delay'] == 2
    assert len(load_checkpoint(tmp_path / 'checkpoint.pt')['state']['memory']) == 4      # h, c, messages, queue
    with pytest.raises(CheckpointError, match='trained with --message-delay 2; this run has --message-delay 1'):
        _train(tmp_path, message_delay=1, message_dropout=0.3, steps=3 * 4 * 4)
    with pytest.raises(ValueError, match="message_delay is a TarMAC option"):
        check_channel(0.0, None, 'i2c', 1)
    with pytest.raises(ValueError, match='message_delay must be a whole number of decisions >= 0, got -1'):
        check_channel(0.0, None, 'tarmac', -1)
    with pytest.raises(ValueError, match='--message-delay must be a whole number of decisions >= 0, got -1'):
        tarmac.TarMACConfig(message_delay=-1)
    with pytest.raises(TypeError, match='message_delay'):                   # I2C has no delay option
        i2c.I2CConfig(message_delay=1)


@pytest.mark.parametrize('arguments, message', [
    (['tarmac', '--message-delay', '-1'], '--message-delay must be a whole number of decisions >= 0'),
    (['i2c', '--message-delay', '1'], 'unrecognized arguments: --message-delay 1'),
    (['mappo', '--message-delay', '1'], 'unrecognized arguments: --message-delay 1'),
    (['tarmac', '--influence-samples', '8'], 'unrecognized arguments: --influence-samples 8'),
    (['i2c', '--influence-samples', '0'], "argument --influence-samples: expected an integer >= 1, got '0'"),
])
def test_command_delay_errors(arguments, message, capsys):
    assert message in _command_error(capsys, *arguments)
