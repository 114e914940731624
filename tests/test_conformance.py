"""The shared differential check against transitions recorded from the original MATE.

Runs `check_fixture` of ../shared/checks/conformance.py on every recorded fixture, with the check's
default tolerance and no special case: every fixture must pass. The check and the fixtures live
outside the package; if they are missing the tests fail.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from modules import load_module

SHARED = Path(__file__).resolve().parents[1].parent / 'shared'
CHECK = SHARED / 'checks' / 'conformance.py'
FIXTURES = SHARED / 'reference' / 'fixtures'
SOFT_TOLERANCE = 0.005  # the check's default: occlusion-dependent outputs may differ on 0.5% of steps


def _fixture_paths():
    paths = sorted(FIXTURES.glob('*.npz'))
    # an empty or missing fixture folder must not silently produce zero tests
    return paths or [FIXTURES / 'MISSING-FIXTURES.npz']


@pytest.fixture(scope='module')
def check():
    if not CHECK.is_file():
        pytest.fail(f'the differential check is missing: expected {CHECK}')
    return load_module(CHECK, 'mate_shared_conformance')


def test_shared_check_and_fixtures_exist():
    assert CHECK.is_file(), f'the differential check is missing: expected {CHECK}'
    assert FIXTURES.is_dir(), f'the reference fixtures are missing: expected {FIXTURES}'
    assert len(list(FIXTURES.glob('*.npz'))) >= 6


@pytest.mark.parametrize('fixture', _fixture_paths(), ids=lambda path: path.stem)
def test_fixture_conforms(check, fixture, capsys):
    assert fixture.is_file(), f'no reference fixtures found in {FIXTURES}'
    assert fixture.with_suffix('.json').is_file(), f'fixture {fixture.stem} has no .json metadata'
    ok = check.check_fixture(fixture, SOFT_TOLERANCE, False)
    assert ok, f'differential check failed for {fixture.stem}:\n{capsys.readouterr().out}'
