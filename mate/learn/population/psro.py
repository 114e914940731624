"""`mate psro`: population training with a meta-solver (PSRO-Nash, fictitious self-play, self-play).

    pools            cameras [random], targets [random] (or other starting members)
    iteration 0      payoff of the 1 x 1 game; meta-strategies sigma_C, sigma_T = solver(payoff)
    iteration i >= 1
      best responses   camera BR (HRL-MAPPO, mixed reward) against the target mixture sigma_T and target BR
                       (MAPPO) against the camera mixture sigma_C, each warm-started from its side's newest
                       policy (from scratch at i = 1); two independent jobs (`jobs.best_response`)
      payoff entries   only the missing (camera k, target l) pairs, E episodes each, one job per entry
                       (`jobs.payoff_entries`)
      exploitability   of the previous sigma over the extended pools (paper Eq. 2; both terms and the mean), and
                       with the best responses re-played on fresh seeds (one job per pairing)
      meta-game        sigma_C, sigma_T = solver(payoff) on the camera team's utility U_C = -U_T

Everything lives in the run directory (`state.json`, rewritten atomically after every finished job and stage:
settings, pools, the `MATRICES`, the fresh-seed entries of the iteration in progress, per iteration both
meta-strategies, the camera value and the exploitability, and the best responses' training summaries; `players/`
with each side's policies and their training runs; `jobs.jsonl`, the log of jobs), so a killed run started again
with the same command resumes at the stage it was in without redoing a finished job (an interrupted best-response
training resumes from its own last checkpoint). Jobs are seeded by what they are (a best response by its iteration
and side, an entry by its episodes' env seeds), so the state does not depend on where they ran, in which order,
or how often a lost one was run again. The paper's §5.3; docs/population.md.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ...cli.progress import logged_steps
from ...tools.runners import STOP, LocalRunner, RayRunner
from ...evaluation.protocol import EVALUATION_SEEDS, FRESH_SEEDS, PAYOFF_SEEDS, SEED_BLOCK, SEED_RANGES
from .jobs import TARGET_CREDITS
from .solvers import SOLVERS, exploitability, meta_strategies

__all__ = ['JOB_LOG', 'LocalRunner', 'PROGRESS_EVERY', 'PSROError', 'PSROSettings', 'RayRunner', 'STATE_FORMAT',
           'TrainingWatch', 'env_of', 'load_state', 'member_payload', 'run_psro']

STATE_FORMAT = 'mate.psro/1'
SIDES = ('camera', 'target')
MATRICES = ('payoff', 'payoff_sem', 'coverage', 'real_coverage')
"""The (cameras x targets) matrices of a state: mean normalised target return U_T, its standard error over
the episodes, mean coverage rate, mean real coverage rate."""

PROGRESS_EVERY = 60.0
"""Seconds between the progress lines a population run says while its best responses train."""


class PSROError(ValueError):
    """A run directory that does not fit the command (other settings, unreadable state)."""


@dataclasses.dataclass
class PSROSettings:
    """What a population run is; stored in `state.json`, and a resumed run must ask for the same."""

    solver: str = 'nash'                 # 'nash' (PSRO-Nash), 'uniform' (FSP), 'last' (SP)
    config: str = 'MATE-2v4-0'           # preset name or YAML/JSON path
    iterations: int = 10                 # PSRO iterations after iteration 0 (paper: 40)
    br_steps: int = 100_000              # decision steps per best response (paper: 5 M)
    eval_episodes: int = 100             # episodes per payoff entry (paper: 100)
    eval_steps: int | None = None        # raw-step cap of an evaluation episode (None: the preset's, 10,000)
    seed: int = 0
    num_envs: int = 16                   # envs per best-response training
    initial_cameras: str = 'random'      # the pools' first members (batched agent names)
    initial_targets: str = 'random'
    target_credit: str = 'team'          # the target best responses' reward: 'team' (the spec's) or 'own' (each
                                         # target's own part of it, as the benchmark's target learners)

    def validate(self) -> PSROSettings:
        if self.solver not in SOLVERS:
            raise PSROError(f'unknown solver {self.solver!r}; choose one of {", ".join(SOLVERS)}')
        if self.target_credit not in TARGET_CREDITS:
            raise PSROError(f'target_credit must be one of {", ".join(TARGET_CREDITS)}, got {self.target_credit!r}')
        for name, minimum in (('iterations', 0), ('br_steps', 1), ('eval_episodes', 1), ('num_envs', 1), ('seed', 0)):
            value = getattr(self, name)
            if not isinstance(value, int) or value < minimum:
                raise PSROError(f'{name} must be an integer >= {minimum}, got {value!r}')
        if self.eval_steps is not None and (not isinstance(self.eval_steps, int) or self.eval_steps < 1):
            raise PSROError('eval_steps must be a positive integer (or None: the preset\'s limit), got '
                            f'{self.eval_steps!r}')
        rows = 2 * self.iterations + 1 + self.num_envs       # the seeds past seed x 1,000 the best responses use
        if rows > SEED_BLOCK:
            raise PSROError(f'{self.iterations} iterations with {self.num_envs} envs train on {rows:,} seeds past '
                            f'seed x {SEED_BLOCK:,}, into the next seed\'s block; 2 x iterations + 1 + num_envs must '
                            f'be at most {SEED_BLOCK:,}')
        last_game = self.best_response_seed(self.iterations, 'target') + self.num_envs - 1
        if last_game >= EVALUATION_SEEDS:
            raise PSROError(f'seed {self.seed} with {self.iterations} iterations and {self.num_envs} envs trains on '
                            f'env seeds up to {last_game:,}, past the training seeds (below {EVALUATION_SEEDS:,}); '
                            f'use seed <= {(EVALUATION_SEEDS - self.num_envs - 2 * self.iterations - 1) // 1000}')
        for name, first in (('payoff', PAYOFF_SEEDS), ('fresh', FRESH_SEEDS)):
            if first + self.eval_episodes > SEED_RANGES[name][1]:
                raise PSROError(f'eval_episodes must be at most {SEED_RANGES[name][1] - first:,} (the {name} seeds)')
        return self

    def best_response_seed(self, iteration: int, side: str) -> int:
        """The seed of the `side` best response of `iteration` (its training games: this seed + row)."""
        return self.seed * 1_000 + 2 * iteration + (side == 'target')

    def same_experiment(self, other: PSROSettings) -> list[str]:
        """Names of the settings that differ from `other`'s, except `iterations` (a run may be extended)."""
        mine, theirs = dataclasses.asdict(self), dataclasses.asdict(other)
        return [k for k in mine if k != 'iterations' and mine[k] != theirs[k]]


