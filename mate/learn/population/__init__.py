"""Population training (the paper's §5.3): the meta-game solvers and exploitability.

    from mate.learn.population import solve_zero_sum, meta_strategies, exploitability
    row, column, value = solve_zero_sum([[1, -1], [-1, 1]])        # matching pennies: 1/2 each, value 0
"""

from .solvers import SOLVERS, exploitability, last_strategies, meta_strategies, solve_zero_sum, uniform_strategies

__all__ = ['SOLVERS', 'exploitability', 'last_strategies', 'meta_strategies', 'solve_zero_sum', 'uniform_strategies']
