"""`mate psro`: population training with a meta-solver (PSRO-Nash, fictitious self-play, self-play).

    pools            cameras [random], targets [random] (or other starting members)
    iteration 0      payoff of the 1 x 1 game; meta-strategies sigma_C, sigma_T = solver(payoff)
    iteration i >= 1
      best responses   camera BR (HRL-MAPPO, mixed reward) against the target mixture sigma_T and target BR
                       (MAPPO) against the camera mixture sigma_C, each warm-started from its side's newest
                       policy (from scratch at i = 1); two independent jobs (`jobs.best_response`)
      payoff entries   only the missing (camera k, target l) pairs, E episodes each (`jobs.payoff_entries`)
      exploitability   of the previous sigma over the extended pools (paper Eq. 2; both terms and the mean)
      meta-game        sigma_C, sigma_T = solver(payoff) on the camera team's utility U_C = -U_T

Everything lives in the run directory (`state.json`, rewritten atomically after every stage: settings,
pools, the `MATRICES`, per iteration both meta-strategies, the camera value and the exploitability, and
the best responses' training summaries; `players/`
with each side's policies and their training runs), so a killed run started again with the same
command resumes at the stage it was in (an interrupted best-response training resumes from its own
last checkpoint). Spec: training.md §5.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ...runners import LocalRunner, RayRunner
from ..evaluation import EVALUATION_SEEDS
from .solvers import SOLVERS, exploitability, meta_strategies

__all__ = ['LocalRunner', 'PSROError', 'PSROSettings', 'RayRunner', 'STATE_FORMAT', 'env_of', 'load_state', 'member_payload',
           'run_psro']

STATE_FORMAT = 'mate.psro/1'
SIDES = ('camera', 'target')
FRESH_SEEDS = EVALUATION_SEEDS
"""First env seed of the fresh-seed exploitability (`exploitability_fresh`): the held-out evaluation seeds of
`mate.learn.evaluation`, which no best response trains on (`PSROSettings.validate` keeps their games below)."""
MATRICES = ('payoff', 'payoff_sem', 'coverage', 'real_coverage')
"""The (cameras x targets) matrices of a state: mean normalised target return U_T, its standard error over
the episodes, mean coverage rate, mean real coverage rate."""


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

    def validate(self) -> PSROSettings:
        if self.solver not in SOLVERS:
            raise PSROError(f'unknown solver {self.solver!r}; choose one of {", ".join(SOLVERS)}')
        for name, minimum in (('iterations', 0), ('br_steps', 1), ('eval_episodes', 1), ('num_envs', 1), ('seed', 0)):
            value = getattr(self, name)
            if not isinstance(value, int) or value < minimum:
                raise PSROError(f'{name} must be an integer >= {minimum}, got {value!r}')
        if self.eval_steps is not None and (not isinstance(self.eval_steps, int) or self.eval_steps < 1):
            raise PSROError(f'eval_steps must be a positive integer (or None: the preset\'s limit), got {self.eval_steps!r}')
        last_game = self.best_response_seed(self.iterations, 'target') + self.num_envs - 1
        if last_game >= FRESH_SEEDS:
            raise PSROError(f'seed {self.seed} with {self.iterations} iterations and {self.num_envs} envs trains on env '
                            f'seeds up to {last_game:,}, into the held-out seeds from {FRESH_SEEDS:,}; use seed <= '
                            f'{(FRESH_SEEDS - self.num_envs - 2 * self.iterations - 1) // 1000}')
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
    from ...registration import registered_ids

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


# ============================================================================ the loop

def run_psro(settings: PSROSettings, out, runner=None, say: Callable[[str], None] = print,
             device: str = 'auto') -> dict:
    """Run (or resume) the population run of `settings` in the directory `out`; returns the final state.

    `runner`: `LocalRunner` (default: in this process) or `RayRunner`. `say(line)` receives one line per
    stage. `device`: where the best responses train (`--device`). PSROError if `out` holds a run with other
    settings. KeyboardInterrupt when a signal stopped it (every finished stage is saved: run it again).
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
                     best_responses=[])
        _save_state(out, state)
    else:
        stored = PSROSettings(**state['settings'])
        differ = stored.same_experiment(settings)
        if differ:
            details = '; '.join(f'{k} {getattr(stored, k)!r} there, {getattr(settings, k)!r} here' for k in differ)
            raise PSROError(f'{str(out)!r} holds a run with other settings ({details}); use another directory, '
                            'or the same settings to resume it')
        state['settings']['iterations'] = settings.iterations
        done = len(state['iterations'])
        if done:
            say(f'resuming {out}: {done - 1} of {settings.iterations} iterations done')
    runner = runner or LocalRunner(1)
    try:
        while len(state['iterations']) <= settings.iterations:
            _iteration(state, settings, env, out, runner, jobs, say, device)
    finally:
        runner.close()
    return state


