"""Schedules that scale with the run's budget (mate.learn.schedules): a step written 'P%' is P % of `--steps`.
Parsed from the command line and config files, resolved against the budget when the trainers read it, refused
with the valid range when malformed; schedules of counts (every default) are the same numbers at every budget."""

import json

import pytest

from mate.learn.command import trainer_config
from mate.learn.schedules import budget_share, check_network_options, piecewise, resolve_schedule

RECIPE = [[0, 0.03], ['50%', 0.01], ['100%', 0]]
"""The recipe's entropy bonus (0.03, 0.01 from 2 M, 0 from 4 M) written for a budget of 4 M decisions."""


def test_a_share_of_the_budget_parses_from_the_command_line_and_from_a_config_file(tmp_path):
    _, config = trainer_config('mappo', ['--hrl', '--steps', '10000000', '--entropy-schedule', json.dumps(RECIPE)])
    assert config.entropy_schedule == ((0, 0.03), ('50%', 0.01), ('100%', 0.0))
    file = tmp_path / 'long.yaml'
    file.write_text("steps: 10000000\nentropy_schedule: [[0, 0.03], ['50%', 0.01], ['100%', 0]]\n"
                    "lr_schedule: [[0, 0.0005], [' 40 %', 0.0001]]\n")
    _, from_file = trainer_config('mappo', ['--hrl', '--config-file', str(file)])
    assert from_file.entropy_schedule == config.entropy_schedule
    assert from_file.lr_schedule == ((0, 5e-4), ('40 %', 1e-4))
    _, iql = trainer_config('iql', ['--steps', '200000', '--epsilon-schedule', '[[0, 1], ["25%", 0.02]]'])
    assert iql.epsilon_schedule == ((0, 1.0), ('25%', 0.02))
    assert json.loads(json.dumps(config.to_dict()))['entropy_schedule'] == RECIPE   # config.json keeps the form


@pytest.mark.parametrize('budget', [4_000_000, 10_000_000, 12_345])
def test_the_schedule_scales_with_the_budget(budget):
    from mate.learn.mappo import MAPPOConfig
    from mate.learn.ppo import Schedules

    points = ((0, 0.03), ('50%', 0.01), ('100%', 0.0))
    assert resolve_schedule(points, budget) == ((0, 0.03), (budget // 2 if budget % 2 == 0 else budget / 2, 0.01),
                                                (budget, 0.0))
    schedules = Schedules(MAPPOConfig(hrl=True, steps=budget, entropy_schedule=points,
                                      lr_schedule=((0, 5e-4), ('40%', 1e-4), ('80%', 5e-5))))
    for fraction, entropy, lr in [(0.0, 0.03, 5e-4), (0.25, 0.02, 5e-4), (0.5, 0.01, 1e-4), (0.75, 0.005, 1e-4),
                                  (1.0, 0.0, 5e-5)]:
        optimizer = _Optimizer()
        got_lr, got_entropy = schedules.apply(optimizer, fraction * budget)
        assert got_entropy == pytest.approx(entropy, abs=1e-12) and got_lr == lr == optimizer.param_groups[0]['lr']


def test_counts_are_the_same_numbers_at_every_budget():
    """Today's schedules (the defaults, counts of decision steps) do not move with the budget: a run that does not
    ask for a share computes what it did."""
    from mate.learn.ppo import PPOConfig

    defaults = PPOConfig()
    assert defaults.entropy_schedule == ((0, 0.01), (1_000_000, 0.001), (3_000_000, 0.0))
    for step in (0, 250_000, 1_000_000, 2_000_000, 5_000_000):
        for budget in (None, 1, 2_000_000, 10_000_000):
            assert (piecewise(defaults.entropy_schedule, step, True, budget)
                    == piecewise(defaults.entropy_schedule, step, True))
    assert resolve_schedule(defaults.lr_schedule, 123) == defaults.lr_schedule


def test_the_trainers_read_shares_against_their_budget():
    """The Q-learners' epsilon and learning rate, as `iql.train` and `qmix.train` read them."""
    from mate.learn.iql import IQLConfig
    from mate.learn.qmix import QMIXConfig

    for make in (IQLConfig, QMIXConfig):
        config = make(steps=100_000, epsilon_schedule=((0, 1.0), ('50%', 0.0)), lr_schedule=((0, 1e-3), ('10%', 1e-4)))
        assert piecewise(config.epsilon_schedule, 25_000, True, config.steps) == pytest.approx(0.5)
        assert piecewise(config.lr_schedule, 9_999, False, config.steps) == 1e-3
        assert piecewise(config.lr_schedule, 10_000, False, config.steps) == 1e-4


@pytest.mark.parametrize('step', ['150%', '-5%', 'half', '40', '%', '1e2%', '100.5%'])
def test_a_bad_share_is_refused_naming_the_valid_range(step):
    from mate.learn.ppo import PPOConfig

    with pytest.raises(ValueError, match="^--entropy-schedule: a step is a decision-step count >= 0 or a share of "
                                         "--steps from '0%' to '100%', got ") as error:
        PPOConfig(entropy_schedule=((0, 0.01), (step, 0.0)))
    assert repr(step) in str(error.value)
    with pytest.raises(ValueError, match="^a share of the budget is 'P%' with P from 0 to 100"):
        budget_share(step)


def test_a_bad_share_on_the_command_line_exits_with_the_range(capsys):
    with pytest.raises(SystemExit):
        trainer_config('qmix', ['--lr-schedule', '[[0, 1e-4], ["120%", 1e-5]]'])
    assert "--lr-schedule: a step is a decision-step count >= 0 or a share of --steps from '0%' to '100%', got '120%'" \
        in capsys.readouterr().err


def test_a_command_without_shares_refuses_them():
    """`mate rllib-train` hands its schedules to RLlib, which counts steps only: its config names that."""
    class Config:
        lr_schedule = ((0, 5e-4), ('50%', 1e-4))

    with pytest.raises(ValueError, match=r'^--lr-schedule: a step is a decision-step count >= 0 \(this command takes '
                                         r"no share of the budget\), got '50%'"):
        check_network_options(Config(), ('lr_schedule',))
    check_network_options(Config(), ('lr_schedule',), shares=True)
    with pytest.raises(ValueError, match="needs the run's --steps"):
        piecewise(Config.lr_schedule, 10, False)


class _Optimizer:
    """What `Schedules.apply` writes the learning rate into."""

    def __init__(self) -> None:
        self.param_groups = [{}]
