"""Long runs on a multi-node Ray cluster: several raylets on this machine (`ray.cluster_utils.Cluster`: a head
node without CPUs, where the driver's objects live, and worker nodes of one CPU each), with faults injected.

* The runner: a job lost with its node is run again on another one and reported once; a job that raises is not
  retried and is named; a shared value travels once, whatever the number of jobs.
* PSRO: a node lost while a best response trains and one lost while a payoff entry is played; the run ends with
  the state of an undisturbed run (pools' policies, payoff matrices, meta-strategies, exploitability).
* The driver killed, then a job failing for its own reason: each time the same command resumes, without running a
  finished job again, and ends with the undisturbed run's state.

`faults.py` holds the stand-in jobs that record each attempt (with the node it ran on) and stall or fail on request.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from conftest import needs_extra

from . import faults

ray = needs_extra('ray')        # the rllib extra (CI installs it)
torch = needs_extra('torch')

from mate.policies.checkpoint import load_checkpoint          # noqa: E402  (needs torch)
from mate.learn.population import jobs as psro_jobs         # noqa: E402
from mate.learn.population.psro import JOB_LOG, LocalRunner, PSROSettings, load_state, run_psro  # noqa: E402
from mate.evaluation.protocol import PAYOFF_SEEDS  # noqa: E402
from mate.tools.runners import JobFailed, RayRunner, RunnerError  # noqa: E402

SETTINGS = dict(solver='nash', iterations=1, br_steps=2000, num_envs=4, eval_episodes=3, eval_steps=120)
"""A run of seconds: 20 training iterations per best response (a checkpoint every 5), 3 episodes per entry."""
ARGUMENTS = ['--solver', 'nash', '--iterations', '1', '--br-steps', '2000', '--num-envs', '4', '--eval-episodes', '3',
             '--eval-steps', '120']
"""The same run on the command line."""
CAMERA, TARGET = 'br-camera-2', 'br-target-3'
"""The keys of iteration 1's best responses in `faults` (their seeds: `PSROSettings.best_response_seed`)."""
ENTRIES = [f'entry-{k}-{l}-{PAYOFF_SEEDS}' for k, l in ((0, 0), (0, 1), (1, 0), (1, 1))]
"""The keys of the payoff entries of the run (env seeds from `PAYOFF_SEEDS`)."""
LOST, FAILING = ENTRIES[3], ENTRIES[2]
"""The entries the tests lose on a node (camera 1, target 1) and make fail (camera 1, target 0)."""
DEADLINE = 600
"""Seconds a test waits for a stage before it fails, rather than hanging (the stages take seconds)."""


def wait_until(condition, what: str, alive=lambda: True) -> None:
    """Poll `condition` until it holds; fail if `alive()` turns false first (the run ended or died)."""
    deadline = time.monotonic() + DEADLINE
    while not condition():
        if not alive():
            if condition():
                return
            pytest.fail(f'the run ended before {what}')
        if time.monotonic() > deadline:
            pytest.fail(f'no {what} after {DEADLINE} s')
        time.sleep(0.05)


def replace_node(cluster, node_id: str):
    """Kill the worker node `node_id` (its raylet, object store and workers, as when a machine dies) and add a
    fresh node of one CPU in its place."""
    node, = [node for node in cluster.worker_nodes if node.node_id == node_id]
    cluster.remove_node(node, allow_graceful=False)
    cluster.add_node(num_cpus=1)


@pytest.fixture(scope='module')
def cluster():
    """A head node without CPUs (the driver connects there) and two worker nodes of one CPU each."""
    from ray.cluster_utils import Cluster

    if ray.is_initialized():
        ray.shutdown()
    cluster = Cluster(initialize_head=True, head_node_args=dict(num_cpus=0, include_dashboard=False))
    try:
        for _ in range(2):
            cluster.add_node(num_cpus=1)
        ray.init(address=cluster.address, log_to_driver=False, configure_logging=False)
        yield cluster
    finally:
        ray.shutdown()
        cluster.shutdown()


@pytest.fixture(scope='module')
def undisturbed(tmp_path_factory) -> Path:
    """The run of SETTINGS with every job in this process, one after the other."""
    out = tmp_path_factory.mktemp('undisturbed') / 'run'
    run_psro(PSROSettings(**SETTINGS), out, LocalRunner(1), say=lambda line: None)
    return out


def assert_same_run(expected: Path, found: Path) -> None:
    """Both runs hold the same state (times aside) and the same policies."""
    a, b = load_state(expected), load_state(found)
    for key in ('settings', 'pools', 'payoff', 'payoff_sem', 'coverage', 'real_coverage', 'fresh_entries'):
        assert a[key] == b[key], key
    for key in ('iterations', 'best_responses'):
        left, right = ([{k: v for k, v in record.items() if k != 'seconds'} for record in state[key]]
                       for state in (a, b))
        assert sorted(left, key=str) == sorted(right, key=str), key
    assert b['iterations'][1]['exploitability'] is not None and b['iterations'][1]['exploitability_fresh']
    for side in ('camera', 'target'):
        left, right = (load_checkpoint(run / 'players' / f'{side}-1.pt')['actor'] for run in (expected, found))
        assert left.keys() == right.keys() and all(torch.equal(left[name], right[name]) for name in left), side


