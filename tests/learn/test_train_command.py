"""`mate train` on a run directory whose run is finished: it says so instead of training 0 steps."""

import pytest

from mate.cli import main
from mate.learn.ppo import PPOConfig, train

from .toy import CueMatching


@pytest.fixture
def finished_run(tmp_path):
    """A run directory trained to 20 decision steps (2 iterations of 2 envs x 5 decisions; `--steps 15` overshoots)."""
    config = PPOConfig(algo='mappo', actor='mlp', total_steps=15, num_envs=2, rollout_length=5, epochs=1, hidden=(8,),
                       seed=0)
    row = train(config, tmp_path, progress=False, envs=CueMatching(num_envs=2))
    assert row['env_steps'] == 20
    return tmp_path


@pytest.mark.parametrize('steps', ['20', '15', '1e1'])
def test_a_finished_run_is_reported_and_left_alone(finished_run, capsys, steps):
    before = {name: (finished_run / name).stat().st_mtime_ns for name in ('checkpoint.pt', 'final.pt', 'progress.csv')}
    assert main(['train', 'mappo', '--steps', steps, '--num-envs', '2', '--rollout-length', '5',
                 '--run-dir', str(finished_run)]) == 0
    out = ' '.join(capsys.readouterr().out.split())
    assert (f'run already done: 20 decision steps >= --steps {int(float(steps))} '
            '(use --fresh to start over or raise --steps)') in out
    assert 'nan' not in out and 'done: 0 decision steps' not in out
    assert before == {name: (finished_run / name).stat().st_mtime_ns for name in before}   # nothing trained


def test_a_run_out_of_minutes_says_so(tmp_path, capsys):
    config = PPOConfig(algo='mappo', actor='mlp', total_steps=10 ** 9, num_envs=2, rollout_length=5, epochs=1,
                       hidden=(8,), time_limit=0.3, seed=0)
    train(config, tmp_path, progress=False, envs=CueMatching(num_envs=2))
    assert main(['train', 'mappo', '--steps', '1e9', '--minutes', '0.005', '--run-dir', str(tmp_path)]) == 0
    out = ' '.join(capsys.readouterr().out.split())
    assert 'run already done:' in out and '>= --minutes 0.005' in out and 'raise --minutes' in out


def test_resuming_with_another_flag_names_the_flag(tmp_path, capsys):
    """A run directory of an HRL run resumed without --hrl: the message names --hrl, not the derived action count."""
    arguments = ['train', 'mappo', '--steps', '10', '--num-envs', '2', '--rollout-length', '5', '--epochs', '1',
                 '--threads', '1', '--no-progress', '--run-dir', str(tmp_path)]
    assert main([*arguments, '--hrl']) == 0
    capsys.readouterr()
    assert main(arguments + ['--steps', '20']) == 2
    err = capsys.readouterr().err
    assert err.startswith('mate train: error: ') and len(err.strip().splitlines()) == 1
    assert 'trained with --hrl; this run is without it' in err and 'num_actions' not in err
