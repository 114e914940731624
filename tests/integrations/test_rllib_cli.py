"""`mate rllib-train`: its options (those of `mate train` with the same meaning, RLlib PPO's with the paper's
defaults), its one-line errors, and the install hint; all without Ray (the runs themselves: test_rllib_witness.py)."""

from __future__ import annotations

import dataclasses
import sys

import pytest

from conftest import needs_extra
from mate.cli import main as cli
from mate.integrations import rllib_train


def parse(*argv: str) -> rllib_train.RLlibPPOConfig:
    return rllib_train.config_of(cli.build_parser().parse_args(['rllib-train', *argv]))


def test_the_command_parses_without_ray():
    config = parse('--team', 'target', '--steps', '2e6', '--eval-every', '500000', '--num-env-runners', '4',
                   '--hidden', '64', '64', '--address', 'auto', '--lr-schedule', '[[0, 0.001], [1000, 0.0001]]')
    assert (config.team, config.steps, config.eval_every, config.num_env_runners) == ('target', 2_000_000, 500_000, 4)
    assert config.hidden == (64, 64) and config.address == 'auto' and config.lr_schedule == ((0, 1e-3), (1000, 1e-4))
    assert config.envs_per_runner == 16 and config.resolved_frame_skip == 10 and config.resolved_horizon == 5000
    assert config.env_id == 'MATE-2v4-0-v0' and parse().env_id == 'MATE-4v8-9-v0'
    assert 'iterations' in dataclasses.asdict(config) and config.iterations is None


def test_the_defaults_are_the_papers_rllib_settings():
    config = parse()
    assert ((config.gamma, config.gae_lambda, config.clip, config.vf_clip, config.value_coef)
            == (0.99, 1.0, 0.3, 1e4, 1.0))
    assert (config.kl_coeff, config.kl_target, config.epochs, config.minibatch_size) == (0.2, 0.01, 16, 256)
    assert config.rollout_length == 25 and config.max_grad_norm == 0 and not config.vf_share_layers
    assert config.lr_schedule == ((0, 5e-4), (4_000_000, 1e-4), (8_000_000, 5e-5))
    assert config.entropy_schedule == ((0, 0.05), (2_000_000, 0.01), (4_000_000, 0.001), (10_000_000, 0.0))


def test_the_run_options_mean_what_they_mean_for_mate_train():
    """Same names, defaults and help as `mate train`'s (RunConfig and TeamEnvConfig fields)."""
    needs_extra('torch')
    from mate.learn.run import RunConfig

    ours = {f.name: f for f in dataclasses.fields(rllib_train.RLlibPPOConfig)}
    for field in dataclasses.fields(RunConfig):
        if field.name in ('threads', 'device'):       # the RLlib learner's own: torch threads of the driver, CPU
            continue
        assert field.name in ours, field.name
        assert ours[field.name].default == field.default, field.name
        if field.name != 'run_dir':                   # its default directory is named after the algorithm
            assert ours[field.name].metadata['help'] == field.metadata['help'], field.name
    for name in ('team', 'config', 'frame_skip', 'horizon', 'num_envs', 'seed'):
        assert name in ours
    assert 'team' in rllib_train.RLlibPPOConfig(team='camera').to_dict()
    assert 'hrl' not in rllib_train.RLlibPPOConfig().to_dict()


def error_of(capsys, *argv: str) -> str:
    """The one line `mate rllib-train ARGV` prints on stderr (exit status 2, no traceback)."""
    try:
        status = cli.main(['rllib-train', *argv])
    except SystemExit as exc:                     # argparse's own errors
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2 and 'Traceback' not in err, err
    lines = [line for line in err.strip().splitlines() if not line.startswith('usage:') and line.startswith('mate')]
    assert len(lines) == 1, err
    return ' '.join(err.split())


@pytest.mark.parametrize('argv, expected', [
    (['--num-envs', '6', '--num-env-runners', '4'], '--num-envs 6 must be a multiple of --num-env-runners 4'),
    (['--lr-schedule', '[[100, 0.001]]'], '--lr-schedule must start at step 0 (RLlib schedules do), got 100'),
    (['--eval-every', '100', '--seed', '999990', '--num-envs', '64'],
     'seed + num_envs must be at most 1,000,000'),
    (['--seed', '999990', '--num-envs', '64'], 'seed + num_envs must be at most 1,000,000'),   # evaluated or not
    (['--eval-episodes', '100001'], "argument --eval-episodes: expected an integer >= 1 and <= 100000, got '100001'"),
    (['--team', 'cameras'], "invalid choice: 'cameras' (choose from 'camera', 'target')"),
    (['--activation', 'gelu'], "invalid choice: 'gelu'"),
    (['--iterations', '0'], "--iterations: expected an integer >= 1, got '0'"),
    (['--num-envs', '4', '--rollout-length', '25'], '--minibatch-size 256 must be at most the batch, num_envs x '
                                                    'rollout_length = 100'),
    (['--config', 'MATE-9v9-9'], 'Known presets'),
])
def test_mistakes_are_one_line(capsys, argv, expected):
    assert expected in error_of(capsys, *argv)


def test_without_ray_the_command_explains_how_to_install_it(capsys, monkeypatch):
    import mate.integrations
    for name in ['ray', *(name for name in sys.modules if name.startswith('ray.'))]:
        monkeypatch.setitem(sys.modules, name, None)  # importing ray now fails, installed or not
    monkeypatch.delitem(sys.modules, 'mate.integrations.rllib', raising=False)
    monkeypatch.delattr(mate.integrations, 'rllib', raising=False)
    assert "pip install 'mate[rllib]'" in error_of(capsys, '--iterations', '1')
