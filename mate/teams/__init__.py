"""Batched teams: one object acts for every agent of a team in B games at once (no torch needed).

The protocol (`BatchedTeam`):

    team.team                                                 # mate.Team.CAMERA or mate.Team.TARGET
    team.reset(observation (B, N, D) float64 raw, rows (B,) bool)   # these rows start an episode
    team.act(observation (B, N, D)) -> actions (B, N, 2) float64    # once per env step, every row
    team.idle(rows (B,) bool)              # optional: these rows' actions no longer matter (until reset)

Teams here:

* `GreedyTeam(team, num_envs, counts, seed, **options)` (`GreedyCameraTeam`, `GreedyTargetTeam`): the
  greedy agents. Their rules are written once, in `rules`, and `mate.GreedyCameraAgent` /
  `mate.GreedyTargetAgent` call the same compiled functions on their own row; the batched teams
  exchange the same messages (per-row, per-pair delays included) on arrays.
* `RandomTeam(team, num_envs, counts, seed, frame_skip=20)`: the random agents.
* `MixtureTeam(members, weights, seed, assignment)`: one member per row and episode.
* `UpperBoundTeam(num_envs, counts, horizon=40, discount=0.9)`: a reference camera team, centralised, that sees
  the true state (every target's position) and plans the cameras' poses ahead to cover the most targets;
  `mate.UpperBoundCameraAgent` runs the same compiled rule in one game. It reads the truth from the vector env
  it watches (`play_batch` calls its `watch`) or from fully observing observations.

Seeds and streams (`streams`): row b of a team seeded with the integer s plays draw for draw as the
Python agents `Cls(seed=s + b).spawn(N)` (a sequence gives each row its seed), so
`play_batch(config, GreedyTeam('camera', B, counts, s), GreedyTeam('target', B, counts, s), B, s)`
plays, row by row, the episodes `mate.evaluation.evaluate.play_episode` plays with seeds s, ..., s + B - 1. A row
that restarts (`reset` with it in `rows`) goes on with its agents' streams, as reused agents do.

`play_batch(config, camera_team, target_team, episodes, seed)` plays B games at once in one vector env.
"""

from ..messages import Team
from .greedy import GREEDY_OPTIONS, GreedyCameraTeam, GreedyTargetTeam, GreedyTeam
from .mixture import MixtureTeam
from .play import BatchEpisode, play_batch
from .interface import BatchedTeam, action_high, as_team, idle
from .random import RandomTeam
from .streams import TeamStreams, row_seeds, spawned_seeds
from .upper_bound import UPPER_BOUND_OPTIONS, UpperBoundTeam

__all__ = [
    'BatchedTeam', 'GreedyTeam', 'GreedyCameraTeam', 'GreedyTargetTeam', 'RandomTeam', 'MixtureTeam',
    'RULE_TEAMS', 'make_team', 'play_batch', 'BatchEpisode', 'GREEDY_OPTIONS', 'TeamStreams', 'row_seeds',
    'spawned_seeds', 'action_high', 'as_team', 'idle', 'UpperBoundTeam', 'UPPER_BOUND_OPTIONS',
]

RULE_TEAMS = ('random', 'greedy', 'upper-bound')
"""Agent names of `mate evaluate` with a batched team here."""


def make_team(name: str, team, num_envs: int, counts, seed=None, **options):
    """The batched team of a built-in agent name ('random', 'greedy', or 'upper-bound' for the cameras) for `team`;
    `options` are the agents' (`frame_skip` for random, `GREEDY_OPTIONS` for greedy, `UPPER_BOUND_OPTIONS` for
    upper-bound). ValueError (one line) otherwise."""
    if name == 'random':
        unknown = sorted(set(options) - {'frame_skip'})
        if unknown:
            raise ValueError(f'unknown option(s) {", ".join(unknown)} for the random agents; they take frame_skip')
        return RandomTeam(team, num_envs, counts, seed=seed, **options)
    if name == 'greedy':
        return GreedyTeam(team, num_envs, counts, seed=seed, **options)
    if name == 'upper-bound':
        if as_team(team) is not Team.CAMERA:
            raise ValueError('upper-bound is a camera team; there is no upper-bound target team')
        unknown = sorted(set(options) - set(UPPER_BOUND_OPTIONS))
        if unknown:
            raise ValueError(f'unknown option(s) {", ".join(unknown)} for the upper-bound cameras; they take '
                             f'{", ".join(UPPER_BOUND_OPTIONS)}')
        return UpperBoundTeam(num_envs, counts, seed=seed, **options)
    raise ValueError(f'agent {name!r} has no batched team in mate.teams; these have: {", ".join(RULE_TEAMS)}')
