"""Mistakes on the `mate` command line: one or two lines on stderr, `mate COMMAND: error: ...`, naming the
problem and the valid choices; exit status 2; no traceback unless asked for (`--debug`, MATE_DEBUG=1).
A bug (any other exception) still shows its traceback."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from mate.cli import main as cli
from mate.learn import CheckpointError, load_checkpoint

os.environ.setdefault('SDL_VIDEODRIVER', 'dummy')


def run(argv: list[str]) -> int:
    """`mate ARGV` in this process: its exit status (argparse's own errors raise SystemExit)."""
    try:
        return cli.main(argv)
    except SystemExit as exc:
        return exc.code


def error_of(capsys, argv: list[str], *expected: str) -> str:
    """Run a mistaken command; check the status, the shape of stderr and that it names `expected`."""
    status = run(argv)
    out, err = capsys.readouterr()
    words = [word for word in argv if not word.startswith('-')]
    # `mate train ALGORITHM` reads its options with the algorithm's own parser: 'mate train mappo: error: ...'
    command = (' '.join(words[:2]) if words[0] == 'train' and err.startswith(f'mate {" ".join(words[:2])}:')
               else words[0])
    assert status == 2, (status, out, err)
    assert 'Traceback' not in out + err
    lines = err.strip().splitlines()
    assert 1 <= len(lines) <= 2, err
    assert lines[0].startswith(f'mate {command}: error: '), err
    for text in expected:
        assert text in err, (text, err)
    assert 'weights_only' not in err and 'Re-running' not in err    # torch's unsafe advice never reaches users
    return err


@pytest.fixture
def bad_files(tmp_path):
    """Files that are no checkpoint: random bytes, text, and a pickle that would create `pwned` if unpickled."""
    random_bytes = tmp_path / 'random.pt'
    random_bytes.write_bytes(os.urandom(4096))
    text = tmp_path / 'text.pt'
    text.write_text('a text file, not a checkpoint\n')
    return {'random': random_bytes, 'text': text, 'malicious': _malicious_checkpoint(tmp_path)}


class _Payload:
    """Unpickling this (weights_only=False) would call os.mkdir(path)."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self):
        return os.mkdir, (str(self.path),)


def _malicious_checkpoint(tmp_path: Path) -> Path:
    path = tmp_path / 'malicious.pt'
    torch.save({'format': 'mate.learn/2', 'actor': _Payload(tmp_path / 'pwned'), 'spec': {}, 'config': {}}, path)
    return path


# ----------------------------------------------------------------------------------- checkpoints
@pytest.mark.parametrize('kind', ['random', 'text', 'malicious'])
def test_a_bad_checkpoint_file_is_our_error_without_torchs_advice(bad_files, kind, tmp_path):
    with pytest.raises(CheckpointError, match='corrupt or not a mate.learn checkpoint') as info:
        load_checkpoint(bad_files[kind])
    assert 'weights_only' not in str(info.value) and 'Re-running' not in str(info.value)
    assert not (tmp_path / 'pwned').exists()      # nothing was unpickled


@pytest.mark.parametrize('kind', ['random', 'text', 'malicious'])
def test_evaluate_with_a_bad_checkpoint(capsys, bad_files, kind, tmp_path):
    error_of(capsys, ['evaluate', '--camera-agent', f'checkpoint:{bad_files[kind]}', '--no-render'],
             str(bad_files[kind]), 'corrupt or not a mate.learn checkpoint')
    assert not (tmp_path / 'pwned').exists()


def test_evaluate_with_a_missing_checkpoint(capsys, tmp_path):
    error_of(capsys, ['evaluate', '--target-agent', f'checkpoint:{tmp_path / "nonexistent.pt"}', '--no-render'],
             'nonexistent.pt', 'does not exist')


def test_train_init_from_a_bad_file(capsys, bad_files, tmp_path):
    error_of(capsys, ['train', 'mappo', '--init-from', str(tmp_path / 'garbage.pt'),
                      '--run-dir', str(tmp_path / 'run')],
             '--init-from', 'garbage.pt', 'does not exist')
    error_of(capsys, ['train', 'mappo', '--init-from', str(bad_files['malicious']), '--run-dir', str(tmp_path / 'run')],
             '--init-from', 'corrupt')
    assert not (tmp_path / 'run').exists() and not (tmp_path / 'pwned').exists()


def test_train_with_a_corrupt_checkpoint_in_the_run_directory(capsys, tmp_path):
    (tmp_path / 'checkpoint.pt').write_text('not a checkpoint')
    error_of(capsys, ['train', 'mappo', '--run-dir', str(tmp_path)], 'corrupt', '--fresh')


# ----------------------------------------------------------------------------------- names
def test_unknown_agents_list_the_valid_ones(capsys):
    error_of(capsys, ['evaluate', '--camera-agent', 'foo', '--no-render'],
             "unknown camera agent 'foo'", 'random, naive, greedy, heuristic, mixture', 'pretrained:NAME')
    error_of(capsys, ['evaluate', '--target-agent', 'pretrained:nope', '--no-render'],
             "no pretrained policy 'nope'", 'mappo-target-2v4-0')
    error_of(capsys, ['evaluate', '--camera-kwargs', '{"bogus": 1}', '--no-render'], '--camera-kwargs', 'bogus')


@pytest.mark.parametrize('command', [['evaluate', '--no-render'], ['train', 'mappo']])
def test_unknown_presets_list_the_valid_ones(capsys, command):
    error_of(capsys, [*command, '--config', 'MATE-9v9-9'], "'MATE-9v9-9'", 'Known presets', 'MATE-4v8-9', 'MATE-2v4-0')


def test_rllib_train_checks_its_config_before_starting_ray(capsys):
    err = error_of(capsys, ['rllib-train', '--config', 'MATE-9v9-9'])
    assert 'Known presets' in err or "pip install 'mate[rllib]'" in err     # without Ray: how to install it


def test_train_options_that_do_not_fit_the_team(capsys):
    error_of(capsys, ['train', 'mappo', '--team', 'target', '--hrl'], '--hrl', 'cameras only')


def test_a_bad_output_path(capsys, tmp_path):
    error_of(capsys, ['generate-config', '--path', str(tmp_path / 'config.txt')], '.yaml or .yml', 'config.txt')


# ----------------------------------------------------------------------------------- numbers (argparse)
@pytest.mark.parametrize('argv, expected', [
    (['evaluate', '--episodes', '0'], ('--episodes', 'integer >= 1', "'0'")),
    (['evaluate', '--frame-size', '-5'], ('--frame-size', 'integer >= 16', "'-5'")),
    (['evaluate', '--max-episode-steps', '0'], ('--max-episode-steps', 'integer >= 1')),
    (['evaluate', '--episodes', 'many'], ('--episodes', "'many'")),
    (['evaluate', '--enhanced-observation', 'cameras'],
     ('--enhanced-observation', "'both', 'camera', 'target', 'none'")),
    (['generate-config', '--num-cameras', '-1'], ('--num-cameras', 'integer >= 0', "'-1'")),
    (['generate-config', '--num-cargoes-per-target', '3'], ('--num-cargoes-per-target', 'integer >= 4')),
    (['train', 'mappo', '--num-envs', '0'], ('--num-envs', 'integer >= 1')),
    (['train', 'mappo', '--steps', 'nan'], ('--steps', 'integer >= 1')),
    (['train', 'mappo', '--team', 'cameras'], ('--team', "'camera', 'target'")),
    (['rllib-train', '--iterations', '0'], ('--iterations', 'integer >= 1')),
])
def test_numbers_and_choices_are_checked_when_parsing(capsys, argv, expected):
    err = error_of(capsys, argv, *expected)
    assert f'see mate {" ".join(argv[:2]) if argv[0] == "train" else argv[0]} -h' in err


# ----------------------------------------------------------------------------------- tracebacks
def test_debug_flag_and_variable_show_the_traceback(capsys, monkeypatch):
    argv = ['evaluate', '--camera-agent', 'foo', '--no-render']
    for variant in (['--debug', *argv], [*argv, '--debug']):
        assert run(variant) == 2
        err = capsys.readouterr().err
        assert ('Traceback' in err
                and err.strip().splitlines()[-1].startswith("mate evaluate: error: unknown camera agent"))
    monkeypatch.setenv('MATE_DEBUG', '1')
    assert run(argv) == 2 and 'Traceback' in capsys.readouterr().err
    monkeypatch.setenv('MATE_DEBUG', '0')
    assert run(argv) == 2 and 'Traceback' not in capsys.readouterr().err


def test_help_documents_the_debug_switches(capsys):
    assert run(['-h']) == 0
    out = ' '.join(capsys.readouterr().out.split())
    assert '--debug' in out and 'MATE_DEBUG=1' in out and 'status 2' in out


def test_a_bug_still_shows_its_traceback(monkeypatch):
    def broken(args):
        raise KeyError('a bug')
    monkeypatch.setattr(cli, '_presets', broken)
    with pytest.raises(KeyError, match='a bug'):
        cli.main(['presets'])


def test_the_console_entry_point(tmp_path):
    mate = shutil.which('mate', path=f'{Path(sys.executable).parent}{os.pathsep}{os.environ.get("PATH", "")}')
    assert mate is not None, 'the `mate` console script is not installed'
    result = subprocess.run([mate, 'evaluate', '--config', 'MATE-9v9-9', '--no-render'], capture_output=True,
                            text=True, cwd=tmp_path, env={**os.environ, 'COLUMNS': '80'})
    assert result.returncode == 2
    assert 'Traceback' not in result.stdout + result.stderr
    assert result.stderr.startswith("mate evaluate: error: unknown preset or config file 'MATE-9v9-9'")
    assert len(result.stderr.strip().splitlines()) == 1 and 'Known presets' in result.stderr


def test_version(capsys):
    import mate

    assert run(['--version']) == 0
    assert capsys.readouterr().out.strip() == f'mate {mate.__version__}'


@pytest.mark.slow
@pytest.mark.parametrize('module', ['mate', 'mate.cli.main'])
def test_python_dash_m_is_the_mate_command(module, tmp_path):
    """`python -m mate ...` (and `python -m mate.cli.main ...`) parse, report and exit exactly as `mate ...`."""
    result = subprocess.run([sys.executable, '-m', module, 'evaluate', '--config', 'MATE-9v9-9', '--no-render'],
                            capture_output=True, text=True, cwd=tmp_path)
    assert result.returncode == 2 and 'Traceback' not in result.stderr
    assert result.stderr.startswith("mate evaluate: error: unknown preset or config file 'MATE-9v9-9'")
    help_text = subprocess.run([sys.executable, '-m', module, '-h'], capture_output=True, text=True, cwd=tmp_path)
    assert help_text.returncode == 0 and help_text.stdout.startswith('usage: mate ')


@pytest.mark.parametrize('batched', [False, True])
def test_evaluate_a_policy_on_a_game_it_was_not_trained_for(capsys, batched):
    error_of(capsys, ['evaluate', '--config', 'MATE-8v8-9', '--camera-agent', 'pretrained:hrl-mappo-camera-4v8-9',
                      '--episodes', '1', '--no-render', *(['--batched'] if batched else [])],
             'was trained with (cameras, targets, obstacles) = (4, 8, 9)', '(8, 8, 9)')


@pytest.mark.slow
def test_ctrl_c_during_evaluate_exits_130_with_one_line(tmp_path):
    """SIGINT once the episodes are being played (its progress line shows): status 130, one line, no traceback.

    The child starts with SIGINT's default action: a suite started in the background (`pytest &` from a script)
    runs with SIGINT ignored, which its children inherit, and Python then installs no KeyboardInterrupt handler
    (the child would rightly ignore the signal). 20,000 games at once: about 24 M env steps, minutes of work."""
    process = subprocess.Popen([sys.executable, '-m', 'mate', 'evaluate', '--episodes', '20000', '--no-render'],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                               env={**os.environ, 'MATE_COMPILE_NOTICE': '0'},
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        for line in process.stdout:                  # not a terminal: plain progress lines
            if line.startswith('evaluating: '):
                break
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=120)
    finally:
        process.kill()
    assert process.returncode == 130, err
    assert err.strip() == 'mate evaluate: interrupted'


@pytest.mark.slow
def test_generate_config_shows_its_progress_in_a_log(tmp_path):
    result = subprocess.run([sys.executable, '-m', 'mate', 'generate-config', '--num-cameras', '2', '--path',
                             str(tmp_path / 'two.yaml')], capture_output=True, text=True, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert (lines[0].startswith('placing 2 cameras: 3 runs of up to 2,000 Adam steps')
            and ' s for 6 cameras on 2 cores)' in lines[0])
    progress = [line for line in lines if line.startswith('placing cameras: ')]
    assert (progress[0].startswith('placing cameras: 0/6,000 (0%)')
            and progress[-1].startswith('placing cameras: 6,000/6,000'))
    assert 'covering distance' in progress[-1] and (tmp_path / 'two.yaml').is_file()
