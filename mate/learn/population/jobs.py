"""The two jobs of a population run, as plain functions of plain data (a process pool or Ray runs them).

* `best_response(...)`: train one team's best response against a mixture over the other team's pool;
  returns the bytes of the chosen policy file and a summary.
* `payoff_entries(...)`: play every asked (camera k, target l) pairing for E episodes in one batch;
  returns each entry's means.

Pool members travel as *payloads*: a batched agent name of `mate evaluate` ('random', 'greedy',
'pretrained:NAME') or the bytes of a policy file, so that a worker on another machine of a Ray cluster
needs no shared file system. A worker turns a payload into a batched team (`mate.policies.policy.make_team`);
population members always sample their actions (they are stochastic policies).
"""

from __future__ import annotations

import csv
import math
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ['TARGET_CREDITS', 'best_response', 'member_team', 'payoff_entries', 'policy_from_bytes',
           'rescaled_schedules']

TARGET_CREDITS = ('team', 'own')
"""The rewards a target best response can train on: 'team', the team's (the spec's), or 'own', each target's own
part of it."""


def policy_from_bytes(data: bytes, team):
    """A `LoadedPolicy` from a policy file's bytes (read through a private temporary file, checked by
    `load_checkpoint` like any file)."""
    from ...policies.policy import load_policy

    with tempfile.TemporaryDirectory(prefix='mate-member-') as folder:
        path = Path(folder) / 'policy.pt'
        path.write_bytes(data)
        return load_policy(path, team)


def member_team(payload, team, num_envs: int, counts, seed: int | None, device='cpu'):
    """The batched team of one pool member: a policy file's bytes, or an agent name of `make_team` (a policy's
    forward passes on `device`)."""
    from ...policies.policy import PolicyTeam, make_team

    if isinstance(payload, (bytes, bytearray)):
        return PolicyTeam(policy_from_bytes(bytes(payload), team), team, num_envs, counts, seed=seed,
                          deterministic=False, device=device)
    if str(payload).partition(':')[0] in ('pretrained', 'checkpoint'):
        return make_team(str(payload), team, num_envs, counts, seed=seed, deterministic=False, device=device)
    return make_team(str(payload), team, num_envs, counts, seed=seed)


def rescaled_schedules(total_steps: int) -> dict:
    """The PSRO best responses' schedules rescaled to a budget of T decision steps (docs/population.md):
    learning rate 5e-4, 1e-4 from 0.4 T, 5e-5 from 0.8 T; entropy coefficient 0.05 -> 0.01 at 0.2 T ->
    0.001 at 0.4 T -> 0 at T (linear in between)."""
    T = int(total_steps)
    return dict(lr_schedule=((0, 5e-4), (int(0.4 * T), 1e-4), (int(0.8 * T), 5e-5)),
                entropy_schedule=((0, 0.05), (int(0.2 * T), 0.01), (int(0.4 * T), 0.001), (T, 0.0)))


def best_response(team: str, env: dict, opponents: list, weights: list[float], steps: int, seed: int,
                  run_dir: str, init: bytes | None = None, num_envs: int = 16, torch_threads: int = 1,
                  checkpoint_every: int = 5, device: str = 'auto', credit: str = 'team') -> dict:
    """Train `team`'s best response (cameras: HRL-MAPPO with the mixed reward; targets: MAPPO, rewarded by `credit`:
    'team', the team's reward as the spec says, or 'own', each target's own part of it) for `steps` decision steps
    against the mixture of the other team's `opponents` (payloads) with `weights` (drawn per episode and env row),
    warm-started from the actor of `init` (policy bytes) if given.

    `torch_threads`: threads of the training's updates; one, because a best response's minibatches are small
    and two threads ran them several times slower whenever the other core was busy (another job, the env).
    `env`: {'env_id': ..., 'config': ...} of the game. Resumes from `run_dir/checkpoint.pt` when a stopped
    job left one. Returns {'policy': bytes of best.pt (else final.pt), 'chosen': 'best' | 'final', 'steps',
    'seconds', 'episode_return', 'episode_coverage', 'episode_normalized_target_return', 'interrupted'}.
    """
    from ...teams import MixtureTeam
    from ..mappo import MAPPOConfig, policy_spec, train

    other = 'target' if team == 'camera' else 'camera'
    kept = [(member, w) for member, w in zip(opponents, weights) if w > 0]     # zero-weight members dropped
    if not kept:
        raise ValueError('the opponent mixture has no member with a positive weight')

    def opponent(num_envs_, counts, seed_):
        members = [member_team(member, other, num_envs_, counts, None if seed_ is None else seed_ + 101 * k)
                   for k, (member, _) in enumerate(kept)]
        return MixtureTeam(members, [w for _, w in kept], seed=seed_)

    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    init_path = None
    if init is not None:
        init_path = run_dir / 'init.pt'
        init_path.write_bytes(init)
    camera = team == 'camera'
    config = MAPPOConfig(team=team, config=env.get('config') or env['env_id'].removesuffix('-v0'), hrl=camera,
                         credit=credit,
                         steps=int(steps), num_envs=int(num_envs), seed=int(seed), threads=int(torch_threads),
                         checkpoint_every=int(checkpoint_every), device=device, run_dir=str(run_dir), progress=False,
                         init_from=None if init_path is None else str(init_path), **rescaled_schedules(steps))
    envs = config.make_env(policy_spec(config), opponent=opponent, camera_reward='mixed' if camera else 'coverage')
    start = time.perf_counter()
    run = train(config, envs=envs)
    row = run.last_row or _last_logged_row(run_dir)   # nothing trained now: a rerun of a finished job
    chosen = 'best' if (run_dir / 'best.pt').exists() else 'final'
    return dict(policy=(run_dir / f'{chosen}.pt').read_bytes() if not run.interrupted else b'', chosen=chosen,
                steps=int(run.env_steps), seconds=time.perf_counter() - start, interrupted=run.interrupted,
                **{key: float(row.get(key, math.nan)) for key in
                   ('episode_return', 'episode_coverage', 'episode_normalized_target_return')})


