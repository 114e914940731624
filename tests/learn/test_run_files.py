"""What a run folder says about its run (`config.json`, `command.txt`, `--config-file`, Weights & Biases), and what a
newcomer reads in training output (the rounding to whole iterations, the learner's reward, episodes not finished,
a population whose best responses did not train)."""

from __future__ import annotations

import json

import pytest

from mate.cli.main import main
from mate.learn.run import config_hash

pytest.importorskip('torch', reason='needs the train extra')

TINY = ['--num-envs', '4', '--rollout-length', '10', '--hidden', '16', '16', '--no-progress']


def test_a_run_folder_keeps_its_config_its_hash_and_its_command(tmp_path, capsys):
    run = tmp_path / 'run'
    assert main(['train', 'mappo', *TINY, '--steps', '100', '--run-dir', str(run)]) == 0
    out = capsys.readouterr().out
    assert 'an iteration is 40 decision steps: the run trains whole iterations, 120 decision steps for --steps 100' \
        in out
    assert 'done: 120 decision steps (--steps 100 rounded up to whole iterations)' in out
    assert 'no episode finished yet' in out and 'return nan' not in out
    saved = json.loads((run / 'config.json').read_text())
    assert saved['algorithm'] == 'mappo' and saved['config']['num_envs'] == 4 and saved['config']['hidden'] == [16, 16]
    assert saved['resolved'] == dict(env_id='MATE-4v8-9-v0', game=None, frame_skip=5, horizon=2500, team='camera')
    assert saved['config_hash'] == config_hash('mappo', saved['config'])
    assert (run / 'command.txt').read_text().split() == ['mate', 'train', 'mappo', *TINY, '--steps', '100',
                                                         '--run-dir', str(run)]
    moved = dict(saved['config'], run_dir='elsewhere', threads=2, progress=True)
    assert config_hash('mappo', moved) == saved['config_hash']              # where and how it runs: the same run
    assert config_hash('mappo', dict(saved['config'], seed=1)) != saved['config_hash']


def test_a_config_file_and_the_command_line_over_it(tmp_path, capsys):
    file = tmp_path / 'mappo.yaml'
    file.write_text('num-envs: 4\nrollout_length: 10\nhidden: [16, 16]\nprogress: false\nsteps: 400\nseed: 3\n')
    run = tmp_path / 'run'
    assert main(['train', 'mappo', '--config-file', str(file), '--steps', '40', '--run-dir', str(run)]) == 0
    saved = json.loads((run / 'config.json').read_text())['config']
    assert (saved['num_envs'], saved['hidden'], saved['progress'], saved['steps'], saved['seed']) == \
        (4, [16, 16], False, 40, 3)
    for text, message in (('num_env: 4\n', "unknown option 'num_env'; the options are"),
                          ('progress: maybe\n', 'progress is true or false'),
                          ('- 4\n', 'expected a mapping of options')):
        file.write_text(text)
        assert main(['train', 'mappo', '--config-file', str(file), '--run-dir', str(run)]) == 2
        assert message in capsys.readouterr().err
    file.write_text('num_envs: 0\n')
    with pytest.raises(SystemExit):       # the parser's own range check (two lines, status 2)
        main(['train', 'mappo', '--config-file', str(file), '--run-dir', str(run)])
    assert 'expected an integer >= 1' in capsys.readouterr().err


@pytest.mark.slow
def test_weights_and_biases_logs_every_row_offline(tmp_path, monkeypatch):
    pytest.importorskip('wandb', reason='needs wandb (the test extra)')
    monkeypatch.setenv('WANDB_MODE', 'offline')
    monkeypatch.setenv('WANDB_DIR', str(tmp_path))
    monkeypatch.setenv('WANDB_SILENT', 'true')
    run = tmp_path / 'run'
    assert main(['train', 'mappo', *TINY, '--steps', '80', '--run-dir', str(run), '--wandb',
                 '--wandb-project', 'mate-test']) == 0
    logged = list(run.rglob('*.wandb'))
    assert logged, sorted(str(p.relative_to(run)) for p in run.rglob('*'))[:20]


def test_one_thread_is_the_default():
    from mate.learn.run_config import RunConfig

    assert RunConfig().threads == 1


def test_a_population_whose_best_responses_finished_no_episode_says_its_numbers_mean_nothing(tmp_path, capsys):
    out = tmp_path / 'psro'
    assert main(['psro', '--iterations', '1', '--br-steps', '40', '--num-envs', '4', '--eval-episodes', '2',
                 '--eval-steps', '20', '--workers', '1', '--out', str(out)]) == 0
    said = capsys.readouterr().out
    assert 'finished no training episode' in said and 'means nothing at this budget' in said
    logged = [json.loads(line) for line in (out / 'jobs.jsonl').read_text().splitlines()]
    assert any(r['status'] == 'warning' and 'means nothing at this budget' in r['reason'] for r in logged)

