"""The benchmark's evaluation protocol for any policy: held-out seeds, the absolute metric, references on the same
games.

    import mate

    def policy(observations):                     # (B, N, D) float64 raw observations -> (B, N, 2) actions
        return np.zeros((*observations.shape[:2], 2))

    score = mate.score_policy(policy, team='camera')                # MATE-4v8-9 against the greedy targets
    print(score)                                  # the absolute metric beside the references', one line each
    score.absolute_mean, score.reference_means    # 0.29..., {'random': 0.28, 'greedy': 0.61, 'upper-bound': 0.85}

It is the protocol `mate benchmark` scores its own learners with (Agarwal et al. 2021; Gorsane et al. 2022):

* **evaluation episodes**: `episodes` games on env seeds `EVALUATION_SEEDS`, `EVALUATION_SEEDS + 1`, ..., the seeds
  every periodic evaluation of every benchmark run plays (`evaluate`: call it during training for a curve);
* **the absolute metric**: `ABSOLUTE_FACTOR` x `episodes` games on seeds `ABSOLUTE_SEEDS`, ... (never trained on,
  never used to choose a policy), the number a benchmark table reports;
* **the references** (random and greedy, and for cameras the upper-bound controller that sees the true state) on
  the very same games, against the same opponent.

Each game is one episode cut at `max_episode_steps` env steps (default `horizon(team)`: the benchmark's 500 decisions
at the paper's frame skip, 2,500 env steps for cameras, 5,000 for targets), against the other team's `opponent`
('greedy' by default), seeded as the env: row i of a batch is the game `mate evaluate --seed S` plays as its episode
i. The metric is the team's: the coverage rate for cameras, the normalised target return for targets
(`TEAM_METRIC`).

A policy is one of:

* a callable `policy(observations) -> actions`: raw observations (B, N, D) float64 of the team's N agents in B
  games (the layouts of `mate.spaces`; `mate.SingleTeamVecEnv` gives the same arrays), actions (B, N, 2) in the
  env's units (cameras: rotation and zoom in degrees, targets: a displacement), called once per env step;
* a batched team of `mate.teams`' protocol (`reset(observations, rows)`, `act(observations)`), given as a factory
  `team_factory(num_envs, counts, seed)` since the protocol plays batches of different sizes;
* a built-in agent name of `mate evaluate` with a batched form ('random', 'greedy', 'upper-bound',
  'pretrained:NAME', 'checkpoint:PATH'; the last two need the train extra).

`run_dir`: the run files `mate benchmark report` reads: `evaluations.jsonl` (one line per evaluation, at
`env_steps` decisions) and `absolute.json` (the absolute metric's episodes), in the format of `mate train`'s runs,
and `references.json` (the references' episodes, for the user; a benchmark directory plays its own reference jobs).

**The cost, and scoring cheaply while iterating.** Nearly all of a default score of cameras is the references: each
of the three plays the same 32 + 320 games of 2,500 env steps as the policy (measured on two cores shared with other
jobs: 77-117 s of a score of 85-125 s; docs/own-algorithm.md). They are the same games every time, so
`reference_cache=True` keeps their episodes between runs in `reference_cache_dir()` (or a folder of yours), as JSON
files keyed by everything that decides a rule team's score (`reference_cache_key`), and plays a reference only when
no file matches; `episodes=4` scores on the first 4 + 40 of the games, for quick comparisons (the benchmark's
default stays 32).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..teams.interface import as_team

__all__ = ['ABSOLUTE_FACTOR', 'ABSOLUTE_SEEDS', 'CallableTeam', 'EPISODE_INFO', 'EVALUATION_SEEDS', 'FRESH_SEEDS',
           'PAPER_SETTINGS', 'PAYOFF_SEEDS', 'PolicyScore', 'REFERENCES', 'REFERENCE_CACHE_FORMAT', 'RESET_SEED_STRIDE',
           'SEED_RANGES', 'TEAM_METRIC', 'REWARDS', 'MAX_EVAL_EPISODES', 'SEED_BLOCK', 'agent_team_factory',
           'check_eval_episodes', 'checked_reward', 'evaluate', 'horizon', 'paper_config', 'reference_cache_dir',
           'reference_cache_key', 'score_policy', 'training_reset_seed']

EVALUATION_SEEDS = 1_000_000
"""First env seed of the periodic evaluation episodes (and the end of the training seeds)."""
ABSOLUTE_SEEDS = 2_000_000
"""First env seed of the final evaluation of the best policy (the absolute metric)."""
PAYOFF_SEEDS = 3_000_000
"""First env seed of a population run's payoff entries (`mate psro`)."""
FRESH_SEEDS = 4_000_000
"""First env seed of a population run's fresh-seed exploitability (its best responses re-played)."""
SEED_RANGES = {'training': (0, EVALUATION_SEEDS), 'evaluation': (EVALUATION_SEEDS, ABSOLUTE_SEEDS),
               'absolute': (ABSOLUTE_SEEDS, PAYOFF_SEEDS), 'payoff': (PAYOFF_SEEDS, FRESH_SEEDS),
               'fresh': (FRESH_SEEDS, FRESH_SEEDS + 1_000_000)}
