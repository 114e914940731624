"""Env-steps/s of `mate.make_vec` against the bare batched core it wraps, with random actions.

    python examples/vector_throughput.py --num-envs 4096 --preset MATE-4v8-9

Protocol (that of `mate bench`): a bank of 16 random joint actions drawn before timing and
cycled through; the core and the vector env step two identically seeded batches in alternating
one-second blocks (so that machine noise hits both alike); the median block is reported. A
third figure draws fresh actions every step with `sample_actions`.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import mate
from mate.core import engine


def blocks(step, batch_size: int, count: int, seconds: float) -> list[float]:
    out = []
    for _ in range(count):
        calls, start = 0, time.perf_counter()
        while (elapsed := time.perf_counter() - start) < seconds:
            step(calls)
            calls += 1
        out.append(calls * batch_size / elapsed)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--preset', default='MATE-4v8-9')
    parser.add_argument('--num-envs', type=int, default=4096)
    parser.add_argument('--dtype', choices=['float64', 'float32'], default='float64')
    parser.add_argument('--blocks', type=int, default=6)
    parser.add_argument('--seconds', type=float, default=1.0)
    args = parser.parse_args()

    B, env_id = args.num_envs, f'{args.preset}-v0'
    envs = mate.make_vec(env_id, num_envs=B, observation_dtype=args.dtype)
    envs.reset(seed=0)
    rng = np.random.default_rng(0)
    bank = [envs.sample_actions(rng) for _ in range(16)]
    # the bare core: a second batch driven through mate.core.engine with the vector env's buffers
    bare = mate.make_vec(env_id, num_envs=B, observation_dtype=args.dtype)
    bare.reset(seed=0)
    params, world, camera_obs, target_obs = bare.params, bare._world, bare._camera_obs, bare._target_obs

    def core_step(i):
        engine.step(params, world, *bank[i % 16], camera_obs, target_obs)

    def vector_step(i):
        envs.step(bank[i % 16])

    def vector_fresh_actions(i):
        envs.step(envs.sample_actions(rng))

    for step in (core_step, vector_step, vector_fresh_actions):  # warm up (compilation, threads)
        blocks(step, B, 1, 0.3)
    core, vector, fresh = [], [], []
    for _ in range(args.blocks):
        core += blocks(core_step, B, 1, args.seconds)
        vector += blocks(vector_step, B, 1, args.seconds)
        fresh += blocks(vector_fresh_actions, B, 1, args.seconds)
    print(f'{args.preset}, B={B}, {args.dtype} observations, {engine.NUM_THREADS} threads; '
          f'median of {args.blocks} blocks')
    print(f'  batched core                       {np.median(core):>12,.0f} env-steps/s')
    print(f'  make_vec, action bank              {np.median(vector):>12,.0f} env-steps/s '
          f'({np.median(vector) / np.median(core):.1%} of the core)')
    print(f'  make_vec, sample_actions each step {np.median(fresh):>12,.0f} env-steps/s')


if __name__ == '__main__':
    main()
