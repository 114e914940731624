"""Seeds that never cross: every use of env seeds has its own range (`mate.evaluation.protocol.SEED_RANGES`), and no
iteration, resume or population run leaves it."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mate.evaluation import protocol


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


@settings(max_examples=300, deadline=None)
@given(st.integers(0, protocol.EVALUATION_SEEDS // protocol.SEED_BLOCK - 1), st.integers(1, protocol.SEED_BLOCK),
       st.integers(0, 100_000))
def test_a_resumed_benchmark_run_stays_in_its_own_block(run_seed, num_envs, iteration):
    """Run seed k (`mate train --seed k x 1,000`, at most 1,000 envs) resumed without its batch's state at any
    iteration resets inside its own block [k x 1,000, (k + 1) x 1,000): it never plays another run's games."""
    seed = run_seed * protocol.SEED_BLOCK
    first = protocol.training_reset_seed(seed, iteration, num_envs)
    assert seed <= first and first + num_envs <= seed + protocol.SEED_BLOCK


def test_a_resumed_session_varies_its_games_inside_its_blocks():
    """Later sessions reset with different seeds (not one block's start every time), and rows that begin in one
    block and end in the next own both."""
    seeds = {protocol.training_reset_seed(5_000, iteration, 64) for iteration in range(1, 50)}
    assert len(seeds) > 40 and min(seeds) >= 5_000 and max(seeds) + 64 <= 6_000
    crossing = [protocol.training_reset_seed(5_990, iteration, 64) for iteration in range(50)]
    assert crossing[0] == 5_990 and min(crossing) >= 5_000 and max(crossing) + 64 <= 7_000


def test_eval_episodes_are_bounded_by_the_absolute_metrics_seeds():
    """The absolute metric plays 10 x eval_episodes games from ABSOLUTE_SEEDS: 100,000 episodes fill its range
    exactly, one more would reach the payoff seeds; every entry point refuses it in one line naming the range."""
    start, end = protocol.SEED_RANGES['absolute']
    assert protocol.MAX_EVAL_EPISODES == 100_000 == (end - start) // protocol.ABSOLUTE_FACTOR
    assert protocol.EVALUATION_SEEDS + protocol.MAX_EVAL_EPISODES <= protocol.SEED_RANGES['evaluation'][1]
    assert protocol.check_eval_episodes(100_000) == 100_000
    for bad in (0, 100_001, 10_000_000, 2.5, True):
        with pytest.raises(ValueError, match=r'must be a whole number in 1\.\.100,000 .*seeds 2,000,000-2,999,999'):
            protocol.check_eval_episodes(bad)
    for play in (protocol.evaluate, protocol.score_policy):     # refused before a game is played
        with pytest.raises(ValueError, match=r'episodes must be a whole number in 1\.\.100,000'):
            play(lambda observations: observations[..., :2] * 0, team='camera', episodes=100_001)


def test_an_experiment_refuses_what_would_leave_its_seeds():
    """`Experiment` bounds eval_episodes; `plan` refuses a trainer setting with more envs than a run seed's block and
    a population setting whose best responses' rows leave it."""
    import dataclasses

    from mate.benchmark.experiments import Setting, experiment
    from mate.benchmark.jobs import PSRO_ENVS, SEED_STRIDE, check_run_seeds, plan
    from mate.learn.population.psro import PSROSettings

    smoke = experiment('smoke')
    with pytest.raises(ValueError, match=r"'smoke': eval_episodes must be a whole number in 1\.\.100,000"):
        dataclasses.replace(smoke, eval_episodes=100_001)
    assert SEED_STRIDE == protocol.SEED_BLOCK and PSRO_ENVS == PSROSettings().num_envs
    def with_envs(*options):
        return dataclasses.replace(smoke, settings=(Setting('MAPPO', 'mappo', options=options), *smoke.settings[1:]))

    with pytest.raises(ValueError, match=r"setting 'MAPPO': --num-envs 1,001 .* 1\.\.1,000 envs"):
        plan(with_envs('--num-envs=1001'), [0], 'unused')
    check_run_seeds(with_envs('--num-envs', '1000'))
    population = experiment('smoke-psro')
    long = dataclasses.replace(population, iterations=498)        # --num-envs 4: 2 x 498 + 1 + 4 = 1,001 rows
    with pytest.raises(ValueError, match='2 x iterations \\+ 1 \\+ num_envs must be at most 1,000'):
        check_run_seeds(long)
    check_run_seeds(dataclasses.replace(population, iterations=497))                          # 999 rows


def test_mate_train_and_psro_refuse_what_would_leave_their_seeds():
    """`mate train --eval-episodes` is bounded like the protocol's evaluations; a standalone PSRO run's best
    responses stay in their run seed's block (the next run seed trains from seed x 1,000 + 1,000)."""
    from mate.learn.population.psro import PSROError, PSROSettings
    from mate.learn.ppo import PPOConfig
    from mate.evaluation.protocol import MAX_EVAL_EPISODES, SEED_BLOCK

    with pytest.raises(ValueError, match=f'--eval-episodes must be an integer >= 1 and <= {MAX_EVAL_EPISODES}'):
        PPOConfig(eval_episodes=MAX_EVAL_EPISODES + 1)
    PPOConfig(eval_episodes=MAX_EVAL_EPISODES)
    iterations = (SEED_BLOCK - 1 - 4) // 2                       # 2 x iterations + 1 + 4 envs = 1,000: fits
    PSROSettings(iterations=iterations, num_envs=4).validate()
    with pytest.raises(PSROError, match='into the next seed.s block'):
        PSROSettings(iterations=iterations + 1, num_envs=4).validate()