def env_of(config: str) -> dict:
    """{'env_id', 'config'} of a preset name (registered ID) or a config file."""
    from ...envs.registration import registered_ids

    name = str(config).removesuffix('-v0')
    if f'{name}-v0' in registered_ids():
        return dict(env_id=f'{name}-v0', config=None)
    from ...config import read_config

    read_config(config)     # a bad name or file fails now (ConfigError lists the presets)
    return dict(env_id='MultiAgentTracking-v0', config=str(config))


# ============================================================================ the run directory

def load_state(out) -> dict | None:
    """The state of the run in `out`, or None if there is none; PSROError if unreadable."""
    path = Path(out) / 'state.json'
    if not path.exists():
        return None
    try:
        state = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise PSROError(f'{str(path)!r} is not a readable PSRO state: {exc}') from None
    if not isinstance(state, dict) or state.get('format') != STATE_FORMAT:
        raise PSROError(f'{str(path)!r} is not a PSRO state of format {STATE_FORMAT!r}')
    return state


def _save_state(out: Path, state: dict) -> None:
    path = out / 'state.json'
    tmp = path.with_name('state.json.tmp')
    tmp.write_text(json.dumps(state, indent=1, allow_nan=True))
    os.replace(tmp, path)


def _grow(matrix: list, rows: int, columns: int) -> list:
    """`matrix` (list of lists, None = missing) padded with None to rows x columns."""
    matrix = [list(row) + [None] * (columns - len(row)) for row in matrix]
    return matrix + [[None] * columns for _ in range(rows - len(matrix))]


