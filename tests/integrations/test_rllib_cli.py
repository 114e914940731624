"""`mate rllib-train`: the command exists without Ray, says how to install it, and (slow, with
Ray installed) trains end to end on a local Ray instance."""

from __future__ import annotations

import importlib.util
import sys

import pytest

from mate import cli

HAS_RLLIB = importlib.util.find_spec('ray') is not None and importlib.util.find_spec('ray.rllib') is not None


def test_the_command_parses_without_ray():
    args = cli.build_parser().parse_args(['rllib-train', '--config', 'MATE-2v4-9', '--iterations', '3',
                                          '--address', 'auto', '--policy-per-camera', '--hidden', '64', '64'])
    assert (args.iterations, args.address, args.policy_per_camera, args.hidden) == (3, 'auto', True, [64, 64])
    assert args.opponent == 'greedy' and args.num_env_runners == 0


def test_without_ray_the_command_explains_how_to_install_it(capsys, monkeypatch):
    import mate.integrations
    for name in ['ray', *(name for name in sys.modules if name.startswith('ray.'))]:
        monkeypatch.setitem(sys.modules, name, None)  # importing ray now fails, installed or not
    monkeypatch.delitem(sys.modules, 'mate.integrations.rllib', raising=False)
    monkeypatch.delattr(mate.integrations, 'rllib', raising=False)
    assert cli.main(['rllib-train', '--iterations', '1']) == 2
    assert "pip install 'mate[rllib]'" in capsys.readouterr().err.replace('\n', '')


@pytest.mark.slow
@pytest.mark.skipif(not HAS_RLLIB, reason='needs the optional extra mate[rllib]')
def test_trains_end_to_end_and_saves_a_checkpoint(tmp_path, capsys):
    checkpoint = tmp_path / 'ppo'
    assert cli.main(['rllib-train', '--config', 'MATE-2v4-9', '--iterations', '2', '--train-batch-size', '100',
                     '--minibatch-size', '50', '--epochs', '1', '--max-episode-steps', '25', '--hidden', '32',
                     '--num-cpus', '2', '--checkpoint-dir', str(checkpoint)]) == 0
    out = capsys.readouterr().out
    assert 'iter   2' in out and 'coverage' in out
    assert checkpoint.exists() and any(checkpoint.iterdir())
