"""The one off-policy loop of `mate.learn`: IQL, QMIX and MA-TD3 train here, each bringing what is its own.

    spec (what the policy sees and does)  ->  batched training envs (`TrainingEnv`: B games, the other team a
            batched opponent; with `--game-device cuda` the games on a GPU, their arrays brought to the host once
            per decision for the replay)
        ->  the learner (`OffPolicyLearner`, one per algorithm file): its networks, optimisers and replay
        ->  loop: at every decision the learner acts for the B x N agents and stores the transition; once
            `learning_starts` decision steps are stored, one update every `update_every` decision steps (the
            learner's: double Q, the mixed value, twin critics and delayed actors); its own schedule after every
            decision (QMIX and IQL's target copies); a log row (an iteration) every `report_every` decision steps
        ->  `Run`: logs, checkpoints, best.pt, final.pt

The loop owns what the three share: the seeding (torch's seed, one numpy generator `[seed, 0]` for exploration and
replay sampling), the resume (the checkpoint at the end of a session holds the replay's filled rows and the
schedule, so the same command continues exactly; a periodic one leaves the replay out and refills it for
`learning_starts` decision steps first), the schedule of updates and log rows, the thread counts (one torch thread
for acting, `update_threads` for the updates), the log row's shared columns and the checkpoint's layout
(`networks`, `rng`, `schedule`, `envs`, `replay` beside the learner's own entries).
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import torch
from torch import nn

from ..core.arrays import host_array
from ..cli.options import option
from ..policies.device import resolve_device, update_threads
from .envs import GameDeviceConfig, TeamEnvConfig
from .run import Run, RunConfig

__all__ = ['OffPolicyConfig', 'OffPolicyLearner', 'on_host', 'train_off_policy']


@dataclasses.dataclass
class OffPolicyConfig(GameDeviceConfig, RunConfig, TeamEnvConfig):
    """The options of every trainer on this loop (the team env's, the run's, then the loop's own); each algorithm's
    config adds its replay, networks and optimisers."""

    num_envs: int = option(16, 'games played at once', minimum=1)
    threads: int = option(1, 'torch threads of the updates; 0: every core (acting always uses 1; the updates are small '
                             'and come between decisions, so more threads rarely pay for switching)', minimum=0)
    learning_starts: int = option(5_000, 'decision steps stored before the first update (a run resumed without its '
                                         'replay stores as many again)', minimum=0)
    update_every: int = option(128, "decision steps between updates (the Q-learners' spec: a sampling round of "
                                    '16 x 8)', minimum=1)
    gamma: float = option(0.99, 'discount per decision', minimum=0, maximum=1)
    report_every: int = option(5_120, 'decision steps per log row (an iteration; and one at the end)', minimum=1)
    game_device: Literal['auto', 'cpu', 'cuda'] = option(
        'cpu', "where the games and the greedy opponent run: cpu (numba; the default: the off-policy learners' 16 "
               'games step faster there), cuda (CUDA kernels, the gpu extra; their arrays come to the host once per '
               'decision for the replay), or auto: cuda when --device is a GPU and the settings allow it')

    def cuts_its_last_iteration(self) -> bool:
        """A row every `report_every` decision steps and one at the budget: early unless `steps` is a multiple."""
        return self.steps % self.report_every != 0

    def __post_init__(self) -> None:
        TeamEnvConfig.__post_init__(self)
        RunConfig.__post_init__(self)
        GameDeviceConfig.__post_init__(self)


class OffPolicyLearner:
    """What an off-policy algorithm brings to `train_off_policy` (its file's class): made from (config, spec, envs,
    device, rng) after torch's seed is set, it holds

    * `networks`: {name: module}, saved under the checkpoint's 'networks' ('actor' is the policy);
    * `replay`: a buffer with `size`, `fits(state)`, `state_dict()` and `load_state_dict()`;
    * `schedule_keys`: its own entries of the schedule (decision steps), kept across resumes.

    and answers the loop's calls below (the defaults do nothing)."""

    networks: dict[str, nn.Module]
    replay = None
    schedule_keys: tuple[str, ...] = ()

    def state_dict(self) -> dict:
        """Its own entries of the checkpoint (optimisers, counters, generators)."""
        return {}

    def load_state_dict(self, saved: dict) -> None:
        """Continue from a checkpoint (`saved`: the run state `train_off_policy` wrote): its networks and own
        entries."""
        for name, module in self.networks.items():
            module.load_state_dict(saved['networks'][name])

    def start(self, run: Run, saved: dict | None) -> None:
        """The session's first decision is next (`run.continues_episodes(saved)`: the envs go on with theirs)."""

    def begin_replay(self) -> None:
        """The replay starts empty (a fresh run, or a resume without the replay)."""

    def own_schedule(self, steps: int) -> dict:
        """Its schedule entries for a run that (re)starts at `steps` without its replay."""
        return {}

    def act(self, obs: np.ndarray, state: np.ndarray, steps: int, rng: np.random.Generator):
        """(what the replay stores, what the envs take) for the decision at `obs` (B, N, D), `state` (B, S)."""
        raise NotImplementedError

    def store(self, obs, state, action, reward, done, truncated, next_obs, next_state, info) -> None:
        """Put the decision's transitions into the replay (host arrays; `info` the envs' step info)."""
        raise NotImplementedError

    def update(self, steps: int, rng: np.random.Generator) -> None:
        """One update from the replay."""
        raise NotImplementedError

    def after_step(self, steps: int, schedule: dict) -> None:
        """After every decision (its own schedule: e.g. the target copies)."""

    def row(self, steps: int) -> dict:
        """The log row's columns of the iteration that ends (then its metrics start anew)."""
        raise NotImplementedError

    def status(self) -> str:
        """What the progress line shows beside the shared figures."""
        return ''


def on_host(values):
    """The envs' arrays on the host: numpy arrays as they are, tensors (games on a device) copied to numpy;
    dicts and tuples of them too."""
    if isinstance(values, dict):
        return {key: on_host(value) for key, value in values.items()}
    if isinstance(values, tuple):
        return tuple(on_host(value) for value in values)
    return host_array(values) if hasattr(values, 'detach') else values


def train_off_policy(config, name: str, spec, make_learner, envs=None, callback=None, console=None) -> Run:
    """Train `make_learner(config, spec, envs, device, rng)`'s learner as `config` says (in `config.run_dir`,
    default runs/NAME-TEAM-seedN); resume from its checkpoint unless `config.fresh` (module docstring). `envs`
    replaces the training envs (anything with `TrainingEnv`'s attributes, `spec` and reset/step: tests' toy tasks);
    `callback(row)` sees every log row. Returns the `Run`."""
    device = resolve_device(config.device)
    run = Run.of(config, name, spec, callback, console)
    envs = envs or config.make_env(spec)
    B = envs.num_envs
    # one torch thread for acting (the vector env runs its own threads) and for the initialisation, whose
    # orthogonal matrices (QR decompositions) differ with the thread count
    torch.set_num_threads(1)
    torch.manual_seed(config.seed)
    rng = np.random.default_rng([config.seed, 0])                   # exploration and replay sampling
    learner = make_learner(config, spec, envs, device, rng)
    replay = learner.replay
    saved = run.resume()
    if saved is not None:
        learner.load_state_dict(saved)
        rng.bit_generator.state = saved['rng']
    obs, state = on_host(run.first_observations(envs, saved))
    learner.start(run, saved)

    # ---- the schedule, in decision steps: updates, the learner's own (target copies), log rows
    steps = run.env_steps
    if saved is not None and replay.fits(saved.get('replay')):       # the end of a session: continue exactly
        replay.load_state_dict(saved['replay'])
        schedule = {key: saved['schedule'][key] for key in ('learning_from', 'next_update', *learner.schedule_keys,
                                                             'next_report')}
    else:                                                            # fresh, or a periodic checkpoint: fill first
        learner.begin_replay()
        learning_from = steps + config.learning_starts
        schedule = dict(learning_from=learning_from, next_update=max(learning_from, steps + config.update_every),
                        **learner.own_schedule(steps),
                        next_report=(steps // config.report_every + 1) * config.report_every)
        if saved is not None:
            schedule.update({key: saved['schedule'][key] for key in (*learner.schedule_keys, 'next_report')})

    def run_state(with_replay: bool = False) -> dict:   # everything the run's future depends on
        algorithm = dict(networks={key: module.state_dict() for key, module in learner.networks.items()},
                         **learner.state_dict(), rng=rng.bit_generator.state, schedule=dict(schedule))
        if hasattr(envs, 'state_dict'):
            algorithm['envs'] = envs.state_dict()
        if with_replay:
            algorithm['replay'] = replay.state_dict()
        return algorithm

    learn_threads = update_threads(config)
    actor = learner.networks['actor']
    coverage, episodes = [], []
    with run:
        while run.running():
            while True:   # one iteration: decisions until the next log row
                action, env_action = learner.act(obs, state, steps, rng)
                next_obs, next_state, reward, done, truncated, info = on_host(envs.step(env_action))
                learner.store(obs, state, action, reward, done, truncated, next_obs, next_state, info)
                obs, state = next_obs, next_state
                steps += B
                coverage.append(float(np.mean(info['coverage'])))
                episodes += info['episodes']

                # ---- learn: one update every `update_every` decision steps, from `learning_from` on
                if steps >= schedule['next_update'] and replay.size:
                    torch.set_num_threads(learn_threads)
                    while steps >= schedule['next_update'] and replay.size:
                        schedule['next_update'] += config.update_every
                        learner.update(steps, rng)
                    torch.set_num_threads(1)
                learner.after_step(steps, schedule)
                if steps >= schedule['next_report'] or steps >= config.steps or run.out_of_time():
                    break

            # ---- log, keep the best policy, checkpoint
            schedule['next_report'] += config.report_every
            run.end_iteration(steps - run.env_steps, coverage, episodes, learner.row(steps), status=learner.status(),
                              actor=actor.state_dict, save=run_state)
            coverage, episodes = [], []
    run.finish(run_state(with_replay=True), actor.state_dict())
    return run