"""Every use of env seeds and its own range [first, end): the games of every training env row (any run, iteration or
resume), the periodic evaluations, the absolute metric, PSRO's payoff entries and its fresh-seed exploitability. No
game of one use is a game of another (tests/test_seed_ranges.py)."""
ABSOLUTE_FACTOR = 10
"""The absolute metric plays this many times the periodic evaluation's episodes."""
TEAM_METRIC = {'camera': 'coverage_rate', 'target': 'normalized_target_return'}
"""The metric a team is scored by (the paper's Fig. 4 and Figs. 5-6)."""
PAPER_SETTINGS = {
    'camera': dict(env_id='MATE-4v8-9-v0', frame_skip=5),
    'target': dict(env_id='MATE-2v4-0-v0', frame_skip=10),
}
"""The paper's game and frame skip per trained team (a training episode: 500 decisions)."""
REFERENCES = {'camera': ('random', 'greedy', 'upper-bound'), 'target': ('random', 'greedy')}
"""The rule teams the benchmark plays as references on the evaluation games, per team."""
DEFAULT_EPISODES = 32
"""Episodes of one evaluation (the benchmark's `eval_episodes`); the absolute metric plays ten times as many."""
RESET_SEED_STRIDE = 10_007
"""A training session that cannot continue its checkpoint's episodes resets from `training_reset_seed`."""
SEED_BLOCK = 1000
"""The training seeds are dealt in blocks of this many: the benchmark's run seed k trains in block k (`mate train
--seed k x SEED_BLOCK`, at most SEED_BLOCK envs), and a resumed session stays in the blocks its rows start in
(`training_reset_seed`), so that no run plays another's training games."""
MAX_EVAL_EPISODES = (SEED_RANGES['absolute'][1] - SEED_RANGES['absolute'][0]) // ABSOLUTE_FACTOR
"""The most episodes one evaluation may play (100,000): the absolute metric plays ABSOLUTE_FACTOR times as many, on
seeds ABSOLUTE_SEEDS, ... that must stay below the payoff seeds (and the evaluation's below the absolute ones)."""


def check_eval_episodes(episodes, option: str = 'eval_episodes') -> int:
    """`episodes` as an int if it is a whole number in 1..`MAX_EVAL_EPISODES`; ValueError (one line, naming `option`
    and the valid range) otherwise."""
    whole = isinstance(episodes, (int, np.integer)) and not isinstance(episodes, bool)
    if not whole or not 1 <= episodes <= MAX_EVAL_EPISODES:
        first, end = SEED_RANGES['absolute']
        raise ValueError(f'{option} must be a whole number in 1..{MAX_EVAL_EPISODES:,} (the absolute metric plays '
                         f'{ABSOLUTE_FACTOR} x as many, on seeds {first:,}-{end - 1:,}), got {episodes!r}')
    return int(episodes)


