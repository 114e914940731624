"""Train PPO cameras against greedy targets with Ray RLlib (needs `pip install 'mate[rllib]'`).

    python examples/rllib_ppo.py [--iterations 5]

RLlib's own loop written out: the env config, the PPO config (one policy shared by the cameras), a
local Ray instance and the training loop. `mate rllib-train` does the same as a `mate train` run
(run directory, resumes, the evaluation protocol, policies exported to mate policy files).
"""

from __future__ import annotations

import argparse

import ray

from mate.integrations import rllib as mate_rllib


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--iterations', type=int, default=5)
    args = parser.parse_args()

    env_config = {
        'config': 'MATE-4v4-9',
        'overrides': {'max_episode_steps': 200},
        'team': 'camera',          # RLlib controls the cameras
        'opponent': 'greedy',      # mate.agents.GreedyTargetAgent plays the targets
    }
    config = mate_rllib.ppo_config(env_config, train_batch_size=2000, minibatch_size=250, num_epochs=5, seed=0)
    ray.init(address='local', num_cpus=2, include_dashboard=False)
    try:
        algo = config.build_algo()
        for _ in range(args.iterations):
            result = algo.train()
            runners = result['env_runners']
            print(f"iteration {result['training_iteration']}: "
                  f"camera return {runners['module_episode_returns_mean']['camera']:,.0f}, "
                  f"coverage {runners['mate/coverage_rate']:.3f}")
        algo.stop()
    finally:
        ray.shutdown()


if __name__ == '__main__':
    main()
