"""Random cameras against random targets in 256 games at once with `mate.make_vec`.

    python examples/vector_random.py [--num-envs 256] [--steps 400]

Shows the batched step, next-step autoreset (the step after an episode ends restarts that game
and returns reward 0) and how to keep per-game episode returns with masks.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import mate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--num-envs', type=int, default=256)
    parser.add_argument('--steps', type=int, default=400)
    parser.add_argument('--max-episode-steps', type=int, default=100)
    args = parser.parse_args()

    envs = mate.make_vec('MATE-4v8-9-v0', num_envs=args.num_envs, observation_dtype=np.float32,
                         max_episode_steps=args.max_episode_steps)
    (camera_obs, target_obs), infos = envs.reset(seed=0)  # game i is seeded 0 + i
    print(envs, camera_obs.shape, target_obs.shape)

    rng = np.random.default_rng(0)
    returns = np.zeros(args.num_envs)          # camera-team return of each game's current episode
    finished_returns, coverage = [], []
    start = time.perf_counter()
    for _ in range(args.steps):
        camera_actions, target_actions = envs.sample_actions(rng)   # (B, Nc, 2), (B, Nt, 2)
        (camera_obs, target_obs), (camera_reward, _), terminated, truncated, infos = envs.step(
            (camera_actions, target_actions))
        returns += camera_reward                 # 0 on the autoreset step, so nothing leaks across episodes
        coverage.append(infos['coverage_rate'].mean())
        done = terminated | truncated
        finished_returns.extend(returns[done])
        returns[done] = 0.0
    elapsed = time.perf_counter() - start
    print(f'{args.steps * args.num_envs / elapsed:,.0f} env-steps/s, {len(finished_returns)} episodes finished, '
          f'camera return {np.mean(finished_returns):,.1f}, mean coverage {np.mean(coverage):.3f}')


if __name__ == '__main__':
    main()
