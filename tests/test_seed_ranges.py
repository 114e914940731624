"""Seeds that never cross: every use of env seeds has its own range (`mate.protocol.SEED_RANGES`), and no iteration,
resume or population run leaves it."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mate import protocol


def test_the_ranges_are_disjoint_and_the_protocol_fits_in_them():
    ranges = sorted(protocol.SEED_RANGES.values())
    assert all(end <= start for (_, end), (start, _) in zip(ranges, ranges[1:]))
    for name, first in (('evaluation', protocol.EVALUATION_SEEDS), ('absolute', protocol.ABSOLUTE_SEEDS),
                        ('payoff', protocol.PAYOFF_SEEDS), ('fresh', protocol.FRESH_SEEDS)):
        assert protocol.SEED_RANGES[name][0] == first
    start, end = protocol.SEED_RANGES['absolute']
    assert protocol.ABSOLUTE_FACTOR * 10_000 <= end - start      # 10,000 evaluation episodes still fit


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 4096), st.integers(0, 999), st.integers(0, 100_000))
def test_a_resumed_session_trains_in_the_training_range(num_envs, run_seed, iteration):
    """The benchmark's run seed k trains from seed k x 1,000 (any number of envs up to 4,096 below the evaluation
    seeds); a session that resets at any iteration stays there."""
    seed = min(run_seed * 1000, protocol.EVALUATION_SEEDS - num_envs)
    first = protocol.training_reset_seed(seed, iteration, num_envs)
    assert 0 <= first and first + num_envs <= protocol.SEED_RANGES['training'][1]
    assert protocol.training_reset_seed(seed, 0, num_envs) == seed            # a fresh run: its own seed


def test_a_seed_past_the_training_range_is_refused():
    with pytest.raises(ValueError, match='at most 1,000,000'):
        protocol.training_reset_seed(999_990, 0, 64)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 900), st.integers(0, 40), st.integers(1, 64), st.integers(1, 5000))
def test_a_population_run_plays_each_kind_of_game_in_its_range(seed, iterations, num_envs, episodes):
    pytest.importorskip('scipy', reason='needs the train extra')
    from mate.learn.population.psro import PSROError, PSROSettings

    population = PSROSettings(seed=seed, iterations=iterations, num_envs=num_envs, eval_episodes=episodes)
    try:
        population.validate()
    except PSROError:
        return                                          # refused: it would have left the training range
    for iteration in range(iterations + 1):
        for side in ('camera', 'target'):
            first = population.best_response_seed(iteration, side)
            for session in (0, 7, 20_000):           # its own resumes
                reset = protocol.training_reset_seed(first, session, num_envs)
                assert reset + num_envs <= protocol.SEED_RANGES['training'][1]
    for name in ('payoff', 'fresh'):
        start, end = protocol.SEED_RANGES[name]
        assert start + episodes <= end