def _last_logged_row(run_dir: Path) -> dict:
    """The last row of a training run's `progress.csv` as numbers ({} when there is none): the summary of a run that
    was already complete when its job ran again (a retry after its result was lost with a node, or a resumed
    population run killed between a best response's end and its saving). The CSV holds each float's repr, so the
    numbers are the ones the first run returned."""
    path = run_dir / 'progress.csv'
    if not path.exists():
        return {}
    with open(path, newline='') as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return {}
    values = {}
    for key, text in rows[-1].items():
        try:
            values[key] = float(text)
        except (TypeError, ValueError):
            continue
    return values


def payoff_entries(env: dict, cameras: list, targets: list, pairs: list[tuple[int, int]], episodes: int,
                   seed: int = 0, max_episode_steps: int | None = None, device: str = 'cpu') -> list[dict]:
    """Play each pairing (camera member k, target member l) of `pairs` for `episodes` episodes with env
    seeds seed .. seed + episodes - 1 (the same seeds for every pairing), all in one vector env (the policies'
    forward passes on `device`).

    `cameras` / `targets` are the pools' payloads (only the members named in `pairs` are built: the others may be
    None). An entry depends only on its pairing, its episodes and `seed` (the members' teams are seeded by their pool
    index, each pairing's rows by its env seeds) when `pairs` holds one pairing, as `mate psro` sends them.
    Returns one dict per pair, in order: k, l, `payoff` (mean normalised target-team return, the target's
    utility U_T), its standard error `payoff_sem`, `coverage`, `real_coverage`, `length` (means) and
    `env_steps_per_second`.
    """
    from ...teams import MixtureTeam, play_batch

    if not pairs:
        return []
    pairs = [(int(k), int(l)) for k, l in pairs]
    rows = len(pairs) * episodes
    seeds = [seed + e for _ in pairs for e in range(episodes)]
    camera_ids = sorted({k for k, _ in pairs})
    target_ids = sorted({l for _, l in pairs})
    camera_rows = np.repeat([camera_ids.index(k) for k, _ in pairs], episodes)
    target_rows = np.repeat([target_ids.index(l) for _, l in pairs], episodes)
    config = env.get('config') or env['env_id'].removesuffix('-v0')

    def team_of(pool, ids, assignment, side, offset):
        def build(num_envs, counts):
            members = [member_team(pool[i], side, num_envs, counts, seed=10_000 * offset + i, device=device)
                       for i in ids]
            return MixtureTeam(members, assignment=assignment)
        return build

    results, timing = play_batch(config, team_of(cameras, camera_ids, camera_rows, 'camera', 1),
                                 team_of(targets, target_ids, target_rows, 'target', 2), rows, seed=seeds,
                                 max_episode_steps=max_episode_steps)
    entries = []
    for p, (k, l) in enumerate(pairs):
        block = results[p * episodes:(p + 1) * episodes]
        payoff = np.array([r.normalized_target_return for r in block])
        entries.append(dict(k=k, l=l, payoff=float(payoff.mean()),
                            payoff_sem=float(payoff.std(ddof=1) / np.sqrt(episodes)) if episodes > 1 else 0.0,
                            coverage=float(np.mean([r.coverage_rate for r in block])),
                            real_coverage=float(np.mean([r.real_coverage_rate for r in block])),
                            length=float(np.mean([r.episode_length for r in block])),
                            env_steps_per_second=float(timing['env_steps_per_second'])))
    return entries
