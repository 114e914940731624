"""Drive a team of agents through one env step: reset, observe, two communication rounds, act.

    (camera_obs, target_obs), (camera_infos, target_infos) = env.reset(seed=0)
    mate.group_reset(cameras, camera_obs); mate.group_reset(targets, target_obs)
    camera_infos = target_infos = None      # no infos before the first step
    while ...:
        camera_actions = mate.group_step(env, cameras, camera_obs, camera_infos)
        target_actions = mate.group_step(env, targets, target_obs, target_infos)
        (camera_obs, target_obs), _, terminated, truncated, (camera_infos, target_infos) = \
            env.step((camera_actions, target_actions))

Rows of a joint observation and entries of `infos` are paired with the agents in list order.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import repeat

__all__ = ['group_reset', 'group_observe', 'group_communicate', 'group_act', 'group_step']


def group_reset(agents: Sequence, joint_observation) -> None:
    """`agent.reset(row)` for each agent and its row of `joint_observation` (N, D)."""
    for agent, observation in zip(agents, joint_observation):
        agent.reset(observation)


def group_observe(agents: Sequence, joint_observation, infos: Sequence[dict] | None = None) -> None:
    """`agent.observe(row, info)` for each agent; `infos=None` gives every agent a None info."""
    for agent, observation, info in zip(agents, joint_observation, repeat(None) if infos is None else infos):
        agent.observe(observation, info)


def group_communicate(env, agents: Sequence) -> None:
    """The two communication rounds, each a pass of sending then a pass of receiving, in list order:
    every request sent in the first pass is delivered in the second, whoever sent it; likewise for
    responses. `env` is anything with `send_messages` / `receive_messages` (wrappers included).
    """
    send, receive = env.send_messages, env.receive_messages
    for agent in agents:
        send(agent.send_requests() or ())
    for agent in agents:
        agent.receive_requests(receive(agent=agent))
    for agent in agents:
        send(agent.send_responses() or ())
    for agent in agents:
        agent.receive_responses(receive(agent=agent))


def group_act(agents: Sequence, joint_observation, infos: Sequence[dict] | None = None,
              deterministic: bool | None = None) -> list:
    """`[agent.act(row, info, deterministic) for each agent]`: the team's joint action (N x (2,))."""
    return [agent.act(observation, info, deterministic)
            for agent, observation, info in zip(agents, joint_observation,
                                                repeat(None) if infos is None else infos)]


def group_step(env, agents: Sequence, joint_observation, infos: Sequence[dict] | None = None,
               deterministic: bool | None = None) -> list:
    """Observe, communicate, act: returns the team's joint action. Does not call `env.step`."""
    observations = list(joint_observation)   # rows of a 2-D array, split once for both passes
    infos = [None] * len(observations) if infos is None else list(infos)
    for agent, observation, info in zip(agents, observations, infos):
        agent.observe(observation, info)
    group_communicate(env, agents)
    return [agent.act(observation, info, deterministic)
            for agent, observation, info in zip(agents, observations, infos)]
