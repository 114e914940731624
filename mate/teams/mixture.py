"""Batched mixture: one member team per row and episode, drawn with weights or assigned."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .interface import idle

__all__ = ['MixtureTeam']


class MixtureTeam:
    """Plays member k in a row for a whole episode, k drawn with probabilities `weights` at the row's
    reset. Every member steps on every row (its per-row state stays consistent) and each row takes its
    member's actions; members that can idle make no decisions in the rows they do not play (a mixture
    of policies costs about one policy's forward passes; rule teams skip those rows).

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
        """Draw (or assign) the member of every row of `rows` and reset every member there."""
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
            idle(member, rows & (self.choice != k))

    def idle(self, rows: np.ndarray) -> None:
        """The rows `rows` are out of play for every member."""
        for member in self.members:
            idle(member, rows)

    def state_dict(self) -> dict:
        """The members' states, the member of every row and the drawing generator (exact resumes)."""
        return dict(rng=self.rng.bit_generator.state, choice=None if self.choice is None else self.choice.copy(),
                    members=[member.state_dict() for member in self.members])

    def load_state_dict(self, state: dict) -> None:
        self.rng.bit_generator.state = state['rng']
        self.choice = None if state['choice'] is None else np.array(state['choice'])
        for member, member_state in zip(self.members, state['members']):
            member.load_state_dict(member_state)

    def act(self, observation: np.ndarray) -> np.ndarray:
        """(B, N, 2): each row's member's actions."""
        actions = [member.act(observation) for member in self.members]
        return np.stack(actions)[self.choice, np.arange(len(self.choice))]
