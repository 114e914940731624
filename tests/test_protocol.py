"""`mate.score_policy`: a user's policy scored as the benchmark scores its learners (held-out seeds, the absolute
metric, the references on the same games), with the run files `mate benchmark report` reads."""

from __future__ import annotations

import json

import numpy as np
import pytest

import mate
from mate import protocol
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
