"""Tests of mate.messages: Team, Message and the MessageChannel bookkeeping."""

import numpy as np
import pytest

from mate.messages import Message, MessageChannel, Team


class FakeAgent:
    def __init__(self, team, index):
        self.TEAM = team
        self.index = index


def cam(sender, recipient, content=None, **kwargs):
    return Message(sender=sender, recipient=recipient, content=content if content is not None else {},
                   team=Team.CAMERA, **kwargs)


def snapshot(channel):
    """Everything observable about a channel, for unchanged-state checks."""
    return (
        [channel.buffer(team) for team in Team],
        [channel.edges(team).tolist() for team in Team],
        [channel.total_edges(team).tolist() for team in Team],
        [[list(queue) for queue in channel._queues[team]] for team in Team],
    )


def test_team_values():
    assert Team.CAMERA == 0 and Team.TARGET == 1
    assert Team(1) is Team.TARGET


def test_message_item_access_forwards_to_content():
    message = cam(0, 1, {'a': 1})
    assert 'a' in message and 'b' not in message
    assert message['a'] == 1
    message['b'] = 2
    assert message.content == {'a': 1, 'b': 2}
    assert message.broadcasting is False


def test_broadcast_includes_sender_and_deep_copies_content():
    channel = MessageChannel(3, 2)
    content = {'positions': [1, 2]}
    channel.send(cam(1, None, content))
    cameras, targets = channel.receive()
    assert targets == [[], []]
    assert [len(lst) for lst in cameras] == [1, 1, 1]
    copies = [lst[0] for lst in cameras]
    assert [m.recipient for m in copies] == [0, 1, 2]
    assert all(m.sender == 1 and m.broadcasting and m.team is Team.CAMERA for m in copies)
    assert all(m.content == content and m.content is not content for m in copies)
    assert copies[0].content['positions'] is not copies[1].content['positions']
    np.testing.assert_array_equal(channel.edges(Team.CAMERA), [[0, 0, 0], [1, 1, 1], [0, 0, 0]])


def test_peer_to_peer_is_not_copied():
    channel = MessageChannel(2, 2)
    message = Message(sender=0, recipient=1, content={'x': 1}, team=Team.TARGET)
    channel.send(message)
    received = channel.receive(agent_id=(Team.TARGET, 1))
    assert received == [message] and received[0] is message
    assert received[0].broadcasting is False


def test_route_is_pure():
    channel = MessageChannel(2, 0)
    routed = channel.route([cam(0, None, {'k': 1}), cam(1, 0)])
    assert [(m.sender, m.recipient, m.broadcasting) for m in routed] == [(0, 0, True), (0, 1, True), (1, 0, False)]
    assert channel.buffer(Team.CAMERA) == [[], []]
    assert channel.edges(Team.CAMERA).sum() == 0


def test_edge_counts_in_and_out():
    channel = MessageChannel(4, 1)
    channel.send([cam(0, 1), cam(0, 2), cam(3, 1), cam(2, None)])
    edges = channel.edges(Team.CAMERA)
    assert edges.dtype == np.int64 and edges.shape == (4, 4)
    np.testing.assert_array_equal(edges.sum(axis=1), [2, 0, 4, 1])  # out-edges (broadcast: 4 incl. self)
    np.testing.assert_array_equal(edges.sum(axis=0), [1, 3, 2, 1])  # in-edges
    assert [len(b) for b in channel.buffer(Team.CAMERA)] == [1, 3, 2, 1]
    assert channel.edges(Team.TARGET).tolist() == [[0]]


def test_multi_round_within_a_step():
    channel = MessageChannel(2, 0)
    channel.send(cam(0, 1, {'round': 'request'}))
    first = channel.receive(agent_id=(Team.CAMERA, 1))
    assert [m['round'] for m in first] == ['request']
    assert channel.receive(agent_id=(Team.CAMERA, 1)) == []
    channel.send(cam(1, 0, {'round': 'response'}))
    channel.send(cam(0, 1, {'round': 'response'}))
    assert [m['round'] for m in channel.receive(agent_id=(Team.CAMERA, 1))] == ['response']
    # buffer keeps every delivered message, received or not, in delivery order
    buffers = channel.buffer(Team.CAMERA)
    assert [m['round'] for m in buffers[1]] == ['request', 'response']
    assert [m['round'] for m in buffers[0]] == ['response']
    assert channel.edges(Team.CAMERA).tolist() == [[0, 2], [1, 0]]


def test_receive_only_empties_the_agent_queue():
    channel = MessageChannel(2, 0)
    channel.send(cam(0, None))
    assert len(channel.receive(agent=FakeAgent(Team.CAMERA, 0))) == 1
    cameras, targets = channel.receive()
    assert [len(lst) for lst in cameras] == [0, 1] and targets == []
    assert channel.receive() == ([[], []], [])


def test_receive_with_agent_object_positionally():
    channel = MessageChannel(1, 2)
    message = Message(sender=0, recipient=1, content=None, team=Team.TARGET)
    channel.send(message)
    assert channel.receive(FakeAgent(Team.TARGET, 1)) == [message]


