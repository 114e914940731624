"""The evaluation protocol of a run (mate.learn.evaluation): evaluations at fixed intervals on seeds never trained
on, the best evaluated policy kept and scored again on other held-out seeds (the absolute metric), and exact
resumes with it."""

import json

import numpy as np
import pytest

from mate.policies.checkpoint import load_checkpoint
from mate.learn.evaluation import ABSOLUTE_SEEDS, EVALUATION_SEEDS, evaluate_policy, read_evaluations
from mate.learn.mappo import MAPPOConfig, train
from mate.policies.policy import load_policy, pretrained_path

from .resume import assert_same_run, stopped_and_resumed

TINY = dict(seed=1, num_envs=4, rollout_length=10, epochs=1, minibatches=2, horizon=40, threads=1, progress=False,
            hidden=(16, 16))


def test_the_evaluation_seeds_never_overlap_the_training_seeds(tmp_path):
    """Training rows start from seed + b (b < num_envs) and continue their streams; evaluation episodes start from
    EVALUATION_SEEDS + i, the absolute metric from ABSOLUTE_SEEDS + i: disjoint ranges, enforced."""
    config = MAPPOConfig(steps=80, eval_every=40, eval_episodes=3, run_dir=str(tmp_path), **TINY)
    train(config)
    training = set(range(config.seed, config.seed + config.num_envs))
    evaluations = read_evaluations(tmp_path)
    absolute = json.loads((tmp_path / 'absolute.json').read_text())
    evaluated = {seed for record in evaluations for seed in (e['seed'] for e in record['episodes'])}
    scored = {e['seed'] for e in absolute['episodes']}
    assert evaluated == set(range(EVALUATION_SEEDS, EVALUATION_SEEDS + 3))
    assert scored == set(range(ABSOLUTE_SEEDS, ABSOLUTE_SEEDS + 30))
    assert not (training & evaluated) and not (training & scored) and not (evaluated & scored)
    with pytest.raises(ValueError, match='would train on evaluation seeds'):
        train(MAPPOConfig(steps=80, eval_every=40, run_dir=str(tmp_path / 'x'), **dict(TINY, seed=EVALUATION_SEEDS)))


def test_evaluations_at_fixed_intervals_and_the_absolute_metric(tmp_path):
    config = MAPPOConfig(steps=200, eval_every=80, eval_episodes=4, run_dir=str(tmp_path), **TINY)
    rows = []
    train(config, callback=rows.append)
    evaluations = read_evaluations(tmp_path)
    assert [record['env_steps'] for record in evaluations] == [80, 160, 200]     # every 80 decisions, and the end
    for record in evaluations:
        values = [e['coverage_rate'] for e in record['episodes']]
        assert len(values) == 4 and record['mean'] == pytest.approx(np.mean(values))
        assert all(e['episode_length'] == 40 for e in record['episodes'])         # cut at the training horizon
    column = [row['evaluation_coverage_rate'] for row in rows]                  # logged beside the training metrics
    assert [v for v in column if v == v] == [record['mean'] for record in evaluations]
    best = max(evaluations, key=lambda record: record['mean'])
    kept = load_checkpoint(tmp_path / 'best-eval.pt')
    assert kept['note'] == f"best evaluation, iteration {best['iteration']}"
    absolute = json.loads((tmp_path / 'absolute.json').read_text())
    assert absolute['best_evaluation'] == best['mean'] and len(absolute['episodes']) == 40
    again = evaluate_policy(load_policy(tmp_path / 'best-eval.pt'), 40, ABSOLUTE_SEEDS, 40)   # reproducible
    assert absolute['mean'] == pytest.approx(np.mean([e['coverage_rate'] for e in again]), abs=0)


def test_evaluating_a_policy_is_playing_it_batched_against_the_greedy_agents():
    policy = load_policy(pretrained_path('mappo-target-2v4-0'))
    first = evaluate_policy(policy, 3, EVALUATION_SEEDS, max_episode_steps=100)
    assert [e['seed'] for e in first] == [EVALUATION_SEEDS + i for i in range(3)]
    assert all(-1 <= e['normalized_target_return'] <= 1 and e['episode_length'] == 100 for e in first)
    assert evaluate_policy(policy, 3, EVALUATION_SEEDS, max_episode_steps=100) == first


@pytest.mark.slow
def test_a_run_with_evaluations_resumes_exactly(tmp_path):
    def config_of(run_dir, fresh):
        return MAPPOConfig(steps=240, eval_every=60, eval_episodes=2, run_dir=run_dir, fresh=fresh, **TINY)

    straight, stopped = stopped_and_resumed(train, config_of, 3, tmp_path)
    assert_same_run(straight, stopped)
    assert read_evaluations(straight) == read_evaluations(stopped)
    assert json.loads((straight / 'absolute.json').read_text()) == json.loads((stopped / 'absolute.json').read_text())
