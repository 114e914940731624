"""`Run`: one training run's directory and life, shared by every trainer.

    run = Run.of(config, 'mappo', spec)     # or Run(run_dir, 'mappo', config, spec, total_steps=..., ...)
    state = run.resume()                  # the checkpoint's algorithm state, or None for a fresh run
    with run:                             # SIGINT / SIGTERM: finish the iteration, checkpoint, stop
        while run.running():
            ... one iteration ...
            run.end_iteration(steps, coverage, episodes, columns, actor=policy_state, save=lambda: algorithm_state)
    run.finish(algorithm_state, policy)   # checkpoint.pt, and final.pt once the run is complete

What lives in the run directory:

* `checkpoint.pt`: everything the run's future depends on (format `mate.learn/2`): the `PolicySpec`, the
  algorithm's config, the counters (decision steps, iterations, training seconds), the window of recent
  episodes and the best return so far, and the algorithm's state (networks, optimisers, random generators,
  the training envs with their opponents). Written every `checkpoint_every` iterations, when a signal stops
  the run, and at the end. Resuming from it continues the run exactly: the same command gives the same
  weights, optimiser state and log rows as an uninterrupted run (CPU; `docs/training.md`).
* `progress.csv`: one row per iteration. A resumed run first drops the rows logged after its checkpoint
  (left by a killed process), so the file never holds an iteration twice; TensorBoard scalars (`tensorboard/`,
  when TensorBoard is installed) are purged from the same step.
* `best.pt`: the policy at the best mean return over the last 25 training episodes, once 25 have finished.
* `final.pt`: the policy when the run is complete (its decision steps or its time budget spent).

Signals: the first SIGINT (Ctrl-C) or SIGTERM (a cluster's scheduler) lets the iteration finish, writes the
checkpoint and stops (`interrupted`; the command exits with status 130); a second SIGINT stops at once
(KeyboardInterrupt), resuming then from the last periodic checkpoint.

Progress: the one-line bar on a terminal; plain lines every 30 s when the output is a file (`nohup`, a job).
"""

from __future__ import annotations

import csv
import dataclasses
import math
import signal
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..policies.checkpoint import CheckpointError, load_checkpoint, read_spec, save_checkpoint
from ..evaluation.protocol import EVALUATION_SEEDS, training_reset_seed
from .evaluation import Evaluator
from .run_config import RunConfig, default_run_dir
from ..policies.spec import PolicySpec

__all__ = ['EPISODE_WINDOW', 'Run', 'RunConfig', 'TENSORBOARD_MISSING', 'config_hash', 'default_run_dir',
           'episode_reward_phrase', 'mean_or_nan', 'write_run_config']

EPISODE_WINDOW = 25
"""Episodes the episode metrics are averaged over (RLlib's smoothing, which the paper's curves show)."""
TENSORBOARD_MISSING = ("TensorBoard is not installed: the run logs to progress.csv only (for TensorBoard scalars: "
                       "pip install tensorboard, or the train extra: pip install -e '.[train]')")
"""What a run with a progress display says once at its start when `torch.utils.tensorboard` cannot be imported."""
TIMING_COLUMNS = ('wall_seconds', 'steps_per_second', 'collect_share')
"""Log columns that measure the machine, not the run (they differ between two runs of the same seed)."""


RESUME_SETTINGS = ('credit',)
"""Config settings that a resumed run must share with its checkpoint beside the spec and the algorithm (the reward
each agent learns from, hence the critic's outputs)."""


NOT_IN_THE_HASH = ('run_dir', 'fresh', 'progress', 'threads', 'device', 'minutes', 'checkpoint_every',
                   'snapshot_every', 'wandb', 'wandb_project')
"""Config fields that do not define the run (where it runs, how it shows and saves it), left out of `config_hash`.
The budget (`steps`) is in: a run of another budget is another run. Threads and device may change the last bits of
the floats (another summation order), so the benchmark's job identity (`mate.benchmark.identity`) keeps them."""


