"""`mate evaluate`: play camera agents against target agents and summarise the episodes.

Protocol (the one behind the reference statistics of the original): episode i uses seed
`seed + i`: a fresh environment reset with that seed, camera agents `CameraCls(seed=...)`
spawned per camera and target agents likewise; each step the camera team observes,
communicates (two rounds) and acts, then the target team does, then the env steps. An
episode ends when every cargo unit is delivered or after `max_episode_steps` steps.
The first episode can be rendered to a GIF and/or a video.
"""

from __future__ import annotations

import importlib
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..agents import (
    CameraAgentBase,
    GreedyCameraAgent,
    GreedyTargetAgent,
    HeuristicCameraAgent,
    HeuristicTargetAgent,
    MixtureCameraAgent,
    MixtureTargetAgent,
    NaiveCameraAgent,
    NaiveTargetAgent,
    RandomCameraAgent,
    RandomTargetAgent,
    TargetAgentBase,
    UpperBoundCameraAgent,
    group_reset,
    group_step,
)
from ..messages import Team
from ..teams.play import EpisodeSummary

BUILT_IN_AGENTS = {
    Team.CAMERA: {'random': RandomCameraAgent, 'naive': NaiveCameraAgent, 'greedy': GreedyCameraAgent,
                  'heuristic': HeuristicCameraAgent, 'mixture': MixtureCameraAgent,
                  'upper-bound': UpperBoundCameraAgent},
    Team.TARGET: {'random': RandomTargetAgent, 'naive': NaiveTargetAgent, 'greedy': GreedyTargetAgent,
                  'heuristic': HeuristicTargetAgent, 'mixture': MixtureTargetAgent},
}
BASE_CLASSES = {Team.CAMERA: CameraAgentBase, Team.TARGET: TargetAgentBase}
SEES_TRUE_STATE = ('upper-bound',)
"""Agents that read the true state: in the single env the cameras get the `EnhancedObservation` wrapper, batched
the team watches the vector env (`UpperBoundTeam.watch`)."""


def resolve_agent(spec: str, team: Team) -> Callable[..., Any]:
    """An agent factory from a short name (`greedy`), `module:Class`, `checkpoint:PATH` or
    `pretrained:NAME`; called with the agent's keyword arguments (seed included)."""
    if spec in BUILT_IN_AGENTS[team]:
        return BUILT_IN_AGENTS[team][spec]
    prefix = spec.split(':', 1)[0]
    if prefix in ('checkpoint', 'pretrained'):
        try:
            from ..policies.policy import load_agent
        except ImportError as exc:
            raise ValueError(f'{spec!r}: loading learned policies needs the training extra '
                             f"(pip install 'mate[train]'): {exc}") from None
        return load_agent(spec, team)
    if ':' not in spec:
        names = ', '.join(BUILT_IN_AGENTS[team])
        raise ValueError(f'unknown {team.name.lower()} agent {spec!r}: use one of {names}, '
                         "'module:Class', 'checkpoint:PATH' or 'pretrained:NAME'")
    module_name, _, attribute = spec.partition(':')
    try:
        cls = getattr(_import_from_working_directory(module_name), attribute)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f'cannot load agent {spec!r}: {exc}') from None
    base = BASE_CLASSES[team]
    if not (isinstance(cls, type) and issubclass(cls, base)):
        raise ValueError(f'agent {spec!r} must be a subclass of mate.{base.__name__}')
    return cls


def _import_from_working_directory(module_name: str):
    """Import `module_name` with the current directory first on the module path, as `python -m` finds modules (the
    `mate` console script does not put it there)."""
    import os
    import sys

    here = os.getcwd()
    added = here not in sys.path
    if added:
        sys.path.insert(0, here)
    try:
        return importlib.import_module(module_name)
    finally:
        if added:
            sys.path.remove(here)


@dataclass
class EpisodeResult(EpisodeSummary):
    """An `EpisodeSummary` with the speed of its play (env steps per second)."""
    steps_per_second: float


