"""Experiments of the user's own files (`mate.benchmark.user`): a Python or YAML file outside the package, with mate
trainers, command lines and training functions as settings, run, reported and followed from any directory."""

from __future__ import annotations

import json
import sys
import textwrap

import pytest

from mate.benchmark.experiments import Claim, Experiment, Setting, experiment_of
from mate.benchmark.user import load_experiment
from mate.cli.main import main

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


def run_and_report(experiment, folder):
    """`mate benchmark run EXPERIMENT --out out` then `report out --out report`, both from `folder`; returns it."""
    monkey = pytest.MonkeyPatch()
    monkey.chdir(folder)
    try:
        assert main(['benchmark', 'run', str(experiment), '--out', 'out', '--jobs', '2', '--threads', '1']) == 0
        assert main(['benchmark', 'report', 'out', '--out', 'report', '--reps', '500']) == 0
    finally:
        monkey.undo()
    return folder


@pytest.fixture(scope='module')
def mine(tmp_path_factory):
    """A Python experiment run from another directory, and its report."""
    home = tmp_path_factory.mktemp('home')
    (home / 'mine.py').write_text(PYTHON_EXPERIMENT)
    return run_and_report(home / 'mine.py', tmp_path_factory.mktemp('elsewhere'))


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_the_runner_recipe_works_as_written(tmp_path, monkeypatch):
    """The recipe of mate/benchmark/runner.py's docstring, run as written (in a temporary directory)."""
    import mate.benchmark.runner as runner

    monkeypatch.chdir(tmp_path)
    exec(_recipe(runner), {})
    assert (tmp_path / 'bench' / 'smoke' / 'benchmark.json').exists()
    assert main(['benchmark', 'report', 'bench/smoke', '--out', 'report', '--reps', '200']) == 0


REFERENCE_EXPERIMENT = '''
import numpy as np

from mate.benchmark.experiments import Claim, Experiment, Reference, Setting
from mate.teams import make_team


def still(observations):
    """A scripted team: no camera moves."""
    return np.zeros((*observations.shape[:2], 2))


def greedy_by_factory(num_envs, counts, seed):
    """The greedy cameras as a team factory of mine."""
    return make_team('greedy', 'camera', num_envs, counts, seed=seed)


def stand_still(team, config, steps, seed, run_dir):
    return still


def greedy(team, config, steps, seed, run_dir):
    return 'greedy'


def curve(team, config, steps, seed, run_dir, protocol):
    """A 'training' of 40 decisions a step that logs the evaluations its protocol asks for."""
    assert (protocol.team, protocol.config, protocol.steps) == (team, config, steps) == ('camera', 'MATE-2v4-0', 100)
    assert (protocol.horizon, protocol.eval_every, protocol.eval_episodes, protocol.seed) == (30, 25, 2, seed)
    for done in range(40, steps + 40, 40):
        if protocol.due(done - 40, done):
            protocol.evaluate(still, env_steps=done)
    return still


EXPERIMENT = Experiment(
    'with-mine', 'rules of mine as references', 'camera', ('MATE-2v4-0',),
    (Setting('stand still', call=stand_still), Setting('greedy again', call=greedy), Setting('curve', call=curve)),
    steps=100, eval_every=25, eval_episodes=2, horizon=30, seeds=3,
    references=('random', 'greedy', Reference('still cameras', call=still),
                {'label': 'my greedy', 'call': 'with_mine.py:greedy_by_factory'}),
    claim='the greedy rules beat standing still',
    claims=(Claim('greedy again beats the still cameras', 'greedy again', 'still cameras'),
            Claim('my greedy beats standing still', 'my greedy', 'stand still')))
'''


@pytest.fixture(scope='module')
def with_mine(tmp_path_factory):
    """An experiment with two reference teams of the user's (a policy and a factory, the second given as a YAML
    file would give it) and a training function that takes the protocol, run and reported."""
    home = tmp_path_factory.mktemp('with-mine')
    (home / 'with_mine.py').write_text(REFERENCE_EXPERIMENT)
    return run_and_report('with_mine.py', home)


@pytest.mark.slow
def test_a_reference_team_of_yours_is_played_once_on_the_same_games(with_mine):
    summary = json.loads((with_mine / 'report' / 'results.json').read_text())['with-mine']
    task = summary['tasks']['MATE-2v4-0 cameras']
    references, settings = task['references'], task['settings']
    assert list(references) == ['random', 'greedy', 'still cameras', 'my greedy']
    assert all(reference['episodes'] == 20 for reference in references.values())
    # the same games: a factory of the greedy cameras scores as the greedy reference, episode for episode, and a
    # setting that returns the reference's policy as the reference
    folder = with_mine / 'out' / 'references'
    episodes = {name: json.loads((folder / f'{name}-MATE-2v4-0' / 'absolute.json').read_text())['episodes']
                for name in ('greedy', 'my-greedy', 'still-cameras')}
    assert [e['coverage_rate'] for e in episodes['greedy']] == [e['coverage_rate'] for e in episodes['my-greedy']]
    assert settings['stand still']['absolute']['IQM']['point'] == pytest.approx(references['still cameras']['absolute'])
    assert references['greedy']['absolute'] > references['still cameras']['absolute']
    jobs = json.loads((with_mine / 'out' / 'benchmark.json').read_text())['jobs']
    assert sum(job['label'] == 'still cameras' for job in jobs) == 1      # once per game: no seeds, no budget
    markdown = (with_mine / 'report' / 'results.md').read_text()
    assert '| *still cameras* (reference) |' in markdown and '| *my greedy* (reference) |' in markdown


