"""The generated tables of the docs match the code: regenerating them changes nothing."""

from __future__ import annotations

import re

import pytest

from modules import load_module

from .markdown_blocks import ROOT

SCRIPT = ROOT / 'docs' / 'tools' / 'docs_tables.py'


@pytest.fixture(scope='module')
def docs_tables():
    return load_module(SCRIPT)


def test_regenerating_the_tables_changes_no_page(docs_tables):
    pages = docs_tables.render_pages()
    stale = [str(path.relative_to(ROOT)) for path, (current, regenerated) in pages.items() if current != regenerated]
    assert not stale, f'run python docs/tools/docs_tables.py; stale pages: {stale}'
    assert len(pages) >= 4


def test_every_block_is_filled(docs_tables):
    for path, (current, _) in docs_tables.render_pages().items():
        for match in docs_tables.MARKER.finditer(current):
            assert match['body'].startswith('| '), f'{path}: block {match["name"]} is empty'


def test_tables_follow_the_code(docs_tables, monkeypatch):
    """A change in the code shows up in the tables (the generator reads the code, not a copy)."""
    from mate.config import schema
    before = docs_tables.config_table()
    changed = dict(schema.SCHEMA.fields, max_episode_steps=schema.Number(123, low=0, low_open=True, integer=True))
    monkeypatch.setattr(schema, 'SCHEMA', schema.Section(changed))
    after = docs_tables.config_table()
    assert '`10000`' in before and '`123`' in after
    layout = docs_tables.layout_table(__import__('mate').Team.CAMERA)
    assert '| `opponent_mask` | [26, 62), step 5 | 8 |' in layout


def test_a_missing_meaning_is_an_error(docs_tables, monkeypatch):
    monkeypatch.delitem(docs_tables.CONFIG_MEANING, 'camera.radius')
    with pytest.raises(docs_tables.StaleDocsError, match='camera.radius'):
        docs_tables.config_table()


def test_an_unknown_block_is_an_error(docs_tables):
    text = '<!-- generated:no-such-table -->\n<!-- /generated:no-such-table -->\n'
    with pytest.raises(docs_tables.StaleDocsError, match='no-such-table'):
        docs_tables.fill(text, 'page.md', {'presets': ''})


def test_marker_pattern_matches_only_pairs(docs_tables):
    text = '<!-- generated:a -->\nx\n<!-- /generated:b -->\n'
    assert not re.search(docs_tables.MARKER, text)


def _rows(table: str) -> list[list[str]]:
    return [[cell.strip() for cell in line.strip('|').split('|')] for line in table.splitlines()[2:]]


@pytest.mark.parametrize('team_name', ['CAMERA', 'TARGET'])
def test_entry_names_match_what_the_env_puts_there(docs_tables, team_name):
    """Read an observation through the documented names: counts, positions and flags are the world's."""
    import mate
    team = mate.Team[team_name]
    env = mate.make('MATE-4v8-9-v0')
    observations, _ = env.reset(seed=3)
    for _ in range(30):
        observations, *_ = env.step(env.action_space.sample())
    world = env.get_world()
    own_kind = team_name.lower()
    states = {'camera': world['camera_state'], 'target': world['target_state'], 'obstacle': world['obstacle_state']}
    seen = {(observer, kind): world[f'{observer}_{kind}_view_mask']   # who observes whom, (observer, observed)
            for observer in ('camera', 'target') for kind in ('camera', 'target', 'obstacle')}
    checked = 0
    for agent, row in enumerate(observations[team]):
        for index, part, entity, entry in _rows(docs_tables.entries_table(team)):
            value = row[int(index)]
            if entry.startswith('number of'):
                assert value == {'N_c': 4, 'N_t': 8, 'N_o': 9}[entry[-3:]]
            elif part == 'own state' and entry in ('x', 'y'):
                assert value == states[own_kind][agent, 'xy'.index(entry)]
            elif entity:
                kind, slot = entity.split()
                flag = seen[own_kind, kind][agent, int(slot)]
                if entry.startswith('flag'):
                    assert value == flag, (index, entity)
                elif entry in ('x', 'y'):
                    expected = states[kind][int(slot), 'xy'.index(entry)] if flag else 0.0
                    assert value == pytest.approx(expected), (index, entity, entry)
                else:
                    continue
            else:
                continue
            checked += 1
    assert checked > 100
