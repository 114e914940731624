"""`mate.score_policy`: a user's policy scored as the benchmark scores its learners (held-out seeds, the absolute
metric, the references on the same games), with the run files `mate benchmark report` reads."""

from __future__ import annotations

import json

import numpy as np
import pytest

import mate
from mate.evaluation import protocol
from mate.teams import GreedyTeam, play_batch


def still(observations):
    return np.zeros((*observations.shape[:2], 2))


def test_greedy_as_a_policy_scores_as_the_greedy_reference():
    score = mate.score_policy('greedy', team='camera', episodes=2, max_episode_steps=60, references=['greedy'])
    assert score.absolute_mean == score.reference_means['greedy']
    assert [e['seed'] for e in score.evaluation] == [protocol.EVALUATION_SEEDS, protocol.EVALUATION_SEEDS + 1]
    assert score.absolute[0]['seed'] == protocol.ABSOLUTE_SEEDS and len(score.absolute) == 20


def test_a_callable_is_played_on_the_games_mate_evaluate_plays():
    """The evaluation episodes are play_batch's games on the evaluation seeds (mate evaluate --seed 1000000)."""
    score = mate.score_policy(still, team='target', episodes=3, max_episode_steps=40, references=())
    results, _ = play_batch('MATE-2v4-0', lambda n, c: GreedyTeam('camera', n, c, seed=protocol.EVALUATION_SEEDS),
                            lambda n, c: protocol.CallableTeam(still, 'target', n), 3, seed=protocol.EVALUATION_SEEDS,
                            max_episode_steps=40)
    assert [e['normalized_target_return'] for e in score.evaluation] == \
        [r.normalized_target_return for r in results]
    assert score.config == 'MATE-2v4-0' and score.metric == 'normalized_target_return'


def test_a_team_factory_and_the_run_files(tmp_path):
    factory = lambda num_envs, counts, seed: GreedyTeam('camera', num_envs, counts, seed=seed)  # noqa: E731
    score = mate.score_policy(team='camera', team_factory=factory, episodes=2, max_episode_steps=50,
                              references=('random', 'greedy'), run_dir=tmp_path, env_steps=1234)
    assert score.normalised('greedy') == pytest.approx(1.0)
    lines = (tmp_path / 'evaluations.jsonl').read_text().splitlines()
    assert len(lines) == 1 and json.loads(lines[0])['env_steps'] == 1234
    absolute = json.loads((tmp_path / 'absolute.json').read_text())
    assert absolute['metric'] == 'coverage_rate' and absolute['mean'] == score.absolute_mean
    assert len(absolute['episodes']) == 20
    assert set(json.loads((tmp_path / 'references.json').read_text())['references']) == {'random', 'greedy'}
    with pytest.raises(ValueError, match="'upper-bound'"):
        score.normalised('upper-bound')


def test_bad_input_is_named():
    with pytest.raises(ValueError, match=r'expected \(2, 4, 2\)'):
        mate.score_policy(lambda o: np.zeros((2, 8)), team='camera', episodes=2, max_episode_steps=5, references=())
    with pytest.raises(ValueError, match='NaN or inf'):
        mate.score_policy(lambda o: np.full((*o.shape[:2], 2), np.nan), team='camera', episodes=1,
                          max_episode_steps=5, references=())
    with pytest.raises(ValueError, match=r'episodes must be a whole number in 1\.\.100,000'):
        mate.score_policy(still, team='camera', episodes=0)
    with pytest.raises(ValueError, match="team must be 'camera' or 'target'"):
        mate.score_policy(still, team='cameras')
    with pytest.raises(TypeError, match='policy must be a callable'):
        mate.score_policy(3, team='camera', episodes=1, max_episode_steps=5, references=())


def test_evaluate_appends_a_curve(tmp_path):
    for steps in (100, 200):
        protocol.evaluate(still, 'camera', episodes=1, max_episode_steps=10, run_dir=tmp_path, env_steps=steps)
    records = [json.loads(line) for line in (tmp_path / 'evaluations.jsonl').read_text().splitlines()]
    assert [r['env_steps'] for r in records] == [100, 200] and records[0]['episodes'] == records[1]['episodes']


def test_the_references_are_cached_by_what_decides_their_score(tmp_path, monkeypatch):
    """`reference_cache`: a rule team's episodes are played once per key and read back (JSON) on the next call;
    another horizon is another key; a file that does not parse or holds another key is played again."""
    arguments = dict(team='camera', config='MATE-2v4-0', episodes=1, max_episode_steps=20, references=('random',),
                     reference_cache=tmp_path)
    first = mate.score_policy(still, **arguments)
    files = sorted(tmp_path.glob('random-camera-*.json'))
    assert len(files) == 2                               # the evaluation and the absolute episodes
    assert json.loads(files[0].read_text())['key']['max_episode_steps'] == 20
    played = []
    real = protocol.play_policy_episodes

    def counted(policy, *args, **kwargs):
        played.append(policy)
        return real(policy, *args, **kwargs)

    monkeypatch.setattr(protocol, 'play_policy_episodes', counted)
    second = mate.score_policy(still, **arguments)
    assert 'random' not in played and second.references == first.references       # read back, the same episodes
    mate.score_policy(still, **dict(arguments, max_episode_steps=21))
    assert played.count('random') == 2 and len(list(tmp_path.glob('random-camera-*.json'))) == 4
    files[0].write_text('{not json')
    played.clear()
    third = mate.score_policy(still, **arguments)
    assert played.count('random') == 1 and third.references == first.references
    keys = [json.loads(path.read_text())['key'] for path in files]       # the bad file replaced
    assert sorted(keys, key=lambda key: key['first_seed']) == [
        protocol.reference_cache_key('random', 'camera', 'MATE-2v4-0', 1, protocol.EVALUATION_SEEDS, 20, 'greedy'),
        protocol.reference_cache_key('random', 'camera', 'MATE-2v4-0', 10, protocol.ABSOLUTE_SEEDS, 20, 'greedy')]


def test_the_reference_cache_folder_is_documented(monkeypatch, tmp_path):
    monkeypatch.setenv('MATE_CACHE_DIR', str(tmp_path / 'mine'))
    assert protocol.reference_cache_dir() == tmp_path / 'mine' / 'references'
    monkeypatch.delenv('MATE_CACHE_DIR')
    monkeypatch.setenv('XDG_CACHE_HOME', str(tmp_path / 'xdg'))
    assert protocol.reference_cache_dir() == tmp_path / 'xdg' / 'mate' / 'references'
    key = protocol.reference_cache_key('greedy', 'camera', 'MATE-4v8-9', 32, protocol.EVALUATION_SEEDS, 2500, 'greedy')
    assert {'reference', 'team', 'config', 'episodes', 'first_seed', 'max_episode_steps', 'opponent', 'code',
            'numpy'} <= set(key)
    config = tmp_path / 'game.yaml'
    config.write_text('a: 1\n')
    first = protocol.reference_cache_key('greedy', 'camera', str(config), 1, 0, 10, 'greedy')
    config.write_text('a: 2\n')
    assert protocol.reference_cache_key('greedy', 'camera', str(config), 1, 0, 10, 'greedy')['sha256'] != \
        first['sha256']                                  # a YAML game is keyed by its text, not its name