def member_payload(member: str, out: Path):
    """What a job receives for a pool member: a policy file's bytes, or the agent name."""
    return (out / member).read_bytes() if member.endswith('.pt') else member


class TrainingWatch:
    """Says how far best responses have trained, every `every` seconds while open (a thread of the driver), when
    it changed: 'iteration 3: training camera 40,000, target 38,400 of 100,000 decision steps each (39 %)'. It reads
    each run directory's `progress.csv`, so it sees the jobs of this machine or of a cluster sharing the run
    directory; jobs whose directory it cannot see say nothing until they end."""

    def __init__(self, iteration: int, runs: dict[str, Path], steps: int, say: Callable[[str], None],
                 every: float | None = None) -> None:
        self.iteration, self.runs, self.steps, self.say = iteration, runs, int(steps), say
        self.every = PROGRESS_EVERY if every is None else float(every)
        self.last: dict[str, int | None] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name='psro-progress', daemon=True)

    def line(self) -> str | None:
        """The progress line of now, or None when no run logged a row since the last line."""
        now = {side: logged_steps(run_dir) for side, run_dir in self.runs.items()}
        if now == self.last or all(steps is None for steps in now.values()):
            return None
        self.last = now
        done = [min(steps or 0, self.steps) for steps in now.values()]
        parts = ', '.join(f'{side} {steps or 0:,}' for side, steps in now.items())
        return (f'iteration {self.iteration}: training {parts} of {self.steps:,} decision steps'
                f'{" each" if len(now) > 1 else ""} ({100 * sum(done) / (self.steps * len(done)):.0f} %)')

    def _loop(self) -> None:
        while not self._stop.wait(self.every):
            line = self.line()
            if line is not None:
                self.say(line)

    def __enter__(self) -> TrainingWatch:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


# ============================================================================ the loop

def run_psro(settings: PSROSettings, out, runner=None, say: Callable[[str], None] = print,
             device: str = 'auto') -> dict:
    """Run (or resume) the population run of `settings` in the directory `out`; returns the final state.

    `runner`: `LocalRunner` (default: in this process), `ThreadRunner` or `RayRunner` (`mate.tools.runners`).
    `say(line)` receives one line per stage. `device`: where the best responses train (`--device`). PSROError if `out`
    holds a run with other settings. KeyboardInterrupt when a signal stopped it (every finished stage is saved: run it
    again). `mate.tools.runners.JobFailed` naming the jobs that raised (the other jobs of the stage finish and are saved
    first; the same call resumes once the cause is fixed).

    The result depends on the settings only, not on the runner: each job is one best response or one payoff
    entry, seeded by what it is, so a process pool, a Ray cluster that loses nodes on the way, or a run resumed
    after a kill all end with the same state. `DIR/jobs.jsonl` logs every finished or failed job (one JSON object
    a line: `job` name, `iteration`, `status`, its own `seconds`, the `wall` seconds from submission to result,
    the `fetch` seconds of its shared arguments, the Ray `node`).
    """
    from . import jobs

    settings.validate()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = env_of(settings.config)
    state = load_state(out)
    if state is None:
        state = dict(format=STATE_FORMAT, settings=dataclasses.asdict(settings),
                     pools=dict(camera=[settings.initial_cameras], target=[settings.initial_targets]),
                     payoff=[[None]], payoff_sem=[[None]], coverage=[[None]], real_coverage=[[None]], iterations=[],
                     best_responses=[], fresh_entries={})
        _save_state(out, state)
    else:
        stored = PSROSettings(**state['settings'])
        differ = stored.same_experiment(settings)
        if differ:
            details = '; '.join(f'{k} {getattr(stored, k)!r} there, {getattr(settings, k)!r} here' for k in differ)
            raise PSROError(f'{str(out)!r} holds a run with other settings ({details}); use another directory, '
                            'or the same settings to resume it')
        state['settings']['iterations'] = settings.iterations
        state.setdefault('fresh_entries', {})
        done = len(state['iterations'])
        if done:
            say(f'resuming {out}: {done - 1} of {settings.iterations} iterations done')
    loop = _Loop(state, settings, env, out, runner or LocalRunner(1), jobs, say, device)
    try:
        while len(state['iterations']) <= settings.iterations:
            loop.iteration()
    finally:
        loop.runner.close()
    return state