def _iteration(state: dict, settings: PSROSettings, env: dict, out: Path, runner, jobs, say, device: str) -> None:
    i = len(state['iterations'])
    started = time.perf_counter()
    pools = state['pools']
    record = dict(iteration=i)

    # ---- 1. best responses (iteration i adds member i to each pool)
    if i >= 1:
        previous = state['iterations'][i - 1]
        strategies = dict(camera=previous['camera_strategy'], target=previous['target_strategy'])
        todo = [side for side in SIDES if len(pools[side]) <= i]
        job_list = []
        for side in todo:
            other = 'target' if side == 'camera' else 'camera'
            init = member_payload(pools[side][i - 1], out) if i >= 2 and pools[side][i - 1].endswith('.pt') else None
            job_list.append((jobs.best_response, dict(
                team=side, env=env, opponents=[member_payload(m, out) for m in pools[other][:len(strategies[other])]],
                weights=strategies[other], steps=settings.br_steps,
                seed=settings.best_response_seed(i, side),
                run_dir=str((out / 'players' / f'{side}-{i}').resolve()), init=init, num_envs=settings.num_envs,
                device=device)))
        if todo:
            say(f'iteration {i}/{settings.iterations}: training the {" and ".join(todo)} best response'
                f'{"s" if len(todo) > 1 else ""} ({settings.br_steps:,} decision steps each)')

        stopped = []

        def trained(index, result):
            side = todo[index]
            if result.pop('interrupted', False):   # a signal stopped it: its run directory holds its checkpoint
                stopped.append(side)
                return
            path = Path('players') / f'{side}-{i}.pt'
            (out / path).write_bytes(result.pop('policy'))
            pools[side].append(str(path))
            state['best_responses'].append(dict(iteration=i, team=side, **result))
            _save_state(out, state)
            scores = ('no training episode finished' if np.isnan(result['episode_return']) else
                      f'training return {result["episode_return"]:.3f}, coverage {result["episode_coverage"]:.3f}')
            say(f'iteration {i}: {side} best response done in {result["seconds"]:.0f} s ({result["chosen"]} '
                f'checkpoint; {scores})')

        runner.run(job_list, trained)
        if stopped:
            raise KeyboardInterrupt(f'the {" and ".join(stopped)} best response of iteration {i} stopped by a signal')

    # ---- 2. the missing payoff entries
    m, n = len(pools['camera']), len(pools['target'])
    for key in MATRICES:
        state[key] = _grow(state.get(key, []), m, n)
    missing = [(k, l) for k in range(m) for l in range(n) if state['payoff'][k][l] is None]
    if missing:
        say(f'iteration {i}: evaluating {len(missing)} payoff entr{"y" if len(missing) == 1 else "ies"} '
            f'({settings.eval_episodes} episodes each)')
        payoff_device = 'cpu' if device == 'auto' else device    # (auto: the CPU; small forward passes)
        chunks = [missing[c::runner.parallel] for c in range(min(runner.parallel, len(missing)))]
        cameras = [member_payload(member, out) for member in pools['camera']]
        targets = [member_payload(member, out) for member in pools['target']]
        evaluated = time.perf_counter()

        def evaluated_chunk(_, entries):
            for entry in entries:
                k, l = entry['k'], entry['l']
                for key in MATRICES:
                    state[key][k][l] = entry[key]
            _save_state(out, state)

        runner.run([(jobs.payoff_entries, dict(env=env, cameras=cameras, targets=targets, pairs=chunk,
                                               episodes=settings.eval_episodes, seed=0,
                                               max_episode_steps=settings.eval_steps, device=payoff_device))
                    for chunk in chunks], evaluated_chunk)
        say(f'iteration {i}: payoff entries done in {time.perf_counter() - evaluated:.0f} s')

    # ---- 3. exploitability of the previous meta-strategies; 4. the new meta-game
    target_utility = np.array(state['payoff'], dtype=np.float64)
    camera_utility = -target_utility
    if i >= 1:
        previous = state['iterations'][i - 1]
        gains = exploitability(camera_utility, previous['camera_strategy'], previous['target_strategy'])
        record['exploitability'] = dict(camera=gains['row'], target=gains['column'], mean=gains['mean'])
        record['exploitability_fresh'] = _fresh_exploitability(state, settings, env, out, runner, jobs, previous,
                                                               device)
    else:
        record['exploitability'] = None
    camera_strategy, target_strategy = meta_strategies(settings.solver, camera_utility)
    record.update(camera_strategy=[float(x) for x in camera_strategy], target_strategy=[float(x) for x in target_strategy],
                  camera_value=float(camera_strategy @ camera_utility @ target_strategy),
                  seconds=time.perf_counter() - started)
    state['iterations'].append(record)
    _save_state(out, state)
    gains, fresh = record['exploitability'], record.get('exploitability_fresh')
    say(f'iteration {i}: exploitability '
        + ('- (no best responses yet)' if gains is None else
           f'{gains["mean"]:.4f} (cameras {gains["camera"]:.4f}, targets {gains["target"]:.4f}; on fresh seeds '
           f'{fresh["mean"]:.4f})')
        + f'; {settings.solver} meta-strategies: cameras {_fmt(camera_strategy)}, targets {_fmt(target_strategy)}')


