"""Config dataclasses as command lines (mate.cli.options): a field's range is checked on the command line and, for
a config made in Python, by `check_ranges` in the config's own checks, with the same words."""

from __future__ import annotations

import dataclasses
import math

import pytest

from mate.cli.options import RANGE_KEYS, check_ranges, flag_of


def _trainer_configs():
    from mate.integrations.rllib_train import RLlibPPOConfig      # (its config needs no Ray)
    from mate.learn.i2c import I2CConfig
    from mate.learn.iql import IQLConfig
    from mate.learn.mappo import MAPPOConfig
    from mate.learn.mappo_lstm import RecurrentConfig
    from mate.learn.matd3 import MATD3Config
    from mate.learn.qmix import QMIXConfig
    from mate.learn.tarmac import TarMACConfig
    return [MAPPOConfig, RecurrentConfig, TarMACConfig, I2CConfig, IQLConfig, QMIXConfig, MATD3Config, RLlibPPOConfig]


def _outside(minimum, above, maximum) -> list[float]:
    """Values just outside a range (and NaN, never inside one)."""
    values = [math.nan]
    if minimum is not None:
        values.append(minimum - 1 if float(minimum).is_integer() else minimum - 1e-6)
    if above is not None:
        values.append(above)
    if maximum is not None:
        values.append(maximum + 1e-6)
    return values


@pytest.mark.parametrize('config_class', _trainer_configs(), ids=lambda c: c.__name__)
def test_every_ranged_option_refuses_a_value_outside_its_range_in_python_too(config_class):
    """Every field with a range: its default passes; just outside the range, making the config raises ValueError
    naming the option as the command line spells it."""
    check_ranges(config_class())
    ranged = [field for field in dataclasses.fields(config_class)
              if field.init and any(key in field.metadata for key in RANGE_KEYS)]
    assert ranged, f'{config_class.__name__} has no ranged options'
    for field in ranged:
        default = getattr(config_class(), field.name)
        for bad in _outside(*(field.metadata.get(key) for key in RANGE_KEYS)):
            value = (bad,) * max(1, len(default)) if isinstance(default, tuple) else bad
            with pytest.raises(ValueError, match=f'^{flag_of(field.name)} must be '):
                config_class(**{field.name: value})


def test_the_bounds_in_words():
    from mate.learn.matd3 import MATD3Config
    from mate.learn.ppo import PPOConfig
    with pytest.raises(ValueError, match=r'^--gamma must be a number >= 0 and <= 1, got 1\.5$'):
        PPOConfig(gamma=1.5)
    with pytest.raises(ValueError, match=r'^--tau must be a number > 0 and <= 1, got 0\.0$'):
        MATD3Config(tau=0.0)
    with pytest.raises(ValueError, match=r'^--hidden must be an integer >= 1, got 0$'):
        PPOConfig(hidden=(64, 0))