class FrameRecorder:
    """Renders every `every`-th step of an episode into frames of `size` x `size` pixels (at most
    `max_frames`), with the heads-up line (step, coverage, delivered cargo) unless `hud` is False;
    `max_episode_steps`: the episode's step cap, when below the env's own (shown in the HUD)."""

    def __init__(self, size: int = 600, every: int = 4, max_frames: int = 300, hud: bool = True,
                 max_episode_steps: int | None = None) -> None:
        from ..envs.render import Renderer
        self.renderer = Renderer('rgb_array', window_size=size, hud=hud)
        self.every, self.max_frames, self.frames = every, max_frames, []
        self.max_episode_steps = max_episode_steps

    def _cap(self, env) -> int:
        return env.max_episode_steps if self.max_episode_steps is None else min(env.max_episode_steps,
                                                                                 self.max_episode_steps)

    def __call__(self, env, step: int, joint_action=None) -> None:
        """Record a single env's current world (a `play_episode` callback)."""
        if step % self.every == 0 and len(self.frames) < self.max_frames:
            env = env.unwrapped
            self.frames.append(self.renderer.render(env, max_episode_steps=self._cap(env)))

    def record_row(self, vec, step: int) -> None:
        """Record row 0 of a vector env (a `play_batch` callback: the first game of a batched evaluation)."""
        if step % self.every == 0 and len(self.frames) < self.max_frames:
            self.frames.append(self.renderer.frame(vec.get_world(0), transmittance=float(vec.params.transmittance),
                                                   name=vec.name, max_episode_steps=self._cap(vec)))

    def close(self) -> None:
        self.renderer.close()


def check_agents_fit(env, camera_factory, target_factory, seed: int) -> None:
    """Reset `env` with `seed` and the agents of both teams on its first observations, as `play_episode` does,
    so that an agent refusing this game (ValueError: a policy trained for another preset or team size) says so
    before any episode is played."""
    (camera_obs, target_obs), _ = env.reset(seed=seed)
    group_reset(camera_factory(seed=seed).spawn(env.num_cameras), camera_obs)
    group_reset(target_factory(seed=seed).spawn(env.num_targets), target_obs)


def play_episode(env, camera_factory, target_factory, seed: int, max_steps: int,
                 on_step: Callable | None = None) -> EpisodeResult:
    """One episode of the protocol in the module docstring.

    `on_step(env, step, joint_action)` is called after reset (step 0, joint_action None) and
    after every step with the (camera_action, target_action) just played (e.g. a
    `FrameRecorder`); its time is left out of the episode's steps/s. ValueError if `max_steps` < 1.
    """
    if max_steps < 1:
        raise ValueError(f'max_steps must be at least 1, got {max_steps}')
    (camera_obs, target_obs), (camera_infos, target_infos) = env.reset(seed=seed)
    cameras = camera_factory(seed=seed).spawn(env.num_cameras)
    targets = target_factory(seed=seed).spawn(env.num_targets)
    group_reset(cameras, camera_obs)
    group_reset(targets, target_obs)
    callback_seconds = 0.0

    def observe(step: int, joint_action) -> None:
        nonlocal callback_seconds
        if on_step is not None:
            start = time.perf_counter()
            on_step(env, step, joint_action)
            callback_seconds += time.perf_counter() - start

    observe(0, None)
    start = time.perf_counter()
    for step in range(1, max_steps + 1):
        joint_action = (group_step(env, cameras, camera_obs, camera_infos),
                        group_step(env, targets, target_obs, target_infos))
        (camera_obs, target_obs), rewards, terminated, truncated, (camera_infos, target_infos) = env.step(joint_action)
        info = target_infos[0] if target_infos else camera_infos[0]
        observe(step, joint_action)
        if terminated or truncated:
            break
    elapsed = time.perf_counter() - start - callback_seconds
    target_return = info['episode_target_return']        # the episode's statistics, as the core counted them
    return EpisodeResult(
        seed=seed, coverage_rate=info['episode_coverage_rate'], real_coverage_rate=info['episode_real_coverage_rate'],
        transport_rate=float(info['mean_transport_rate']), camera_return=-target_return, target_return=target_return,
        normalized_target_return=float(target_return / env.max_target_team_episode_reward),
        delivered_cargoes=int(info['num_delivered_cargoes']), episode_length=step,
        steps_per_second=step / max(elapsed, 1e-9))


