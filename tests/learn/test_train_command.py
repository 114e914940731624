"""`mate train ALGORITHM`: options generated from the trainer's config (another trainer's option is refused), a
finished run left alone, a signal stops at an iteration with status 130 and the same command continues, and a log
file gets plain progress lines."""

import os
import signal
import subprocess
import sys
import time

import pytest

from mate.cli.main import main
from mate.policies.checkpoint import load_checkpoint
from mate.learn.command import TRAINERS, trainer_parser
from mate.learn.mappo import MAPPOConfig, train

from .toy import CueMatching


@pytest.fixture
def finished_run(tmp_path):
    """A run directory trained to 20 decision steps (2 iterations of 2 envs x 5 decisions; `--steps 15` overshoots)."""
    config = MAPPOConfig(actor='mlp', steps=15, num_envs=2, rollout_length=5, epochs=1, hidden=(8,), seed=0,
                         run_dir=str(tmp_path), progress=False)
    assert train(config, envs=CueMatching(num_envs=2)).env_steps == 20
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
    config = MAPPOConfig(actor='mlp', steps=10 ** 9, num_envs=2, rollout_length=5, epochs=1, hidden=(8,),
                         minutes=0.3 / 60, seed=0, run_dir=str(tmp_path), progress=False)
    train(config, envs=CueMatching(num_envs=2))
    assert main(['train', 'mappo', '--steps', '1e9', '--minutes', '0.005', '--run-dir', str(tmp_path)]) == 0
    out = ' '.join(capsys.readouterr().out.split())
    assert 'run already done:' in out and '>= --minutes 0.005' in out and 'raise --minutes' in out


@pytest.mark.parametrize('algo, option', [('iql', '--epochs'), ('mappo', '--buffer-size'), ('matd3', '--hrl'),
                                          ('qmix', '--credit'), ('ippo', '--critic'), ('i2c', '--message-delay')])
def test_an_option_of_another_trainer_is_refused(capsys, algo, option):
    with pytest.raises(SystemExit) as stop:         # the trainer's own parser, as argparse's errors do
        main(['train', algo, option, '4'])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and 'Traceback' not in err
    assert err.startswith(f'mate train {algo}: error: ') and option in err


def test_the_options_and_defaults_come_from_the_config_dataclasses(capsys):
    with pytest.raises(SystemExit):
        main(['train', '-h'])
    listing = capsys.readouterr().out
    assert all(name in listing for name in TRAINERS)
    parser, _, config_class = trainer_parser('iql')
    text = parser.format_help()
    assert '--buffer-size' in text and '--epochs' not in text and '(default: 500,000)' in text
    parser, _, config_class = trainer_parser('mappo')
    text = ' '.join(parser.format_help().split())
    assert ('--rollout-length ROLLOUT_LENGTH decisions per env per iteration (the paper: 25-step fragments) '
            '(default: 25)' in text)
    assert '--paper' in text and '--critic' not in text          # `mappo` fixes the critic; `ippo` is its twin


@pytest.mark.slow
def test_a_signal_stops_training_at_an_iteration_and_the_command_continues(tmp_path):
    """SIGINT while `mate train` runs with its output in a file: status 130, a checkpoint of the iteration and a
    plain progress line in the log (no bar escape codes); the same command then finishes the run."""
    command = [sys.executable, '-m', 'mate', 'train', 'mappo', '--steps', '4000', '--num-envs', '4', '--rollout-length',
               '10', '--horizon', '40', '--threads', '1', '--seed', '3', '--run-dir', str(tmp_path / 'run')]
    log = tmp_path / 'train.log'
    env = dict(os.environ, MATE_COMPILE_NOTICE='0')
    with open(log, 'w') as out:
        process = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, env=env)
        csv = tmp_path / 'run' / 'progress.csv'
        deadline = time.time() + 300
        while (time.time() < deadline and process.poll() is None
               and not (csv.exists() and csv.read_text().count('\n') >= 3)):
            time.sleep(0.02)
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=300) == 130
    text = log.read_text()
    assert 'training: 0/4,000 (0%)' in text and 'stopping after this iteration' in text and '\x1b' not in text
    assert 'Traceback' not in text and 'run the same command again to continue' in text
    saved = load_checkpoint(tmp_path / 'run' / 'checkpoint.pt')
    stopped_at = saved['run']['iteration']
    assert 2 <= stopped_at < 100 and not (tmp_path / 'run' / 'final.pt').exists()
    rows = (tmp_path / 'run' / 'progress.csv').read_text().splitlines()
    assert len(rows) == 1 + stopped_at                       # one row per iteration, up to the checkpoint
    done = subprocess.run(command, capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stdout[-2000:]
    assert f'resuming from {tmp_path / "run" / "checkpoint.pt"}' in ' '.join(done.stdout.split())
    assert (tmp_path / 'run' / 'final.pt').exists()
    assert len((tmp_path / 'run' / 'progress.csv').read_text().splitlines()) == 1 + 100


def test_resuming_with_another_flag_names_the_flag(tmp_path, capsys):
    """A run directory of an HRL run resumed without --hrl: the message names --hrl, not the derived action count."""
    arguments = ['train', 'mappo', '--steps', '10', '--num-envs', '2', '--rollout-length', '5', '--epochs', '1',
                 '--threads', '1', '--no-progress', '--run-dir', str(tmp_path)]
    assert main([*arguments, '--hrl']) == 0
    capsys.readouterr()
    assert main(arguments + ['--steps', '20']) == 2
    err = capsys.readouterr().err
    assert err.startswith('mate train: error: ') and len(err.strip().splitlines()) == 1
    assert 'trained with per-target HRL selections (--hrl); this run has grid moves (no --hrl)' in err
    assert 'num_actions' not in err
