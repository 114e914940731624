"""Communication wrappers (spec §8.7): MessageFilter, NoCommunication, RandomMessageDropout,
RestrictedCommunicationRange, ExtraCommunicationDelays; RenderCommunication bookkeeping and drawing."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import needs_extra
from wrapper_scene import SCENE, ZERO_ACTION, make_env, set_scene

import mate
from mate import Message, Team


def camera(sender, recipient, content=None):
    return Message(sender=sender, recipient=recipient, content=content, team=Team.CAMERA)


def target(sender, recipient, content=None):
    return Message(sender=sender, recipient=recipient, content=content, team=Team.TARGET)


def delivered(env):
    """(camera, target) lists of (sender, recipient, content) delivered since the last step (from the base env)."""
    return tuple(sorted((m.sender, m.recipient, repr(m.content)) for queue in buffers for m in queue)
                 for buffers in env.unwrapped.message_buffers)


def test_message_filter_routes_then_filters_and_may_edit():
    def keep_and_tag(env, message):
        message.content['seen_by_filter'] = True
        return message.recipient != 2

    env = make_env(wrappers=[mate.WrapperSpec(mate.MessageFilter, filter=keep_and_tag)])
    env.send_messages(target(0, None, {'x': 1}))                 # broadcast: routed into 3 copies, one dropped
    env.send_messages([target(1, 2, {'y': 2})])                  # peer-to-peer to the filtered recipient
    cams, tgts = delivered(env)
    assert cams == [] and [(s, r) for s, r, _ in tgts] == [(0, 0), (0, 1)]
    queue = env.receive_messages(agent_id=(Team.TARGET, 1))
    assert queue[0].content == {'x': 1, 'seen_by_filter': True} and queue[0].broadcasting


def test_message_filters_stack():
    env = make_env(wrappers=[mate.WrapperSpec(mate.MessageFilter, filter=lambda e, m: m.sender != 0),
                             mate.WrapperSpec(mate.MessageFilter, filter=lambda e, m: m.recipient != 0)])
    env.send_messages([camera(0, 1), camera(1, 0), camera(1, 1)])
    assert [(s, r) for s, r, _ in delivered(env)[0]] == [(1, 1)]


@pytest.mark.parametrize('team, camera_count, target_count', [('both', 0, 0), ('camera', 0, 3), ('target', 2, 0),
                                                               ('none', 2, 3)])
def test_no_communication(team, camera_count, target_count):
    env = make_env(wrappers=[mate.WrapperSpec(mate.NoCommunication, team=team)])
    env.send_messages(camera(0, None))
    env.send_messages(target(1, None))
    cams, tgts = delivered(env)
    assert (len(cams), len(tgts)) == (camera_count, target_count)
    assert str(env).startswith(f'<NoCommunication(team={team})')


def test_random_message_dropout_rates_and_reproducibility():
    def run(rate, seed=0):
        env = make_env(wrappers=[mate.WrapperSpec(mate.RandomMessageDropout, dropout_rate=rate)])
        env.reset(seed=seed)
        kept = []
        for _ in range(200):
            env.send_messages(target(0, None))                    # 3 routed copies, each an independent draw
            kept.append(len(delivered(env)[1]))
            env.step(ZERO_ACTION)
        return kept

    assert run(0.0) == [3] * 200 and run(1.0) == [0] * 200
    half = run(0.5)
    assert half == run(0.5) and half != run(0.5, seed=1)
    assert 0.4 < sum(half) / 600 < 0.6


def test_dropout_does_not_change_the_world():
    plain, dropping = make_env(), make_env(wrappers=[mate.WrapperSpec(mate.RandomMessageDropout, dropout_rate=0.5)])
    for env in (plain, dropping):
        env.reset(seed=4)
        for _ in range(10):
            env.send_messages(camera(0, None))
            env.step(ZERO_ACTION)
    np.testing.assert_array_equal(plain.unwrapped.state(), dropping.unwrapped.state())


def test_restricted_communication_range():
    env = make_env(wrappers=[mate.WrapperSpec(mate.RestrictedCommunicationRange, range_limit=600.0)])
    set_scene(env, **SCENE)          # cameras 1000 apart; targets: |t0 t1| = 583.1, |t0 t2| = 761.6, |t1 t2| = 894.4
    env.send_messages(camera(0, 1))
    env.send_messages([target(0, None), target(1, None)])
    cams, tgts = delivered(env)
    assert cams == []
    assert [(s, r) for s, r, _ in tgts] == [(0, 0), (0, 1), (1, 0), (1, 1)]


def test_extra_communication_delays_release_step_and_ties():
    env = make_env(wrappers=[mate.WrapperSpec(mate.ExtraCommunicationDelays, delay=2)])
    env.send_messages([camera(0, 1, 'a'), camera(1, 0, 'b')])   # same release step: no crash, kept in order
    assert delivered(env) == ([], [])
    env.step(ZERO_ACTION)                                        # episode_step 1
    env.send_messages([])
    assert delivered(env) == ([], [])
    env.step(ZERO_ACTION)                                        # episode_step 2: released by the next send call
    assert [m for _, m in env.pending_messages] == [camera(0, 1, 'a'), camera(1, 0, 'b')]
    env.send_messages(target(2, 0, 'c'))
    cams, tgts = delivered(env)
    assert [(s, r, c) for s, r, c in cams] == [(0, 1, "'a'"), (1, 0, "'b'")]
    assert tgts == []                                            # 'c' waits until step 4
    assert [release for release, _ in env.pending_messages] == [4]


def test_extra_communication_delays_mixed_release_and_callable():
    env = make_env(wrappers=[mate.WrapperSpec(mate.ExtraCommunicationDelays,
                                              delay=lambda base, m: 0 if m.team is Team.TARGET else 1)])
    env.send_messages(camera(0, None, 'later'))
    env.send_messages(target(1, 2, 'now'))                       # delay 0: delivered at once
    assert [c for _, _, c in delivered(env)[1]] == ["'now'"] and delivered(env)[0] == []
    env.step(ZERO_ACTION)
    env.send_messages(target(0, 1, 'again'))                     # releases the camera broadcast too, split by team
    cams, tgts = delivered(env)
    assert [(s, r) for s, r, _ in cams] == [(0, 0), (0, 1)] and [(s, r) for s, r, _ in tgts] == [(0, 1)]
    env.send_messages(camera(1, 0, 'dropped by reset'))
    env.reset(seed=0)
    assert env.pending_messages == []


# ---------------------------------------------------------------------------- RenderCommunication

def test_render_communication_bookkeeping_and_arrows():
    env = make_env(wrappers=[mate.WrapperSpec(mate.RenderCommunication, duration=4)])
    set_scene(env, **SCENE)
    env.send_messages(camera(0, 1))
    env.send_messages(target(2, None))
    env.step(ZERO_ACTION)
    assert env.camera_remaining.tolist() == [[0, 4], [0, 0]]
    assert env.target_remaining[2].tolist() == [4, 4, 4] and env.target_remaining[:2].sum() == 0
    env.send_messages(camera(1, 0))
    env.step(ZERO_ACTION)
    assert env.camera_remaining.tolist() == [[0, 3], [4, 0]]
    arrows = env.arrows()
    assert [(a.team, a.sender, a.recipient) for a in arrows] == [
        (Team.CAMERA, 0, 1), (Team.CAMERA, 1, 0), (Team.TARGET, 2, 0), (Team.TARGET, 2, 1)]
    first = arrows[0]
    assert first.color == (0.0, 0.0, 1.0) and first.alpha == pytest.approx(min(1.0, 1.2 * 3 / 4))
    # cameras at (-500, 0) and (500, 0), both directions active: shortened to 950 and shifted 10 to the right
    np.testing.assert_allclose(first.start, [-475.0, -10.0])
    np.testing.assert_allclose(first.end, [475.0, -10.0])
    assert len(first.barbs) == 1
    one_way = arrows[2]                                           # target 2 -> target 0, one way: two barbs
    assert one_way.color == (1.0, 0.0, 0.0) and len(one_way.barbs) == 2 and one_way.alpha == pytest.approx(0.9)
    for _ in range(4):
        env.step(ZERO_ACTION)
    assert env.arrows() == [] and env.camera_remaining.sum() == 0
    env.send_messages(camera(0, 1))
    env.step(ZERO_ACTION)
    env.reset(seed=0)
    assert env.camera_remaining.sum() == 0


def test_render_communication_registers_its_callback():
    needs_extra('pygame')
    env = make_env(wrappers=[mate.RenderCommunication], render_mode='rgb_array')
    assert env.unwrapped.render_callbacks['communication'] == env.draw
    set_scene(env, **SCENE)
    env.send_messages(camera(0, 1))
    env.step(ZERO_ACTION)

    calls = []

    class Recorder:
        def dashed_line(self, start, end, color, **kwargs):
            calls.append(('dashed_line', color, kwargs['alpha'], kwargs['layer']))

        def line(self, start, end, color, **kwargs):
            calls.append(('line', color, kwargs['alpha'], kwargs['layer']))

    env.draw(env.unwrapped, Recorder())
    assert calls[0] == ('dashed_line', (0.0, 0.0, 1.0), 1.0, 'below') and len(calls) == 3
    frame = env.render()
    assert frame.shape == (800, 800, 3)
    env.close()