def training_reset_seed(seed: int, iteration: int, num_envs: int) -> int:
    """The seed a training batch of `num_envs` rows resets with at `iteration` (0: a fresh run, `seed` itself; later:
    a resumed session without the batch's state): `seed + RESET_SEED_STRIDE x iteration`, wrapped so that every row
    (this seed + row) stays in the `SEED_BLOCK`-seed blocks the fresh run's rows [seed, seed + num_envs) fall in (one
    block for a benchmark run: it never plays another run's games), inside the training range [0,
    EVALUATION_SEEDS). ValueError when `seed + num_envs` leaves that range already."""
    end = SEED_RANGES['training'][1]
    if seed < 0 or num_envs < 1 or seed + num_envs > end:
        raise ValueError(f'training seeds: seed + num_envs must be at most {end:,} (the evaluation seeds start there), '
                         f'got seed {seed:,} with {num_envs:,} envs')
    first = seed - seed % SEED_BLOCK
    last = min(end, -(-(seed + num_envs) // SEED_BLOCK) * SEED_BLOCK)        # the blocks' end, rounded up
    return first + (seed - first + RESET_SEED_STRIDE * iteration) % (last - first - num_envs + 1)


def horizon(team) -> int:
    """Env steps per episode of the protocol for `team` ('camera' or 'target'): 500 decisions at the paper's frame
    skip (2,500 for cameras, 5,000 for targets)."""
    return 500 * PAPER_SETTINGS[as_team(team).name.lower()]['frame_skip']


REWARDS = {'camera': ('team', 'coverage', 'difference'), 'target': ('team', 'own')}
"""The reward kinds one team can be played for (`mate.SingleTeamVecEnv`'s docstring): the team's reward, the coverage
rate (cameras), each camera's marginal share of it ('difference'), each target's own part of the team reward."""


EPISODE_INFO = 'mate_episode'
"""The infos key of the ended games' statistics in the single-team envs (`mate.SingleTeamVecEnv`, its device form;
mask `'_' + EPISODE_INFO`): not `'episode'`, which Gymnasium's `RecordEpisodeStatistics` adds and will not overwrite."""


def checked_reward(team, reward: str) -> str:
    """`reward` if it is one of `team`'s kinds (`REWARDS`); ValueError (one line) naming them otherwise."""
    name = as_team(team).name.lower()
    if reward not in REWARDS[name]:
        raise ValueError(f"reward {reward!r} is not one of the {name} team's: {', '.join(REWARDS[name])}")
    return reward


def paper_config(team) -> str:
    """The paper's preset for `team`: 'MATE-4v8-9' for cameras, 'MATE-2v4-0' for targets."""
    return PAPER_SETTINGS[as_team(team).name.lower()]['env_id'].removesuffix('-v0')


class CallableTeam:
    """A batched team (`mate.teams` protocol) that asks `policy(observations) -> actions` at every env step.

    Args:
        policy: (B, N, D) float64 raw observations -> (B, N, 2) actions in env units.
        team: 'camera' or 'target'.
        num_envs: B. An answer of another shape, or with NaN or inf, raises ValueError naming the expected shape.
    """

    def __init__(self, policy: Callable, team, num_envs: int) -> None:
        self.policy, self.team, self.num_envs = policy, as_team(team), int(num_envs)

    def reset(self, observation: np.ndarray, rows: np.ndarray) -> None:
        """Nothing to do: a callable policy keeps no state between steps (a stateful one is a batched team)."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        actions = np.asarray(self.policy(observation), dtype=np.float64)
        expected = (*observation.shape[:2], 2)
        if actions.shape != expected:
            raise ValueError(f'the policy answered actions of shape {actions.shape} for observations of shape '
                             f'{observation.shape}; expected {expected} (games, agents, 2)')
        if not np.isfinite(actions).all():
            raise ValueError('the policy answered NaN or inf actions; every action must be finite')
        return actions


@dataclasses.dataclass
class PolicyScore:
    """What `score_policy` measured: every episode of every part, and the means.

    Attributes:
        team, config, metric: the team scored, its game, and the metric (`TEAM_METRIC`).
        evaluation: the policy's evaluation episodes (one dict each: `mate.teams.EpisodeSummary` fields).
        absolute: its absolute-metric episodes.
        references: reference name -> {'evaluation': episodes, 'absolute': episodes} on the same games.
    """

    team: str
    config: str
    metric: str
    evaluation: list[dict]
    absolute: list[dict]
    references: dict[str, dict[str, list[dict]]]

    def _mean(self, episodes: list[dict]) -> float:
        return float(np.mean([episode[self.metric] for episode in episodes]))

    @property
    def evaluation_mean(self) -> float:
        """The mean metric over the evaluation episodes."""
        return self._mean(self.evaluation)

    @property
    def absolute_mean(self) -> float:
        """The absolute metric: the mean metric over the absolute episodes."""
        return self._mean(self.absolute)

    @property
    def reference_means(self) -> dict[str, float]:
        """Each reference's mean metric over the absolute episodes."""
        return {name: self._mean(parts['absolute']) for name, parts in self.references.items()}

    def normalised(self, reference: str = 'greedy') -> float:
        """The absolute metric rescaled so that random scores 0 and `reference` 1 (the benchmark's normalised
        score); needs both references."""
        means = self.reference_means
        if 'random' not in means or reference not in means:
            raise ValueError(f"normalised scores need the 'random' and {reference!r} references; this score has "
                             f'{", ".join(means) or "none"}')
        return (self.absolute_mean - means['random']) / (means[reference] - means['random'])

    def __str__(self) -> str:
        lines = [f'{self.team}s on {self.config}, {self.metric} (absolute metric, {len(self.absolute)} held-out '
                 f'episodes): policy {self.absolute_mean:.3f}']
        lines += [f'  {name} {mean:.3f}' for name, mean in self.reference_means.items()]
        return '\n'.join(lines)


def play_policy_episodes(policy, team_factory, team: str, config: str, episodes: int, first_seed: int,
                         max_episode_steps: int, opponent: str, device: str) -> list[dict]:
    """`episodes` games on seeds first_seed, ... of the policy (or of `team_factory`) against `opponent`."""
    from ..teams import play_batch

    own = _team_factory(policy, team_factory, team, first_seed, device)
    other = _team_factory(opponent, None, 'target' if team == 'camera' else 'camera', first_seed, device)
    cameras, targets = (own, other) if team == 'camera' else (other, own)
    results, _ = play_batch(config, cameras, targets, episodes, seed=first_seed, max_episode_steps=max_episode_steps)
    return [dataclasses.asdict(result) for result in results]


def _team_factory(policy, team_factory, team: str, seed: int, device: str) -> Callable:
    """A factory f(num_envs, counts) of the team that plays `policy` (play_batch's form of a team)."""
    if team_factory is None and isinstance(policy, str):
        team_factory = agent_team_factory(policy, team, 'policy', device=device)
    if team_factory is not None:
        return lambda num_envs, counts: team_factory(num_envs, counts, seed)
    if not callable(policy):
        raise TypeError(f'policy must be a callable (observations -> actions), an agent name or None with a '
                        f'team_factory; got {type(policy).__name__}')
    return lambda num_envs, counts: CallableTeam(policy, team, num_envs)


def agent_team_factory(agent, team, role: str = 'agent', device: str = 'cpu'):
    """A factory f(num_envs, counts, seed) of `team` played by `agent`: a built-in agent name with a batched form
    ('random', 'greedy', 'upper-bound' for cameras; 'pretrained:NAME', 'checkpoint:PATH' with the train extra), or
    such a factory itself. `role` names the agent in the errors (ValueError for an unknown name or a missing extra);
    `device`: where a trained policy's forward passes run."""
    team = as_team(team)
    if callable(agent) and not isinstance(agent, str):
        return agent
    if not isinstance(agent, str):
        raise TypeError(f'{role} must be an agent name or a factory f(num_envs, counts, seed); got {agent!r}')
    from ..teams import RULE_TEAMS, make_team

    if agent in RULE_TEAMS:
        make_team(agent, team, 1, (1, 1, 0))   # an unknown name or a wrong team fails now, with the usual line
        return lambda num_envs, counts, seed: make_team(agent, team, num_envs, counts, seed=seed)
    if agent.partition(':')[0] not in ('pretrained', 'checkpoint'):
        raise ValueError(f'unknown {role} {agent!r}: use one of {", ".join(RULE_TEAMS)}, pretrained:NAME, '
                         'checkpoint:PATH or a factory f(num_envs, counts, seed)')
    try:
        from ..policies.policy import make_team as make_policy_team
    except ModuleNotFoundError as exc:   # torch, which the train extra installs
        if (exc.name or '').startswith('mate'):
            raise
        raise ValueError(f"the {role} {agent} needs the train extra (no module {exc.name!r}): "
                         "pip install 'mate[train]'") from None

    return lambda num_envs, counts, seed: make_policy_team(agent, team, num_envs, counts, seed=seed, device=device)


def _settings(team, config, episodes, max_episode_steps) -> tuple[str, str, int, int]:
    team = as_team(team).name.lower()
    config = paper_config(team) if config is None else str(config)
    episodes = check_eval_episodes(episodes, 'episodes')
    steps = horizon(team) if max_episode_steps is None else max_episode_steps
    if not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f'max_episode_steps must be a positive integer, got {max_episode_steps!r}')
    return team, config, int(episodes), int(steps)


def evaluate(policy=None, team='camera', config: str | None = None, *, team_factory: Callable | None = None,
             episodes: int = DEFAULT_EPISODES, max_episode_steps: int | None = None, opponent: str = 'greedy',
             run_dir=None, env_steps: int = 0, iteration: int | None = None, device: str = 'cpu') -> list[dict]:
    """One periodic evaluation of the protocol: `episodes` games on seeds `EVALUATION_SEEDS`, ...; returns one dict
    per episode. With `run_dir`, appends the evaluation (at `env_steps` decision steps) to its `evaluations.jsonl`,
    the line `mate train` writes, so that `mate benchmark report` draws the curve. `config` None: the paper's preset
    of the team (`paper_config`)."""
    team, config, episodes, steps = _settings(team, config, episodes, max_episode_steps)
    played = play_policy_episodes(policy, team_factory, team, config, episodes, EVALUATION_SEEDS, steps, opponent,
                                  device)
    if run_dir is not None:
        metric = TEAM_METRIC[team]
        record = dict(iteration=int(env_steps if iteration is None else iteration), env_steps=int(env_steps),
                      metric=metric, mean=float(np.mean([e[metric] for e in played])),
                      seeds=[EVALUATION_SEEDS, EVALUATION_SEEDS + episodes - 1], episodes=played)
        folder = Path(run_dir)
        folder.mkdir(parents=True, exist_ok=True)
        with open(folder / 'evaluations.jsonl', 'a') as file:
            file.write(json.dumps(record) + '\n')
    return played


REFERENCE_CACHE_FORMAT = 'mate.reference-cache/1'
"""The format of a file of `score_policy`'s reference cache."""


def reference_cache_dir() -> Path:
    """The folder `score_policy(reference_cache=True)` keeps the references' episodes in: `$MATE_CACHE_DIR/references`
    when that variable is set, else `$XDG_CACHE_HOME/mate/references`, else `~/.cache/mate/references`."""
    if os.environ.get('MATE_CACHE_DIR'):
        return Path(os.environ['MATE_CACHE_DIR']).expanduser() / 'references'
    return Path(os.environ.get('XDG_CACHE_HOME') or Path.home() / '.cache').expanduser() / 'mate' / 'references'


NOT_IN_A_RULE_GAME = ('learn', 'benchmark', 'integrations')
"""The subpackages of mate that no game between rule teams runs (trainers, the benchmark, other libraries'
adapters): left out of the code hash of `reference_cache_key`, so that editing them keeps the cache."""


@functools.cache
@functools.cache
def _code_hash() -> str:
    """sha256 of the code and presets that play a game between rule teams (every .py and .yaml file of mate but those
    of `NOT_IN_A_RULE_GAME`, in path order): a changed game, rule team or preset is another game, whatever the
    version says. Read once per process (the code this process plays with), not at every cache key."""
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(p for p in root.rglob('*') if p.suffix in ('.py', '.yaml') and '__pycache__' not in p.parts
                       and p.relative_to(root).parts[0] not in NOT_IN_A_RULE_GAME):
        digest.update(str(path.relative_to(root)).encode() + b'\0' + path.read_bytes() + b'\0')
    return digest.hexdigest()


def reference_cache_key(reference: str, team: str, config: str, episodes: int, first_seed: int,
                        max_episode_steps: int, opponent: str) -> dict:
    """Everything that decides the episodes of the rule team `reference` (one of `mate.teams.RULE_TEAMS`) on
    `episodes` games from `first_seed` cut at `max_episode_steps` env steps against the rule team `opponent`: those
    values, the game (a preset's name, or a YAML file's name and the sha256 of its text), the code of this mate that
    plays such a game (the sha256 of its files: `_code_hash`, which a new version changes too) and numpy's version
    (the rules' random draws)."""
    game = dict(config=str(config))
    if Path(config).is_file():
        game['sha256'] = hashlib.sha256(Path(config).read_bytes()).hexdigest()
    return dict(format=REFERENCE_CACHE_FORMAT, reference=reference, team=team, **game, episodes=int(episodes),
                first_seed=int(first_seed), max_episode_steps=int(max_episode_steps), opponent=opponent,
                code=_code_hash(), numpy=np.__version__)


def _reference_episodes(name: str, team: str, config: str, episodes: int, first_seed: int, steps: int, opponent,
                        device: str, cache: Path | None) -> list[dict]:
    """The reference `name`'s episodes (`play_policy_episodes`), read from the file of `cache` whose key matches when
    there is one (a rule team against a rule team only; a file that does not parse or whose key differs is played again
    and replaced), else played and, with `cache`, written there (JSON, replaced whole)."""
    from ..teams import RULE_TEAMS

    if cache is None or name not in RULE_TEAMS or not isinstance(opponent, str) or opponent not in RULE_TEAMS:
        return play_policy_episodes(name, None, team, config, episodes, first_seed, steps, opponent, device)
    key = reference_cache_key(name, team, config, episodes, first_seed, steps, opponent)
    text = json.dumps(key, sort_keys=True)
    path = cache / f'{name}-{team}-{hashlib.sha256(text.encode()).hexdigest()[:24]}.json'
    try:
        kept = json.loads(path.read_text())
        if kept['key'] == key and isinstance(kept['episodes'], list) and len(kept['episodes']) == episodes:
            return kept['episodes']
    except (OSError, ValueError, KeyError, TypeError):
        pass
    played = play_policy_episodes(name, None, team, config, episodes, first_seed, steps, opponent, device)
    cache.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f'{path.name}.{os.getpid()}.tmp')
    tmp.write_text(json.dumps(dict(key=key, episodes=played)))
    os.replace(tmp, path)
    return played


