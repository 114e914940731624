"""Batched play of any camera team against any target team: the engine of payoff matrices.

`play_batch(config, camera_team, target_team, episodes, seed)` plays `episodes` games at once in one
vector env (row i seeded with `seed + i`, as `mate evaluate` seeds episode i) until every row has
finished its first episode, and returns one `BatchEpisode` per row. Each team is a *batched team*:
an object acting for every agent of every row in one call,

    team.reset(observation (B, N, D) float64 raw, rows (B,) bool)   # rows that start an episode
    team.act(observation (B, N, D)) -> actions (B, N, 2)            # once per env step
    team.idle(rows)                     # optional: these rows' actions no longer matter (finished games)

Batched teams here:

* `PolicyTeam`: a trained policy (checkpoint, pretrained or in memory) as the deployment agents of
  `mate.learn.agents` apply it: the same preprocessing, sighting memory, velocity columns and
  recurrent state, a decision per row every `frame_skip` steps (all rows and agents deciding at a step
  in one forward pass), the HRL executor re-aiming at every step. The whole team of a row decides together
  (inputs (R, N, D)), so the agents of a TarMAC policy read each other's last messages, and those of an
  I2C policy the current observations of the teammates their priors ask, as in training.
  Sampling (the default of a checkpoint) uses the team's own generator, so it matches the agents in distribution, not draw by draw.
* `RandomTeam`: `RandomCameraAgent` / `RandomTargetAgent` (uniform in each agent's action box, held
  20 steps).
* `GreedyTeam`: the batched greedy rules of `mate.learn.opponents` (their documented differences from
  the Python greedy agents apply: the cameras share sightings at once instead of after 6-49 steps).
* `MixtureTeam`: one member per row and episode, drawn with the given weights (all agents of a row
  play the same member, as the mixture agents of a team do).

`make_team(spec, team, num_envs, counts, seed)` builds one from `mate evaluate`'s agent names.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np
import torch

from ..evaluate import EpisodeSummary
from ..messages import Team
from ..vector import make_vec
from .agents import LoadedPolicy, choose, load_policy, pretrained_path
from .envs import action_high, as_team, discrete_to_continuous
from .hrl import executor_actions, masked_selection_logits, selection_bits
from .memory import SightingMemory
from .opponents import VecGreedyCamera, VecGreedyTarget

__all__ = ['BATCHED_AGENTS', 'BatchEpisode', 'GreedyTeam', 'MixtureTeam', 'PolicyTeam', 'RandomTeam', 'make_team',
           'play_batch']

BATCHED_AGENTS = ('random', 'greedy', 'checkpoint:PATH', 'pretrained:NAME')
"""Agent names of `mate evaluate` that have a batched team."""


_NEVER = np.iinfo(np.int64).max // 2
"""A decision countdown that does not run out within any episode."""


def _idle(team, rows: np.ndarray) -> None:
    """`team.idle(rows)` for the teams that have it (the others just go on acting there)."""
    if hasattr(team, 'idle'):
        team.idle(rows)


class PolicyTeam:
    """A trained policy playing every agent of a team in B games (see the module docstring).

    Args:
        policy: a `LoadedPolicy` (`load_policy(path)`), or a checkpoint path.
        team: Team.CAMERA / Team.TARGET (or 'camera' / 'target').
        num_envs: B.
        counts: (Nc, Nt, No) of the game; must be the policy's.
        seed: seed of the sampling generator.
        deterministic: argmax instead of sampling (None: the policy file's default).
        frame_skip: env steps a decision is held (None: the training frame skip).
    """

    def __init__(self, policy, team, num_envs: int, counts, seed: int | None = None,
                 deterministic: bool | None = None, frame_skip: int | None = None) -> None:
        self.team = as_team(team)
        self.policy = policy if isinstance(policy, LoadedPolicy) else load_policy(policy, self.team)
        meta = self.policy.meta
        if meta['team'] != self.team.name.lower():
            raise ValueError(f'policy {self.policy.source!r} was trained for the {meta["team"]} team, '
                             f'not the {self.team.name.lower()} team')
        self.counts = tuple(int(n) for n in counts)
        if list(self.counts) != list(meta['counts']):
            raise ValueError(f'policy {self.policy.source!r} was trained with (cameras, targets, obstacles) = '
                             f'{tuple(meta["counts"])}; this game has {self.counts}')
        self.num_envs = int(num_envs)
        self.num_agents = self.counts[0] if self.team is Team.CAMERA else self.counts[1]
        self.deterministic = bool(meta.get('deterministic', False) if deterministic is None else deterministic)
        self.frame_skip = int(frame_skip or meta.get('frame_skip', 1))
        self.heads = int(meta.get('action_heads', 1))
        self.rng = np.random.default_rng(seed)
        shape = (self.num_envs, self.num_agents)
        self.continuous = bool(meta.get('continuous', False))       # MADDPG: held actions in [-1, 1]^2
        self.held = (np.zeros(shape + (int(meta['num_actions']),)) if self.continuous
                     else np.zeros(shape + (self.heads,), dtype=np.int64))
        self.countdown = np.zeros(self.num_envs, dtype=np.int64)
        period = int(meta.get('memory', 0))
        self.sightings = SightingMemory(self.num_envs, self.counts, period) if period else None
        self.previous = None                                        # velocity: last step's observations
        self.memory = self.policy.initial_memory(*shape)   # recurrent state: (h, c), (h,), (h, c, messages) or None

    def reset(self, observation: np.ndarray, rows: np.ndarray) -> None:
        rows = np.asarray(rows, dtype=bool)
        self.countdown[rows] = 0
        if self.sightings is not None:
            self.sightings.forget(rows)
        if self.previous is None:
            self.previous = np.array(observation, dtype=np.float64)
        self.previous[rows] = observation[rows]
        if self.memory is not None:
            index = torch.as_tensor(rows)
            for part in self.memory:
                part[index] = 0.0

    def idle(self, rows: np.ndarray) -> None:
        """Make no more decisions in the rows `rows` (until their next reset): their games are over."""
        self.countdown[np.asarray(rows, dtype=bool)] = _NEVER

    def _decide(self, observation: np.ndarray, rows: np.ndarray) -> None:
        """New decisions for the rows `rows` (indices): one forward pass for all their agents."""
        raw = observation[rows]
        memory = None if self.sightings is None else self.sightings.features(raw, rows)
        processed = self.policy.inputs(raw, memory, self.previous[rows])
        if self.memory is not None:
            index = torch.as_tensor(rows)
            logits, memory = self.policy.logits(processed, tuple(part[index] for part in self.memory))
            for part, value in zip(self.memory, memory):
                part[index] = value
        else:
            logits = self.policy.logits(processed)
        if self.continuous:
            self.held[rows] = logits.reshape(len(rows), self.num_agents, -1)
            return
        logits = logits.reshape(len(rows), self.num_agents, self.heads, -1)
        if self.policy.meta.get('joint_selection'):   # only selections of visible targets, as in training
            logits = masked_selection_logits(logits[..., 0, :], raw, *self.counts)[..., None, :]
        self.held[rows] = choose(logits, self.deterministic, self.rng)

    def act(self, observation: np.ndarray) -> np.ndarray:
        observation = np.asarray(observation, dtype=np.float64)
        if self.sightings is not None:   # every step: the team's sightings enter its memory
            self.sightings.tick()
            self.sightings.observe_team(observation)
        deciding = np.flatnonzero(self.countdown <= 0)
        if deciding.size:
            self._decide(observation, deciding)
            self.countdown[deciding] = self.frame_skip
        self.countdown -= 1
        self.previous = observation.copy()
        if self.policy.meta.get('hrl'):
            selection = self.held
            if self.policy.meta.get('joint_selection'):   # one index among 2^Nt selections
                selection = selection_bits(self.counts[1])[self.held[..., 0]]
            return executor_actions(observation, selection, *self.counts)
        if self.continuous:
            return self.held * action_high(observation, self.team)
        return discrete_to_continuous(self.held[..., 0], observation, self.team, self.policy.meta['levels'])


class RandomTeam:
    """`RandomCameraAgent` / `RandomTargetAgent` for B games: a uniform action in each agent's box,
    redrawn at steps 0, frame_skip, 2 frame_skip, ... of the row's episode."""

    def __init__(self, team, num_envs: int, counts, seed: int | None = None, frame_skip: int = 20) -> None:
        if int(frame_skip) < 1:
            raise ValueError(f'frame_skip must be a positive integer, got {frame_skip!r}')
        self.team = as_team(team)
        self.frame_skip = int(frame_skip)
        self.rng = np.random.default_rng(seed)
        count = counts[0] if self.team is Team.CAMERA else counts[1]
        self.action = np.zeros((num_envs, count, 2))
        self.step = np.zeros(num_envs, dtype=np.int64)

    def reset(self, observation: np.ndarray, rows: np.ndarray) -> None:
        self.step[np.asarray(rows, dtype=bool)] = 0

    def act(self, observation: np.ndarray) -> np.ndarray:
        drawing = np.flatnonzero(self.step % self.frame_skip == 0)
        if drawing.size:
            high = action_high(np.asarray(observation)[drawing], self.team)
            self.action[drawing] = (2.0 * self.rng.random(high.shape) - 1.0) * high
        self.step += 1
        return self.action.copy()


class GreedyTeam:
    """The batched greedy rules (`VecGreedyCamera` / `VecGreedyTarget`) as a batched team."""

    def __init__(self, team, num_envs: int, counts, seed: int | None = None) -> None:
        self.team = as_team(team)
        nc, nt, no = counts
        self.rules = (VecGreedyCamera(num_envs, nc, nt, no, seed=seed) if self.team is Team.CAMERA
                      else VecGreedyTarget(num_envs, nt, seed=seed))

    def reset(self, observation: np.ndarray, rows: np.ndarray) -> None:
        self.rules.reset(observation, np.asarray(rows, dtype=bool))

    def act(self, observation: np.ndarray) -> np.ndarray:
        return self.rules.act(observation)


class MixtureTeam:
    """Plays member k in a row for a whole episode, k drawn with probabilities `weights` at the row's
    reset. Every member steps on every row (its per-row state stays consistent) and each row takes its
    member's actions; members that can idle (`PolicyTeam`) make no decisions in the rows they do not
    play, so a mixture of policies costs about one policy's forward passes.

    Args:
        members: batched teams of one team, all for the same B games.
        weights: non-negative, not all zero (default: equal); normalised.
        seed: seed of the generator that draws the members.
        assignment: (B,) member index of every row, fixed instead of drawn (a payoff matrix's entries
            played side by side in one batch).
    """

    def __init__(self, members: Sequence, weights=None, seed: int | None = None, assignment=None) -> None:
        self.members = list(members)
        if not self.members:
            raise ValueError('a mixture needs at least one member')
        teams = {member.team for member in self.members}
        if len(teams) != 1:
            raise ValueError('the members of a mixture must all play the same team')
        self.team = teams.pop()
        weights = np.ones(len(self.members)) if weights is None else np.asarray(weights, dtype=np.float64).ravel()
        if weights.shape != (len(self.members),) or not np.isfinite(weights).all() or (weights < 0).any() \
                or not (weights > 0).any():
            raise ValueError(f'weights must be {len(self.members)} finite non-negative numbers, not all zero; '
                             f'got {weights.tolist()}')
        self.weights = weights / weights.sum()
        self.rng = np.random.default_rng(seed)
        self.choice = None
        self.assignment = None
        if assignment is not None:
            self.assignment = np.asarray(assignment, dtype=np.int64)
            if self.assignment.ndim != 1 or ((self.assignment < 0) | (self.assignment >= len(self.members))).any():
                raise ValueError(f'assignment must be a vector of member indices in [0, {len(self.members) - 1}]')

    def reset(self, observation: np.ndarray, rows: np.ndarray) -> None:
        rows = np.asarray(rows, dtype=bool)
        if self.choice is None:
            self.choice = np.zeros(len(rows), dtype=np.int64)
        if self.assignment is not None:
            if len(self.assignment) != len(rows):
                raise ValueError(f'assignment has {len(self.assignment)} rows; the batch has {len(rows)}')
            self.choice[rows] = self.assignment[rows]
        else:
            self.choice[rows] = self.rng.choice(len(self.members), size=int(rows.sum()), p=self.weights)
        for k, member in enumerate(self.members):
            member.reset(observation, rows)
            _idle(member, rows & (self.choice != k))

    def idle(self, rows: np.ndarray) -> None:
        for member in self.members:
            _idle(member, rows)

    def act(self, observation: np.ndarray) -> np.ndarray:
        actions = [member.act(observation) for member in self.members]
        return np.stack(actions)[self.choice, np.arange(len(self.choice))]


def make_team(spec: str, team, num_envs: int, counts, seed: int | None = None, **kwargs):
    """A batched team from an agent name of `mate evaluate`: 'random', 'greedy', 'checkpoint:PATH' or
    'pretrained:NAME' (kwargs: deterministic, frame_skip). ValueError naming the batched agents otherwise."""
    team = as_team(team)
    kind, _, value = spec.partition(':')
    if spec == 'random':
        return RandomTeam(team, num_envs, counts, seed=seed, **kwargs)
    if spec == 'greedy':
        if kwargs:
            raise ValueError(f'the batched greedy agents take no keyword arguments, got {sorted(kwargs)}')
        return GreedyTeam(team, num_envs, counts, seed=seed)
    if kind in ('checkpoint', 'pretrained') and value:
        path = value if kind == 'checkpoint' else pretrained_path(value)
        return PolicyTeam(load_policy(path, team), team, num_envs, counts, seed=seed, **kwargs)
    raise ValueError(f'agent {spec!r} has no batched version; batched agents: {", ".join(BATCHED_AGENTS)}')


BatchEpisode = EpisodeSummary
"""One row's first episode (`mate.evaluate.EpisodeSummary`: rates are means over its steps, returns sums)."""


def play_batch(config, camera_team, target_team, episodes: int, seed: int | Sequence[int] = 0,
               max_episode_steps: int | None = None,
               progress: Callable[[int, int], None] | None = None) -> tuple[list[BatchEpisode], dict]:
    """Play `episodes` games at once, row i seeded with `seed + i` (or `seed[i]` for a sequence of
    `episodes` seeds), each to the end of its first episode (at most `max_episode_steps` steps; default:
    the config's limit).

    `camera_team` / `target_team` are batched teams or factories `f(num_envs, counts) -> team`.
    `progress(finished_rows, episodes)` is called after every step on which some row finished.
    Returns (one `BatchEpisode` per row, in row order; timing: `env_steps` played in the finished
    episodes, `seconds` and `env_steps_per_second`).
    """
    if episodes < 1:
        raise ValueError(f'episodes must be at least 1, got {episodes}')
    seeds = [int(seed) + i for i in range(episodes)] if np.ndim(seed) == 0 else [int(s) for s in seed]
    if len(seeds) != episodes:
        raise ValueError(f'seed must be one integer or {episodes} integers (one per episode), got {len(seeds)}')
    overrides = {} if max_episode_steps is None else {'max_episode_steps': int(max_episode_steps)}
    vec = make_vec('MultiAgentTracking-v0', num_envs=episodes, config=config, autoreset_mode='disabled', **overrides)
    counts = (vec.num_cameras, vec.num_targets, vec.num_obstacles)
    cameras = camera_team(episodes, counts) if callable(camera_team) and not hasattr(camera_team, 'act') else camera_team
    targets = target_team(episodes, counts) if callable(target_team) and not hasattr(target_team, 'act') else target_team
    if cameras.team is not Team.CAMERA or targets.team is not Team.TARGET:
        raise ValueError('camera_team must play the cameras and target_team the targets')
    start = time.perf_counter()
    (camera_obs, target_obs), _ = vec.reset(seed=seeds)
    everyone = np.ones(episodes, dtype=bool)
    cameras.reset(camera_obs, everyone)
    targets.reset(target_obs, everyone)
    live = everyone.copy()
    coverage, real_coverage, returns = np.zeros(episodes), np.zeros(episodes), np.zeros((2, episodes))
    length = np.zeros(episodes, dtype=np.int64)
    transport, delivered = np.zeros(episodes), np.zeros(episodes, dtype=np.int64)
    while live.any():
        actions = (cameras.act(camera_obs), targets.act(target_obs))
        (camera_obs, target_obs), rewards, terminated, truncated, infos = vec.step(actions)
        coverage += np.where(live, infos['coverage_rate'], 0.0)
        real_coverage += np.where(live, infos['real_coverage_rate'], 0.0)
        returns += np.where(live, np.stack(rewards), 0.0)
        length += live
        finished = terminated | truncated
        ended = live & finished
        if ended.any():
            transport[ended] = infos['mean_transport_rate'][ended]
            delivered[ended] = infos['num_delivered_cargoes'][ended]
            live &= ~ended
            if progress is not None:
                progress(int((~live).sum()), episodes)
        if finished.any() and live.any():   # finished rows restart (ignored) so that the batch keeps stepping
            (camera_obs, target_obs), _ = vec.reset(options={'reset_mask': finished})
            if ended.any():
                _idle(cameras, ended)
                _idle(targets, ended)
    seconds = time.perf_counter() - start
    normaliser = float(vec.params.max_target_team_episode_reward)
    results = [BatchEpisode(seed=seeds[i], coverage_rate=float(coverage[i] / length[i]),
                            real_coverage_rate=float(real_coverage[i] / length[i]),
                            transport_rate=float(transport[i]), camera_return=float(returns[0, i]),
                            target_return=float(returns[1, i]),
                            normalized_target_return=float(returns[1, i] / normaliser),
                            delivered_cargoes=int(delivered[i]), episode_length=int(length[i]))
               for i in range(episodes)]
    steps = int(length.sum())
    return results, {'env_steps': steps, 'seconds': seconds, 'env_steps_per_second': steps / max(seconds, 1e-9)}