def config_hash(algo: str, config_dict: dict) -> str:
    """sha256 of the canonical JSON of the algorithm and the config fields that define the run (all but
    `NOT_IN_THE_HASH`): two runs with the same hash run the same computation."""
    import hashlib
    import json

    defining = {key: value for key, value in config_dict.items() if key not in NOT_IN_THE_HASH}
    text = json.dumps(dict(algorithm=algo, config=defining), sort_keys=True, separators=(',', ':'), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def write_run_config(run_dir: Path, algo: str, config, spec: PolicySpec) -> Path:
    """`RUN_DIR/config.json`: every resolved setting of the run (the config's fields, the game, frame skip and
    horizon its spec resolved), the algorithm, the mate version and `config_hash`."""
    import json

    from ..version import __version__

    fields = _config_dict(config)
    data = dict(algorithm=algo, mate_version=__version__, config=fields,
                resolved=dict(env_id=spec.env_id, game=spec.config, frame_skip=spec.frame_skip,
                              horizon=getattr(config, 'resolved_horizon', None), team=spec.team),
                config_hash=config_hash(algo, fields))
    path = Path(run_dir) / 'config.json'
    path.write_text(json.dumps(data, indent=1, default=str) + '\n')
    return path


def _wandb_run(run_dir: Path, algo: str, config):
    """A Weights & Biases run logging this run's rows (resumed with the run: its id comes from the run directory)."""
    import hashlib

    try:
        import wandb
    except ImportError:
        raise ValueError("--wandb needs Weights & Biases: pip install wandb") from None
    identity = hashlib.sha256(str(Path(run_dir).resolve()).encode()).hexdigest()[:16]
    return wandb.init(project=config.wandb_project, name=Path(run_dir).name, id=identity, resume='allow',
                      dir=str(run_dir), config=dict(algorithm=algo, **_config_dict(config)), reinit=True)


def episode_reward_phrase(row: dict) -> str:
    """How a log row's episode window reads in progress lines: the learner's reward summed over an episode (for
    cameras the coverage rate of each decision, not the env's raw team reward that `mate evaluate` reports), over the
    last finished episodes, or that none has finished yet."""
    if not row.get('episodes'):
        return 'no episode finished yet'
    return f"learner's episode reward {row['episode_return']:.1f} (last {row['episodes']})"


def mean_or_nan(values) -> float:
    """The mean of `values`, NaN when there are none (a log column of an iteration without updates)."""
    return float(np.mean(values)) if len(values) else math.nan


class Run:
    """A training run's directory, counters, logs, checkpoints, budget and signals (module docstring).

    Args:
        run_dir: the run directory (created).
        algo: the trainer's name ('mappo', 'iql', ...), stored and checked on resume.
        config: the trainer's config dataclass (stored as `config.to_dict()` or its fields).
        spec: the trained policy's spec (a resumed checkpoint must have the same, up to `algo`).
        total_steps: decision steps of the whole run.
        time_limit: seconds of training wall time (earlier sessions included); 0: none.
        checkpoint_every: iterations between periodic checkpoints.
        snapshot_every: iterations between snapshots of the policy (`snapshots/policy-STEPS.pt`); 0: none.
        progress: show the progress bar (or plain lines).
        callback: `callback(row)` after every logged row.
        resume: continue from `run_dir/checkpoint.pt` when it exists (else start over, overwriting).
        console: where progress and notices go (default: a rich Console on stdout).
        evaluator: the run's evaluation protocol (`mate.learn.evaluation.Evaluator`), or None.
    """

    def __init__(self, run_dir, algo: str, config, spec: PolicySpec, *, total_steps: int, time_limit: float = 0.0,
                 checkpoint_every: int = 20, snapshot_every: int = 0, progress: bool = True,
                 callback: Callable[[dict], None] | None = None, resume: bool = True, console=None,
                 evaluator: Evaluator | None = None) -> None:
        self.dir = Path(run_dir)
        self.evaluator = evaluator
        self.dir.mkdir(parents=True, exist_ok=True)
        self.algo, self.config, self.spec = algo, config, spec
        self.total_steps, self.time_limit = int(total_steps), float(time_limit)
        self.checkpoint_every, self.snapshot_every = int(checkpoint_every), int(snapshot_every)
        self.show_progress, self.callback, self.console = progress, callback, console
        self.env_steps, self.iteration, self.best_return = 0, 0, -math.inf
        self.episodes: deque = deque(maxlen=EPISODE_WINDOW)
        self._earlier_seconds = 0.0          # training seconds of the sessions before this one
        self._started = None
        self._start_steps = 0
        self._stop_requested = False
        self.interrupted = False             # stopped by a signal before the run was complete
        self._resume = resume
        self._writer = self._csv_fields = self._line = self._wandb = None
        self._handlers = {}
        self.last_row: dict = {}

    @classmethod
    def of(cls, config: RunConfig, algo: str, spec: PolicySpec, callback=None, console=None) -> Run:
        """The run of a trainer's `config` (its `RunConfig` fields: directory, default runs/ALGO-TEAM-seedN, budget,
        checkpoints, progress, --fresh) training the policy of `spec` with algorithm `algo`."""
        run_dir = config.run_dir or default_run_dir(algo, config)
        if config.seed + config.num_envs > EVALUATION_SEEDS:
            raise ValueError(f'--seed {config.seed} with --num-envs {config.num_envs} would train on evaluation seeds: '
                             f'seed + num_envs must be at most {EVALUATION_SEEDS:,} '
                             '(mate.evaluation.protocol.SEED_RANGES)')
        evaluator = None
        if config.eval_every:
            from ..policies.device import resolve_device

            evaluator = Evaluator(run_dir, spec, config.eval_every, config.eval_episodes, config.resolved_horizon,
                                  resolve_device(config.device))
        return cls(run_dir, algo, config, spec, total_steps=config.steps, time_limit=config.time_limit,
                   checkpoint_every=config.checkpoint_every, snapshot_every=config.snapshot_every,
                   progress=config.progress, callback=callback,
                   resume=not config.fresh, console=console, evaluator=evaluator)

    # ------------------------------------------------------------------ resume
    @property
    def checkpoint_path(self) -> Path:
        return self.dir / 'checkpoint.pt'

    def resume(self) -> dict | None:
        """Load `checkpoint.pt` if resuming and it exists: restore the counters and the episode window, and
        return the algorithm's saved state (None for a fresh run). CheckpointError if the checkpoint belongs
        to another experiment (another algorithm, or a spec that differs: the message names the setting)."""
        if not (self._resume and self.checkpoint_path.exists()):
            return None
        data = load_checkpoint(self.checkpoint_path)
        if data.get('algo') not in (None, self.algo):
            raise CheckpointError(f'checkpoint {str(self.checkpoint_path)!r} does not match this experiment: '
                                  f'trained by {data.get("algo")}; this run is {self.algo}')
        saved_spec = read_spec(data, self.checkpoint_path)
        differences = saved_spec.differences(self.spec)
        if differences:
            raise CheckpointError(f'checkpoint {str(self.checkpoint_path)!r} does not match this experiment: '
                                  f'{differences[0]}')
        saved_config, config = data.get('config') or {}, _config_dict(self.config)
        for key in RESUME_SETTINGS:     # settings outside the spec that change what the networks learn
            if key in saved_config and key in config and saved_config[key] != config[key]:
                raise CheckpointError(f'checkpoint {str(self.checkpoint_path)!r} does not match this experiment: '
                                      f'trained with --{key.replace("_", "-")} {saved_config[key]}; this run has '
                                      f'--{key.replace("_", "-")} {config[key]}')
        if 'run' not in data or 'state' not in data:
            raise CheckpointError(f'checkpoint {str(self.checkpoint_path)!r} was written by an older mate (format '
                                  f'{data.get("format")!r}): it cannot be resumed exactly; use --fresh or another '
                                  '--run-dir (its policy still loads with --init-from)')
        run = data['run']
        self.env_steps, self.iteration = int(run['env_steps']), int(run['iteration'])
        self._earlier_seconds, self.best_return = float(run['wall_seconds']), float(run['best_return'])
        self.episodes.extend(run['episodes'])
        if self.evaluator is not None:
            self.evaluator.resume(run.get('evaluation'), self.iteration, self.env_steps)
        return data['state']

    @staticmethod
    def continues_episodes(saved: dict | None) -> bool:
        """Whether this session goes on with the episodes the checkpoint stopped in: `saved` (what `resume`
        returned) holds the batch's state. False for a fresh run and for an older checkpoint without it, whose batch
        `first_observations` resets: every episode starts anew, and with it any memory an actor carries."""
        return saved is not None and 'envs' in saved

    def first_observations(self, envs, saved: dict | None):
        """The first decision of this session in `envs` (a `TrainingEnv`): `(features (B, N, D), state (B, S))`.

        A checkpoint with the batch's state (`saved['envs']`, what `resume` returned) continues the very episodes
        it stopped in (an exact resume); otherwise the batch is reset with seed `config.seed + RESET_SEED_STRIDE x
        iteration` wrapped into the run's own 1,000-seed block(s) of the training seeds
        (`mate.evaluation.protocol.training_reset_seed`), the config's seed for a
        fresh run and other seeds for each later session of an older checkpoint."""
        if self.continues_episodes(saved):
            envs.load_state_dict(saved['envs'])
            return envs.observations()
        return envs.reset(seed=training_reset_seed(self.config.seed, self.iteration, envs.num_envs))

    # ------------------------------------------------------------------ the session
    def __enter__(self) -> Run:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def start(self) -> None:
        """Write `config.json`; open the logs (dropping rows logged after the checkpoint), the progress display and the
        signal handlers."""
        self._started, self._start_steps = time.perf_counter(), self.env_steps
        write_run_config(self.dir, self.algo, self.config, self.spec)
        self._open_logs()
        if self.show_progress:
            from ..cli.progress import ProgressLine

            self._line = ProgressLine('training', total=self.total_steps, completed=self.env_steps,
                                      console=self.console)
            self._line.start()
            if self._tensorboard is None:
                self._say(TENSORBOARD_MISSING)
        if threading.current_thread() is threading.main_thread():
            for number in (signal.SIGINT, signal.SIGTERM):
                self._handlers[number] = signal.signal(number, self._on_signal)

    def close(self) -> None:
        for number, handler in self._handlers.items():
            signal.signal(number, handler)
        self._handlers = {}
        if self._line is not None:
            self._line.stop(finished=not self.interrupted)
            self._line = None
        if self._tensorboard is not None:
            self._tensorboard.close()
            self._tensorboard = None
        if self._wandb is not None:
            self._wandb.finish()
            self._wandb = None

    def _on_signal(self, number, frame) -> None:
        if self._stop_requested and number == signal.SIGINT:
            raise KeyboardInterrupt
        self._stop_requested = True
        name = signal.Signals(number).name
        self._say(f'{name}: stopping after this iteration and writing the checkpoint (Ctrl-C again: stop at once, '
                  'losing the iterations since the last checkpoint)')

    def _say(self, text: str) -> None:
        if self.console is not None:
            self.console.print(text, soft_wrap=True, highlight=False)
        else:
            print(text, flush=True)

    @property
    def wall_seconds(self) -> float:
        """Training seconds so far, earlier sessions included."""
        return self._earlier_seconds + (time.perf_counter() - self._started if self._started else 0.0)

    def out_of_time(self) -> bool:
        return self.time_limit > 0 and self.wall_seconds >= self.time_limit

    def running(self) -> bool:
        """Whether to do another iteration: decision steps left, budget left, no stop requested."""
        if self._stop_requested:
            self.interrupted = self.env_steps < self.total_steps
            return False
        return self.env_steps < self.total_steps and not self.out_of_time()

    @property
    def complete(self) -> bool:
        """The run has done its decision steps or spent its time budget (its final policy is written)."""
        return self.env_steps >= self.total_steps or self.out_of_time()

    # ------------------------------------------------------------------ logs
    def _open_logs(self) -> None:
        if getattr(self.config, 'wandb', False):
            self._wandb = _wandb_run(self.dir, self.algo, self.config)
        path = self.dir / 'progress.csv'
        if self.iteration == 0 or not path.exists():
            path.unlink(missing_ok=True)
            self._csv_fields = None
        else:      # keep the rows up to the checkpoint's iteration (a killed run may have logged more)
            with open(path, newline='') as f:
                reader = csv.DictReader(f)
                self._csv_fields = reader.fieldnames
                rows = [row for row in reader if int(float(row['iteration'])) <= self.iteration]
            with open(path, 'w', newline='') as f:
                writer = csv.DictWriter(f, self._csv_fields)
                writer.writeheader()
                writer.writerows(rows)
        try:
            from torch.utils.tensorboard import SummaryWriter
            purge = dict(purge_step=self.env_steps + 1) if self.iteration else {}
            self._tensorboard = SummaryWriter(str(self.dir / 'tensorboard'), **purge)
        except Exception:  # noqa: BLE001  (tensorboard missing or broken: CSV only)
            self._tensorboard = None

    def episode_means(self) -> dict:
        """Means over the window of recent episodes (NaN before the first): coverage, return, normalised target
        return, and the window's size."""
        recent = list(self.episodes)

        def mean(key: str) -> float:
            return float(np.mean([e.get(key, np.nan) for e in recent])) if recent else math.nan

        return dict(episode_coverage=mean('coverage'), episode_return=mean('return'),
                    episode_normalized_target_return=mean('raw_return'), episodes=len(recent))

    def row(self, coverage, **columns) -> dict:
        """The log row of the iteration just done: iteration, decision and raw steps, wall seconds, decisions per
        second of this session, the iteration's mean rollout coverage, the episode window's means, `columns`."""
        elapsed = time.perf_counter() - self._started
        return dict(iteration=self.iteration, env_steps=self.env_steps, raw_steps=self.env_steps * self.spec.frame_skip,
                    wall_seconds=round(self.wall_seconds, 2),
                    steps_per_second=(self.env_steps - self._start_steps) / max(elapsed, 1e-9),
                    rollout_coverage=float(np.mean(coverage)), **self.episode_means(), **columns)

    def end_iteration(self, steps: int, coverage, episodes, columns: dict, status: str = '',
                      actor: Callable[[], dict] | None = None, save: Callable[[], dict] | None = None) -> dict:
        """Count the iteration's `steps` and finished `episodes`; evaluate the policy (`actor()` gives its network's
        state) when the evaluation protocol is due; log the row (CSV, TensorBoard, progress, callback), keep the
        policy as `best.pt` when the episode window's mean return is the best so far (and as `best-eval.pt` after its
        best evaluation) and as a snapshot every `snapshot_every` iterations, and write the periodic checkpoint
        (`save()` gives the algorithm's state). Returns the row."""
        self.env_steps += int(steps)
        self.iteration += 1
        self.episodes.extend(episodes)
        if self.evaluator is not None:
            last = self.env_steps >= self.total_steps or self.out_of_time()
            evaluation = math.nan
            if actor is not None and (self.evaluator.due(self.env_steps) or last):
                record = self.evaluator(actor(), self.iteration, self.env_steps)
                evaluation = record['mean']
                if record['best']:
                    self.save_policy('best-eval.pt', actor(), note=f'best evaluation, iteration {self.iteration}')
            columns = dict(columns, **{f'evaluation_{self.evaluator.metric}': evaluation})
        row = self.row(coverage, **columns)
        self._write(row)
        if len(self.episodes) == EPISODE_WINDOW and row['episode_return'] > self.best_return:
            self.best_return = row['episode_return']
            if actor is not None:
                self.save_policy('best.pt', actor(), note=f'best, iteration {self.iteration}')
        if self.callback is not None:
            self.callback(row)
        if self.iteration == 1 and self.total_steps % int(steps):
            self._say_rounding(int(steps))
        if self._line is not None:
            self._line.update(completed=self.env_steps, status=(
                f"{row['steps_per_second']:,.0f} steps/s  coverage {row['rollout_coverage']:.3f}  "
                f'{episode_reward_phrase(row)}' + (f'  {status}' if status else '')))
        if actor is not None and self.snapshot_every and self.iteration % self.snapshot_every == 0:
            self.save_policy(f'snapshots/policy-{self.env_steps:010d}.pt', actor())
        if save is not None and self.iteration % self.checkpoint_every == 0:
            self.checkpoint(save())
        self.last_row = row
        return row

    def _say_rounding(self, steps: int) -> None:
        """Say (once, after the first iteration) that the run trains whole iterations of `steps` decisions, so its
        budget rounds up, and show the rounded total in the progress display."""
        total = -(-self.total_steps // steps) * steps
        self._say(f'an iteration is {steps:,} decision steps: the run trains whole iterations, '
                  f'{total:,} decision steps for --steps {self.total_steps:,}')
        if self._line is not None:
            self._line.update(total=total)

    def _write(self, row: dict) -> None:
        path = self.dir / 'progress.csv'
        if self._csv_fields is None:
            self._csv_fields = list(row)
            with open(path, 'w', newline='') as f:
                csv.DictWriter(f, self._csv_fields).writeheader()
        with open(path, 'a', newline='') as f:
            csv.DictWriter(f, self._csv_fields, extrasaction='ignore').writerow(row)
        if self._tensorboard is not None:
            for key, value in row.items():
                if key != 'env_steps' and isinstance(value, (int, float)) and not math.isnan(value):
                    self._tensorboard.add_scalar(key, value, row['env_steps'])
            self._tensorboard.flush()
        if self._wandb is not None:
            self._wandb.log({key: value for key, value in row.items() if isinstance(value, (int, float))},
                            step=int(row['env_steps']))

    # ------------------------------------------------------------------ files
    def checkpoint(self, state: dict, path: Path | None = None) -> Path:
        """Write the run's checkpoint (`checkpoint.pt` by default) with the algorithm's `state`."""
        return save_checkpoint(path or self.checkpoint_path, dict(
            spec=self.spec.to_dict(), algo=self.algo, config=_config_dict(self.config),
            run=dict(env_steps=self.env_steps, iteration=self.iteration, wall_seconds=self.wall_seconds,
                     best_return=self.best_return, episodes=[dict(e) for e in self.episodes],
                     evaluation=None if self.evaluator is None else self.evaluator.state_dict()),
            state=state))

    def save_policy(self, path, actor_state: dict, note: str = '') -> Path:
        """Write a policy file (the acting part: spec and actor weights; `mate.policies.policy.load_policy` reads
        it)."""
        return save_checkpoint(self.dir / path if not Path(path).is_absolute() else path, dict(
            spec=self.spec.to_dict(), algo=self.algo, actor=actor_state, config=_config_dict(self.config),
            env_steps=self.env_steps, note=note or f'iteration {self.iteration}'))

    def finish(self, state: dict, actor_state: dict) -> dict:
        """The end of a session: the checkpoint, and when the run is complete `final.pt` and (with an evaluation
        protocol) the absolute metric of its best evaluated policy. Returns the last row."""
        self.checkpoint(state)
        if self.complete and not self.interrupted:
            self.save_policy('final.pt', actor_state, note='final')
            if self.evaluator is not None and not (self.dir / 'absolute.json').exists():
                self.evaluator.absolute()
        return self.last_row


def _config_dict(config) -> dict:
    """The config as plain data: a dataclass's fields (tuples as lists), or a dict as it is."""
    if hasattr(config, 'to_dict'):
        return config.to_dict()
    if dataclasses.is_dataclass(config):
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(config).items()}
    return dict(config)
