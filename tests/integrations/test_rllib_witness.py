"""`mate rllib-train` runs end to end (slow: a local Ray instance, a few RLlib iterations of tiny batches on
MATE-2v4-0): the files of a `mate train` run with the evaluation protocol of `mate.learn.evaluation`, for cameras
and targets; a run that goes on from its checkpoint; a run directory of another algorithm refused in one line."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import torch

from conftest import needs_extra

needs_extra('ray.rllib')

from mate.cli import main as cli  # noqa: E402
from mate.integrations.rllib_export import export_run_checkpoint  # noqa: E402
from mate.policies.checkpoint import load_checkpoint, save_checkpoint  # noqa: E402
from mate.learn.evaluation import ABSOLUTE_SEEDS, EVALUATION_SEEDS, evaluate_policy, read_evaluations  # noqa: E402
from mate.policies.policy import load_policy  # noqa: E402

pytestmark = pytest.mark.slow
TINY = ['--config', 'MATE-2v4-0', '--num-envs', '2', '--rollout-length', '10', '--epochs', '1', '--minibatch-size',
        '20', '--hidden', '16', '--threads', '1', '--no-progress', '--eval-episodes', '2']


@pytest.fixture(scope='module', autouse=True)
def ray_instance():
    """One local Ray instance for the module (the runs use an initialised Ray as it is)."""
    import ray

    ray.init(address='local', num_cpus=1, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield
    ray.shutdown()


def train(*argv: str) -> int:
    return cli.main(['rllib-train', *TINY, *argv])


def progress(run_dir) -> list[dict]:
    with open(run_dir / 'progress.csv', newline='') as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
@pytest.mark.parametrize('team, horizon, metric', [('camera', 50, 'coverage_rate'),
                                                   ('target', 100, 'normalized_target_return')])
def test_a_run_writes_the_files_and_evaluations_of_mate_train(tmp_path, capsys, team, horizon, metric):
    run_dir = tmp_path / team
    assert train('--team', team, '--horizon', str(horizon), '--steps', '60', '--eval-every', '20', '--seed', '7',
                 '--run-dir', str(run_dir)) == 0
    assert 'done: 60 decision steps' in capsys.readouterr().out

    rows = progress(run_dir)
    frame_skip = 5 if team == 'camera' else 10
    assert [int(row['env_steps']) for row in rows] == [20, 40, 60]            # 2 envs x 10 decisions per iteration
    assert [int(row['raw_steps']) for row in rows] == [20 * frame_skip, 40 * frame_skip, 60 * frame_skip]
    assert all(np.isfinite(float(row[f'evaluation_{metric}'])) for row in rows)
    assert all(0.0 <= float(row['rollout_coverage']) <= 1.0 for row in rows)
    assert int(rows[-1]['episodes']) == 60 * frame_skip // horizon           # every training episode counted once
    assert {'policy_loss', 'value_loss', 'entropy', 'lr', 'kl_coeff', 'episode_return'} <= set(rows[0])

    evaluations = read_evaluations(run_dir)
    assert [(e['iteration'], e['env_steps']) for e in evaluations] == [(1, 20), (2, 40), (3, 60)]
    for evaluation in evaluations:
        assert evaluation['metric'] == metric and evaluation['seeds'] == [EVALUATION_SEEDS, EVALUATION_SEEDS + 1]
        assert [e['episode_length'] for e in evaluation['episodes']] == [horizon, horizon]
    absolute = json.loads((run_dir / 'absolute.json').read_text())
    assert absolute['metric'] == metric and absolute['seeds'] == [ABSOLUTE_SEEDS, ABSOLUTE_SEEDS + 19]
    assert len(absolute['episodes']) == 20 and absolute['best_evaluation'] == max(e['mean'] for e in evaluations)

    # the protocol's own code scores the exported policies: replaying them gives the files' numbers
    best = load_policy(run_dir / 'best-eval.pt')
    assert (best.spec.team, best.spec.algo, best.spec.frame_skip, best.spec.hidden) == (team, 'rllib-ppo', frame_skip,
                                                                                          (16,))
    replay = evaluate_policy(best, 20, ABSOLUTE_SEEDS, horizon)
    assert np.mean([e[metric] for e in replay]) == pytest.approx(absolute['mean'], abs=1e-12)
    replay = evaluate_policy(best, 2, EVALUATION_SEEDS, horizon)
    assert np.mean([e[metric] for e in replay]) == pytest.approx(absolute['best_evaluation'], abs=1e-12)

    # final.pt is the policy of the RLlib state the run ends with (kept in checkpoint.pt as plain data)
    exported = load_policy(export_run_checkpoint(run_dir / 'checkpoint.pt', tmp_path / 'again.pt')).actor.state_dict()
    final = load_policy(run_dir / 'final.pt').actor.state_dict()
    assert set(final) == set(exported) and not (run_dir / 'rllib').exists()
    for name in final:
        torch.testing.assert_close(final[name], exported[name], rtol=0, atol=0)


@pytest.mark.slow
def test_the_same_command_goes_on_from_the_checkpoint(tmp_path, capsys):
    run_dir = tmp_path / 'run'
    common = ['--horizon', '50', '--run-dir', str(run_dir), '--checkpoint-every', '1']
    assert train('--steps', '100', '--iterations', '2', *common) == 0
    assert 'stopped after --iterations 2 (40 of 100 decision steps)' in capsys.readouterr().out
    assert not (run_dir / 'final.pt').exists()
    kl_before = float(progress(run_dir)[-1]['kl_coeff'])

    assert train('--steps', '100', *common) == 0
    out = capsys.readouterr().out
    assert 'resuming from' in out and 'done: 100 decision steps' in out
    rows = progress(run_dir)
    assert [int(row['iteration']) for row in rows] == [1, 2, 3, 4, 5]
    assert [int(row['env_steps']) for row in rows] == [20, 40, 60, 80, 100]
    # the adaptive KL coefficient goes on from where it was (RLlib's own checkpoints leave it out)
    assert float(rows[2]['kl_coeff']) in (pytest.approx(kl_before * 0.5), pytest.approx(kl_before),
                                          pytest.approx(kl_before * 1.5))
    assert load_checkpoint(run_dir / 'checkpoint.pt')['run']['iteration'] == 5
    assert (run_dir / 'final.pt').exists()

    assert train('--steps', '100', *common) == 0
    assert 'run already done: 100 decision steps >= --steps 100' in capsys.readouterr().out


def test_a_run_directory_of_another_algorithm_is_refused(tmp_path, capsys):
    from mate.integrations import rllib_train

    config = rllib_train.config_of(cli.build_parser().parse_args(['rllib-train', *TINY]))
    spec = config.policy_spec(action='grid', network='mlp', hidden=config.hidden, algo='ippo')
    save_checkpoint(tmp_path / 'checkpoint.pt', dict(spec=spec.to_dict(), algo='ippo', config={},
                                                     run=dict(env_steps=10), state={}))
    try:
        status = train('--steps', '100', '--run-dir', str(tmp_path))
    except SystemExit as exc:
        status = exc.code
    err = ' '.join(capsys.readouterr().err.split())
    assert status == 2 and 'Traceback' not in err
    assert 'does not match this experiment: trained by ippo; this run is rllib-ppo (use --fresh' in err