@pytest.mark.slow
def test_a_claim_against_a_reference_team_of_yours(with_mine):
    summary = json.loads((with_mine / 'report' / 'results.json').read_text())['with-mine']
    claims = {claim['text']: claim for claim in summary['claims']}
    against = claims['greedy again beats the still cameras']
    assert against['statistic'].startswith('IQM of greedy again - still cameras')
    assert against['test'] == 'paired t, runs x episodes' and against['verdict'] == 'confirmed'
    assert against['low'] > 0
    reverse = claims['my greedy beats standing still']             # the reference on the better side
    assert reverse['statistic'].startswith('IQM of stand still - my greedy') and reverse['verdict'] == 'confirmed'


@pytest.mark.slow
def test_a_training_function_gets_the_protocol_and_draws_a_curve(with_mine):
    from mate.learn.evaluation import read_evaluations

    for seed in range(3):
        logged = read_evaluations(with_mine / 'out' / 'runs' / f'curve-MATE-2v4-0-seed{seed}')
        assert [e['env_steps'] for e in logged] == [40, 80, 100]     # due at 25, 50 and 75; the benchmark's at 100
        assert all(len(e['episodes']) == 2 for e in logged)
    still = read_evaluations(with_mine / 'out' / 'runs' / 'stand-still-MATE-2v4-0-seed0')
    assert [e['env_steps'] for e in still] == [100]                  # a function without `protocol`: as before
    summary = json.loads((with_mine / 'report' / 'results.json').read_text())['with-mine']
    assert summary['tasks']['MATE-2v4-0 cameras']['settings']['curve']['runs'] == 3


def test_a_reference_team_is_checked_when_it_is_built(tmp_path):
    from mate.benchmark.experiments import Reference

    def local(observations):
        return observations

    setting = (Setting('MAPPO', 'mappo'),)
    with pytest.raises(ValueError, match="the labels random, greedy, upper-bound .in any case. are the rule teams'"):
        Reference('Greedy', call='rules.py:greedy')
    with pytest.raises(ValueError, match='a reference needs a function defined at the top level'):
        Reference('mine', call=local)
    with pytest.raises(ValueError, match="reference 'MAPPO' is named twice"):
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), setting, steps=10,
                   references=('random', Reference('MAPPO', call='rules.py:act')))
    with pytest.raises(ValueError, match="reference 'mine': missing call"):
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), setting, steps=10, references=({'label': 'mine'},))
    with pytest.raises(ValueError, match='unknown reference .greedyy.; references are random, greedy, upper-bound, or'):
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), setting, steps=10, references=('greedyy',))
    (tmp_path / 'mine.yaml').write_text(textwrap.dedent('''
        name: mine
        figure: a reference of mine
        team: target
        presets: MATE-2v4-0
        settings: [{label: MAPPO, command: mappo}]
        steps: 10
        references: [random, {label: my rules, call: 'rules.py:act'}]
        claims: [{text: MAPPO beats my rules, better: MAPPO, worse: my rules}]
        '''))
    experiment = load_experiment(tmp_path / 'mine.yaml')
    assert experiment.references == ('random', Reference('my rules', f'{(tmp_path / "rules.py").resolve()}:act'))
    assert Experiment.from_dict(experiment.to_dict()) == experiment            # what the manifest keeps


def test_a_claim_between_settings_that_its_seeds_cannot_decide_warns():
    import dataclasses
    import warnings

    from mate.benchmark.experiments import EXPERIMENTS, UndecidableClaimWarning

    settings = (Setting('A', 'mappo'), Setting('B', 'ippo'))
    one = (Claim('A beats B', 'A', 'B'),)
    with pytest.warns(UndecidableClaimWarning, match=r"claim 'A beats B': at seeds=3 a claim between two settings can "
                                                      r"never be decisive .* is 0\.1, .*4 seeds or more"):
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), settings, steps=10, seeds=3, claims=one)
    three = (*one, Claim('A beats random', 'A', 'random'), Claim('B beats random', 'B', 'random'))
    with pytest.warns(UndecidableClaimWarning, match=r"at seeds=4 it is decisive only if the other claims' tests are "
                                                      r"significant first .*3 tests.* by 3\); 5 seeds or more"):
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), settings, steps=10, seeds=4, claims=three)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), settings, steps=10, seeds=4, claims=one)
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), settings, steps=10, seeds=5, claims=three)
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), settings, steps=10, seeds=2, claims=three[1:])  # references
        Experiment('x', 'x', 'camera', ('MATE-2v4-0',), settings, steps=10, seeds=3,
                   claims=(Claim('A and B agree', 'A', 'B', kind='agree', margin=0.1),))       # TOST: a t-test
        dataclasses.replace(EXPERIMENTS['smoke'], seeds=2)       # the package's experiments: their docs say so
        experiment_of(dict(definition=dict(EXPERIMENTS['smoke'].to_dict(), source='user')))   # said when built


def test_the_protocol_says_when_an_evaluation_is_due():
    from mate.benchmark.user import RunProtocol

    protocol = RunProtocol('camera', 'MATE-4v8-9', steps=10, seed=0, run_dir='run', horizon=30, eval_every=4,
                           eval_episodes=2)
    assert [protocol.due(before, after) for before, after in ((0, 3), (3, 5), (5, 8), (8, 9), (8, 10), (9, 12))] == \
        [False, True, True, False, False, False]          # 4 and 8 passed; at 10 (the budget) the benchmark's own