def _fresh_exploitability(state: dict, settings: PSROSettings, env: dict, out: Path, runner, jobs, previous: dict,
                          device: str) -> dict:
    """The exploitability with each side's best response re-played on fresh seeds (FRESH_SEEDS, ...).

    The best response of Eq. 2 is the pool member with the highest entry against the other side's meta-strategy;
    picking the maximum of noisy entries biases the estimate upwards. Here that member (`camera_response`,
    `target_response`) plays again against every member of the other meta-strategy's support, on `eval_episodes`
    episodes of seeds no best response trained on, and its gain is measured from those entries (the meta-game's
    value stays that of the payoff matrix)."""
    camera_utility = -np.array(state['payoff'], dtype=np.float64)
    p, q = np.asarray(previous['camera_strategy']), np.asarray(previous['target_strategy'])
    m, n = p.size, q.size
    value = float(p @ camera_utility[:m, :n] @ q)
    camera_response = int(np.argmax(camera_utility[:, :n] @ q))
    target_response = int(np.argmax(-(p @ camera_utility[:m, :])))
    pairs = [(camera_response, l) for l in np.flatnonzero(q > 0)] + \
            [(k, target_response) for k in np.flatnonzero(p > 0)]
    pairs = list(dict.fromkeys((int(k), int(l)) for k, l in pairs))
    fresh: dict[tuple[int, int], float] = {}

    def played(_, entries):
        for entry in entries:
            fresh[(entry['k'], entry['l'])] = entry['payoff']

    runner.run([(jobs.payoff_entries, dict(env=env, cameras=[member_payload(x, out) for x in state['pools']['camera']],
                                           targets=[member_payload(x, out) for x in state['pools']['target']],
                                           pairs=pairs, episodes=settings.eval_episodes, seed=FRESH_SEEDS,
                                           max_episode_steps=settings.eval_steps,
                                           device='cpu' if device == 'auto' else device))], played)
    camera_gain = float(sum(q[l] * -fresh[(camera_response, l)] for l in np.flatnonzero(q > 0))) - value
    target_gain = float(sum(p[k] * fresh[(k, target_response)] for k in np.flatnonzero(p > 0))) + value
    return dict(camera=camera_gain, target=target_gain, mean=0.5 * (camera_gain + target_gain),
                camera_response=camera_response, target_response=target_response, seeds=FRESH_SEEDS)


def _fmt(strategy) -> str:
    return '[' + ' '.join(f'{p:.2f}' for p in strategy) + ']'

