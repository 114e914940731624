"""The README stays a front page: at most about 200 lines, no dates or issue numbers (those belong in the
contributors' records), and every `mate` command it shows is one the package takes: parsed by the command's own
parser (a trainer's options by the trainer's config, an experiment by its name). What the commands do is tested
where they are built (evaluate, train, benchmark, psro)."""

from __future__ import annotations

import re
import shlex

import pytest

from mate.cli.main import build_parser

from .markdown_blocks import ROOT

README = (ROOT / 'README.md').read_text()


def bash_lines() -> list[str]:
    """The command lines of the README's ```bash blocks, comments cut."""
    lines = []
    for block in re.findall(r'```bash\n(.*?)```', README, re.S):
        for line in block.splitlines():
            line = line.split('  #')[0].strip()
            if line:
                lines.append(line)
    return lines


def mate_commands() -> list[list[str]]:
    """Every `mate ...` command of the README's bash blocks (those after `&&` too), as argument lists."""
    commands = []
    for line in bash_lines():
        for part in line.split('&&'):
            words = shlex.split(part)
            if words and words[0] == 'mate':
                commands.append(words[1:])
    return commands


def test_the_readme_is_short_and_undated():
    assert len(README.splitlines()) <= 200
    assert not re.search(r'\b20\d\d-\d\d-\d\d\b', README), 'a date in the README'
    assert not re.search(r'\bissue \d+', README, re.I), 'an issue number in the README'


def test_the_quick_start_is_two_commands_install_and_run_then_the_tests():
    block = re.search(r'## Quick start\n\n```bash\n(.*?)```', README, re.S)[1].strip().splitlines()
    assert len(block) == 2
    assert block[0].startswith('pip install -e ') and '&& mate ' in block[0]
    assert block[1].split('  #')[0].strip() == 'pip install -e ".[test]" && python -m pytest -q -n auto'


@pytest.mark.parametrize('argv', mate_commands(), ids=' '.join)
def test_every_mate_command_of_the_readme_parses(argv):
    args = build_parser().parse_args(argv)
    if args.command == 'train':
        from mate.learn.command import trainer_config

        trainer_config(args.algo, args.options)
    if args.command == 'benchmark' and args.benchmark_command == 'run':
        from mate.benchmark.experiments import experiment

        experiment(args.name)
    if args.command == 'evaluate':
        from mate.evaluation.evaluate import resolve_agent
        from mate.messages import Team

        for agent, team in ((args.camera_agent, Team.CAMERA), (args.target_agent, Team.TARGET)):
            if not agent.startswith('checkpoint:'):      # a checkpoint the README's own training writes
                resolve_agent(agent, team)


def test_the_readme_shows_the_main_commands():
    commands = {' '.join(argv[:2]) for argv in mate_commands()}
    assert {'evaluate', 'train mappo', 'benchmark run', 'benchmark report'} <= commands | {argv[0] for argv in
                                                                                          mate_commands()}
