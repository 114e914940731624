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


def test_a_yaml_experiment_with_a_command_line_and_a_function_setting(tmp_path, monkeypatch):
    """A YAML file beside its script and its training function, run from another folder: `{here}`, `{python}`, the
    placeholders and the environment variables of a command line, and a 'file.py:function' call."""
    home = tmp_path / 'home'
    home.mkdir()
    (home / 'my_trainer.py').write_text(textwrap.dedent('''
        import os
        import sys
        import numpy as np
        import mate
        run_dir, seed, horizon = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
        assert os.environ['MATE_BENCHMARK_RUN_DIR'] == run_dir and os.path.isabs(run_dir), run_dir
        assert seed == int(os.environ['MATE_BENCHMARK_SEED']) == 0
        mate.score_policy(lambda o: np.zeros((*o.shape[:2], 2)), team='target', config='MATE-2v4-0', episodes=2,
                          max_episode_steps=horizon, references=(), run_dir=run_dir)
        '''))
    (home / 'helpers.py').write_text(textwrap.dedent('''
        def train(team, config, steps, seed, run_dir):
            assert (team, config, steps, seed) == ('target', 'MATE-2v4-0', 10, 0)
            return 'greedy'
        '''))
    (home / 'mine.yaml').write_text(textwrap.dedent('''
        name: mine-yaml
        figure: a command line and a function against the rules
        team: target
        presets: MATE-2v4-0
        settings:
          - label: script
            argv: ['{python}', '{here}/my_trainer.py', '{run_dir}', '{seed}', '{horizon}']
          - {label: rules, call: 'helpers.py:train'}
        steps: 10
        eval_episodes: 2
        horizon: 20
        seeds: 1
        claims:
          - {text: the rules beat the script, better: rules, worse: script}
        '''))
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(['benchmark', 'run', str(home / 'mine.yaml'), '--out', 'out', '--jobs', '2']) == 0
    assert main(['benchmark', 'report', 'out', '--out', 'report', '--reps', '200']) == 0
    assert main(['benchmark', 'status', 'out']) == 0
    results = json.loads((elsewhere / 'report' / 'results.json').read_text())['mine-yaml']
    settings = results['tasks']['MATE-2v4-0 targets']['settings']
    assert {label: s['runs'] for label, s in settings.items()} == {'script': 1, 'rules': 1}
    assert 'Claims of this experiment' in (elsewhere / 'report' / 'results.md').read_text()
    marl = json.loads((elsewhere / 'report' / 'marl_eval.json').read_text())
    assert set(marl['mine-yaml']['MATE-2v4-0 targets']) == {'script', 'rules'}


def test_a_command_line_must_leave_the_run_files(tmp_path, capsys):
    (tmp_path / 'lazy.yaml').write_text(textwrap.dedent('''
        name: lazy
        figure: a command that writes nothing
        team: camera
        presets: [MATE-2v4-0]
        settings: [{label: lazy, argv: ['{python}', -c, 'pass']}]
        steps: 10
        eval_episodes: 2
        horizon: 20
        seeds: 1
        references: [random]
        '''))
    assert main(['benchmark', 'run', str(tmp_path / 'lazy.yaml'), '--out', str(tmp_path / 'out')]) == 1
    log = next((tmp_path / 'out' / 'runs').glob('lazy-*/job.log')).read_text()
    assert 'ended without writing' in log


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
    with pytest.raises(ValueError, match="'upper-bound' is neither a setting"):   # a reference it does not play
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), (Setting('MAPPO', 'mappo'),), steps=10,
                   references=('random', 'greedy'), claims=(Claim('above the bound', 'MAPPO', 'upper-bound'),))
    with pytest.raises(ValueError, match='steps is a positive whole number'):
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), (Setting('MAPPO', 'mappo'),), steps='2e6')
    with pytest.raises(ValueError, match="'upper-bound' is a camera controller"):
        Experiment('x', 'x', 'target', ('MATE-2v4-0',), (Setting('MAPPO', 'mappo'),), steps=10,
                   references=('upper-bound',))
    (tmp_path / 'two.py').write_text('EXPERIMENTS = {}\n')
    with pytest.raises(ValueError, match='one experiment per file'):
        load_experiment(tmp_path / 'two.py')
    assert main(['benchmark', 'run', str(tmp_path / 'missing.py')]) == 2


def test_the_manifest_keeps_the_definition(mine):
    manifest = json.loads((mine / 'out' / 'benchmark.json').read_text())
    experiment = experiment_of(manifest)
    assert experiment.name == 'mine' and [s.kind for s in experiment.settings] == ['trainer', 'call', 'call']


def test_an_old_manifest_names_a_package_experiment():
    """Format 1 manifests (docs/results/*/benchmark) keep the name alone: the package's experiment of that name."""
    from mate.benchmark.experiments import EXPERIMENTS

    assert experiment_of(dict(format='mate.benchmark/1', experiment='smoke')) is EXPERIMENTS['smoke']
    with pytest.raises(ValueError, match="'mine' without its definition"):
        experiment_of(dict(format='mate.benchmark/1', experiment='mine'))


def test_a_newer_manifest_is_refused(tmp_path):
    from mate.benchmark.directory import read_manifest

    (tmp_path / 'benchmark.json').write_text(json.dumps(dict(format='mate.benchmark/9', experiment='smoke')))
    with pytest.raises(ValueError, match="format 'mate.benchmark/9'"):
        read_manifest(tmp_path)


def test_a_returned_policy_or_team_factory():
    from mate.benchmark.user import _is_factory

    def policy(observations, state=None, deterministic=True):
        return observations

    def factory(num_envs, counts, seed):
        return None

    assert not _is_factory(policy) and _is_factory(factory) and not _is_factory(print)


def _recipe(module) -> str:
    """The first indented block of a module's docstring (its recipe), dedented."""
    recipe = []
    for line in module.__doc__.splitlines():
        if line.startswith('    ') or (recipe and not line.strip()):
            recipe.append(line)
        elif recipe:
            break
    return textwrap.dedent('\n'.join(recipe))


def test_the_jobs_recipe_works_as_written(capsys):
    import mate.benchmark.jobs as jobs

    recipe = _recipe(jobs)
    exec(recipe, {})
    printed, = capsys.readouterr().out.splitlines()
    assert '# ' + printed in recipe               # what it prints is what its comment says


def test_the_runner_recipe_works_as_written(tmp_path, monkeypatch):
    """The recipe of mate/benchmark/runner.py's docstring, run as written (in a temporary directory)."""
    import mate.benchmark.runner as runner

    monkeypatch.chdir(tmp_path)
    exec(_recipe(runner), {})
    assert (tmp_path / 'bench' / 'smoke' / 'benchmark.json').exists()
    assert main(['benchmark', 'report', 'bench/smoke', '--out', 'report', '--reps', '200']) == 0
