"""What camera teams do, measured per raw step in the flat learners' training setting.

    python docs/tools/camera_behaviour.py [--policies RUN/final.pt ...] [--frame-skip 2] [--envs 64] [--seed 1]

Plays one training episode (2500 raw steps) of B batched MATE-4v8-9 games against the batched greedy
targets, for the greedy camera rule (`mate.teams.GreedyTeam`, snapped to the 25 grid actions and held for
1 and for --frame-skip raw steps; also without its sighting memory) and for each policy file (sampled and
argmax, in the training envs of its own spec: its game, frame skip, action kind and memory/velocity columns),
and prints per team: the mean coverage rate, the share of camera-steps that see no target, the share of
targets seen by two or more cameras, the mean viewing angle (degrees) and the mean number of targets a
camera sees.
"""

from __future__ import annotations

import argparse

import numpy as np

from mate.constants import PRESERVED_DIM
from mate.learn.envs import TeamEnvConfig, TrainingEnv
from mate.policies.memory import camera_sightings
from mate.policies.policy import LoadedPolicy, load_policy
from mate.teams import GreedyTeam
from mate.wrappers.discrete_action_spaces import nearest_grid_indices, square_grid


def record(env: TrainingEnv) -> dict:
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


def greedy_actions(env: TrainingEnv, seed: int, period: int):
    """The greedy camera rule, asked once per decision, its action snapped to the nearest of the grid's moves."""
    greedy = GreedyTeam('camera', env.num_envs, env.counts, seed=seed, memory_period=period)
    greedy.reset(env.raw_observations, np.ones(env.num_envs, dtype=bool))
    grid = square_grid(env.spec.levels)
    return lambda obs: nearest_grid_indices(greedy.act(env.raw_observations), grid,
                                            env.raw_observations[..., PRESERVED_DIM + 7:PRESERVED_DIM + 9])


def policy_actions(policy: LoadedPolicy, argmax: bool, seed: int):
    """The policy's decisions from the env's features (its spec's), as `PolicyTeam` takes them; a recurrent policy
    keeps its memory (the envs play one episode: no row restarts)."""
    rng = np.random.default_rng(seed)
    memory = policy.initial_memory(1)

    def act(obs):
        nonlocal memory
        if policy.recurrent:
            if memory[0].shape[:-1] != obs.shape[:-1]:
                memory = policy.initial_memory(*obs.shape[:-1])
            outputs, memory = policy.outputs(obs, memory)
        else:
            outputs = policy.outputs(obs)
        return policy.spec.choose(outputs, obs, argmax, rng)
    return act


def measure(name: str, env: TrainingEnv, make_actions, seed: int) -> None:
    stats = record(env)
    obs, _ = env.reset(seed=seed)
    act = make_actions(env)
    for _ in range(env.horizon // env.frame_skip):
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
        config = TeamEnvConfig(team='camera', config='MATE-4v8-9', frame_skip=hold, horizon=2500, num_envs=args.envs,
                               seed=args.seed)
        measure(label, config.make_env(config.policy_spec()), lambda env: greedy_actions(env, args.seed, period),
                args.seed)
    for path in args.policies:
        policy = load_policy(path, 'camera')
        if policy.spec.comm != 'none':
            raise SystemExit(f'{path}: a {policy.spec.network} policy talks through messages; this script plays '
                             'policies without communication')
        for argmax in (False, True):
            env = TrainingEnv(policy.spec, num_envs=args.envs, horizon=2500, seed=args.seed)
            measure(f"{path} ({'argmax' if argmax else 'sampled'}, held {policy.spec.frame_skip})", env,
                    lambda env: policy_actions(policy, argmax, args.seed), args.seed)


if __name__ == '__main__':
    main()
