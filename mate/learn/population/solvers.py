"""The meta-game of a population run: meta-strategy solvers and exploitability.

The meta-game is a matrix game between two pools of policies. `payoff[k, l]` is the row player's
utility (in `mate psro`: the camera team's normalised return) when row policy k meets column policy
l; the game is zero-sum, so the column player's utility is `-payoff`. Three solvers give a
meta-strategy (a probability vector over each pool):

* `'nash'`:    an exact Nash equilibrium of the zero-sum game by linear programming (PSRO-Nash);
* `'uniform'`: uniform over each whole pool, its first (random) policy included (fictitious self-play);
* `'last'`:    all mass on each pool's newest policy (self-play).

`exploitability` is the paper's Eq. 2 with the best responses approximated by the best policies of
the extended pools (docs/population.md).
"""

from __future__ import annotations

import numpy as np

__all__ = ['SOLVERS', 'effective_policies', 'exploitability', 'last_strategies', 'meta_strategies', 'solve_zero_sum',
           'uniform_strategies']

_LP_OPTIONS = {'primal_feasibility_tolerance': 1e-10, 'dual_feasibility_tolerance': 1e-10}


def _payoff_matrix(payoff, name: str = 'payoff') -> np.ndarray:
    """`payoff` as a finite float64 (m, n) array with m, n >= 1; ValueError naming the problem otherwise."""
    try:
        matrix = np.array(payoff, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{name} must be a 2-D array of numbers: {exc}') from None
    if matrix.ndim != 2:
        raise ValueError(f'{name} must be a 2-D (rows, columns) matrix, got {matrix.ndim} dimension(s) '
                         f'(shape {matrix.shape})')
    if matrix.size == 0:
        raise ValueError(f'{name} is empty (shape {matrix.shape}); each pool needs at least one policy')
    if not np.isfinite(matrix).all():
        bad = [tuple(int(i) for i in index) for index in np.argwhere(~np.isfinite(matrix))[:5]]
        raise ValueError(f'{name} holds NaN or inf at {bad}; every entry must be finite')
    return matrix


def _maximin(matrix: np.ndarray) -> np.ndarray:
    """The row strategy p maximising min_j (p @ matrix)[j], for entries in [0, 1]: one LP over (p, v).

    maximise v  s.t.  v - (matrix.T @ p)_j <= 0 for every column j,  sum(p) = 1,  p >= 0.
    """
    from scipy.optimize import linprog   # here, so that `mate psro -h` and the parser need no scipy

    rows, columns = matrix.shape
    cost = np.zeros(rows + 1)
    cost[-1] = -1.0
    upper = np.hstack([-matrix.T, np.ones((columns, 1))])
    equal = np.hstack([np.ones((1, rows)), np.zeros((1, 1))])
    bounds = [(0.0, None)] * rows + [(None, None)]
    result = linprog(cost, A_ub=upper, b_ub=np.zeros(columns), A_eq=equal, b_eq=[1.0], bounds=bounds,
                     method='highs', options=_LP_OPTIONS)
    if not result.success:   # cannot happen for a finite matrix game (always feasible and bounded)
        raise RuntimeError(f'the zero-sum LP failed: {result.message}')
    strategy = np.clip(result.x[:rows], 0.0, None)
    return strategy / strategy.sum()


def solve_zero_sum(payoff) -> tuple[np.ndarray, np.ndarray, float]:
    """A Nash equilibrium of the zero-sum game with row utility `payoff` (m, n).

    Returns (row_strategy (m,), column_strategy (n,), value): the row strategy maximises the row
    player's guaranteed utility, the column strategy minimises what the row player can get, and
    value = row_strategy @ payoff @ column_strategy is the game's value. Each strategy is found by a
    linear program (scipy's HiGHS) on the payoff rescaled to [0, 1]; a constant matrix gives the
    uniform strategies. ValueError for an empty matrix, one that is not 2-D, or NaN/inf entries.
    """
    matrix = _payoff_matrix(payoff)
    rows, columns = matrix.shape
    low, span = matrix.min(), matrix.max() - matrix.min()
    if span == 0.0:
        return np.full(rows, 1.0 / rows), np.full(columns, 1.0 / columns), float(low)
    scaled = (matrix - low) / span
    row_strategy = _maximin(scaled)
    column_strategy = _maximin(1.0 - scaled.T)   # the column player maximises the row player's loss
    value = float(row_strategy @ matrix @ column_strategy)
    return row_strategy, column_strategy, value


def uniform_strategies(payoff) -> tuple[np.ndarray, np.ndarray]:
    """Uniform over every row and every column policy (fictitious self-play's meta-strategy)."""
    rows, columns = _payoff_matrix(payoff).shape
    return np.full(rows, 1.0 / rows), np.full(columns, 1.0 / columns)


def last_strategies(payoff) -> tuple[np.ndarray, np.ndarray]:
    """All mass on the newest (last) row and column policy (self-play's meta-strategy)."""
    rows, columns = _payoff_matrix(payoff).shape
    row_strategy, column_strategy = np.zeros(rows), np.zeros(columns)
    row_strategy[-1] = column_strategy[-1] = 1.0
    return row_strategy, column_strategy


SOLVERS = {
    'nash': lambda payoff: solve_zero_sum(payoff)[:2],
    'uniform': uniform_strategies,
    'last': last_strategies,
}
"""Solver name -> function of the payoff matrix giving (row_strategy, column_strategy)."""


def meta_strategies(solver: str, payoff) -> tuple[np.ndarray, np.ndarray]:
    """The meta-strategies of both pools under `solver` ('nash', 'uniform' or 'last')."""
    if solver not in SOLVERS:
        raise ValueError(f'unknown meta-solver {solver!r}; choose one of {", ".join(SOLVERS)}')
    return SOLVERS[solver](payoff)


def _strategy(strategy, size: int, name: str) -> np.ndarray:
    vector = np.asarray(strategy, dtype=np.float64)
    if vector.ndim != 1 or not 1 <= vector.size <= size:
        raise ValueError(f'{name} must be a vector over the first 1..{size} policies of its pool, '
                         f'got shape {vector.shape}')
    if not np.isfinite(vector).all() or (vector < 0).any() or abs(vector.sum() - 1.0) > 1e-6:
        raise ValueError(f'{name} must be a probability vector (non-negative, summing to 1), got {vector.tolist()}')
    return vector


def effective_policies(strategy) -> float:
    """How many policies a meta-strategy spreads over: exp of its entropy (in nats), from 1 (a pure strategy) to
    the pool size (uniform). ValueError unless `strategy` is a probability vector."""
    vector = _strategy(strategy, len(np.atleast_1d(strategy)), 'strategy')
    weights = vector[vector > 0]
    return float(np.exp(-(weights * np.log(weights)).sum()))


def exploitability(payoff, row_strategy, column_strategy) -> dict[str, float]:
    """Eq. 2 of the paper: how much each side gains by deviating from its meta-strategy.

    `payoff` (M, N) is the row utility over the extended pools; `row_strategy` (m,) and
    `column_strategy` (n,) weigh their first m <= M and n <= N policies (the meta-strategies of the
    previous iteration; the newer policies are the approximate best responses). Returns

    * `row`:    max_k payoff[k, :n] @ q - p @ payoff[:m, :n] @ q (the row player's gain, >= 0 when m < M
      or p is not a best response),
    * `column`: max_l (-p @ payoff[:m, l]) + p @ payoff[:m, :n] @ q (the column player's gain),
    * `mean`:   their mean, the exploitability.
    """
    matrix = _payoff_matrix(payoff)
    p = _strategy(row_strategy, matrix.shape[0], 'row_strategy')
    q = _strategy(column_strategy, matrix.shape[1], 'column_strategy')
    m, n = p.size, q.size
    value = float(p @ matrix[:m, :n] @ q)
    row_gain = float((matrix[:, :n] @ q).max()) - value
    column_gain = float((-(p @ matrix[:m, :])).max()) + value
    return {'row': row_gain, 'column': column_gain, 'mean': 0.5 * (row_gain + column_gain)}
