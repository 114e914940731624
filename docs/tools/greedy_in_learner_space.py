"""How well do rules do when restricted to what the camera learners can do?

    python docs/tools/greedy_in_learner_space.py [--envs 64] [--steps 2500] [--seed 1]

Plays B batched MATE-4v8-9 games against the batched greedy targets (the training opponent) for one
training episode (2500 raw steps) and prints the mean coverage rate of:

* flat:  the greedy camera rule (`mate.teams.GreedyTeam`, asked once per decision), its action snapped to
         the 5-level grid (25 actions) and held for the frame skip (1 and 5), i.e. the flat learner's
         action space;
* HRL:   scripted target selections through the rule executor (`mate.policies.hrl`), held for 5 steps:
         select every visible target / the nearest visible one / nothing (sweep) / the visible targets
         no other camera's sector contains (sweep when there are none) / every visible target when one
         of them is in no other camera's sector (else sweep).

These are reference points for the learning curves: a flat policy has to out-play the snapped greedy
rule, an HRL policy the scripted selections.
"""

from __future__ import annotations

import argparse

import numpy as np

from mate.constants import PRESERVED_DIM
from mate.learn.envs import TeamEnvConfig, TrainingEnv
from mate.messages import Team
from mate.spaces import observation_indices_of
from mate.teams import GreedyTeam
from mate.wrappers.discrete_action_spaces import nearest_grid_indices, square_grid


def camera_env(num_envs: int, horizon: int, frame_skip: int = 5, hrl: bool = False) -> TrainingEnv:
    """The camera learners' training envs on MATE-4v8-9: grid moves, or (hrl) one keep/ignore bit per target slot."""
    config = TeamEnvConfig(team='camera', config='MATE-4v8-9', num_envs=num_envs, frame_skip=frame_skip,
                           horizon=horizon, hrl=hrl, seed=0)
    return config.make_env(config.policy_spec(action='hrl' if hrl else 'grid'))


def play(env: TrainingEnv, policy, decisions: int, seed: int) -> float:
    env.reset(seed=seed)
    coverage = [env.step(policy(env.raw_observations))[5]['coverage'].mean() for _ in range(decisions)]
    return float(np.mean(coverage))


def snapped_greedy(env: TrainingEnv, seed: int):
    greedy = GreedyTeam('camera', env.num_envs, env.counts, seed=seed)
    grid = square_grid(env.spec.levels)
    first = True

    def policy(raw):
        nonlocal first
        if first:
            greedy.reset(raw, np.ones(env.num_envs, dtype=bool))
            first = False
        return nearest_grid_indices(greedy.act(raw), grid, raw[..., PRESERVED_DIM + 7:PRESERVED_DIM + 9])
    return policy


def selections(env: TrainingEnv):
    """Scripted HRL selections, (B, Nc, Nt) bits from raw camera observations."""
    nc, nt, no = env.counts
    starts = observation_indices_of(Team.CAMERA, nc, nt, no)
    targets, cameras = slice(starts[2], starts[3]), slice(starts[4], starts[5])

    def records(raw):
        return raw[..., targets].reshape(*raw.shape[:-1], nt, 5)

    def covered_by_others(raw):
        rec = records(raw)
        cams = raw[..., cameras].reshape(*raw.shape[:-1], nc, 7)            # (B, c, other, 7)
        own = raw[..., PRESERVED_DIM:PRESERVED_DIM + 2]
        dx = rec[..., None, :, 0] - cams[..., :, None, 0]                    # (B, c, other, t)
        dy = rec[..., None, :, 1] - cams[..., :, None, 1]
        rx, ry, theta = (cams[..., :, None, k] for k in (3, 4, 5))
        reach, distance = np.hypot(rx, ry), np.hypot(dx, dy)
        cosine = (dx * rx + dy * ry) / np.maximum(distance * reach, 1e-9)
        inside = (distance <= reach) & (np.degrees(np.arccos(np.clip(cosine, -1, 1))) <= theta / 2)
        itself = np.all(np.abs(cams[..., :2] - own[..., None, :]) < 1e-6, axis=-1)   # (B, c, other)
        return (inside & ~itself[..., None]).any(axis=-2)

    def visible(raw):
        return records(raw)[..., 4] > 0.5

    def nearest(raw):
        rec = records(raw)
        own = raw[..., PRESERVED_DIM:PRESERVED_DIM + 2]
        distance = np.where(visible(raw), np.hypot(*np.moveaxis(rec[..., :2] - own[..., None, :], -1, 0)), np.inf)
        bits = np.zeros(distance.shape, dtype=int)
        np.put_along_axis(bits, distance.argmin(-1)[..., None], 1, -1)
        return bits * visible(raw)

    def uncovered(raw):
        return (visible(raw) & ~covered_by_others(raw)).astype(int)

    def all_if_one_uncovered(raw):
        return visible(raw) * uncovered(raw).any(axis=-1, keepdims=True)

    return {'every visible target': lambda raw: visible(raw).astype(int), 'nearest visible target': nearest,
            'nothing (sweep)': lambda raw: np.zeros(visible(raw).shape, dtype=int),
            'visible and in no other sector': uncovered,
            'every visible target if one is in no other sector, else nothing': all_if_one_uncovered}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--envs', type=int, default=64)
    parser.add_argument('--steps', type=int, default=2500, help='raw steps (one training episode: 2500)')
    parser.add_argument('--seed', type=int, default=1)
    args = parser.parse_args()
    print(f'MATE-4v8-9, {args.envs} games x {args.steps} raw steps vs batched greedy targets: mean coverage rate')
    for skip in (1, 5):
        env = camera_env(args.envs, args.steps, frame_skip=skip)
        print(f'  flat, greedy rule snapped to 25 actions, frame skip {skip}: '
              f'{play(env, snapped_greedy(env, args.seed + 2), args.steps // skip, args.seed):.4f}')
    env = camera_env(args.envs, args.steps, hrl=True)
    for name, policy in selections(env).items():
        print(f'  HRL, select {name}: {play(env, policy, args.steps // 5, args.seed):.4f}')


if __name__ == '__main__':
    main()
