"""Meta-game solvers and exploitability (mate.learn.population.solvers; spec training.md §5.4-5.5)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mate.learn.population import exploitability, last_strategies, meta_strategies, solve_zero_sum, uniform_strategies

TOLERANCE = 1e-7


def assert_equilibrium(payoff, row, column, value):
    """p and q are probability vectors, max_i (A q)_i = value = min_j (p A)_j within TOLERANCE."""
    payoff = np.asarray(payoff, dtype=np.float64)
    for strategy in (row, column):
        assert np.all(strategy >= 0) and strategy.sum() == pytest.approx(1.0, abs=1e-12)
    assert (payoff @ column).max() == pytest.approx(value, abs=TOLERANCE)
    assert (row @ payoff).min() == pytest.approx(value, abs=TOLERANCE)
    assert row @ payoff @ column == pytest.approx(value, abs=TOLERANCE)


def test_matching_pennies():
    row, column, value = solve_zero_sum([[1, -1], [-1, 1]])
    np.testing.assert_allclose(row, [0.5, 0.5], atol=1e-9)
    np.testing.assert_allclose(column, [0.5, 0.5], atol=1e-9)
    assert value == pytest.approx(0.0, abs=1e-9)


def test_rock_paper_scissors_and_a_biased_variant():
    rps = [[0, -1, 1], [1, 0, -1], [-1, 1, 0]]
    row, column, value = solve_zero_sum(rps)
    np.testing.assert_allclose(row, [1 / 3] * 3, atol=1e-9)
    np.testing.assert_allclose(column, [1 / 3] * 3, atol=1e-9)
    assert value == pytest.approx(0.0, abs=1e-9)
    # rock beats scissors by 2 (still skew-symmetric, value 0): p A = 0 gives p2 = 2 p3, p1 = p3, p2 = 2 p1,
    # so p = q = (1/4, 1/2, 1/4)
    biased = [[0, -1, 2], [1, 0, -1], [-2, 1, 0]]
    row, column, value = solve_zero_sum(biased)
    np.testing.assert_allclose(row, [1 / 4, 1 / 2, 1 / 4], atol=1e-9)
    np.testing.assert_allclose(column, [1 / 4, 1 / 2, 1 / 4], atol=1e-9)
    assert_equilibrium(biased, row, column, value)


def test_pure_saddle_point():
    payoff = [[4, 2, 5], [1, 0, 3], [6, 1, 0]]        # row 0 / column 1: 2 is its row's min and its column's max
    row, column, value = solve_zero_sum(payoff)
    np.testing.assert_allclose(row, [1, 0, 0], atol=1e-9)
    np.testing.assert_allclose(column, [0, 1, 0], atol=1e-9)
    assert value == pytest.approx(2.0)


def test_dominated_strategies_get_no_mass():
    # row 2 is strictly dominated by row 0; column 2 strictly dominated (for the minimiser) by column 0
    payoff = [[3, -1, 4], [-1, 1, 2], [2, -2, 3]]
    row, column, value = solve_zero_sum(payoff)
    assert row[2] == pytest.approx(0.0, abs=1e-9) and column[2] == pytest.approx(0.0, abs=1e-9)
    # the remaining 2x2 game [[3, -1], [-1, 1]]: p = (1/3, 2/3), q = (1/3, 2/3), value 1/3
    np.testing.assert_allclose(row, [1 / 3, 2 / 3, 0], atol=1e-9)
    np.testing.assert_allclose(column, [1 / 3, 2 / 3, 0], atol=1e-9)
    assert value == pytest.approx(1 / 3)


def test_one_by_one_constant_and_rectangular_games():
    row, column, value = solve_zero_sum([[0.25]])
    assert row.tolist() == [1.0] and column.tolist() == [1.0] and value == 0.25
    row, column, value = solve_zero_sum(np.full((2, 3), -0.5))
    assert_equilibrium(np.full((2, 3), -0.5), row, column, value)
    assert value == -0.5
    row, column, value = solve_zero_sum([[1, 0, 2]])                    # one row: the column player picks the min
    np.testing.assert_allclose(column, [0, 1, 0], atol=1e-9)
    assert value == pytest.approx(0.0, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 9), st.integers(1, 9)),
              elements=st.floats(-1, 1, allow_nan=False, width=32)))
def test_random_games_satisfy_the_equilibrium_conditions(payoff):
    assert_equilibrium(payoff, *solve_zero_sum(payoff))


def test_large_random_game():
    payoff = np.random.default_rng(0).normal(size=(40, 30))
    assert_equilibrium(payoff, *solve_zero_sum(payoff))


@pytest.mark.parametrize('bad, message', [
    ([[1.0, np.nan]], 'NaN or inf'),
    ([[np.inf]], 'NaN or inf'),
    (np.zeros((0, 3)), 'empty'),
    ([1.0, 2.0], '2-D'),
    (np.zeros((2, 2, 2)), '2-D'),
    ([['a', 'b']], 'numbers'),
])
def test_bad_payoff_is_a_clear_error(bad, message):
    for solver in (solve_zero_sum, uniform_strategies, last_strategies):
        with pytest.raises(ValueError, match=message):
            solver(bad)


def test_uniform_and_last_solvers():
    payoff = np.arange(6.0).reshape(2, 3)
    row, column = meta_strategies('uniform', payoff)
    np.testing.assert_array_equal(row, [0.5, 0.5])
    np.testing.assert_array_equal(column, [1 / 3] * 3)
    row, column = meta_strategies('last', payoff)
    np.testing.assert_array_equal(row, [0, 1])
    np.testing.assert_array_equal(column, [0, 0, 1])
    row, column = meta_strategies('nash', payoff)
    np.testing.assert_allclose(row, [0, 1], atol=1e-9)
    with pytest.raises(ValueError, match="unknown meta-solver 'psro'.*nash, uniform, last"):
        meta_strategies('psro', payoff)


def test_exploitability_of_a_hand_made_population():
    """Pools of 2 + 1 new policy each; meta-strategies p = (1/2, 1/2), q = (1, 0) over the old 2 x 2.

    payoff (row utility):        by hand: p A q over the old pools = (1 + 0) / 2 = 0.5
        [[ 1, -1,  0],           row term: rows against q = column 0 -> (1, 0, 2): max 2, gain 2 - 0.5 = 1.5
         [ 0,  2, -1],           column term: -(p A) over all columns = -(0.5, 0.5, -0.5) -> max 0.5,
         [ 2,  0,  1]]             gain 0.5 + 0.5 = 1.0;  exploitability = (1.5 + 1.0) / 2 = 1.25
    """
    payoff = [[1, -1, 0], [0, 2, -1], [2, 0, 1]]
    result = exploitability(payoff, [0.5, 0.5], [1.0, 0.0])
    assert result == pytest.approx({'row': 1.5, 'column': 1.0, 'mean': 1.25})


def test_an_equilibrium_of_the_whole_pool_is_not_exploitable():
    payoff = np.random.default_rng(1).uniform(-1, 1, size=(5, 4))
    row, column, _ = solve_zero_sum(payoff)
    result = exploitability(payoff, row, column)
    assert result['row'] == pytest.approx(0.0, abs=1e-7) and result['column'] == pytest.approx(0.0, abs=1e-7)
    uniform = exploitability(payoff, *uniform_strategies(payoff))
    assert uniform['mean'] > 1e-3


def test_exploitability_rejects_bad_strategies():
    with pytest.raises(ValueError, match='probability vector'):
        exploitability([[1, 0], [0, 1]], [0.7, 0.7], [1.0])
    with pytest.raises(ValueError, match='first 1..2 policies'):
        exploitability([[1, 0], [0, 1]], [0.2, 0.3, 0.5], [1.0])


def test_effective_policies_of_a_meta_strategy():
    """exp of the entropy: how many policies a meta-strategy spreads over."""
    from mate.learn.population.solvers import effective_policies

    assert effective_policies([1.0]) == pytest.approx(1.0)
    assert effective_policies([0.0, 1.0, 0.0]) == pytest.approx(1.0)           # pure: one policy
    assert effective_policies([0.25] * 4) == pytest.approx(4.0)                # uniform: the pool
    assert effective_policies([0.5, 0.5, 0.0]) == pytest.approx(2.0)
    assert 1.0 < effective_policies([0.9, 0.1]) < 2.0
    with pytest.raises(ValueError, match='probability vector'):
        effective_policies([0.5, 0.6])
