"""What a benchmark job computes, as data: its command lines resolved into configs.

Each command line of a job (`Job.commands`) is resolved by the command's own parser, every default filled in:
`mate train ALGORITHM ...` into the trainer's config (the fields its `RUN_DIR/config.json` holds), `mate evaluate`,
`mate psro` and `mate rllib-train` into their parsed options, and a user's setting (`mate benchmark job`) into the
setting's definition and the values the benchmark gives it (`jobs.job_values`). Left out is where a job writes and
how it shows its progress (`WHERE_AND_HOW`): two jobs with equal resolved configs run the same computation, whatever
their directories. The thread count stays in: torch's kernels may sum in another order on another count.

A runner writes a job's resolved config and its hash to `JOB_DIR/job.json` as it starts the job
(`write_job_config`); `mate benchmark run --reuse` copies a complete job whose config equals the missing one's, and
`--extend` continues a training run whose config differs in its budget alone (`mate.benchmark.directory`).

    from mate.benchmark.identity import command_config

    command_config(['evaluate', '--config', 'MATE-2v4-0', '--episodes', '4', '--json', 'a.json'])
    # {'command': 'evaluate', 'settings': {'config': 'MATE-2v4-0', 'episodes': 4, ...}}: no 'json'
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import io
import json
import shlex
from collections.abc import Sequence
from pathlib import Path

from .jobs import Job

__all__ = ['JOB_CONFIG', 'JOB_CONFIG_FORMAT', 'WHERE_AND_HOW', 'command_config', 'config_hash', 'job_config',
           'ran_config', 'wanted_config', 'write_job_config']

JOB_CONFIG = 'job.json'
"""The file in a job's directory holding its resolved config (`job_config`) and `config_hash`."""
JOB_CONFIG_FORMAT = 'mate.job/1'
"""The format of `JOB_CONFIG`."""
WHERE_AND_HOW = ('run_dir', 'out', 'json', 'dir', 'progress', 'fresh', 'wandb', 'wandb_project', 'checkpoint_every',
                 'command', 'benchmark_command', 'run', 'debug')
"""Options left out of a resolved config: where the job writes (run directory, output files, the benchmark
directory), how it shows and saves its progress, and the parser's own bookkeeping. None changes the numbers."""


def command_config(command: Sequence[str]) -> dict:
    """The resolved config of one command line of a job (after `python -m mate`): {'command', 'settings'} (and
    'algorithm' for `mate train`), as plain JSON data. A command line its parser refuses raises (CommandError or
    argparse's SystemExit), as the command would."""
    command = tuple(str(part) for part in command)
    if command[0] == 'train':
        from ..learn.command import trainer_config

        _, config = trainer_config(command[1], list(command[2:]))
        return _plain(dict(command='train', algorithm=command[1], settings=_kept(config.to_dict())))
    parser, name = _parser(command[:2])
    parsed = parser.parse_args(command[2:] if name == 'benchmark job' else command[1:])
    settings = {key: value for key, value in vars(parsed).items() if not callable(value)}
    if name == 'benchmark job':
        settings.update(_user_setting(parsed))
    return _plain(dict(command=name, settings=_kept(settings)))


def job_config(job: Job) -> list[dict]:
    """The resolved configs of `job`'s command lines, in order (`command_config`)."""
    return [command_config(command) for command in job.commands]


def wanted_config(job: Job) -> list[dict] | None:
    """`job_config(job)`, or None when a command line of the job is refused by its parser (the job fails when run,
    with the parser's message in its log; nothing stands for it)."""
    try:
        return job_config(job)
    except (SystemExit, ValueError, OSError):
        return None


def config_hash(configs: list[dict]) -> str:
    """sha256 of the canonical JSON of a job's resolved configs: equal for jobs of equal configs."""
    text = json.dumps(configs, sort_keys=True, separators=(',', ':'))
    return hashlib.sha256(text.encode()).hexdigest()


def write_job_config(job: Job, configs: list[dict] | None = None) -> Path:
    """Write `job`'s resolved config (`configs`, as `job_config` gives them; None: resolved now) and its hash to
    `JOB_DIR/job.json` (replaced whole); the path."""
    configs = job_config(job) if configs is None else configs
    path = job.dir / JOB_CONFIG
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f'{JOB_CONFIG}.tmp')
    tmp.write_text(json.dumps(dict(format=JOB_CONFIG_FORMAT, configs=configs, config_hash=config_hash(configs)),
                              indent=1) + '\n')
    tmp.replace(path)
    return path


def ran_config(folder) -> list[dict] | None:
    """The resolved configs of the job that ran in `folder`: its `job.json`; for a directory written before jobs
    had one, its `job.log`'s command lines ('$ mate ...', one per command; a resumed job logs its lines again)
    resolved now. None when neither is there or readable, as for a log of such a mate whose options held spaces
    (it joined them unquoted): a job nothing sure can be said of is never taken for another."""
    folder = Path(folder)
    try:
        saved = json.loads((folder / JOB_CONFIG).read_text())
        if saved.get('format') == JOB_CONFIG_FORMAT:
            return saved['configs']
    except (OSError, ValueError, KeyError):
        pass
    try:
        lines = (folder / 'job.log').read_text(errors='replace').splitlines()
    except OSError:
        return None
    commands = list(dict.fromkeys(line[len('$ mate '):] for line in lines if line.startswith('$ mate ')))
    try:
        with contextlib.redirect_stderr(io.StringIO()):      # a refused line: argparse's usage is no news here
            return [command_config(shlex.split(line)) for line in commands] or None
    except (SystemExit, ValueError, OSError):
        return None


@functools.cache
def _parser(words: tuple[str, ...]):
    """(parser, name) of the command a job's command line starts with: `mate evaluate`, `mate psro`, `mate
    rllib-train` or `mate benchmark job` (each command's own arguments, as `mate.cli.main` builds them)."""
    from ..cli.arguments import ArgumentParser

    name = 'benchmark job' if words == ('benchmark', 'job') else words[0]
    parser = ArgumentParser(prog=f'mate {name}')
    if name == 'evaluate':
        from ..evaluation.command import add_arguments
    elif name == 'psro':
        from ..learn.population.command import add_arguments
    elif name == 'rllib-train':
        from ..integrations.rllib_train import add_arguments
    elif name == 'benchmark job':
        from .jobs import add_job_arguments as add_arguments
    else:
        raise ValueError(f'a benchmark job runs mate train, evaluate, psro, rllib-train or benchmark job; got {name!r}')
    add_arguments(parser)
    return parser, name


def _user_setting(parsed) -> dict:
    """What a user's setting's job (`mate benchmark job DIR LABEL PRESET SEED`) computes beside its arguments: the
    setting's definition in the directory's manifest and the values the benchmark gives it (no run directory)."""
    from .user import user_job

    manifest = json.loads((Path(parsed.dir) / 'benchmark.json').read_text())
    setting, values = user_job(manifest, parsed.dir, parsed.label, parsed.preset, parsed.seed, parsed.threads)
    values.pop('run_dir')
    return dict(setting=setting.to_dict(), values=values)


def _kept(settings: dict) -> dict:
    return {key: value for key, value in settings.items() if key not in WHERE_AND_HOW}


def _plain(data):
    """`data` as JSON reads it back (tuples as lists, paths as strings): what `job.json` holds compares equal."""
    return json.loads(json.dumps(data, default=str))
