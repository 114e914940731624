"""What camera teams do, measured per raw step in the flat learners' training setting.

    python scripts/camera_behaviour.py [--policies RUN/final.pt ...] [--frame-skip 2] [--envs 64] [--seed 1]

Plays one training episode (2500 raw steps) of B batched MATE-4v8-9 games against the batched greedy
targets, for the greedy camera rule (snapped to the 25 grid actions and held for 1 and for --frame-skip
raw steps; also without its sighting memory) and for each policy file (sampled and argmax, decisions
held for --frame-skip steps, the policy's own memory/velocity columns), and prints per team: the mean
coverage rate, the share of camera-steps that see no target, the share of targets seen by two or more
cameras, the mean viewing angle (degrees) and the mean number of targets a camera sees.
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from mate.constants import PRESERVED_DIM
from mate.learn.agents import load_policy
from mate.learn.envs import TeamVecEnv
from mate.learn.memory import camera_sightings
from mate.learn.opponents import VecGreedyCamera
from mate.wrappers.discrete_camera import nearest_grid_indices, square_grid


def record(env: TeamVecEnv) -> dict:
    """Wrap `env.vec.step` so that every raw step's camera statistics are appended to the returned lists."""
    stats = {'coverage': [], 'seeing nothing': [], 'seen twice or more': [], 'viewing angle': [], 'targets per camera': []}
    step = env.vec.step

    def recording(actions):
        result = step(actions)
        raw = result[0][0]
        sees = camera_sightings(raw, *env.counts)[1]                          # (B, Nc, Nt)
        stats['coverage'].append(result[4]['coverage_rate'].mean())
        stats['seeing nothing'].append((sees.sum(-1) == 0).mean())
        stats['seen twice or more'].append((sees.sum(1) >= 2).mean())
        stats['viewing angle'].append(raw[..., PRESERVED_DIM + 5].mean())
        stats['targets per camera'].append(sees.sum(-1).mean())
        return result

    env.vec.step = recording
    return stats


def greedy_actions(env: TeamVecEnv, seed: int, period: int):
    greedy = VecGreedyCamera(env.num_envs, *env.counts, seed=seed, memory_period=period)
    greedy.reset(env.raw_observations)
    grid = square_grid(env.levels)
    return lambda obs: nearest_grid_indices(greedy.act(env.raw_observations), grid,
                                            env.raw_observations[..., PRESERVED_DIM + 7:PRESERVED_DIM + 9])


def policy_actions(path: str, argmax: bool, seed: int):
    policy = load_policy(path, 'camera')
    generator = torch.Generator().manual_seed(seed)

    def act(obs):
        logits = torch.as_tensor(policy.logits(obs))
        if argmax:
            return logits.argmax(-1).numpy()
        probs = torch.softmax(logits.reshape(-1, logits.shape[-1]), -1)
        return torch.multinomial(probs, 1, generator=generator).reshape(logits.shape[:-1]).numpy()
    return act


def measure(name: str, make_actions, frame_skip: int, envs: int, seed: int, meta: dict | None = None) -> None:
    meta = meta or {}
    env = TeamVecEnv('camera', num_envs=envs, frame_skip=frame_skip, horizon=2500, seed=seed,
                     memory=int(meta.get('memory', 0)), velocity=bool(meta.get('velocity', False)))
    stats = record(env)
    obs, _ = env.reset(seed=seed)
    act = make_actions(env)
    for _ in range(2500 // frame_skip):
        obs = env.step(act(obs))[0]
    values = {key: float(np.mean(v)) for key, v in stats.items()}
    print(f"{name:<60} coverage {values['coverage']:.3f}  seeing nothing {values['seeing nothing']:5.1%}  "
          f"seen twice or more {values['seen twice or more']:5.1%}  angle {values['viewing angle']:5.1f} deg  "
          f"targets per camera {values['targets per camera']:.2f}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--policies', nargs='*', default=[], help='checkpoints or exported policies of cameras')
    parser.add_argument('--frame-skip', type=int, default=2, help='hold of the snapped greedy rule (default 2)')
    parser.add_argument('--envs', type=int, default=64)
    parser.add_argument('--seed', type=int, default=1)
    args = parser.parse_args()
    for hold, period, label in ((1, 25, 'greedy, deciding every step'), (args.frame_skip, 25, f'greedy, held {args.frame_skip}'),
                                (args.frame_skip, 1, f'greedy, held {args.frame_skip}, no memory')):
        measure(label, lambda env: greedy_actions(env, args.seed, period), hold, args.envs, args.seed)
    for path in args.policies:
        meta = load_policy(path, 'camera').meta
        for argmax in (False, True):
            measure(f"{path} ({'argmax' if argmax else 'sampled'}, held {meta['frame_skip']})",
                    lambda env: policy_actions(path, argmax, args.seed), meta['frame_skip'], args.envs, args.seed, meta)


if __name__ == '__main__':
    main()
