"""scripts/paper_curves.py: with no command it redraws the figures from the thinned logs shipped in
scripts/results/ (no training), and says so when it finds nothing to draw."""

from pathlib import Path

import pytest
from PIL import Image

from modules import load_module

SCRIPT = Path(__file__).resolve().parents[1] / 'scripts' / 'paper_curves.py'
FIGURES = ('cameras-4v8-9', 'targets-2v4-0', 'targets-2v4-0-observability', 'targets-4v8-0', 'cameras-4v8-9-communication',
           'targets-4v8-0-communication', 'cameras-4v8-9-hrl')


@pytest.fixture(scope='module')
def paper_curves():
    return load_module(SCRIPT)


def test_the_default_command_redraws_every_figure_from_the_shipped_logs(paper_curves, tmp_path, monkeypatch):
    import matplotlib
    matplotlib.use('Agg')

    def no_training(*args):
        raise AssertionError('plotting must not train')
    monkeypatch.setattr(paper_curves, 'run_one', no_training)
    assert paper_curves.main(['--out', str(tmp_path)]) == 0
    for figure in FIGURES:
        with Image.open(tmp_path / f'{figure}.png') as image:
            assert image.format == 'PNG' and image.width >= 600 and image.height >= 400
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f'{figure}.png' for figure in FIGURES)


def test_nothing_to_plot_is_an_error(paper_curves, tmp_path, capsys):
    assert paper_curves.main(['plot', '--logs', str(tmp_path)]) == 1
    assert 'nothing to plot' in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_a_training_run_directory_is_preferred_to_a_thinned_log(paper_curves, tmp_path):
    run = 'mappo-camera-4v8-9-seed0'
    assert paper_curves.find_log(tmp_path, run) is None
    (tmp_path / f'{run}.csv').write_text('env_steps\n')
    assert paper_curves.find_log(tmp_path, run) == tmp_path / f'{run}.csv'
    (tmp_path / 'runs' / run).mkdir(parents=True)
    (tmp_path / 'runs' / run / 'progress.csv').write_text('env_steps\n')
    assert paper_curves.find_log(tmp_path, run) == tmp_path / 'runs' / run / 'progress.csv'


def test_the_table_reads_each_curve_at_the_budgets_it_reaches(paper_curves, tmp_path, capsys):
    header = 'iteration,env_steps,episode_normalized_target_return\n'
    for seed, rows in ((0, [(1, 100, ''), (2, 200, 0.1), (3, 400, 0.3)]), (1, [(1, 200, 0.2), (2, 300, 0.4)])):
        (tmp_path / f'mappo-target-4v8-0-seed{seed}.csv').write_text(
            header + ''.join(f'{i},{x},{y}\n' for i, x, y in rows))
    assert paper_curves.main(['table', '--logs', str(tmp_path), '--experiments', 'target-4v8-0', '--algos', 'mappo',
                              '--at', '200', '300', '400']) == 0
    row = capsys.readouterr().out.strip().splitlines()[-1]
    # 200: seeds 0 (0.1) and 1 (0.2); 300: seed 0 interpolated (0.2) and seed 1 (0.4); 400: seed 0 only
    assert row == '| target-4v8-0 | mappo | 2 | 0.150 ± 0.050 (2) | 0.300 ± 0.100 (2) | 0.300 ± 0.000 (1) |'


def test_train_refuses_to_start_without_an_importable_mate(paper_curves, tmp_path, monkeypatch, capsys):
    real_find_spec = paper_curves.importlib.util.find_spec
    monkeypatch.setattr(paper_curves.importlib.util, 'find_spec',
                        lambda name, *rest: None if name == 'mate' else real_find_spec(name, *rest))

    def no_training(*args):
        raise AssertionError('nothing may train before the check')
    monkeypatch.setattr(paper_curves, 'run_one', no_training)
    with pytest.raises(SystemExit) as exit_info:
        paper_curves.main(['train', '--out', str(tmp_path / 'out'), '--experiments', 'target-2v4-0'])
    assert exit_info.value.code == 2
    assert 'mate package is not importable' in capsys.readouterr().err
    assert not (tmp_path / 'out').exists()