JOB_LOG = 'jobs.jsonl'
"""The run directory's log of jobs, one JSON object a line (appended to by every session)."""
ENTRY_GPU_SHARE = 0.125
"""The share of a GPU a payoff entry asks a Ray cluster for when the jobs run on GPUs (`--device cuda`): its forward
passes are small batches, so eight entries share a GPU while a best response has one to itself."""


@dataclasses.dataclass
class _Loop:
    """One session of a population run: the state, and how its jobs are sent and logged."""

    state: dict
    settings: PSROSettings
    env: dict
    out: Path
    runner: object
    jobs: object
    say: Callable[[str], None]
    device: str
    shared: dict = dataclasses.field(default_factory=dict)

    def payload(self, member: str):
        """The job argument of a pool member: its payload, shared through the runner once per session (Ray: one
        copy in the object store, fetched once per node)."""
        if member not in self.shared:
            value = member_payload(member, self.out)
            self.shared[member] = self.runner.share(value) if isinstance(value, bytes) else value
        return self.shared[member]

    def members(self, side: str, wanted) -> list:
        """The `side` pool as job arguments: the payloads of the members in `wanted`, None for the others (a job
        builds only the members it plays)."""
        wanted = set(int(j) for j in wanted)
        return [self.payload(member) if j in wanted else None for j, member in enumerate(self.state['pools'][side])]

    def run(self, job_list: list, names: list[str], done: Callable[[int, object], None], iteration: int,
            gpu_share: float = 1.0) -> None:
        """Run `job_list` on the runner, logging each job in `DIR/jobs.jsonl` once it is saved (`done`, which may
        return another status than 'done') or failed."""

        def finished(index, result):
            status = done(index, result)
            self.log(names[index], iteration, status or 'done', index)
            return STOP if status == 'interrupted' else None    # a signal stopped it: start no further job

        def failed(name, reason):
            self.log(name, iteration, 'failed', None, reason=reason)
            self.say(f'{name} failed: {reason}; the run stops once the other jobs of this stage have finished')

        self.runner.run(job_list, finished, names=names, failed=failed, gpu_share=gpu_share)

    def log(self, name: str, iteration: int, status: str, index: int | None, **extra) -> None:
        timings = getattr(self.runner, 'timings', None)
        timing = timings[index] if index is not None and timings and index < len(timings) else None
        record = dict(job=name, iteration=iteration, status=status, **(timing or {}), **extra,
                      at=time.strftime('%Y-%m-%dT%H:%M:%S'))
        with open(self.out / JOB_LOG, 'a') as f:
            f.write(json.dumps(record) + '\n')

    # ------------------------------------------------------------------ one iteration
    def iteration(self) -> None:
        state, settings, out, say = self.state, self.settings, self.out, self.say
        i = len(state['iterations'])
        started = time.perf_counter()
        record = dict(iteration=i)
        if i >= 1:
            self.best_responses(i)
        self.payoff_entries(i)

        # ---- 3. exploitability of the previous meta-strategies; 4. the new meta-game
        target_utility = np.array(state['payoff'], dtype=np.float64)
        camera_utility = -target_utility
        if i >= 1:
            previous = state['iterations'][i - 1]
            gains = exploitability(camera_utility, previous['camera_strategy'], previous['target_strategy'])
            record['exploitability'] = dict(camera=gains['row'], target=gains['column'], mean=gains['mean'])
            record['exploitability_fresh'] = self.fresh_exploitability(i, previous)
        else:
            record['exploitability'] = None
        camera_strategy, target_strategy = meta_strategies(settings.solver, camera_utility)
        record.update(camera_strategy=[float(x) for x in camera_strategy],
                      target_strategy=[float(x) for x in target_strategy],
                      camera_value=float(camera_strategy @ camera_utility @ target_strategy),
                      seconds=time.perf_counter() - started)
        state['iterations'].append(record)
        state['fresh_entries'].pop(str(i), None)
        _save_state(out, state)
        gains, fresh = record['exploitability'], record.get('exploitability_fresh')
        say(f'iteration {i}: exploitability '
            + ('- (no best responses yet)' if gains is None else
               f'{gains["mean"]:.4f} (cameras {gains["camera"]:.4f}, targets {gains["target"]:.4f}; on fresh seeds '
               f'{fresh["mean"]:.4f})')
            + f'; {settings.solver} meta-strategies: cameras {_fmt(camera_strategy)}, targets {_fmt(target_strategy)}')
        untrained = [response['team'] for response in state['best_responses']
                     if response['iteration'] == i and math.isnan(response.get('episode_return', math.nan))]
        if untrained:
            warning = (f'the {" and ".join(untrained)} best response{"s" * (len(untrained) > 1)} of iteration {i} '
                       f'finished no training episode in {settings.br_steps:,} decision steps: '
                       'they are barely trained, '
                       'and this exploitability means nothing at this budget (raise --br-steps: an episode is 500 '
                       'decisions per env)')
            say(f'warning: {warning}')
            self.log('exploitability', i, 'warning', None, reason=warning)     # in the run's jobs.jsonl too

    def best_responses(self, i: int) -> None:
        """1. The best responses of iteration i (member i of each pool), the missing ones."""
        state, settings, out, say = self.state, self.settings, self.out, self.say
        pools = state['pools']
        previous = state['iterations'][i - 1]
        strategies = dict(camera=previous['camera_strategy'], target=previous['target_strategy'])
        todo = [side for side in SIDES if len(pools[side]) <= i]
        if not todo:
            return
        job_list = []
        for side in todo:
            other = 'target' if side == 'camera' else 'camera'
            weights = strategies[other]
            init = self.payload(pools[side][i - 1]) if i >= 2 and pools[side][i - 1].endswith('.pt') else None
            opponents = self.members(other, [j for j, w in enumerate(weights) if w > 0])[:len(weights)]
            job_list.append((self.jobs.best_response, dict(
                team=side, env=self.env, opponents=opponents, weights=weights, steps=settings.br_steps,
                seed=settings.best_response_seed(i, side), run_dir=str((out / 'players' / f'{side}-{i}').resolve()),
                init=init, num_envs=settings.num_envs, device=self.device,
                credit=settings.target_credit if side == 'target' else 'team')))
        say(f'iteration {i}/{settings.iterations}: training the {" and ".join(todo)} best response'
            f'{"s" if len(todo) > 1 else ""} ({settings.br_steps:,} decision steps each)')
        stopped = []

        def trained(index, result):
            side = todo[index]
            if result.pop('interrupted', False):   # a signal stopped it: its run directory holds its checkpoint
                stopped.append(side)
                return 'interrupted'
            path = Path('players') / f'{side}-{i}.pt'
            (out / path).write_bytes(result.pop('policy'))
            pools[side].append(str(path))
            state['best_responses'].append(dict(iteration=i, team=side, **result))
            _save_state(out, state)
            scores = ('no training episode finished' if np.isnan(result['episode_return']) else
                      f'training return {result["episode_return"]:.3f}, coverage {result["episode_coverage"]:.3f}')
            say(f'iteration {i}: {side} best response done in {result["seconds"]:.0f} s ({result["chosen"]} '
                f'checkpoint; {scores})')

        runs = {side: out / 'players' / f'{side}-{i}' for side in todo}
        with TrainingWatch(i, runs, settings.br_steps, say):
            self.run(job_list, [f'the {side} best response of iteration {i}' for side in todo], trained, i)
        if stopped:
            raise KeyboardInterrupt(f'the {" and ".join(stopped)} best response of iteration {i} stopped by a signal')

    def payoff_entries(self, i: int) -> None:
        """2. The missing payoff entries, one job each (an entry is the same whatever else is played)."""
        state, settings, say = self.state, self.settings, self.say
        pools = state['pools']
        m, n = len(pools['camera']), len(pools['target'])
        for key in MATRICES:
            state[key] = _grow(state.get(key, []), m, n)
        missing = [(k, l) for k in range(m) for l in range(n) if state['payoff'][k][l] is None]
        if not missing:
            return
        say(f'iteration {i}: evaluating {len(missing)} payoff entr{"y" if len(missing) == 1 else "ies"} '
            f'({settings.eval_episodes} episodes each)')
        evaluated = time.perf_counter()

        def entered(_, entries):
            for entry in entries:
                k, l = entry['k'], entry['l']
                for key in MATRICES:
                    state[key][k][l] = entry[key]
            _save_state(self.out, state)

        self.run([self.entry_job(k, l, PAYOFF_SEEDS) for k, l in missing],
                 [f'payoff entry (camera {k}, target {l}) of iteration {i}' for k, l in missing], entered, i,
                 gpu_share=ENTRY_GPU_SHARE)
        say(f'iteration {i}: payoff entries done in {time.perf_counter() - evaluated:.0f} s')

    def entry_job(self, k: int, l: int, seed: int) -> tuple:
        """The job playing camera member k against target member l for `eval_episodes` episodes from env seed
        `seed` (the policies' forward passes on the CPU unless `--device` names one)."""
        return (self.jobs.payoff_entries, dict(
            env=self.env, cameras=self.members('camera', [k]), targets=self.members('target', [l]), pairs=[(k, l)],
            episodes=self.settings.eval_episodes, seed=seed, max_episode_steps=self.settings.eval_steps,
            device='cpu' if self.device == 'auto' else self.device))

    def fresh_exploitability(self, i: int, previous: dict) -> dict:
        """The exploitability with each side's best response re-played on fresh seeds (FRESH_SEEDS, ...).

        The best response of Eq. 2 is the pool member with the highest entry against the other side's
        meta-strategy; picking the maximum of noisy entries biases the estimate upwards. Here that member
        (`camera_response`, `target_response`) plays again against every member of the other meta-strategy's
        support, on `eval_episodes` episodes of seeds no best response trained on (one job per pairing, each saved
        in the state as it finishes), and its gain is measured from those entries (the meta-game's value stays that
        of the payoff matrix)."""
        state = self.state
        camera_utility = -np.array(state['payoff'], dtype=np.float64)
        p, q = np.asarray(previous['camera_strategy']), np.asarray(previous['target_strategy'])
        m, n = p.size, q.size
        value = float(p @ camera_utility[:m, :n] @ q)
        camera_response = int(np.argmax(camera_utility[:, :n] @ q))
        target_response = int(np.argmax(-(p @ camera_utility[:m, :])))
        pairs = [(camera_response, l) for l in np.flatnonzero(q > 0)] + \
                [(k, target_response) for k in np.flatnonzero(p > 0)]
        pairs = list(dict.fromkeys((int(k), int(l)) for k, l in pairs))
        saved = state['fresh_entries'].setdefault(str(i), {})
        todo = [(k, l) for k, l in pairs if f'{k},{l}' not in saved]

        def played(_, entries):
            for entry in entries:
                saved[f'{entry["k"]},{entry["l"]}'] = entry['payoff']
            _save_state(self.out, state)

        if todo:
            self.run([self.entry_job(k, l, FRESH_SEEDS) for k, l in todo],
                     [f'fresh-seed entry (camera {k}, target {l}) of iteration {i}' for k, l in todo], played, i,
                     gpu_share=ENTRY_GPU_SHARE)
        fresh = {(k, l): saved[f'{k},{l}'] for k, l in pairs}
        camera_gain = float(sum(q[l] * -fresh[(camera_response, l)] for l in np.flatnonzero(q > 0))) - value
        target_gain = float(sum(p[k] * fresh[(k, target_response)] for k in np.flatnonzero(p > 0))) + value
        return dict(camera=camera_gain, target=target_gain, mean=0.5 * (camera_gain + target_gain),
                    camera_response=camera_response, target_response=target_response, seeds=FRESH_SEEDS)


def _fmt(strategy) -> str:
    return '[' + ' '.join(f'{p:.2f}' for p in strategy) + ']'

