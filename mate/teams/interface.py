"""The batched team protocol: one object acts for every agent of a team in B games at once.

    team.team                                                 # mate.Team.CAMERA or mate.Team.TARGET
    team.reset(observation (B, N, D) float64 raw, rows (B,) bool)   # these rows start an episode
    team.act(observation (B, N, D)) -> actions (B, N, 2) float64    # once per env step, every row
    team.idle(rows (B,) bool)              # optional: these rows' actions no longer matter (until reset)

Observations are the raw ones of `mate.make_vec` (no wrappers), one row per game. `act` is called
once per env step for all rows; a row's actions are only used between its `reset` and its `idle`.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from ..core.arrays import array_namespace
from ..constants import PRESERVED_DIM
from ..messages import Team, as_team

__all__ = ['BatchedTeam', 'action_high', 'as_team', 'idle']


@runtime_checkable
class BatchedTeam(Protocol):
    """What `play_batch` needs of a team (see the module docstring); `idle(rows)` is optional."""

    team: Team

    def reset(self, observation: np.ndarray, rows: np.ndarray) -> None:
        """Start an episode in the rows `rows` (B,) bool from their first observations (B, N, D)."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The actions (B, N, 2) float64 of every agent of every row for this step's observations (B, N, D)."""


def idle(team, rows: np.ndarray) -> None:
    """`team.idle(rows)` for the teams that have it (the others just go on acting there)."""
    if hasattr(team, 'idle'):
        team.idle(rows)


def action_high(observation, team):
    """Each agent's action bound (..., 2), float64, from its raw observation (..., D): cameras
    (rotation step, zooming step) in degrees, targets (step size, step size). A tensor for a tensor."""
    if not hasattr(observation, 'shape'):
        observation = np.asarray(observation)
    xp = array_namespace(observation)
    own = observation[..., PRESERVED_DIM:]
    if as_team(team) is Team.CAMERA:
        return xp.astype(own[..., 7:9], xp.float64)
    step = xp.astype(own[..., 4:5], xp.float64)
    return xp.concat([step, step], axis=-1)
