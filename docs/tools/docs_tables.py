"""Write the generated tables of the documentation site into its markdown pages.

Each table sits between two marker comments in a page:

    <!-- generated:NAME -->
    ...table written by this script...
    <!-- /generated:NAME -->

and is built from the code (the observation index helpers, the state spaces, the config schema,
the preset files), so that the pages cannot drift from it. Usage:

    python docs/tools/docs_tables.py           # rewrite the pages in place
    python docs/tools/docs_tables.py --check   # exit 1 naming the stale pages, change nothing

tests/docs/test_generated_tables.py runs the check in memory.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # run from a checkout without installing
    sys.path.insert(0, str(ROOT))

import mate  # noqa: E402
from mate import constants, spaces  # noqa: E402
from mate.config import schema  # noqa: E402

DOCS = ROOT / 'docs'
MARKER = re.compile(r'(<!-- generated:(?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- /generated:(?P=name) -->)', re.S)
EXAMPLE_COUNTS = (4, 8, 9)
"""Team sizes (N_c, N_t, N_o) of the worked index examples: the default preset MATE-4v8-9."""

# ----------------------------------------------------------------------------- entry names
# The meaning of each entry, in the code's order. The generator checks every list against the
# dimension the code uses, and takes the bounds from the code's spaces.

PRESERVED_ENTRIES = (
    ['number of cameras N_c', 'number of targets N_t', 'number of obstacles N_o', "the agent's own index in its team"]
    + [f'warehouse {w} ({side}) {axis}' for w, side in enumerate(('NE', 'NW', 'SW', 'SE')) for axis in 'xy']
    + ['warehouse half-width (75)']
)
CAMERA_PUBLIC_ENTRIES = ['x', 'y', 'body radius r_c', 'R_s cos(phi): sight range times cos(orientation)',
                         'R_s sin(phi)', 'viewing angle theta (degrees)']
CAMERA_PRIVATE_ENTRIES = CAMERA_PUBLIC_ENTRIES + ['max sight range R_max (at the narrowest angle)',
                                                  'rotation step (degrees)', 'zooming step (degrees)']
TARGET_PUBLIC_ENTRIES = ['x', 'y', 'sight range', 'is loaded (0 / 1)']
TARGET_PRIVATE_ENTRIES = TARGET_PUBLIC_ENTRIES + ['step size (largest move per step)', 'capacity (1 or 2)'] + [
    f'goal bit {w}: cargo weight bound for warehouse {w}' for w in range(constants.NUM_WAREHOUSES)] + [
    f'empty bit {w}: warehouse {w} remembered as empty' for w in range(constants.NUM_WAREHOUSES)]
OBSTACLE_ENTRIES = ['x', 'y', 'radius']

SLICE_MEANING = {
    'preserved_data': 'the preserved part (counts, own index, warehouses)',
    'self_state': "the agent's own private state",
    'opponent_states_with_mask': 'one block per {opponent}: public state + flag',
    'opponent_mask': 'the flag column of the {opponent} blocks (strided)',
    'obstacle_states_with_mask': 'one block per obstacle: state + flag',
    'obstacle_mask': 'the flag column of the obstacle blocks (strided)',
    'teammate_states_with_mask': 'one block per {teammate} (itself included): public state + flag',
    'teammate_mask': 'the flag column of the {teammate} blocks (strided)',
}

# ----------------------------------------------------------------------------- config key meanings

CONFIG_MEANING = {
    'name': 'a label shown by `str(env)`',
    'max_episode_steps': 'steps after which the episode is truncated',
    'reward_type': "'dense': rewards every step; 'sparse': only when cargo is delivered",
    'num_cargoes_per_target': 'cargo units placed per target in the warehouses at reset',
    'high_capacity_target_split': 'share of targets with capacity 2 (they move at half speed)',
    'targets_start_with_cargoes': 'whether every target starts loaded',
    'bounty_factor': 'scale of the reward for delivered cargo',
    'shuffle_entities': 'whether entity slots are shuffled at every reset',
    'camera': 'the cameras (absent: no cameras)',
    'camera.location': 'cameras at fixed positions',
    'camera.location_random_range': 'cameras placed uniformly in these boxes at reset',
    'camera.radius': 'body radius; targets cannot enter it',
    'camera.min_viewing_angle': 'narrowest field of view',
    'camera.max_sight_range': 'sight range at the narrowest field of view',
    'camera.rotation_step': 'largest turn per step',
    'camera.zooming_step': 'largest change of the viewing angle per step',
    'target': 'the targets (at least one)',
    'target.location': 'targets at fixed positions',
    'target.location_random_range': 'targets placed uniformly in these boxes at reset',
    'target.step_size': 'largest move per step of a capacity-1 target',
    'target.sight_range': 'how far a target sees',
    'obstacle': 'the obstacles (absent: no obstacles)',
    'obstacle.location': 'obstacles at fixed positions',
    'obstacle.location_random_range': 'obstacles placed uniformly in these boxes at reset',
    'obstacle.radius': 'one radius for every obstacle (give this or radius_random_range)',
    'obstacle.radius_random_range': 'radii drawn uniformly at reset (give this or radius)',
    'obstacle.transmittance': 'probability that sight passes through an obstacle',
}


class StaleDocsError(RuntimeError):
    """A page and the code disagree on something the generator cannot fill in by itself."""


# ----------------------------------------------------------------------------- helpers


def _number(value: float) -> str:
    if math.isinf(value):
        return 'inf' if value > 0 else '-inf'
    return f'{value:g}'


def _table(header: list[str], rows: list[list[object]]) -> str:
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '|'.join('---' for _ in header) + '|']
    lines += ['| ' + ' | '.join(str(cell) for cell in row) + ' |' for row in rows]
    return '\n'.join(lines) + '\n'


def _entry_rows(names: list[str], box, first_index: int = 0) -> list[list[object]]:
    """Rows (index, meaning, low, high) of a state part whose bounds are `box`."""
    if len(names) != box.shape[0]:
        raise StaleDocsError(f'{len(names)} entry names for a part of {box.shape[0]} entries: '
                             'update the names in docs/tools/docs_tables.py')
    return [[first_index + i, name, _number(low), _number(high)]
            for i, (name, low, high) in enumerate(zip(names, box.low, box.high))]


def _slice_text(piece: slice) -> str:
    step = '' if piece.step in (None, 1) else f', step {piece.step}'
    return f'[{piece.start}, {piece.stop}){step}'


def _slice_length(piece: slice) -> int:
    return len(range(piece.start, piece.stop, piece.step or 1))


# ----------------------------------------------------------------------------- observation tables


def preserved_table() -> str:
    box = spaces.camera_observation_space_of(*EXAMPLE_COUNTS)
    if len(PRESERVED_ENTRIES) != constants.PRESERVED_DIM:
        raise StaleDocsError('PRESERVED_ENTRIES does not match constants.PRESERVED_DIM')
    low, high = box.low[:constants.PRESERVED_DIM], box.high[:constants.PRESERVED_DIM]
    rows = [[i, name, _number(lo), _number(hi)] for i, (name, lo, hi) in enumerate(zip(PRESERVED_ENTRIES, low, high))]
    return _table(['index', 'entry', 'low', 'high'], rows)


def state_table(kind: str) -> str:
    """Entries of one entity state (`camera-private`, `target-public`, ...), bounds from mate.spaces."""
    tables = {
        'camera-public': (CAMERA_PUBLIC_ENTRIES, spaces.camera_state_space(private=False)),
        'camera-private': (CAMERA_PRIVATE_ENTRIES, spaces.camera_state_space(private=True)),
        'target-public': (TARGET_PUBLIC_ENTRIES, spaces.target_state_space(private=False)),
        'target-private': (TARGET_PRIVATE_ENTRIES, spaces.target_state_space(private=True)),
        'obstacle': (OBSTACLE_ENTRIES, spaces.obstacle_state_space()),
    }
    names, box = tables[kind]
    return _table(['index', 'entry', 'low', 'high'], _entry_rows(names, box))


def layout_table(team: mate.Team) -> str:
    """The named slices of an observation of `team` for the example team sizes."""
    slices = spaces.observation_slices_of(team, *EXAMPLE_COUNTS)
    unknown = sorted(set(slices) - set(SLICE_MEANING))
    if unknown:
        raise StaleDocsError(f'slices without a meaning in docs/tools/docs_tables.py: {", ".join(unknown)}')
    opponents, teammates = ('targets', 'cameras') if team is mate.Team.CAMERA else ('cameras', 'targets')
    rows = []
    for name, piece in slices.items():
        meaning = SLICE_MEANING[name].format(opponent=f'opponent {opponents[:-1]}',
                                             teammate=f'teammate {teammates[:-1]}')
        rows.append([f'`{name}`', _slice_text(piece), _slice_length(piece), meaning])
    return _table(['slice', 'indices', 'entries', 'content'], rows)


def entries_table(team: mate.Team) -> str:
    """Every entry of an observation of `team` for the example sizes: index, part, entity slot, entry."""
    slices = spaces.observation_slices_of(team, *EXAMPLE_COUNTS)
    camera = team is mate.Team.CAMERA
    own = CAMERA_PRIVATE_ENTRIES if camera else TARGET_PRIVATE_ENTRIES
    opponent = ('target', TARGET_PUBLIC_ENTRIES) if camera else ('camera', CAMERA_PUBLIC_ENTRIES)
    teammate = ('camera', CAMERA_PUBLIC_ENTRIES) if camera else ('target', TARGET_PUBLIC_ENTRIES)
    rows = [[i, 'preserved', '', name] for i, name in enumerate(PRESERVED_ENTRIES)]
    rows += [[slices['self_state'].start + i, 'own state', '', name] for i, name in enumerate(own)]
    for part, (kind, names) in (('opponent', opponent), ('obstacle', ('obstacle', OBSTACLE_ENTRIES)),
                                ('teammate', teammate)):
        block = slices[f'{part}_states_with_mask']
        fields = names + ['flag: observed (1) or not (0)']
        for offset in range(block.stop - block.start):
            slot, entry = divmod(offset, len(fields))
            rows.append([block.start + offset, part, f'{kind} {slot}', fields[entry]])
    dim = int(spaces.observation_indices_of(team, *EXAMPLE_COUNTS)[-1])
    if [row[0] for row in rows] != list(range(dim)):
        raise StaleDocsError(f'the {team.name.lower()} entry names do not cover indices 0..{dim - 1}: '
                             'update docs/tools/docs_tables.py')
    return _table(['index', 'part', 'entity', 'entry'], rows)


def indices_table() -> str:
    """The part offsets returned by the index helpers, for the example sizes."""
    rows = []
    for team, function in ((mate.Team.CAMERA, 'camera_observation_indices_of'),
                           (mate.Team.TARGET, 'target_observation_indices_of')):
        indices = spaces.observation_indices_of(team, *EXAMPLE_COUNTS)
        rows.append([team.name.lower(), f'`mate.{function}{EXAMPLE_COUNTS}`', f'`{list(map(int, indices))}`'])
    return _table(['team', 'call', 'offsets'], rows)


def dimensions_table() -> str:
    """Observation and state lengths of every preset."""
    rows = []
    for name in mate.list_presets():
        counts = preset_counts(mate.read_config(name))
        rows.append([name, *counts, constants.camera_observation_dim(*counts),
                     constants.target_observation_dim(*counts), constants.state_dim(*counts)])
    return _table(['preset', 'N_c', 'N_t', 'N_o', 'camera obs D_c', 'target obs D_t', 'state'], rows)


# ----------------------------------------------------------------------------- config and presets


def preset_counts(config: dict) -> tuple[int, int, int]:
    """(N_c, N_t, N_o) of a normalised config."""
    def count(section: str) -> int:
        part = config.get(section, {})
        return len(part.get('location', [])) + len(part.get('location_random_range', []))
    return count('camera'), count('target'), count('obstacle')


def _field_type(spec: object) -> str:
    if isinstance(spec, schema.Number):
        return 'int' if spec.integer else 'float'
    return {
        schema.Flag: 'bool', schema.Choice: 'str', schema.Text: 'str', schema.Section: 'mapping',
        schema.Locations: 'list of [x, y]', schema.LocationRanges: 'list of [x_low, x_high, y_low, y_high]',
        schema.RadiusRange: '[r_low, r_high]',
    }[type(spec)]


def _field_default(spec: object) -> str:
    default = spec.default
    if default is schema.REQUIRED:
        return '**required**'
    if default is schema.OMIT:
        return '(absent)'
    if isinstance(default, bool):
        return f'`{str(default).lower()}`'
    if isinstance(default, tuple):
        return '`[]`'
    return f'`{default!r}`'


def _field_range(spec: object) -> str:
    if isinstance(spec, schema.Number):
        return spec.describe()
    if isinstance(spec, schema.Choice):
        return ' or '.join(f'`{choice!r}`' for choice in spec.choices)
    if isinstance(spec, schema.Flag):
        return '`true` or `false`'
    if isinstance(spec, schema.LocationRanges):
        return 'low <= high on each axis'
    if isinstance(spec, schema.RadiusRange):
        return '0 <= r_low <= r_high'
    return 'any' if isinstance(spec, (schema.Text, schema.Locations)) else 'see the keys below'


def _config_rows(fields: dict, prefix: str = '') -> list[list[object]]:
    rows = []
    for key, spec in fields.items():
        path = f'{prefix}{key}'
        if path not in CONFIG_MEANING:
            raise StaleDocsError(f'config key {path!r} has no meaning in docs/tools/docs_tables.py CONFIG_MEANING')
        rows.append([f'`{path}`', _field_type(spec), _field_default(spec), _field_range(spec), CONFIG_MEANING[path]])
        if isinstance(spec, schema.Section):
            rows += _config_rows(spec.fields, f'{path}.')
    return rows


def config_table() -> str:
    rows = _config_rows(schema.SCHEMA.fields)
    extra = sorted(set(CONFIG_MEANING) - {row[0].strip('`') for row in rows})
    if extra:
        raise StaleDocsError(f'CONFIG_MEANING names keys the schema does not have: {", ".join(extra)}')
    return _table(['key', 'type', 'default', 'valid values', 'meaning'], rows)


def presets_table() -> str:
    """One row per preset; columns whose value is the same for every preset become a sentence after it."""
    header = ['preset', 'cameras', 'targets', 'obstacles', 'cargo per target', 'max steps', 'reward',
              'cargo at start', 'camera min angle', 'camera max range', 'target step', 'target sight range',
              'target start boxes', 'obstacle radius range', 'transmittance']
    rows = []
    for name in mate.list_presets():
        config = mate.read_config(name)
        camera, target, obstacle = config.get('camera', {}), config['target'], config.get('obstacle', {})
        boxes = sorted({str(box) for box in target['location_random_range']}) or ['-']
        radius = obstacle.get('radius_random_range', obstacle.get('radius')) if obstacle else None
        rows.append([name, *preset_counts(config), config['num_cargoes_per_target'],
                     config['max_episode_steps'], config['reward_type'],
                     'yes' if config['targets_start_with_cargoes'] else 'no',
                     _number(camera['min_viewing_angle']) if camera else '-',
                     _number(camera['max_sight_range']) if camera else '-',
                     _number(target['step_size']), _number(target['sight_range']), ' '.join(boxes),
                     str(radius) if obstacle else '-',
                     _number(obstacle['transmittance']) if obstacle else '-'])
    # '-' = not applicable (no cameras, no obstacles): such a column still counts as shared
    constant = [k for k in range(1, len(header)) if len({str(row[k]) for row in rows} - {'-'}) == 1]
    keep = [k for k in range(len(header)) if k not in constant]
    table = _table([header[k] for k in keep], [[row[k] for k in keep] for row in rows])
    if not constant:
        return table
    shared = '; '.join(f'{header[k]} {next(row[k] for row in rows if row[k] != "-")}' for k in constant)
    return table + f'\nThe same in every preset that has the entities concerned: {shared}.\n'


GALLERY_COLUMNS = 3


def gallery_table() -> str:
    """The preset gallery: each preset's frame (docs/images/presets/NAME.png) with its name under it."""
    cells = [f'![{name}](../images/presets/{name}.png){{ width="200" }}<br>{name}' for name in mate.list_presets()]
    cells += [''] * (-len(cells) % GALLERY_COLUMNS)
    rows = [cells[i:i + GALLERY_COLUMNS] for i in range(0, len(cells), GALLERY_COLUMNS)]
    return _table([' '] * GALLERY_COLUMNS, rows)


