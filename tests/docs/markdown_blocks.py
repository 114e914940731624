"""Fenced code blocks of the documentation pages, for the tests that run them."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PYTHON_LANGUAGES = {'python', 'py', 'python3'}
OUTPUT_LANGUAGES = {'text', 'console', 'output'}
FENCE = re.compile(r'^(?P<indent> *)(?P<fence>`{3,}|~{3,})(?P<info>[^\n`]*)$')
OUTPUT_LABEL = re.compile(r'^\s*(\*\*)?Output:?(\*\*)?:?\s*$', re.I)


@dataclass
class Block:
    """One fenced block: its language, text and first line (1-based) in `path`."""

    path: Path
    line: int
    language: str
    code: str
    expected_output: str | None = None

    @property
    def where(self) -> str:
        return f'{self.path.relative_to(ROOT)}:{self.line}'


def pages() -> list[Path]:
    """README.md and every markdown file under docs/."""
    return [ROOT / 'README.md', *sorted((ROOT / 'docs').rglob('*.md'))]


def blocks_of(path: Path) -> list[Block]:
    """Every fenced block of `path`, in order; a python block followed by an output block
    (```text, with at most blank lines or an "Output:" line between) gets it as `expected_output`."""
    lines = path.read_text().splitlines()
    blocks: list[Block] = []
    gaps: list[str] = []  # lines between the previous block and this one
    i = 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        if not match:
            gaps.append(lines[i])
            i += 1
            continue
        indent, fence = len(match['indent']), match['fence']
        language = match['info'].strip().split(' ')[0].lower() if match['info'].strip() else ''
        start, body = i + 1, []
        i += 1
        while i < len(lines) and not lines[i].strip().startswith(fence):
            body.append(lines[i][indent:] if lines[i][:indent].strip() == '' else lines[i])
            i += 1
        if i >= len(lines):
            raise ValueError(f'{path}:{start}: code fence opened here is never closed')
        i += 1
        block = Block(path, start, language, '\n'.join(body) + '\n')
        previous = blocks[-1] if blocks else None
        if (language in OUTPUT_LANGUAGES and previous is not None and previous.language in PYTHON_LANGUAGES
                and previous.expected_output is None
                and all(not gap.strip() or OUTPUT_LABEL.match(gap) for gap in gaps)):
            previous.expected_output = block.code
        blocks.append(block)
        gaps = []
    return blocks


def python_blocks(path: Path) -> list[Block]:
    return [block for block in blocks_of(path) if block.language in PYTHON_LANGUAGES]
