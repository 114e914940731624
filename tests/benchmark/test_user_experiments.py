"""Experiments of the user's own files (`mate.benchmark.user`): a Python or YAML file outside the package, with mate
trainers, command lines and training functions as settings, run, reported and followed from any directory."""

from __future__ import annotations

import json
import sys
import textwrap

import pytest

from mate.benchmark.experiments import Claim, Experiment, Setting, experiment_of
from mate.benchmark.user import load_experiment
from mate.cli import main

TINY = "('--num-envs', '2', '--rollout-length', '5', '--hidden', '8', '8')"
PYTHON_EXPERIMENT = f'''
import numpy as np

from mate.benchmark.experiments import Claim, Experiment, Setting


def still(team, config, steps, seed, run_dir):
    """A 'training' that returns the policy that never moves."""
    return lambda observations: np.zeros((*observations.shape[:2], 2))


def greedy(team, config, steps, seed, run_dir):
    return 'greedy'


EXPERIMENT = Experiment(
    'mine', 'my comparison', 'camera', ('MATE-2v4-0',),
    (Setting('MAPPO', 'mappo', {TINY}), Setting('still', call=still), Setting('greedy again', call=greedy)),
    steps=20, eval_every=10, eval_episodes=2, horizon=30, seeds=2, references=('random', 'greedy'),
    claim='rules beat stillness',
    claims=(Claim('greedy again beats still', 'greedy again', 'still'),
            Claim('still is above random', 'still', 'random')))
'''


@pytest.fixture(scope='module')
def mine(tmp_path_factory):
    """A Python experiment run from another directory, and its report."""
    home = tmp_path_factory.mktemp('home')
    (home / 'mine.py').write_text(PYTHON_EXPERIMENT)
    elsewhere = tmp_path_factory.mktemp('elsewhere')
    monkey = pytest.MonkeyPatch()
    monkey.chdir(elsewhere)
    try:
        assert main(['benchmark', 'run', str(home / 'mine.py'), '--out', 'out', '--jobs', '2', '--threads', '1']) == 0
        assert main(['benchmark', 'report', 'out', '--out', 'report', '--reps', '500']) == 0
    finally:
        monkey.undo()
    return elsewhere


def test_a_python_experiment_runs_and_reports_from_any_directory(mine):
    results = json.loads((mine / 'report' / 'results.json').read_text())['mine']
    settings = results['tasks']['MATE-2v4-0 cameras']['settings']
    assert set(settings) == {'MAPPO', 'still', 'greedy again'} and all(s['runs'] == 2 for s in settings.values())
    greedy_again = settings['greedy again']['absolute']['IQM']['point']
    greedy = results['tasks']['MATE-2v4-0 cameras']['references']['greedy']['absolute']
    assert greedy_again == pytest.approx(greedy)          # the same games as the reference: the same score
    assert results['source'] == 'user'
    markdown = (mine / 'report' / 'results.md').read_text()
    assert 'Claims of this experiment' in markdown and 'Claims of the paper' not in markdown
    marl = json.loads((mine / 'report' / 'marl_eval.json').read_text())
    assert {'MAPPO', 'still', 'greedy again'} <= {algorithm for task in marl.values() for tasks in task.values()
                                                  for algorithm in tasks}
    run = mine / 'out' / 'runs' / 'still-MATE-2v4-0-seed1'
    assert json.loads((run / 'job.json').read_text())['values']['seed'] == 1000   # seed x SEED_STRIDE


def test_status_reads_the_manifest_alone(mine, capsys):
    assert main(['benchmark', 'status', str(mine / 'out')]) == 0
    assert 'mine: ' in capsys.readouterr().out


def test_a_yaml_experiment_with_a_command_line_setting(tmp_path):
    script = tmp_path / 'my_trainer.py'
    script.write_text(textwrap.dedent('''
        import sys
        import numpy as np
        import mate
        run_dir, seed, horizon = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
        mate.score_policy(lambda o: np.zeros((*o.shape[:2], 2)), team='target', config='MATE-2v4-0', episodes=2,
                          max_episode_steps=horizon, references=(), run_dir=run_dir)
        '''))
    (tmp_path / 'mine.yaml').write_text(textwrap.dedent(f'''
        name: mine-yaml
        figure: a command line against the rules
        team: target
        presets: [MATE-2v4-0]
        settings:
          - label: script
            argv: ['{sys.executable}', '{script}', '{{run_dir}}', '{{seed}}', '{{horizon}}']
        steps: 10
        eval_episodes: 2
        horizon: 20
        seeds: 1
        claims:
          - {{text: the script beats random, better: script, worse: random}}
        '''))
    assert main(['benchmark', 'run', str(tmp_path / 'mine.yaml'), '--out', str(tmp_path / 'out')]) == 0
    assert main(['benchmark', 'report', str(tmp_path / 'out'), '--out', str(tmp_path / 'report'), '--reps',
                 '200']) == 0
    results = json.loads((tmp_path / 'report' / 'results.json').read_text())['mine-yaml']
    assert results['tasks']['MATE-2v4-0 targets']['settings']['script']['runs'] == 1


def test_a_definition_is_checked_when_it_is_built(tmp_path):
    with pytest.raises(ValueError, match="'MAPO' is neither a setting"):
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), (Setting('MAPPO', 'mappo'),), steps=10,
                   claims=(Claim('typo', 'MAPO', 'random'),))
    with pytest.raises(ValueError, match='exactly one of command'):
        Setting('both', 'mappo', argv=('python', 'x.py'))
    with pytest.raises(ValueError, match='top level of a file'):
        Setting('lambda', call=lambda **kwargs: None)
    (tmp_path / 'bad.yaml').write_text('name: x\nfigure: x\nteam: camera\npresets: [MATE-2v4-0]\nsetings: []\n')
    with pytest.raises(ValueError, match="unknown experiment key"):
        load_experiment(tmp_path / 'bad.yaml')
    assert main(['benchmark', 'run', str(tmp_path / 'missing.py')]) == 2


def test_the_manifest_keeps_the_definition(mine):
    manifest = json.loads((mine / 'out' / 'benchmark.json').read_text())
    experiment = experiment_of(manifest)
    assert experiment.name == 'mine' and [s.kind for s in experiment.settings] == ['trainer', 'call', 'call']


def test_the_runner_recipe_works_as_written(tmp_path, monkeypatch):
    """The recipe of mate/benchmark/runner.py's docstring, run as written (in a temporary directory)."""
    import mate.benchmark.runner as runner

    recipe = []
    for line in runner.__doc__.splitlines():          # the first indented block of the docstring
        if line.startswith('    ') or (recipe and not line.strip()):
            recipe.append(line)
        elif recipe:
            break
    monkeypatch.chdir(tmp_path)
    exec(textwrap.dedent('\n'.join(recipe)), {})
    assert (tmp_path / 'bench' / 'smoke' / 'benchmark.json').exists()
    assert main(['benchmark', 'report', 'bench/smoke', '--out', 'report', '--reps', '200']) == 0