def score_policy(policy=None, team='camera', config: str | None = None, *, team_factory: Callable | None = None,
                 episodes: int = DEFAULT_EPISODES, max_episode_steps: int | None = None, opponent: str = 'greedy',
                 references: Sequence[str] | None = None, run_dir=None, env_steps: int = 0,
                 device: str = 'cpu', reference_cache=None) -> PolicyScore:
    """Score a policy as the benchmark scores its learners (module docstring): an evaluation on `episodes` games, the
    absolute metric on `ABSOLUTE_FACTOR` x `episodes` other held-out games, and the `references` (default
    `REFERENCES[team]`; () for none) on the same games. With `run_dir`, writes the run files `mate benchmark report`
    reads (an evaluation line at `env_steps` unless `evaluations.jsonl` has one there already, `absolute.json`,
    `references.json`). `reference_cache`: None or False, every reference is played; True, the rule teams'
    episodes are kept in `reference_cache_dir()` and read back on the next call with the same key
    (`reference_cache_key`); a folder, kept there. ValueError for a bad team, count or name; the policy's own errors
    pass through."""
    team, config, episodes, steps = _settings(team, config, episodes, max_episode_steps)
    references = REFERENCES[team] if references is None else tuple(references)
    folder = None if run_dir is None else Path(run_dir)
    logged = [] if folder is None or not (folder / 'evaluations.jsonl').exists() else [
        json.loads(line) for line in (folder / 'evaluations.jsonl').read_text().splitlines() if line.strip()]
    if any(record['env_steps'] == env_steps for record in logged):
        evaluation = next(record['episodes'] for record in logged if record['env_steps'] == env_steps)
    else:
        evaluation = evaluate(policy, team, config, team_factory=team_factory, episodes=episodes,
                              max_episode_steps=steps, opponent=opponent, run_dir=folder, env_steps=env_steps,
                              device=device)
    count = ABSOLUTE_FACTOR * episodes
    absolute = play_policy_episodes(policy, team_factory, team, config, count, ABSOLUTE_SEEDS, steps, opponent, device)
    cache = None if reference_cache in (None, False) else \
        reference_cache_dir() if reference_cache is True else Path(reference_cache).expanduser()
    played = {name: {part: _reference_episodes(name, team, config, n, first, steps, opponent, device, cache)
                     for part, n, first in (('evaluation', episodes, EVALUATION_SEEDS),
                                            ('absolute', count, ABSOLUTE_SEEDS))}
              for name in references}
    score = PolicyScore(team, config, TEAM_METRIC[team], evaluation, absolute, played)
    if folder is not None:
        metric = TEAM_METRIC[team]
        record = dict(metric=metric, mean=score.absolute_mean,
                      best_evaluation=score._mean(evaluation), seeds=[ABSOLUTE_SEEDS, ABSOLUTE_SEEDS + count - 1],
                      episodes=absolute)
        (folder / 'absolute.json').write_text(json.dumps(record, indent=1))
        (folder / 'references.json').write_text(json.dumps(dict(metric=metric, references=played), indent=1))
    return score