GENERATORS = {
    'preserved': preserved_table,
    'camera-public': lambda: state_table('camera-public'),
    'camera-private': lambda: state_table('camera-private'),
    'target-public': lambda: state_table('target-public'),
    'target-private': lambda: state_table('target-private'),
    'obstacle-state': lambda: state_table('obstacle'),
    'camera-layout': lambda: layout_table(mate.Team.CAMERA),
    'target-layout': lambda: layout_table(mate.Team.TARGET),
    'observation-indices': indices_table,
    'camera-entries': lambda: entries_table(mate.Team.CAMERA),
    'target-entries': lambda: entries_table(mate.Team.TARGET),
    'dimensions': dimensions_table,
    'config-keys': config_table,
    'presets': presets_table,
    'preset-gallery': gallery_table,
}
"""Block name -> function returning its markdown."""


# ----------------------------------------------------------------------------- filling the pages


def fill(text: str, where: str, tables: dict[str, str]) -> str:
    """`text` with every generated block replaced; an unknown block name raises StaleDocsError."""
    def replace(match: re.Match) -> str:
        name = match['name']
        if name not in tables:
            raise StaleDocsError(f'{where}: unknown generated block {name!r}; known: {", ".join(tables)}')
        return match.group(1) + tables[name] + match.group(4)
    return MARKER.sub(replace, text)


