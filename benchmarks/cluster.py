"""What running mate's jobs on a Ray cluster costs, measured on a local multi-node cluster, and a cost model that
projects the paper's scale from the measured per-job costs.

    python benchmarks/cluster.py [--nodes 2] [--json benchmarks/results/cluster-local.json] [--skip-trainers]
                                 [--trainers-from benchmarks/results/cluster-trainers.json]
    python benchmarks/cluster.py --project benchmarks/results/cluster-local.json     # the tables again, no measuring

Protocol (each part prints a line; `--json` keeps everything):

1. A cluster of `--nodes` worker nodes of one CPU each and a head node without CPUs (where the driver and its
   `ray.put` objects live), all raylets on this machine (`ray.cluster_utils.Cluster`).
2. Task overhead: a job that does nothing, sent 30 times one after the other through `RayRunner` (the wall time
   from submission to result in the driver, minus the job's own time, median); and jobs whose arguments hold 10
   policy files (the pretrained HRL camera policy's bytes, 0.47 MB each: the pools a job of PSRO iteration 10 would
   receive if each job got every member), 8 jobs at once, with the bytes inline in each job's arguments against
   put into the object store once (`runner.share`).
3. Per-job costs on the cluster at the PSRO settings (MATE-2v4-0, 16 envs, one torch thread): a camera and a target
   best response of `--br-steps` decisions side by side (decisions/s from their `progress.csv` between the row at
   25 % of the steps and the last; start-up = job time - steps / rate), after a pair of 1/8 the size that starts
   the worker processes (imports: `worker_start_seconds`, once per worker); and a payoff entry of the two trained
   policies, 100 episodes capped at 1,000 steps (env-steps/s of the batched play, start-up likewise).
4. Trainer rates for `fig4a-cameras` not in docs/performance.md (flat MAPPO and IPPO cameras, HRL-IPPO), measured
   beside HRL-MAPPO with `benchmarks/trainers.py`'s protocol (`--trainer-steps` decisions each, the settings one
   after the other, twice; the best rate of each) and scaled to HRL-MAPPO's documented 2,280 decisions/s (ratios
   hold across machines better than absolute rates). `--skip-trainers` leaves them out.
5. The model checked: a small PSRO run (2 iterations of 12,800 decisions per best response, 100 episodes of at
   most 1,000 steps per entry) on a fresh cluster of `--nodes` nodes and on one of 1 node; its measured wall time
   beside the model's prediction from the costs of 2-3 (measured on a fresh cluster of their own).
6. Projections (`project`): the paper's PSRO run (40 iterations, 5 M decisions per best response, 100 episodes of
   at most 10,000 steps per entry) and `mate benchmark run fig4a-cameras --seeds 0-9` (70 runs of 10 M decisions)
   on clusters of 1, 8, 32 and 100 CPUs, and PSRO on nodes of 16 CPUs with one GPU each (`--device cuda`).

The machine's other load matters: the numbers of `benchmarks/results/cluster-local.json` were measured on a 2-core
machine that ran two training runs at the same time (see its `load` field), so they are below a quiet machine's.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
POLICY = ROOT / 'mate' / 'pretrained' / 'hrl-mappo-camera-4v8-9.pt'

DOCUMENTED = {
    # decisions/s of `mate train` at its defaults on a 2-core AMD EPYC (docs/performance.md, trainers-before-after.json)
    'HRL-MAPPO': 2280.3, 'HRL-IQL': 897.9, 'HRL-QMIX': 411.0, 'MA-TD3': 369.4,
}
GPU_NODE = {
    # one node of 16 CPU cores and one NVIDIA H200, --device cuda --num-envs 2048 (trainers-gpu-h200-2048.json)
    'cpus': 16, 'camera_decisions_per_second': 12274.0, 'target_decisions_per_second': 24134.7,
}
PAPER_PSRO = dict(iterations=40, br_steps=5_000_000, episodes=100, episode_steps=10_000)
FIG4A = dict(settings=('MAPPO', 'IPPO', 'HRL-MAPPO', 'HRL-IPPO', 'HRL-IQL', 'HRL-QMIX', 'MA-TD3'), seeds=10,
             steps=10_000_000, cpus_per_job=2)
CLUSTERS = (1, 8, 32, 100)


def say(line: str) -> None:
    print(line, flush=True)


# ============================================================================ measuring

def start_cluster(nodes: int):
    import ray
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args=dict(num_cpus=0, include_dashboard=False))
    for _ in range(nodes):
        cluster.add_node(num_cpus=1)
    ray.init(address=cluster.address, log_to_driver=False, configure_logging=False)
    return cluster


def noop() -> int:
    return 0


def take(policies: list) -> int:
    return sum(len(p) for p in policies)


def measure_overhead(runner) -> dict:
    """Part 2: the overhead of a job that does nothing; policies inline in every job against shared once."""
    walls, own = [], []
    runner.run([(noop, {})], lambda i, r: None)          # the workers started, the function exported
    for _ in range(30):
        runner.run([(noop, {})], lambda i, r: None)
        walls.append(runner.timings[0]['wall'])
        own.append(runner.timings[0]['seconds'] + runner.timings[0]['fetch'])
    noop_ms = 1000 * statistics.median(w - o for w, o in zip(walls, own))
    data = POLICY.read_bytes()
    members, jobs = 10, 8
    result = dict(noop_overhead_ms=noop_ms, policy_bytes=len(data), members=members, jobs=jobs)
    for how in ('inline', 'shared'):
        runner.run([(noop, {})], lambda i, r: None)
        start = time.perf_counter()
        if how == 'inline':
            policies = [bytes(data) for _ in range(members)]
        else:
            policies = [runner.share(bytes(data)) for _ in range(members)]
        runner.run([(take, dict(policies=policies)) for _ in range(jobs)], lambda i, r: None)
        total = time.perf_counter() - start
        fetch = [t['fetch'] for t in runner.timings]
        result[how] = dict(seconds_for_all_jobs=total, per_job_ms=1000 * total / jobs,
                           fetch_ms_median=1000 * statistics.median(fetch),
                           overhead_ms_median=1000 * statistics.median(t['wall'] - t['seconds']
                                                                       for t in runner.timings))
    say(f'overhead: a job of no work {noop_ms:.1f} ms; {jobs} jobs with {members} policies '
        f'({members * len(data) / 1e6:.1f} MB) each: inline {result["inline"]["seconds_for_all_jobs"]:.2f} s, '
        f'shared once {result["shared"]["seconds_for_all_jobs"]:.2f} s')
    return result


def _rate(progress: Path, steps: int) -> float:
    """Decisions/s between the first row at or after 25 % of `steps` and the last row of a training's log."""
    with open(progress, newline='') as f:
        rows = [{k: float(v) for k, v in row.items() if v not in ('', None)} for row in csv.DictReader(f)]
    first = next(r for r in rows if r['env_steps'] >= steps // 4)
    last = rows[-1]
    return (last['env_steps'] - first['env_steps']) / max(last['wall_seconds'] - first['wall_seconds'], 1e-9)


def measure_jobs(runner, folder: Path, br_steps: int) -> dict:
    """Part 3: a camera and a target best response side by side (against a mixture of random and the pretrained
    MAPPO targets, and of random and greedy cameras), after a short pair that starts the workers (torch and mate
    imported: `worker_start_seconds`, once per worker process); each alone (the other node idle); the camera one
    alone against a mixture of eight policies (eight copies of the pretrained targets: what a mixture of many
    pool members costs); then a payoff entry of the two trained policies, 100 episodes of at most 1,000 steps (the
    paper's batch of 100 rows)."""
    from mate.learn.population import jobs

    env = dict(env_id='MATE-2v4-0-v0', config=None)
    opponents = dict(camera=['random', 'pretrained:mappo-target-2v4-0'], target=['random', 'greedy'])
    results = {}

    def trained(index, result):
        results[('camera', 'target')[index]] = result

    def pair(steps: int, name: str):
        runner.run([(jobs.best_response, dict(team=team, env=env, opponents=opponents[team], weights=[0.5, 0.5],
                                              steps=steps, seed=index, run_dir=str(folder / f'{name}-{team}'),
                                              num_envs=16, device='cpu'))
                    for index, team in enumerate(('camera', 'target'))], trained)
        return list(runner.timings)

    def alone(team: str, name: str, opponent: list, weights: list) -> float:
        runner.run([(jobs.best_response, dict(team=team, env=env, opponents=opponent, weights=weights, steps=br_steps,
                                              seed=7, run_dir=str(folder / name), num_envs=16, device='cpu'))],
                   lambda i, r: None)
        return _rate(folder / name / 'progress.csv', br_steps)

    cold = pair(br_steps // 8, 'warm-up')
    warm = pair(br_steps, 'br')
    costs = {}
    for index, team in enumerate(('camera', 'target')):
        rate = _rate(folder / f'br-{team}' / 'progress.csv', br_steps)
        warm_rate = _rate(folder / f'warm-up-{team}' / 'progress.csv', br_steps // 8)
        costs[f'{team}_best_response'] = dict(
            steps=br_steps, decisions_per_second=rate, job_seconds=warm[index]['seconds'],
            wall_seconds=warm[index]['wall'], startup_seconds=max(0.0, warm[index]['seconds'] - br_steps / rate),
            worker_start_seconds=max(0.0, cold[index]['seconds'] - (br_steps // 8) / warm_rate
                                     - max(0.0, warm[index]['seconds'] - br_steps / rate)),
            alone_decisions_per_second=alone(team, f'alone-{team}', opponents[team], [0.5, 0.5]))
    target_policy = (ROOT / 'mate' / 'pretrained' / 'mappo-target-2v4-0.pt').read_bytes()
    eight = [runner.share(target_policy) for _ in range(8)]
    costs['camera_best_response']['alone_eight_policies_decisions_per_second'] = alone(
        'camera', 'alone-eight', eight, [1 / 8] * 8)
    cameras, targets = [runner.share(results['camera']['policy'])], [runner.share(results['target']['policy'])]
    entries = []
    runner.run([(jobs.payoff_entries, dict(env=env, cameras=cameras, targets=targets, pairs=[(0, 0)], episodes=100,
                                           max_episode_steps=1000))], lambda i, r: entries.extend(r))
    timing, entry = runner.timings[0], entries[0]
    work = 100 * entry['length'] / entry['env_steps_per_second']
    costs['payoff_entry'] = dict(episodes=100, max_steps=1000, mean_length=entry['length'],
                                 env_steps_per_second=entry['env_steps_per_second'], job_seconds=timing['seconds'],
                                 wall_seconds=timing['wall'], startup_seconds=max(0.0, timing['seconds'] - work))
    for key, value in costs.items():
        say(f'{key}: ' + ', '.join(f'{k} {v:,.2f}' if isinstance(v, float) else f'{k} {v}' for k, v in value.items()))
    return costs


def measure_trainers(steps: int, rounds: int = 2) -> dict:
    """Part 4: the fig4a rates missing from docs/performance.md, scaled by HRL-MAPPO measured beside them (the
    settings one after the other, `rounds` times; the best rate of each)."""
    sys.path.insert(0, str(ROOT / 'benchmarks'))
    import trainers

    trainers.SETTINGS.update({'mappo-camera': ['mappo', '--team', 'camera'],
                              'ippo-camera': ['ippo', '--team', 'camera'],
                              'ippo-hrl-camera': ['ippo', '--team', 'camera', '--hrl']})
    names = ('mappo-hrl-camera', 'mappo-camera', 'ippo-camera', 'ippo-hrl-camera')
    rounds_measured = [{name: trainers.measure(name, steps)['decisions_per_second'] for name in names}
                       for _ in range(rounds)]
    measured = {name: max(r[name] for r in rounds_measured) for name in names}
    scale = DOCUMENTED['HRL-MAPPO'] / measured['mappo-hrl-camera']
    rates = {'MAPPO': measured['mappo-camera'] * scale, 'IPPO': measured['ippo-camera'] * scale,
             'HRL-IPPO': measured['ippo-hrl-camera'] * scale}
    say('trainers measured here (decisions/s, best of each): ' + ', '.join(f'{k} {v:,.0f}' for k, v in measured.items())
        + '; scaled to the documented HRL-MAPPO rate: ' + ', '.join(f'{k} {v:,.0f}' for k, v in rates.items()))
    return dict(rounds=rounds_measured, measured_here=measured, scale=scale, rates=rates, steps=steps)


def small_psro(runner, folder: Path, settings: dict) -> dict:
    """Part 5: one small PSRO run on `runner`; its wall time and per stage."""
    from mate.learn.population.psro import PSROSettings, run_psro

    from mate.learn.population.psro import JOB_LOG

    lines = []
    start = time.perf_counter()
    run_psro(PSROSettings(**settings), folder, runner, say=lambda line: lines.append((time.perf_counter() - start,
                                                                                      line)))
    return dict(wall_seconds=time.perf_counter() - start, lines=[[round(t, 2), line] for t, line in lines],
                jobs=[json.loads(line) for line in (folder / JOB_LOG).read_text().splitlines()])


# ============================================================================ the model

def psro_wall(costs: dict, cpus: int, iterations: int, br_steps: int, episodes: int, episode_steps: int,
              br_slots: int | None = None, camera_rate: float | None = None, target_rate: float | None = None,
              rate: str = 'alone_decisions_per_second') -> dict:
    """Projected wall seconds of one `mate psro` run with one CPU per job on `cpus` CPUs (on GPU nodes: `br_slots`
    best responses at a time, one per GPU, at `camera_rate` / `target_rate` decisions/s, and the entries
    `1 / ENTRY_GPU_SHARE` per GPU).

    Iteration i >= 1: the two best responses side by side (one after the other on one slot), then 2i + 1 payoff
    entries and at most 2i fresh-seed entries (the supports of both meta-strategies as large as the previous pools,
    an upper bound) in waves of `slots` jobs; iteration 0 plays one entry. A job costs its start-up + its work at
    the measured rate + the measured task overhead; each worker process starts once (imports). `rate`: which
    measured best-response rate, 'alone_decisions_per_second' (one job on the machine: the nearest to a dedicated
    core) or 'decisions_per_second' (two side by side, as they ran in the checked 2-node run)."""
    from mate.learn.population.psro import ENTRY_GPU_SHARE

    br_slots = br_slots or cpus
    slots = cpus if br_slots == cpus else min(cpus, round(br_slots / ENTRY_GPU_SHARE))
    overhead = costs['overhead']['noop_overhead_ms'] / 1000
    cam, tgt = costs['camera_best_response'], costs['target_best_response']
    entry = costs['payoff_entry']
    t_cam = cam['startup_seconds'] + br_steps / (camera_rate or cam[rate]) + overhead
    t_tgt = tgt['startup_seconds'] + br_steps / (target_rate or tgt[rate]) + overhead
    t_entry = entry['startup_seconds'] + episodes * episode_steps / entry['env_steps_per_second'] + overhead
    start = max(cam['worker_start_seconds'], tgt['worker_start_seconds'])
    best, entries = start, t_entry
    for i in range(1, iterations + 1):
        best += t_cam + t_tgt if br_slots == 1 else max(t_cam, t_tgt)
        entries += (math.ceil((2 * i + 1) / slots) + math.ceil(2 * i / slots)) * t_entry
    return dict(seconds=best + entries, best_responses=best, entries=entries, job_seconds=dict(
        camera_best_response=t_cam, target_best_response=t_tgt, payoff_entry=t_entry))


def makespan(durations: list[float], slots: int) -> float:
    """Wall time of independent jobs on `slots` workers, the longest first to the least loaded (LPT)."""
    loads = [0.0] * max(1, slots)
    for duration in sorted(durations, reverse=True):
        loads[loads.index(min(loads))] += duration
    return max(loads)


def fig4a_wall(rates: dict, cpus: int, overhead: float) -> float:
    """Projected wall seconds of fig4a-cameras, 10 seeds: 70 runs of 10 M decisions at the 2-core rates with 2 CPUs
    per run (one CPU: one run at a time at half the rate, an upper bound), evaluations and references left out."""
    per_run = FIG4A['cpus_per_job']
    durations = [FIG4A['steps'] / rates[name] + overhead for name in FIG4A['settings'] for _ in range(FIG4A['seeds'])]
    if cpus < per_run:
        return makespan([d * per_run for d in durations], 1)
    return makespan(durations, cpus // per_run)


def project(results: dict) -> dict:
    """Part 6: the tables of docs/cluster.md from the measured costs."""
    costs = results['costs']
    rates = dict(DOCUMENTED, **results.get('trainers', {}).get('rates', {}))
    overhead = costs['overhead']['noop_overhead_ms'] / 1000
    rows = []
    for cpus in CLUSTERS:
        psro = psro_wall(costs, cpus, **PAPER_PSRO)
        fig4a = fig4a_wall(rates, cpus, overhead) if set(FIG4A['settings']) <= set(rates) else None
        rows.append(dict(cpus=cpus, psro_hours=psro['seconds'] / 3600, psro_best_response_hours=psro['best_responses']
                         / 3600, psro_entries_hours=psro['entries'] / 3600,
                         fig4a_hours=None if fig4a is None else fig4a / 3600))
    gpu_rows = []
    for nodes in (1, 2, 6):
        psro = psro_wall(costs, nodes * GPU_NODE['cpus'], **PAPER_PSRO, br_slots=nodes,
                         camera_rate=GPU_NODE['camera_decisions_per_second'],
                         target_rate=GPU_NODE['target_decisions_per_second'])
        gpu_rows.append(dict(nodes=nodes, cpus=nodes * GPU_NODE['cpus'], gpus=nodes, psro_hours=psro['seconds'] / 3600,
                             psro_best_response_hours=psro['best_responses'] / 3600,
                             psro_entries_hours=psro['entries'] / 3600))
    checks = [check(run, costs) for run in results.get('check', [])]
    return dict(cpu_rows=rows, gpu_rows=gpu_rows, checks=checks, fig4a_rates=rates)


def _kind(job: str) -> str:
    return 'camera' if job.startswith('the camera') else 'target' if job.startswith('the target') else 'entry'


def check(run: dict, costs: dict) -> dict:
    """Part 5: a small run's measured wall time against (a) its own jobs' times in waves of `cpus` (what is left
    is the overhead: scheduling, transfer, imports, the driver's own work) and (b) the model, with the run's real
    numbers of jobs and with its bound on the fresh-seed entries (`psro_wall`)."""
    settings, cpus = run['settings'], run['cpus']
    rate = 'decisions_per_second' if cpus >= 2 else 'alone_decisions_per_second'
    model = psro_wall(costs, cpus, settings['iterations'], settings['br_steps'], settings['eval_episodes'],
                      settings['eval_steps'], rate=rate)
    stages: dict = {}
    for job in run['jobs']:
        kind = _kind(job['job'])
        stages.setdefault((job['iteration'], 'training' if kind != 'entry' else job['job'][:5]), []).append(job)
    own = sum(makespan([job['seconds'] for job in stage], cpus) for stage in stages.values())
    predicted_job = {'camera': model['job_seconds']['camera_best_response'],
                     'target': model['job_seconds']['target_best_response'],
                     'entry': model['job_seconds']['payoff_entry']}
    counted = sum(makespan([predicted_job[_kind(job['job'])] for job in stage], cpus) for stage in stages.values())
    start = max(costs['camera_best_response']['worker_start_seconds'],
                costs['target_best_response']['worker_start_seconds'])
    measured_job = {kind: statistics.mean(job['seconds'] for job in run['jobs'] if _kind(job['job']) == kind)
                    for kind in ('camera', 'target', 'entry')}
    return dict(cpus=cpus, measured_seconds=run['wall_seconds'], jobs=len(run['jobs']),
                own_job_seconds_in_waves=own, overhead_seconds=run['wall_seconds'] - own,
                overhead_per_job_seconds=(run['wall_seconds'] - own) / len(run['jobs']),
                job_seconds_measured=measured_job, job_seconds_model=predicted_job,
                model_with_real_counts_seconds=counted + start, model_seconds=model['seconds'],
                ratio=run['wall_seconds'] / (counted + start))


def print_projection(projection: dict) -> None:
    say('| CPUs | PSRO, paper scale (h) | of which best responses | entries | fig4a-cameras, 10 seeds (h) |')
    for row in projection['cpu_rows']:
        fig4a = '-' if row['fig4a_hours'] is None else f'{row["fig4a_hours"]:,.1f}'
        say(f'| {row["cpus"]} | {row["psro_hours"]:,.1f} | {row["psro_best_response_hours"]:,.1f} | '
            f'{row["psro_entries_hours"]:,.1f} | {fig4a} |')
    for row in projection['gpu_rows']:
        say(f'GPU nodes {row["nodes"]} ({row["cpus"]} CPUs): PSRO {row["psro_hours"]:,.1f} h (best responses '
            f'{row["psro_best_response_hours"]:,.1f}, entries {row["psro_entries_hours"]:,.1f})')
    for c in projection['checks']:
        say(f'check on {c["cpus"]} CPU(s): measured {c["measured_seconds"]:.1f} s; its {c["jobs"]} jobs\' own times '
            f'in waves {c["own_job_seconds_in_waves"]:.1f} s (overhead {c["overhead_per_job_seconds"]:.2f} s a job); '
            f'model {c["model_with_real_counts_seconds"]:.1f} s with its job counts (ratio {c["ratio"]:.2f}), '
            f'{c["model_seconds"]:.1f} s with the bound on fresh entries; job seconds measured '
            + ', '.join(f'{k} {v:.1f}' for k, v in c['job_seconds_measured'].items()) + ', model '
            + ', '.join(f'{k} {v:.1f}' for k, v in c['job_seconds_model'].items()))


# ============================================================================ main

def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--nodes', type=int, default=2, help='worker nodes of one CPU each (default 2)')
    parser.add_argument('--br-steps', type=int, default=6400, help='decisions of the measured best responses')
    parser.add_argument('--trainer-steps', type=int, default=9_600, help='decisions of each fig4a trainer measured')
    parser.add_argument('--skip-trainers', action='store_true', help='leave part 4 out')
    parser.add_argument('--trainers-from', type=Path, default=None, help='take part 4 from an earlier JSON file')
    parser.add_argument('--json', type=Path, default=None)
    parser.add_argument('--project', type=Path, default=None, help='print the projections of a JSON file and stop')
    args = parser.parse_args(argv)
    if args.project:
        print_projection(project(json.loads(args.project.read_text())))
        return 0
    import ray

    from mate.tools.bench import machine_facts
    from mate.tools.runners import RayRunner

    os.environ.setdefault('MATE_COMPILE_NOTICE', '0')
    results = dict(machine=machine_facts(), load=list(os.getloadavg()), nodes=args.nodes,
                   date=time.strftime('%Y-%m-%d'))
    folder = Path(tempfile.mkdtemp(prefix='mate-cluster-'))
    try:
        if args.trainers_from:
            results['trainers'] = dict(json.loads(args.trainers_from.read_text())['trainers'],
                                       source=str(args.trainers_from))
        elif not args.skip_trainers:
            results['trainers'] = measure_trainers(args.trainer_steps)
        results['check'] = []
        settings = dict(solver='nash', iterations=2, br_steps=12_800, num_envs=16, eval_episodes=100, eval_steps=1000)
        for nodes, part in ((args.nodes, 'costs'), (args.nodes, 'check'), (1, 'check')):
            cluster = start_cluster(nodes)        # a fresh cluster each time: its workers start cold, as a run's do
            try:
                runner = RayRunner()
                if part == 'costs':
                    results['costs'] = dict(overhead=measure_overhead(runner),
                                            **measure_jobs(runner, folder / 'jobs', args.br_steps))
                    continue
                run = small_psro(runner, folder / f'psro-{nodes}', settings)
                say(f'small PSRO on {nodes} node(s): {run["wall_seconds"]:.1f} s')
                results['check'].append(dict(cpus=nodes, settings=settings, **run))
            finally:
                ray.shutdown()
                cluster.shutdown()
        results['load_after'] = list(os.getloadavg())
        results['projection'] = project(results)
        print_projection(results['projection'])
        if args.json:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(results, indent=1))
            say(f'wrote {args.json}')
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