def job_log(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / JOB_LOG).read_text().splitlines()]


@pytest.mark.slow
def test_the_runner_reruns_a_job_lost_with_its_node_and_reports_every_job_once(cluster, tmp_path):
    faults.register()
    runner = RayRunner()                     # the cluster this process is connected to
    assert not runner.owned and runner.parallel == 2
    payload = runner.share(bytes(range(256)) * 4096)                        # 1 MiB, put into the object store once
    (tmp_path / 'stall-job-0').touch()       # job 0's first attempt waits: its node will be killed under it
    (tmp_path / 'fail-job-3').touch()        # job 3 raises: its own failure
    names = ['job zero', 'job one', 'job two', 'job three']
    jobs = [(faults.echo, dict(folder=str(tmp_path), key=f'job-{i}', value=[payload, b'x' * i])) for i in range(4)]
    finished, failures, raised = [], [], []

    def run():
        try:
            runner.run(jobs, lambda index, result: finished.append((index, result)), names=names,
                       failed=lambda name, reason: failures.append((name, reason)))
        except JobFailed as exc:
            raised.append(exc)

    thread = threading.Thread(target=run)
    thread.start()
    wait_until(lambda: faults.attempts(tmp_path, 'job-0'), 'start of job 0', thread.is_alive)
    lost = faults.attempts(tmp_path, 'job-0')[0]
    replace_node(cluster, lost)
    thread.join(DEADLINE)
    assert not thread.is_alive()

    assert sorted(index for index, _ in finished) == [0, 1, 2]               # once each; the failed job not at all
    results = dict(finished)
    assert [results[i]['size'] for i in range(3)] == [2 ** 20 + i for i in range(3)]
    assert results[0]['attempt'] == 1 and results[1]['attempt'] == results[2]['attempt'] == 0
    first, second = faults.attempts(tmp_path, 'job-0')                     # run again, on another node
    assert first == lost and second != lost and runner.timings[0]['node'] == second
    assert len(faults.attempts(tmp_path, 'job-3')) == 1                     # an exception is not retried
    assert failures == [('job three', 'ValueError: injected failure of job-3')]
    assert len(raised) == 1 and str(raised[0]) == 'job three failed: ValueError: injected failure of job-3'
    assert runner.timings[3] is None
    for index in range(3):
        timing = runner.timings[index]
        assert 0 <= timing['fetch'] and 0 <= timing['seconds'] <= timing['wall']


@pytest.mark.slow
def test_jobs_on_gpus_need_a_cluster_with_gpus(cluster):
    """`mate psro --address ... --device cuda` on a cluster without GPUs: one line at once, not tasks that wait."""
    with pytest.raises(RunnerError, match=r'jobs on GPUs \(--device cuda\) need a Ray cluster with GPUs; this '
                                          r'one has 0'):
        RayRunner(task_gpus=1)
    assert ray.is_initialized()              # the connection of this process is left alone


@pytest.mark.slow
def test_psro_that_loses_nodes_mid_job_ends_as_an_undisturbed_run(cluster, undisturbed, tmp_path, monkeypatch):
    """Kill the node of the camera best response once it has written a checkpoint (it trains), and the node of
    a payoff entry while it is played: Ray runs both again on other nodes (the best response resumes from its
    checkpoint, in the run directory both nodes see), and the run ends with the undisturbed run's state."""
    folder = tmp_path / 'attempts'
    folder.mkdir()
    for name, job in faults.stand_ins(folder).items():
        monkeypatch.setattr(psro_jobs, name, job)
    (folder / f'stall-{LOST}').touch()
    out, said, errors = tmp_path / 'run', [], []

    def run():
        try:
            run_psro(PSROSettings(**SETTINGS), out, RayRunner(), say=said.append)
        except BaseException as exc:  # noqa: BLE001  (reported by the test)
            errors.append(exc)

    thread = threading.Thread(target=run)
    thread.start()
    wait_until(lambda: (out / 'players' / 'camera-1' / 'checkpoint.pt').exists(),
               'checkpoint of the camera best response', thread.is_alive)
    lost_training = faults.attempts(folder, CAMERA)[0]
    replace_node(cluster, lost_training)
    wait_until(lambda: faults.attempts(folder, LOST), 'start of payoff entry (1, 1)', thread.is_alive)
    lost_entry = faults.attempts(folder, LOST)[0]
    replace_node(cluster, lost_entry)
    thread.join(DEADLINE)
    assert not thread.is_alive() and not errors, errors

    trained = faults.attempts(folder, CAMERA)
    assert len(trained) == 2 and trained[0] == lost_training != trained[1]
    assert len(faults.attempts(folder, TARGET)) == 1
    entry = faults.attempts(folder, LOST)
    assert len(entry) == 2 and entry[0] == lost_entry != entry[1]
    assert [len(faults.attempts(folder, key)) for key in ENTRIES if key != LOST] == [1, 1, 1]
    rows = (out / 'players' / 'camera-1' / 'progress.csv').read_text().splitlines()[1:]
    assert [int(float(row.split(',')[0])) for row in rows] == list(range(1, 21))   # resumed: no iteration twice
    log = job_log(out)
    names = [record['job'] for record in log]
    assert all(record['status'] == 'done' for record in log) and len(names) == len(set(names))   # each saved once
    assert {'the camera best response of iteration 1', 'payoff entry (camera 1, target 1) of iteration 1'} <= set(names)
    assert_same_run(undisturbed, out)