def render_pages(docs: Path = DOCS) -> dict[Path, tuple[str, str]]:
    """Every page holding a generated block: path -> (current text, regenerated text).

    Raises StaleDocsError when a block is on no page or on two pages.
    """
    tables = {name: generate() for name, generate in GENERATORS.items()}
    pages, seen = {}, {}
    for path in sorted(docs.rglob('*.md')):
        text = path.read_text()
        names = [match['name'] for match in MARKER.finditer(text)]
        for name in names:
            if name in seen:
                raise StaleDocsError(f'generated block {name!r} is on two pages: {seen[name]} and {path}')
            seen[name] = path
        if names:
            pages[path] = (text, fill(text, str(path), tables))
    missing = sorted(set(tables) - set(seen))
    if missing:
        raise StaleDocsError(f'generated blocks on no page: {", ".join(missing)}')
    return pages


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--check', action='store_true', help='change nothing; exit 1 if a page is stale')
    args = parser.parse_args(argv)
    stale = []
    for path, (current, regenerated) in render_pages().items():
        if current != regenerated:
            stale.append(path.relative_to(ROOT))
            if not args.check:
                path.write_text(regenerated)
    verb = 'stale' if args.check else 'rewritten'
    print(f'{verb}: {", ".join(map(str, stale))}' if stale else 'all generated tables up to date')
    return 1 if stale and args.check else 0


if __name__ == '__main__':
    sys.exit(main())
