"""`mate evaluate`: agent resolution, the episode protocol, the summary, and the recorded GIF."""

import json
import os

os.environ.setdefault('SDL_VIDEODRIVER', 'dummy')

import numpy as np
import pytest
from PIL import Image

import mate
from mate.evaluation import evaluate as ev
from mate.cli.main import main
from mate.messages import Team


def test_short_names_and_module_paths_resolve():
    assert ev.resolve_agent('greedy', Team.CAMERA) is mate.GreedyCameraAgent
    assert ev.resolve_agent('heuristic', Team.TARGET) is mate.HeuristicTargetAgent
    assert ev.resolve_agent('mate:RandomTargetAgent', Team.TARGET) is mate.RandomTargetAgent


@pytest.mark.parametrize('spec, team, message', [
    ('greedyy', Team.CAMERA, "unknown camera agent 'greedyy'"),
    ('mate:GreedyTargetAgent', Team.CAMERA, 'must be a subclass of mate.CameraAgentBase'),
    ('mate:NoSuchAgent', Team.TARGET, "cannot load agent 'mate:NoSuchAgent'"),
    ('no_such_module:Agent', Team.TARGET, "cannot load agent 'no_such_module:Agent'"),
])
def test_bad_agent_specs_are_explained(spec, team, message):
    with pytest.raises(ValueError, match=message):
        ev.resolve_agent(spec, team)


def test_episode_protocol_is_reproducible_and_capped():
    env = mate.make('MATE-4v8-9-v0')
    first = ev.play_episode(env, mate.GreedyCameraAgent, mate.GreedyTargetAgent, seed=3, max_steps=60)
    again = ev.play_episode(env, mate.GreedyCameraAgent, mate.GreedyTargetAgent, seed=3, max_steps=60)
    assert first.episode_length == 60
    for key in ('coverage_rate', 'real_coverage_rate', 'camera_return', 'target_return', 'delivered_cargoes'):
        assert getattr(first, key) == getattr(again, key)
    assert first.camera_return == -first.target_return
    assert 0.0 <= first.coverage_rate <= 1.0


def test_summary_works_without_any_delivery():
    """The original's summary crashed when no episode delivered anything (fixed)."""
    env = mate.make('MATE-4v8-9-v0')
    results = [ev.play_episode(env, mate.RandomCameraAgent, mate.RandomTargetAgent, seed=s, max_steps=20)
               for s in range(2)]
    assert all(r.delivered_cargoes == 0 for r in results)
    summary = {row['key']: row for row in ev.summarise(results)}
    assert summary['delivered_cargoes']['mean'] == 0.0
    assert summary['transport_rate']['mean'] == 0.0
    expected = np.mean([r.coverage_rate for r in results])
    assert summary['coverage_rate']['mean'] == pytest.approx(expected)
    assert summary['coverage_rate']['std'] == pytest.approx(np.std([r.coverage_rate for r in results], ddof=1))


def test_command_prints_the_table_and_writes_a_gif_that_shows_the_game(tmp_path, capsys):
    gif, report = tmp_path / 'episode.gif', tmp_path / 'results.json'
    assert main(['evaluate', '--episodes', '2', '--max-episode-steps', '40', '--frame-every', '2',
                 '--save-gif', str(gif), '--json', str(report)]) == 0
    out = capsys.readouterr().out
    for text in ('coverage rate', 'transport rate', 'team return', 'length (steps)', str(gif)):
        assert text in out
    with Image.open(gif) as image:
        assert image.n_frames == 21  # steps 0, 2, ..., 40
        frames = []
        for index in (0, 20):
            image.seek(index)
            frames.append(np.asarray(image.convert('RGB'), dtype=int))
    assert np.abs(frames[0] - frames[1]).sum() > 0          # the game moves
    first = frames[0].reshape(-1, 3)
    tinted = first.max(axis=1) - first.min(axis=1) > 12     # coloured, not white/grey/black
    warehouses = 4 * (150 / 2100 * 400) ** 2 / 400 ** 2    # share of the frame the warehouse squares cover
    assert tinted.mean() > warehouses + 0.05                 # camera sectors are drawn
    data = json.loads(report.read_text())
    assert len(data['episodes']) == 2 and data['episodes'][1]['seed'] == 1
    assert {row['key'] for row in data['summary']} >= {'coverage_rate', 'target_return', 'episode_length'}


def test_no_render_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(['evaluate', '--episodes', '1', '--max-episode-steps', '5', '--no-render']) == 0
    assert not list(tmp_path.iterdir())


def test_agent_kwargs_must_be_a_json_object(capsys):
    assert main(['evaluate', '--episodes', '1', '--camera-kwargs', '{memory: 3}', '--no-render']) == 2
    assert '--camera-kwargs is not valid JSON' in capsys.readouterr().err
    assert main(['evaluate', '--episodes', '1', '--target-kwargs', '[1, 2]', '--no-render']) == 2
    assert '--target-kwargs must be a JSON object' in capsys.readouterr().err


def test_wrapper_flags_build_the_documented_stack(tmp_path):
    assert main(['evaluate', '--episodes', '1', '--max-episode-steps', '5', '--enhanced-observation', 'target',
                 '--no-communication', '--render-communication', '--save-gif', str(tmp_path / 'x.gif'),
                 '--frame-every', '5']) == 0
    assert (tmp_path / 'x.gif').is_file()


