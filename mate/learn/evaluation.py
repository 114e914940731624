"""The evaluation protocol of a training run: the policy played on held-out seeds, at fixed intervals and at the end.

The field's protocol for results one can trust (Agarwal et al. 2021; Gorsane et al. 2022, as marl-eval, Mava and
BenchMARL follow it): a learner is scored on evaluation episodes whose seeds it never trained on, at fixed
intervals of decisions, and, at the end, the best of those policies is played again on other held-out seeds with
ten times the episodes (the "absolute metric").

* Every `eval_every` decision steps (`--eval-every`, 0: off) the current policy plays `eval_episodes` episodes in one
  batch (`mate.teams.play_batch`, the policy as a `PolicyTeam` acting as it would deployed: sampling for policy
  gradients, argmax for Q-learners; the opponent the run's training opponent, the greedy rules) on env seeds
  `EVALUATION_SEEDS`, `EVALUATION_SEEDS + 1`, ...: the same seeds at every evaluation of every run. Each episode is
  cut at the training horizon, so an evaluation scores what the training curve shows, on fresh games. One JSON line
  per evaluation goes to `evaluations.jsonl` in the run directory (decision steps, every episode's summary).
* The evaluation with the best mean team metric (cameras: the coverage rate; targets: the normalised target return)
  keeps its policy as `best-eval.pt`. When the run is complete, that policy plays `ABSOLUTE_FACTOR` x
  `eval_episodes` episodes on seeds `ABSOLUTE_SEEDS`, ... (never used for training or for choosing it); the result
  goes to `absolute.json`.
* Training envs are seeded `seed + b` for the rows b of their first reset and continue their rows' random streams
  after (every later episode of a row draws from its stream); a run with an evaluation must have
  `seed + num_envs <= EVALUATION_SEEDS` (checked), so no training episode starts from an evaluation seed.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..evaluation.protocol import ABSOLUTE_FACTOR, ABSOLUTE_SEEDS, EVALUATION_SEEDS, TEAM_METRIC
from ..policies.spec import PolicySpec

__all__ = ['ABSOLUTE_FACTOR', 'ABSOLUTE_SEEDS', 'EVALUATION_SEEDS', 'Evaluator', 'TEAM_METRIC', 'evaluate_policy',
           'read_evaluations']


def evaluate_policy(policy, episodes: int, first_seed: int, max_episode_steps: int | None = None,
                    opponent: str = 'greedy', device='cpu', seed: int | None = None) -> list[dict]:
    """Play `policy` (a `LoadedPolicy`) for `episodes` episodes in one batch on env seeds first_seed, first_seed + 1,
    ..., against the other team's `opponent` (a batched agent name: 'greedy', 'random'), each cut at
    `max_episode_steps` (None: the game's limit). The policy samples with generator seed `seed` (default
    `first_seed`); the opponent's row i is seeded first_seed + i, as the env. Returns one dict per episode
    (`mate.teams.BatchEpisode` fields: coverage_rate, normalized_target_return, episode_length, ...)."""
    from ..teams import make_team, play_batch
    from ..policies.policy import PolicyTeam

    spec: PolicySpec = policy.spec
    counts = spec.counts
    own = PolicyTeam(policy, spec.team, episodes, counts, seed=first_seed if seed is None else seed, device=device)
    other = make_team(opponent, 'target' if spec.team == 'camera' else 'camera', episodes, counts, seed=first_seed)
    cameras, targets = (own, other) if spec.team == 'camera' else (other, own)
    results, _ = play_batch(spec.game, cameras, targets, episodes, seed=first_seed, max_episode_steps=max_episode_steps)
    return [asdict(result) for result in results]


def read_evaluations(run_dir) -> list[dict]:
    """The periodic evaluations of a run directory (`evaluations.jsonl`), in order ([] without any)."""
    path = Path(run_dir) / 'evaluations.jsonl'
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


class Evaluator:
    """The evaluation protocol of one run (module docstring).

    Args:
        run_dir: the run directory (evaluations.jsonl, best-eval.pt, absolute.json).
        spec: the trained policy's spec.
        every: decision steps between evaluations.
        episodes: episodes per evaluation.
        max_episode_steps: the episodes' cut, env steps (the training horizon).
        device: where the policy's forward passes run.
    """

    def __init__(self, run_dir, spec: PolicySpec, every: int, episodes: int, max_episode_steps: int | None,
                 device='cpu') -> None:
        self.dir, self.spec = Path(run_dir), spec
        self.every, self.episodes, self.max_episode_steps = int(every), int(episodes), max_episode_steps
        self.device = device
        self.metric = TEAM_METRIC[spec.team]
        self.best = -math.inf               # the best evaluation's mean metric so far (restored on resume)
        self.next_at = self.every           # decision steps of the next evaluation

    # ------------------------------------------------------------------ the run's life
    def resume(self, state: dict | None, iteration: int, env_steps: int) -> None:
        """Continue after a checkpoint of `iteration` at `env_steps`: the best value, the next evaluation's step, and
        `evaluations.jsonl` cut to the evaluations of the iterations up to the checkpoint (a killed run may have
        written more)."""
        if state is not None:
            self.best = float(state['best'])
        self.next_at = (env_steps // self.every + 1) * self.every
        path = self.dir / 'evaluations.jsonl'
        if path.exists():
            kept = [line for line in path.read_text().splitlines() if line.strip()
                    and json.loads(line)['iteration'] <= iteration]
            path.write_text(''.join(line + '\n' for line in kept))

    def state_dict(self) -> dict:
        return dict(best=self.best)

    def due(self, env_steps: int) -> bool:
        return env_steps >= self.next_at

    def __call__(self, actor_state: dict, iteration: int, env_steps: int) -> dict:
        """Evaluate the policy of `actor_state` (its spec's network) now; returns the evaluation's record."""
        from ..policies.policy import LoadedPolicy, make_actor

        actor = make_actor(self.spec)
        actor.load_state_dict(actor_state)
        policy = LoadedPolicy(actor, self.spec, f'iteration {iteration}')
        episodes = evaluate_policy(policy, self.episodes, EVALUATION_SEEDS, self.max_episode_steps, device=self.device)
        values = [e[self.metric] for e in episodes]
        record = dict(iteration=iteration, env_steps=env_steps, metric=self.metric, mean=float(np.mean(values)),
                      seeds=[EVALUATION_SEEDS, EVALUATION_SEEDS + self.episodes - 1], episodes=episodes)
        with open(self.dir / 'evaluations.jsonl', 'a') as f:
            f.write(json.dumps(record) + '\n')
        self.next_at = (env_steps // self.every + 1) * self.every
        record['best'] = record['mean'] > self.best
        if record['best']:
            self.best = record['mean']
        return record

    def absolute(self) -> dict | None:
        """The absolute metric: `best-eval.pt` played on ABSOLUTE_FACTOR x `episodes` held-out episodes; written to
        `absolute.json` and returned (None when no evaluation has kept a policy)."""
        from ..policies.policy import load_policy

        path = self.dir / 'best-eval.pt'
        if not path.exists():
            return None
        count = ABSOLUTE_FACTOR * self.episodes
        episodes = evaluate_policy(load_policy(path), count, ABSOLUTE_SEEDS, self.max_episode_steps,
                                   device=self.device)
        values = [e[self.metric] for e in episodes]
        record = dict(metric=self.metric, mean=float(np.mean(values)), best_evaluation=self.best,
                      seeds=[ABSOLUTE_SEEDS, ABSOLUTE_SEEDS + count - 1], episodes=episodes)
        (self.dir / 'absolute.json').write_text(json.dumps(record, indent=1))
        return record