def test_receive_argument_errors():
    channel = MessageChannel(2, 2)
    with pytest.raises(ValueError):
        channel.receive(agent_id=(Team.CAMERA, 0), agent=FakeAgent(Team.CAMERA, 0))
    with pytest.raises(ValueError):
        channel.receive(agent_id=(Team.CAMERA, 2))
    with pytest.raises(ValueError):
        channel.receive(agent=FakeAgent(Team.TARGET, -1))
    with pytest.raises(ValueError):
        channel.receive(agent_id=(5, 0))


def test_end_step_clears_and_totals_accumulate():
    channel = MessageChannel(2, 2)
    channel.send(cam(0, 1))
    infos_buffer = channel.buffer(Team.CAMERA)
    channel.end_step()
    assert infos_buffer[1][0].sender == 0  # earlier results survive the clearing
    assert channel.buffer(Team.CAMERA) == [[], []]
    assert channel.edges(Team.CAMERA).sum() == 0
    assert channel.receive() == ([[], []], [[], []])
    channel.send(cam(0, 1))
    channel.send(cam(1, None))
    channel.end_step()
    assert channel.total_edges(Team.CAMERA).tolist() == [[0, 2], [1, 1]]
    assert channel.total_edges(Team.TARGET).tolist() == [[0, 0], [0, 0]]
    channel.reset()
    assert channel.total_edges(Team.CAMERA).sum() == 0


def test_step_summary_quiet_and_busy_steps():
    channel = MessageChannel(3, 1)
    assert channel.step_summary(Team.CAMERA) == ([[], [], []], [0, 0, 0], [0, 0, 0])
    channel.send([cam(0, 2), cam(1, None)])
    buffers, out_edges, in_edges = channel.step_summary(Team.CAMERA)
    assert [len(b) for b in buffers] == [1, 1, 2] and out_edges == [1, 3, 0] and in_edges == [1, 1, 2]
    assert all(type(n) is int for n in out_edges + in_edges)
    buffers[2].clear()  # fresh lists: the channel is not affected
    assert len(channel.buffer(Team.CAMERA)[2]) == 2
    channel.end_step()
    channel.end_step()  # a quiet step keeps the totals and clears nothing it should keep
    assert channel.step_summary(Team.CAMERA) == ([[], [], []], [0, 0, 0], [0, 0, 0])
    assert channel.total_edges(Team.CAMERA).sum() == 4


def test_reset_clears_pending_messages():
    channel = MessageChannel(2, 2)
    channel.send(cam(0, 1))
    channel.reset()
    assert channel.receive() == ([[], []], [[], []])
    assert channel.edges(Team.CAMERA).sum() == 0


def test_returned_arrays_are_copies():
    channel = MessageChannel(2, 0)
    channel.edges(Team.CAMERA)[0, 0] = 5
    channel.total_edges(Team.CAMERA)[0, 0] = 5
    assert channel.edges(Team.CAMERA).sum() == 0 and channel.total_edges(Team.CAMERA).sum() == 0


@pytest.mark.parametrize('bad_call, error', [
    (lambda: [cam(0, 1), 'not a message'], TypeError),
    (lambda: [cam(0, 1), Message(0, 1, None, Team.TARGET)], ValueError),
    (lambda: [cam(0, 1), cam(0, 7)], ValueError),
    (lambda: [cam(0, None), cam(4, None)], ValueError),
    (lambda: [cam(0, 1), cam(-1, 0)], ValueError),
    (lambda: [cam(0, 1), cam(0, 1.5)], TypeError),
    (lambda: [cam(0, None), Message(0, 1, None, 'not a team')], ValueError),
])
def test_validation_errors_leave_channel_unchanged(bad_call, error):
    channel = MessageChannel(4, 2)
    channel.send(cam(2, 3))
    before = snapshot(channel)
    with pytest.raises(error):
        channel.send(bad_call())
    assert snapshot(channel) == before


def test_error_messages_name_teams_and_ranges():
    channel = MessageChannel(4, 2)
    with pytest.raises(ValueError, match='CAMERA.*TARGET'):
        channel.send([cam(0, 1), Message(0, 1, None, Team.TARGET)])
    with pytest.raises(ValueError, match=r'recipient 7 is out of range: team CAMERA has 4 agents, '
                                         r'valid recipients are 0\.\.3 or None for broadcast'):
        channel.send(cam(0, 7))
    with pytest.raises(ValueError, match=r'sender 5 is out of range: team TARGET has 2 agents'):
        channel.send(Message(5, None, None, Team.TARGET))
    with pytest.raises(TypeError):
        channel.send(42)


def test_numpy_integer_indices_are_accepted():
    channel = MessageChannel(3, 0)
    channel.send(cam(np.int64(0), np.int64(2)))
    assert channel.edges(Team.CAMERA)[0, 2] == 1


def test_empty_send_and_empty_team():
    channel = MessageChannel(0, 3)
    channel.send([])
    assert channel.buffer(Team.CAMERA) == []
    assert channel.edges(Team.CAMERA).shape == (0, 0)
    assert channel.total_edges(Team.CAMERA).shape == (0, 0)
    assert channel.receive() == ([], [[], [], []])
    with pytest.raises(ValueError, match='team CAMERA has 0 agents'):
        channel.send(cam(0, None))
    channel.end_step()
    channel.reset()
    assert channel.num_agents(Team.CAMERA) == 0 and channel.num_agents(Team.TARGET) == 3