SUMMARY_ROWS = (
    ('camera', 'coverage rate', 'coverage_rate'),
    ('camera', 'real coverage rate', 'real_coverage_rate'),
    ('camera', 'team return', 'camera_return'),
    ('target', 'transport rate', 'transport_rate'),
    ('target', 'delivered cargo', 'delivered_cargoes'),
    ('target', 'team return', 'target_return'),
    ('target', 'normalised return', 'normalized_target_return'),
    ('episode', 'length (steps)', 'episode_length'),
    ('episode', 'speed (steps/s)', 'steps_per_second'),
)


BATCHED = ('random', 'greedy', 'upper-bound')
"""Built-in agents with a batched team (`mate.teams`); learned policies (checkpoint:, pretrained:) have one too."""


def has_batched_team(agent: str) -> bool:
    """Whether the `mate evaluate` agent name `agent` can play as a batched team (`batched_team`)."""
    return agent in BATCHED or agent.partition(':')[0] in ('checkpoint', 'pretrained')


def batched_team(env, agent: str, team: Team, episodes: int, seed: int, kwargs: dict | None = None,
                 device: str = 'cpu'):
    """The batched team of `mate evaluate`'s agent name `agent` for `team` (random, greedy, upper-bound: `mate.teams`;
    checkpoint:PATH, pretrained:NAME: `mate.policies.policy.PolicyTeam`; `kwargs`: the agents' options, e.g.
    `frame_skip`, `memory_period`, and `deterministic` for policies) for `episodes` games of `env`'s sizes, seeded
    with `seed`: row i plays as the agents of `play_episode`'s episode i (for the rule agents, the same episode);
    a policy's forward passes run on `device`. ValueError for an unknown agent or one without a batched version;
    TypeError/ValueError for bad options."""
    from .. import teams

    resolve_agent(agent, team)                       # unknown names: the usual message
    counts = (env.num_cameras, env.num_targets, env.num_obstacles)
    if agent in teams.RULE_TEAMS:
        return teams.make_team(agent, team, episodes, counts, seed=seed, **(kwargs or {}))
    try:
        from ..policies.policy import make_team
    except ImportError as exc:
        raise ValueError(f"{agent}: batched policies need the training extra (pip install 'mate[train]'): "
                         f'{exc}') from None
    return make_team(agent, team, episodes, counts, seed=seed, device=device, **(kwargs or {}))


def play_batched(config, cameras, targets, episodes: int, seed: int, max_steps: int,
                 progress: Callable[[int, int], None] | None = None,
                 recorder: FrameRecorder | None = None) -> list[EpisodeResult]:
    """Every episode at once in one vector env (row i seeded with seed + i) with batched teams
    (`batched_team`); each result's `steps_per_second` is the whole batch's. `recorder` records the first
    game's frames (a team that reads the true state, `UpperBoundTeam`, watches the vector env: `play_batch`)."""
    from ..teams import play_batch
    if max_steps < 1:
        raise ValueError(f'max_steps must be at least 1, got {max_steps}')
    batch, timing = play_batch(config, cameras, targets, episodes, seed, max_steps, progress,
                               on_step=None if recorder is None else recorder.record_row)
    return [EpisodeResult(**asdict(episode), steps_per_second=timing['env_steps_per_second']) for episode in batch]


def summarise(results: list[EpisodeResult]) -> list[dict]:
    """Mean and sample standard deviation over episodes of every summary row (works for any
    number of episodes >= 1, deliveries or not)."""
    rows = []
    for team, label, key in SUMMARY_ROWS:
        values = np.array([getattr(r, key) for r in results], dtype=float)
        std = float(values.std(ddof=1)) if len(values) > 1 else 0.0
        rows.append({'team': team, 'metric': label, 'key': key, 'mean': float(values.mean()), 'std': std})
    return rows


def write_json(path: str | Path, settings: dict, results: list[EpisodeResult], summary: list[dict]) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({'settings': settings, 'summary': summary,
                                'episodes': [asdict(r) for r in results]}, indent=2))
    return path
