"""`mate benchmark quote REPORT FILE...`: README and docs tables written from a committed report, never by hand.

A markdown file quotes a report with a block between two marker lines that name the report's `results.json`
(relative to the root directory given, `--root`: by default the current one, the repository's root for the
README and docs) and the experiment:

    <!-- mate benchmark quote: docs/results/fig6-observability/results.json fig6-observability -->
    ... the headline table, written by `mate benchmark quote` ...
    <!-- end of mate benchmark quote -->

A block whose marker names `verdicts` and one or more reports' `results.json` instead gets one table of every claim
of those reports (`verdicts`): the experiment and its budget, linked to its report, the task, the claim, the verdict,
the test's p and why a verdict is not decisive, a line per claim with data; the results summary page and the
README quote it:

    <!-- mate benchmark quote: verdicts docs/results/fig4a-cameras-10M/results.json docs/results/fig7-psro/results.json -->
    <!-- end of mate benchmark quote -->

`quote_blocks` rewrites every such block from its reports; `mate benchmark quote --check` says which blocks differ
from their reports (exit status 1), which is what the test of the repository's own README and docs runs: a number
in those tables that is not in a committed report fails it.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable
from pathlib import Path

from .report import claim_rows, format_each, format_interval, format_number, p_value

__all__ = ['headline', 'quote_blocks', 'quote_files', 'verdicts']

START = re.compile(r'^<!-- mate benchmark quote: (?P<path>\S+) (?P<experiment>\S+(?: \S+)*) -->$', re.MULTILINE)
END = '<!-- end of mate benchmark quote -->'


def headline(summary: dict, link: str) -> str:
    """The headline table of one experiment's report summary (an entry of `results.json`): per task and setting,
    the runs and the absolute metric's IQM with its 95 % CI (population experiments: the final exploitability, also
    on fresh seeds, and how many policies the meta-strategies spread over, on average over the iterations), the
    normalised score (greedy = 1), each run's own score (by run seed), the references on the same episodes; then
    each claim's verdict with its evidence; then the runs not complete when the report was written (left out), if
    any. `link`: the report's `results.md`, which the table's caption links to."""
    population = summary['team'] == 'both'
    unit = 'per best response' if population else 'per run'
    lines = [f'*{summary["experiment"]}* ({summary["figure"]}): {summary["steps"]:,} decision steps {unit}'
             + (f' (the experiment\'s budget: {summary["paper_steps"]:,})' if summary['steps'] != summary['paper_steps']
                else '') + f'; quoted by `mate benchmark quote` from [its report]({link}).', '']
    if population:
        lines += ['| task | setting | runs | final exploitability, IQM [95 % CI] | on fresh seeds, IQM [95 % CI] | '
                  'each run (on fresh seeds when measured) | policies the meta-strategies spread over, mean over '
                  'iterations, IQM [95 % CI]: cameras; targets |', '|---|---|---|---|---|---|---|']
        for task, data in summary['tasks'].items():
            for label, entry in data['settings'].items():
                values, fresh = entry.get('final_exploitability'), entry.get('final_exploitability_fresh')
                each = entry.get('final_exploitability_fresh_values', entry.get('final_exploitability_values'))
                spread = entry.get('mean_effective_policies')
                spread = '; '.join(format_interval(spread[team]['IQM'], 2) for team in ('camera', 'target')) \
                    if spread else '-'
                lines.append(f'| {task} | {label} | {entry["runs"]} | {format_interval(values and values["IQM"], 4)} | '
                             f'{format_interval(fresh and fresh["IQM"], 4)} | {format_each(each, 4)} | {spread} |')
    else:
        lines += ['| task | setting | runs | absolute metric, IQM [95 % CI] | normalised, greedy = 1 | '
                  'each run, by seed |', '|---|---|---|---|---|---|']
        for task, data in summary['tasks'].items():
            for label, entry in data['settings'].items():
                lines.append(f'| {task} | {label} | {entry["runs"]} | {format_interval(entry["absolute"]["IQM"])} | '
                             f'{format_interval(entry.get("normalised_greedy"), 2)} | '
                             f'{format_each(entry.get("values"))} |')
            for agent, reference in data['references'].items():
                lines.append(f'| {task} | *{agent}* (reference) | - | {format_number(reference["absolute"])} | - | - |')
    if summary.get('claims'):
        lines += ['', *claim_rows(summary['claims'])]
    if summary.get('incomplete'):
        lines += ['', 'Not in the table (not complete when the report was written): '
                  f'{", ".join(summary["incomplete"])}.']
    return '\n'.join(lines)


def verdicts(summaries: list[tuple[dict, str]]) -> str:
    """One table of the claims of several reports (`summaries`: (an entry of a `results.json`, the link to its
    `results.md`)): per claim with data, the experiment at its budget (linked), the task, the claim, the verdict in
    bold, the test's p after Holm's correction over the report's claims and, for a verdict that is not decisive,
    why (`mate.benchmark.verdicts.decide`'s `reason`; the column only where some verdict is not decisive)."""
    why = any('reason' in claim for summary, _ in summaries for claim in summary.get('claims', ()) if 'p' in claim)
    lines = ['| experiment, budget | task | claim | verdict | p (Holm) |' + ' why not decisive |' * why,
             '|---|---|---|---|---|' + '---|' * why]
    for summary, link in summaries:
        unit = 'per best response' if summary['team'] == 'both' else 'per run'
        name = f'[{summary["experiment"]}, {_budget(summary["steps"])} {unit}]({link})'
        for claim in summary.get('claims', ()):
            if 'p' in claim:
                lines.append(f'| {name} | {claim["task"]} | {claim["text"]} | **{claim["verdict"]}** | '
                             f'{p_value(claim["p_holm"])} |' + f' {claim.get("reason", "-")} |' * why)
    return '\n'.join(lines)


def _budget(steps: int) -> str:
    """'500k', '2 M', '10 M' decision steps."""
    return f'{steps / 1e6:g} M' if steps >= 1_000_000 else f'{steps / 1e3:g}k'


def _summary(path: str, experiment: str, root: Path) -> dict:
    file = root / path
    if not file.exists():
        raise ValueError(f'a quote names {path}, which does not exist (paths are relative to {root})')
    summaries = json.loads(file.read_text())
    if experiment not in summaries:
        raise ValueError(f'{path} holds no experiment {experiment!r}; it holds {", ".join(summaries) or "none"}')
    return summaries[experiment]


def quote_blocks(text: str, root: Path, here: Path) -> str:
    """`text` with every quote block rewritten from the report its start marker names (module docstring); paths are
    relative to `root`, and the captions' links to the reports' `results.md` relative to `here` (the directory of
    the file the text is from). ValueError for a block without its end marker or a report that is not there."""
    pieces, position = [], 0
    root = Path(root).resolve()
    for start in START.finditer(text):
        if start.start() < position:
            raise ValueError(f'a quote of {start["path"]} starts inside the block before it')
        end = text.find(END, start.end())
        if end < 0:
            raise ValueError(f'the quote of {start["path"]} has no end marker ({END})')
        block = _block(start['path'], start['experiment'].split(), root, here)
        pieces += [text[position:start.end()], '\n', block, '\n']
        position = end
    pieces.append(text[position:])
    return ''.join(pieces)


def _block(first: str, rest: list[str], root: Path, here: Path) -> str:
    """The block of a start marker: `headline` of `first`'s experiment `rest[0]`, or for `verdicts REPORT...` the
    table of every experiment of every report named."""
    def link(path: str) -> str:
        return Path(os.path.relpath((root / path).parent / 'results.md', here)).as_posix()

    if first != 'verdicts':
        if len(rest) != 1:
            raise ValueError(f'a quote of {first} names one experiment, got {" ".join(rest)}')
        return headline(_summary(first, rest[0], root), link(first))
    found = []
    for path in rest:
        for experiment in _experiments(path, root):
            found.append((_summary(path, experiment, root), link(path)))
    return verdicts(found)


def _experiments(path: str, root: Path) -> list[str]:
    file = root / path
    if not file.exists():
        raise ValueError(f'a quote names {path}, which does not exist (paths are relative to {root})')
    return list(json.loads(file.read_text()))


def quote_files(files, root, check: bool = False, say: Callable[[str], None] = print) -> list[Path]:
    """Rewrite the quote blocks of `files` (or, with `check`, only find those that differ from their reports);
    returns the files that changed (or would)."""
    changed = []
    for file in map(Path, files):
        text = file.read_text()
        quoted = quote_blocks(text, Path(root), file.resolve().parent)
        if quoted != text:
            changed.append(file)
            if not check:
                file.write_text(quoted)
        blocks = len(START.findall(text))
        state = ('differs from its reports' if check else 'rewritten') if quoted != text else 'up to date'
        say(f'{file}: {blocks} quote block{"s" * (blocks != 1)}, {state}')
    return changed
