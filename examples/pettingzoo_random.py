"""MATE through PettingZoo: random agents under the Parallel API, then under the AEC API.

    python examples/pettingzoo_random.py
"""

from __future__ import annotations

from mate.integrations import pettingzoo as mate_pz


def parallel(max_cycles: int = 200) -> None:
    env = mate_pz.parallel_env(config='MATE-4v8-9', max_cycles=max_cycles)
    observations, infos = env.reset(seed=0)
    print('agents:', ', '.join(env.agents))
    print('camera_0 observation', observations['camera_0'].shape, 'state', env.state().shape)
    totals = dict.fromkeys(env.possible_agents, 0.0)
    while env.agents:  # empty once the episode is over (max_cycles reached here)
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)
        for agent, reward in rewards.items():
            totals[agent] += reward
    print(f"parallel: {env.num_cycles} cycles, camera team return {totals['camera_0']:.1f}, "
          f"target team return {totals['target_0']:.1f}, coverage {infos['camera_0']['coverage_rate']:.3f}")
    env.close()


def aec(max_cycles: int = 50) -> None:
    env = mate_pz.env(config='MATE-2v4-9', max_cycles=max_cycles)
    env.reset(seed=0)
    turns = 0
    for agent in env.agent_iter():  # camera_0, camera_1, target_0, ... : the world moves once all acted
        observation, reward, termination, truncation, info = env.last()
        env.step(None if termination or truncation else env.action_space(agent).sample())
        turns += 1
    print(f'AEC: {turns} agent turns for {max_cycles} cycles of {env.num_agents or len(env.possible_agents)} agents')
    env.close()


if __name__ == '__main__':
    parallel()
    aec()
