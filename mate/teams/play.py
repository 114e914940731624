"""`play_batch`: B games of a camera team against a target team at once, in one vector env."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..messages import Team
from ..envs.vector import make_vec
from .interface import idle

__all__ = ['BatchEpisode', 'EpisodeSummary', 'play_batch']


@dataclass
class EpisodeSummary:
    """Summary of one episode (rates are means over its steps, returns are sums)."""
    seed: int
    coverage_rate: float
    real_coverage_rate: float
    transport_rate: float
    camera_return: float
    target_return: float
    normalized_target_return: float
    delivered_cargoes: int
    episode_length: int


BatchEpisode = EpisodeSummary
"""One row's first episode (rates are means over its steps, returns sums)."""
RECORDED = ('episode_coverage_rate', 'episode_real_coverage_rate', 'episode_target_return', 'mean_transport_rate',
            'num_delivered_cargoes')
"""The vector env's infos an episode's summary is read from, at its last step (the core's statistics)."""


def play_batch(config, camera_team, target_team, episodes: int, seed: int | Sequence[int] = 0,
               max_episode_steps: int | None = None, progress: Callable[[int, int], None] | None = None,
               on_step: Callable | None = None) -> tuple[list[BatchEpisode], dict]:
    """Play `episodes` games at once, row i seeded with `seed + i` (or `seed[i]` for a sequence of
    `episodes` seeds), each to the end of its first episode (at most `max_episode_steps` steps; default:
    the config's limit).

    `camera_team` / `target_team` are batched teams (`mate.teams.BatchedTeam`) or factories
    `f(num_envs, counts) -> team`. `progress(finished_rows, episodes)` is called after every step on
    which some row finished. `on_step(vec, step)` is called after the reset (step 0) and after every step
    of the first row's episode (e.g. to record its frames: `vec.get_world(0)`); its time is left out of
    the timing. Returns (one `BatchEpisode` per row, in row order; timing: `env_steps` played in the
    finished episodes, `seconds` and `env_steps_per_second`).

    With the greedy or random teams of this package seeded like the env (`GreedyTeam(team, episodes,
    counts, seed)` for both teams), row i is the episode `mate.evaluation.evaluate.play_episode` plays with seed
    `seed + i`.
    """
    if episodes < 1:
        raise ValueError(f'episodes must be at least 1, got {episodes}')
    seeds = [int(seed) + i for i in range(episodes)] if np.ndim(seed) == 0 else [int(s) for s in seed]
    if len(seeds) != episodes:
        raise ValueError(f'seed must be one integer or {episodes} integers (one per episode), got {len(seeds)}')
    overrides = {} if max_episode_steps is None else {'max_episode_steps': int(max_episode_steps)}
    vec = make_vec('MultiAgentTracking-v0', num_envs=episodes, config=config, autoreset_mode='disabled', **overrides)
    counts = (vec.num_cameras, vec.num_targets, vec.num_obstacles)
    cameras, targets = (team(episodes, counts) if callable(team) and not hasattr(team, 'act') else team
                        for team in (camera_team, target_team))
    if cameras.team is not Team.CAMERA or targets.team is not Team.TARGET:
        raise ValueError('camera_team must play the cameras and target_team the targets')
    see = _sight(vec, cameras, targets, counts)
    start = time.perf_counter()
    (camera_obs, target_obs), _ = vec.reset(seed=seeds)
    see(camera_obs, target_obs, 0)
    everyone = np.ones(episodes, dtype=bool)
    cameras.reset(camera_obs, everyone)
    targets.reset(target_obs, everyone)
    live = everyone.copy()
    aside = 0.0                  # seconds of `on_step`, left out of the timing

    def observe(step: int) -> None:
        nonlocal aside
        if on_step is not None:
            begin = time.perf_counter()
            on_step(vec, step)
            aside += time.perf_counter() - begin

    observe(0)
    record = {key: np.zeros(episodes) for key in RECORDED}
    length = np.zeros(episodes, dtype=np.int64)
    while live.any():
        actions = (cameras.act(camera_obs), targets.act(target_obs))
        (camera_obs, target_obs), rewards, terminated, truncated, infos = vec.step(actions)
        see(camera_obs, target_obs, int(length.max()) + 1)
        if live[0]:
            observe(int(length[0]) + 1)
        length += live
        finished = terminated | truncated
        ended = live & finished
        if ended.any():                       # the episode's statistics, as the core counted them
            for key, values in record.items():
                values[ended] = infos[key][ended]
            live &= ~ended
            if progress is not None:
                progress(int((~live).sum()), episodes)
        if finished.any() and live.any():   # finished rows restart (ignored) so that the batch keeps stepping
            (camera_obs, target_obs), _ = vec.reset(options={'reset_mask': finished})
            see(camera_obs, target_obs, int(length.max()))
            if ended.any():
                idle(cameras, ended)
                idle(targets, ended)
    seconds = time.perf_counter() - start - aside
    normaliser = float(vec.params.max_target_team_episode_reward)
    coverage, real_coverage, target_return, transport, delivered = (record[key] for key in RECORDED)
    results = [BatchEpisode(seed=seeds[i], coverage_rate=float(coverage[i]), real_coverage_rate=float(real_coverage[i]),
                            transport_rate=float(transport[i]), camera_return=float(-target_return[i]),
                            target_return=float(target_return[i]),
                            normalized_target_return=float(target_return[i] / normaliser),
                            delivered_cargoes=int(delivered[i]), episode_length=int(length[i]))
               for i in range(episodes)]
    steps = int(length.sum())
    return results, {'env_steps': steps, 'seconds': seconds, 'env_steps_per_second': steps / max(seconds, 1e-9)}


def _sight(vec, cameras, targets, counts) -> Callable[[np.ndarray, np.ndarray, int], None]:
    """What a team sees beyond its raw observations, applied after every reset and step: a team with
    `full_observability` (a policy trained with it) gets its observations filled in place as the
    `EnhancedObservation` wrapper fills them, and a team with `watch(vec, step)` (`UpperBoundTeam`, which reads
    the true state) watches the vector env."""
    enhanced = [getattr(team, 'full_observability', False) for team in (cameras, targets)]
    watchers = [team.watch for team in (cameras, targets) if hasattr(team, 'watch')]
    if not any(enhanced) and not watchers:
        return lambda camera_obs, target_obs, step: None
    from ..core.observability import empty_warehouses, enhance_observations

    def see(camera_obs: np.ndarray, target_obs: np.ndarray, step: int) -> None:
        if any(enhanced):
            enhance_observations(camera_obs, target_obs, vec.obstacle_states, empty_warehouses(vec.remaining_cargoes),
                                 *counts, camera=enhanced[0], target=enhanced[1])
        for watch in watchers:
            watch(vec, step)

    return see
