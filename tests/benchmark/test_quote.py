"""`mate benchmark quote`: the README's and the docs' benchmark tables are the committed reports' numbers."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import pytest

from mate.benchmark.quote import END, START, quote_blocks, quote_files
from mate.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
QUOTING = [ROOT / 'README.md', *sorted((ROOT / 'docs').rglob('*.md'))]


def test_the_readme_and_docs_quote_their_reports_exactly():
    """Every quote block of README.md and docs/ equals the headline table of the committed report it names: a
    hand-edited number, or a report re-run without re-quoting, fails here (`mate benchmark quote FILE` fixes it)."""
    blocks = {file.relative_to(ROOT).as_posix(): len(START.findall(file.read_text())) for file in QUOTING}
    assert blocks['README.md'] >= 1 and blocks['docs/results.md'] >= 1
    assert quote_files(QUOTING, ROOT, check=True, say=lambda line: None) == []


KEPT = sorted((ROOT / 'docs' / 'results').glob('*/benchmark/benchmark.json'))


@pytest.mark.slow
@pytest.mark.parametrize('manifest', KEPT, ids=[path.parts[-3] for path in KEPT])
def test_a_report_with_its_data_committed_is_rebuilt_from_it_exactly(manifest, tmp_path):
    """A report committed with its runs' data beside it (`docs/results/EXPERIMENT/benchmark/`: the manifest and each
    population run's `state.json`) is what `mate benchmark report` writes from that data: every number of the
    committed `results.json` is reproduced."""
    report = manifest.parents[1]
    assert main(['benchmark', 'report', str(manifest.parent), '--out', str(tmp_path)]) == 0
    rebuilt, committed = (json.loads((folder / 'results.json').read_text()) for folder in (tmp_path, report))
    assert _differences(rebuilt, committed) == []


FLOAT64_REL = 1e-12
"""How far a rebuilt float may be from the committed one: numpy sums in SIMD lanes whose width depends on the CPU
(AVX2 or AVX-512), so a mean or bootstrap bound can move in its last bits between CPU families (seen: 1 to 3 ulps,
about 3e-16 relative, between an Intel Xeon and an AMD EPYC). Any real change (another episode, seed or
resample) moves the numbers by far more than 1e-12."""


def _differences(found, expected, where='') -> list[str]:
    """Where the JSON values `found` and `expected` differ: floats beyond `FLOAT64_REL`, anything else at all."""
    if isinstance(found, dict) and isinstance(expected, dict):
        return [line for key in sorted(set(found) | set(expected), key=str)
                for line in _differences(found.get(key), expected.get(key), f'{where}.{key}')]
    if isinstance(found, list) and isinstance(expected, list) and len(found) == len(expected):
        return [line for i, (a, b) in enumerate(zip(found, expected)) for line in _differences(a, b, f'{where}[{i}]')]
    if isinstance(found, float) and isinstance(expected, float) and math.isclose(found, expected, rel_tol=FLOAT64_REL):
        return []
    return [] if found == expected else [f'{where}: rebuilt {found!r}, committed {expected!r}']


def test_some_report_keeps_its_data():
    assert KEPT, 'no docs/results/*/benchmark/benchmark.json: the population reports keep their runs\' data there'


@pytest.fixture()
def report(tmp_path):
    """A copy of a committed report and a markdown file quoting it, in a scratch repository root."""
    source = ROOT / 'docs/results/diag-targets-4v8-0'
    shutil.copytree(source, tmp_path / 'reports/diag')
    page = tmp_path / 'docs/page.md'
    page.parent.mkdir()
    page.write_text('# Page\n\n<!-- mate benchmark quote: reports/diag/results.json diag-targets-4v8-0 -->\nstale\n'
                    f'{END}\n\ntext after\n')
    return tmp_path, page


def test_quote_rewrites_a_stale_block_and_check_finds_a_changed_report(report, capsys):
    root, page = report
    assert main(['benchmark', 'quote', '--root', str(root), '--check', str(page)]) == 1
    assert 'differs from its reports' in capsys.readouterr().out
    assert main(['benchmark', 'quote', '--root', str(root), str(page)]) == 0
    text = page.read_text()
    assert 'stale' not in text and text.endswith(f'{END}\n\ntext after\n') and text.startswith('# Page\n')
    summary = json.loads((root / 'reports/diag/results.json').read_text())['diag-targets-4v8-0']
    own = summary['tasks']['MATE-4v8-0 targets']['settings']['own credit']['absolute']['IQM']
    assert f'| MATE-4v8-0 targets | own credit | 3 | {own["point"]:.3f} [{own["low"]:.3f}, {own["high"]:.3f}] |' in text
    each = summary['tasks']['MATE-4v8-0 targets']['settings']['own credit']['values']     # each run, by seed
    assert f' | {", ".join(f"{value:.3f}" for value in each)} |\n' in text and len(each) == 3
    assert '[its report](../reports/diag/results.md)' in text          # relative to the quoting file
    assert '**unresolved**' in text and '**no data**' in text and 'exact Mann-Whitney: 0.10 (0.40)' in text
    assert "| exact Mann-Whitney: 0.10 (0.40) | 3 runs a side cannot be decisive: the exact test's p is at least " \
           '0.10 |' in text                                      # a verdict not decisive says why, in its row
    assert main(['benchmark', 'quote', '--root', str(root), '--check', str(page)]) == 0
    # the report changes (a re-run): the quoted table is stale again
    summary['tasks']['MATE-4v8-0 targets']['settings']['own credit']['absolute']['IQM']['point'] = 0.5
    (root / 'reports/diag/results.json').write_text(json.dumps({'diag-targets-4v8-0': summary}))
    assert quote_files([page], root, check=True, say=lambda line: None) == [page]
    assert quote_blocks(page.read_text(), root, page.parent) != page.read_text()


def test_quote_errors_are_one_line(report, capsys):
    root, page = report
    page.write_text('<!-- mate benchmark quote: reports/diag/results.json diag-targets-4v8-0 -->\nno end\n')
    assert main(['benchmark', 'quote', '--root', str(root), str(page)]) == 2
    assert 'has no end marker' in capsys.readouterr().err
    page.write_text(f'<!-- mate benchmark quote: reports/diag/results.json fig6-observability -->\n{END}\n')
    assert main(['benchmark', 'quote', '--root', str(root), str(page)]) == 2
    assert "holds no experiment 'fig6-observability'; it holds diag-targets-4v8-0" in capsys.readouterr().err
    page.write_text(f'<!-- mate benchmark quote: reports/none/results.json diag-targets-4v8-0 -->\n{END}\n')
    assert main(['benchmark', 'quote', '--root', str(root), str(page)]) == 2
    assert 'which does not exist' in capsys.readouterr().err


def test_a_quoted_table_names_the_runs_its_report_left_out():
    """A report written while runs were missing says so in the quote too, not only in its results.md."""
    from mate.benchmark.quote import headline
    summary = json.loads((ROOT / 'docs/results/diag-targets-4v8-0/results.json').read_text())['diag-targets-4v8-0']
    summary['incomplete'] = []
    assert 'Not in the table' not in headline(summary, 'results.md')
    summary['incomplete'] = ['own credit on MATE-4v8-0 (seed 3)', 'team credit on MATE-4v8-0 (seeds 2, 4)',
                             'greedy on MATE-4v8-0']          # grouped by the report (mate.benchmark.jobs.by_setting)
    assert headline(summary, 'results.md').endswith(
        '\n\nNot in the table (not complete when the report was written): own credit on MATE-4v8-0 (seed 3), '
        'team credit on MATE-4v8-0 (seeds 2, 4), greedy on MATE-4v8-0.')


def test_a_verdicts_block_lists_every_claim_with_data_of_the_reports_it_names(tmp_path):
    """`<!-- mate benchmark quote: verdicts REPORT... -->`: one row per claim that has a test (claims without runs
    are left out), each with its experiment and budget linked to the report, its verdict and Holm's p; a report that
    is not there is a one-line error."""
    reports = ['docs/results/fig4a-cameras-10M/results.json', 'docs/results/fig7-psro/results.json']
    text = f'<!-- mate benchmark quote: verdicts {" ".join(reports)} -->\n{END}\n'
    quoted = quote_blocks(text, ROOT, ROOT)
    rows = [line for line in quoted.splitlines() if line.startswith('| [')]
    claims = [claim for path in reports for summary in json.loads((ROOT / path).read_text()).values()
              for claim in summary['claims']]
    assert len(rows) == sum('p' in claim for claim in claims) < len(claims)      # fig4a-10M has claims with no data
    assert rows[0].startswith('| [fig4a-cameras, 10 M per run](docs/results/fig4a-cameras-10M/results.md) |')
    assert any(row.startswith('| [fig7-psro, 100k per best response](docs/results/fig7-psro/results.md)') for row in rows)
    for row, claim in zip(rows, [c for c in claims if 'p' in c]):
        assert f'| {claim["text"]} | **{claim["verdict"]}** |' in row
        assert row.endswith(f' | {claim.get("reason", "-")} |')          # why a verdict is not decisive
    assert any('reason' in claim for claim in claims) and any('reason' not in claim for claim in claims)
    with pytest.raises(ValueError, match='does not exist'):
        quote_blocks(f'<!-- mate benchmark quote: verdicts docs/results/none/results.json -->\n{END}\n', ROOT, ROOT)