def test_evaluate_is_batched_by_default_and_plays_the_single_env_episodes(tmp_path, capsys):
    """Greedy vs greedy: the batched path (the default) and --single-env play the same episodes (same results,
    same recorded frames of the first), and each says which path ran."""
    outputs = {}
    for path in ('batched', 'single'):
        gif, report = tmp_path / f'{path}.gif', tmp_path / f'{path}.json'
        flag = ['--single-env'] if path == 'single' else []
        assert main(['evaluate', '--episodes', '3', '--max-episode-steps', '60', '--frame-every', '6', '--save-gif',
                     str(gif), '--json', str(report), *flag]) == 0
        outputs[path] = capsys.readouterr().out
        episodes = json.loads(report.read_text())['episodes']
        outputs[path + '-results'] = [{k: v for k, v in e.items() if k != 'steps_per_second'} for e in episodes]
        with Image.open(gif) as image:
            outputs[path + '-frames'] = [np.asarray(image.convert('RGB')).copy()
                                         for _ in range(image.n_frames) if image.seek(_) is None]
    assert 'batched: 3 games at once' in outputs['batched']
    assert 'single env, one episode after the other: --single-env' in outputs['single']
    assert outputs['batched-results'] == outputs['single-results']
    assert len(outputs['batched-frames']) == 11
    assert all(np.array_equal(a, b) for a, b in zip(outputs['batched-frames'], outputs['single-frames']))


@pytest.mark.parametrize('argv, reason', [
    (['--camera-agent', 'heuristic'], 'heuristic has no batched form'),
    (['--no-communication'], 'the wrappers --no-communication need it'),
])
def test_the_single_env_path_says_why(capsys, argv, reason):
    assert main(['evaluate', '--episodes', '1', '--max-episode-steps', '5', '--no-render', *argv]) == 0
    assert f'(single env, one episode after the other: {reason})' in capsys.readouterr().out


@pytest.mark.parametrize('argv, message', [
    (['--batched', '--camera-agent', 'heuristic'], '--batched has no batched form of heuristic'),
    (['--batched', '--shared-field-of-view'], '--batched plays the game without wrappers; drop --shared-field-of-view'),
    (['--batched', '--single-env'], '--batched and --single-env exclude each other'),
])
def test_batched_refuses_what_it_cannot_play(capsys, argv, message):
    assert main(['evaluate', '--episodes', '1', '--no-render', *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith('mate evaluate: error: ') and message in err and len(err.strip().splitlines()) == 1


def test_device_of_batched_policies(capsys):
    import torch

    assert main(['evaluate', '--episodes', '1', '--no-render', '--device', 'gpu']) == 2
    assert "device must be auto, cpu, cuda or cuda:N" in capsys.readouterr().err
    policy = ['--camera-agent', 'pretrained:hrl-mappo-camera-4v8-9', '--episodes', '2', '--max-episode-steps', '30',
              '--no-render']
    if torch.cuda.is_available():    # the same games with the forward passes on the GPU
        assert main(['evaluate', *policy, '--device', 'cuda']) == 0
    else:
        assert main(['evaluate', *policy, '--device', 'cuda']) == 2
        assert 'PyTorch sees no CUDA GPU here' in capsys.readouterr().err
    assert main(['evaluate', *policy, '--device', 'cpu']) == 0


def test_an_agent_of_a_module_in_the_working_directory(tmp_path, monkeypatch):
    """`--camera-agent my_cameras:StillCamera` finds my_cameras.py in the current directory, as `python -m` would."""
    (tmp_path / 'my_cameras_here.py').write_text(
        'import numpy as np\nimport mate\n\n\nclass StillCamera(mate.CameraAgentBase):\n'
        '    def act(self, observation, info=None, deterministic=None):\n        return np.zeros(2)\n')
    monkeypatch.chdir(tmp_path)
    assert main(['evaluate', '--camera-agent', 'my_cameras_here:StillCamera', '--episodes', '1',
                 '--max-episode-steps', '5', '--no-render']) == 0


@pytest.mark.slow
def test_the_summary_heading_is_one_line_in_a_log(tmp_path):
    """Off a terminal (a pipe, a log file) rich's console is 80 columns wide, and a table's title wraps to the
    table's width (about 50): the heading was three lines for a pretrained camera policy. It is a line of its own
    now, whole however narrow the console; the table below keeps its columns."""
    import subprocess
    import sys

    env = {key: value for key, value in os.environ.items() if key not in ('COLUMNS', 'LINES')}
    policy = 'pretrained:hrl-mappo-camera-4v8-9'
    result = subprocess.run([sys.executable, '-m', 'mate', 'evaluate', '--camera-agent', policy, '--episodes', '12',
                             '--max-episode-steps', '5', '--no-render'],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    heading = (f'MultiAgentTracking(4v8, 9): {policy} cameras vs greedy targets, 12 episodes (seeds 0..11, at most '
               '5 steps)')
    assert heading in lines, result.stdout
    table = lines[lines.index(heading) + 1:]
    assert table[0].startswith('┏') and any('coverage rate' in line for line in table)
    assert max(len(line) for line in table if line.startswith(('┏', '│', '└'))) <= 80
