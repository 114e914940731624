"""Do the batched training opponents play like the built-in greedy agents?

Plays single-env episodes (MATE-4v8-9, `--steps` raw steps each, seeds 0..n-1) and prints mean coverage
rate and delivered cargo for
  * Python GreedyCameraAgent vs Python GreedyTargetAgent   (the reference)
  * Python GreedyCameraAgent vs VecGreedyTarget (B = 1)    (the cameras' training opponent)
  * VecGreedyCamera (B = 1)  vs Python GreedyTargetAgent   (the targets' training opponent)

    python scripts/validate_opponents.py --episodes 5 --steps 2000
"""

from __future__ import annotations

import argparse

import numpy as np

import mate
from mate.learn import VecGreedyCamera, VecGreedyTarget


def play(env, cameras: str, targets: str, seed: int, steps: int) -> tuple[float, int]:
    (camera_obs, target_obs), (camera_infos, target_infos) = env.reset(seed=seed)
    nc, nt, no = env.num_cameras, env.num_targets, env.num_obstacles
    if cameras == 'python':
        camera_agents = mate.GreedyCameraAgent(seed=seed).spawn(nc)
        mate.group_reset(camera_agents, camera_obs)
    else:
        vec_camera = VecGreedyCamera(1, nc, nt, no, seed=seed)
        vec_camera.reset(camera_obs[None])
    if targets == 'python':
        target_agents = mate.GreedyTargetAgent(seed=seed).spawn(nt)
        mate.group_reset(target_agents, target_obs)
    else:
        vec_target = VecGreedyTarget(1, nt, seed=seed)
        vec_target.reset(target_obs[None])
    coverage = []
    for _ in range(steps):
        if cameras == 'python':
            camera_action = mate.group_step(env, camera_agents, camera_obs, camera_infos)
        else:
            camera_action = vec_camera.act(camera_obs[None])[0]
        if targets == 'python':
            target_action = mate.group_step(env, target_agents, target_obs, target_infos)
        else:
            target_action = vec_target.act(target_obs[None])[0]
        (camera_obs, target_obs), _, terminated, truncated, (camera_infos, target_infos) = env.step(
            (camera_action, target_action))
        coverage.append(camera_infos[0]['coverage_rate'])
        if terminated or truncated:
            break
    return float(np.mean(coverage)), int(camera_infos[0]['num_delivered_cargoes'])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--config', default='MATE-4v8-9')
    parser.add_argument('--episodes', type=int, default=5)
    parser.add_argument('--steps', type=int, default=2000)
    args = parser.parse_args()
    env = mate.make('MultiAgentTracking-v0', config=args.config)
    print(f'{args.config}: {args.episodes} episodes x {args.steps} raw steps')
    print(f'{"cameras":>8} {"targets":>8} {"coverage":>14} {"delivered":>14}')
    for cameras, targets in (('python', 'python'), ('python', 'batched'), ('batched', 'python')):
        results = np.array([play(env, cameras, targets, seed, args.steps) for seed in range(args.episodes)])
        cov, delivered = results[:, 0], results[:, 1]
        print(f'{cameras:>8} {targets:>8} {cov.mean():8.3f} ± {cov.std():.3f} {delivered.mean():8.1f} ± {delivered.std():.1f}')


if __name__ == '__main__':
    main()