DRIVER = """
import sys
sys.path.insert(0, sys.argv[1])
import faults
from mate.learn.population import jobs
for name, job in faults.stand_ins(sys.argv[2]).items():
    setattr(jobs, name, job)
from mate.cli.main import main
sys.exit(main(sys.argv[3:]))
"""
"""`mate psro ARGS` as a driver whose jobs are the stand-ins of `faults` (recording in the folder argv[2])."""


@pytest.mark.slow
def test_a_killed_driver_and_a_failing_job_resume_without_redoing_finished_jobs(cluster, undisturbed, tmp_path):
    """`mate psro --address` killed (SIGKILL) once the camera best response is saved, while the target one runs:
    the same command runs the target best response again but not the camera one, then stops at a payoff entry that
    raises, naming it in one line (the other entries saved, the failed one not retried); after the fix the same
    command plays that entry alone and ends with the undisturbed run's state."""
    folder, out = tmp_path / 'attempts', tmp_path / 'run'
    folder.mkdir()
    (folder / f'stall-{TARGET}').touch()
    (folder / f'fail-{FAILING}').touch()
    command = [sys.executable, '-c', DRIVER, str(Path(__file__).parent), str(folder), 'psro', '--address',
               cluster.address, *ARGUMENTS, '--out', str(out)]
    env = dict(os.environ, MATE_COMPILE_NOTICE='0')

    def camera_saved():
        state = load_state(out) if (out / 'state.json').exists() else None
        return state is not None and len(state['pools']['camera']) == 2 and faults.attempts(folder, TARGET)

    driver = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    try:
        wait_until(camera_saved, 'camera best response saved', lambda: driver.poll() is None)
    finally:
        driver.send_signal(signal.SIGKILL)
        _, err = driver.communicate()
    assert driver.returncode == -signal.SIGKILL, err.decode()[-2000:]
    state = load_state(out)
    assert state['pools'] == dict(camera=['random', 'players/camera-1.pt'], target=['random'])

    second = subprocess.run(command, capture_output=True, text=True, env=env)
    assert second.returncode == 2, second.stderr[-2000:]
    error = [line for line in second.stderr.splitlines() if 'error:' in line]
    assert error == [f'mate psro: error: payoff entry (camera 1, target 0) of iteration 1 failed: ValueError: injected '
                     f'failure of {FAILING}; every finished job is saved in {out}: fix the cause and run the same '
                     'command again to resume'], second.stderr[-2000:]
    assert 'Traceback' not in second.stderr and 'resuming' in second.stdout
    state = load_state(out)
    assert state['pools']['target'] == ['random', 'players/target-1.pt']
    assert state['payoff'][1][0] is None and None not in (state['payoff'][0][1], state['payoff'][1][1])
    assert len(faults.attempts(folder, FAILING)) == 1                 # its own failure: not retried

    (folder / f'fail-{FAILING}').unlink()                                  # the fix
    third = subprocess.run(command, capture_output=True, text=True, env=env)
    assert third.returncode == 0, third.stderr[-2000:]
    counts = {key: len(faults.attempts(folder, key)) for key in (CAMERA, TARGET, *ENTRIES)}
    assert counts == {CAMERA: 1, TARGET: 2, ENTRIES[0]: 1, ENTRIES[1]: 1, FAILING: 2, LOST: 1}
    log = job_log(out)
    done = [record['job'] for record in log if record['status'] == 'done']
    assert len(done) == len(set(done))                                      # no job saved twice
    assert [(r['job'], r['reason']) for r in log if r['status'] == 'failed'] == [
        ('payoff entry (camera 1, target 0) of iteration 1', f'ValueError: injected failure of {FAILING}')]
    assert_same_run(undisturbed, out)
