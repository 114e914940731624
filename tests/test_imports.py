"""The package's import graph has no cycle: data flows one way (config -> core -> env -> agents/teams -> learn ->
cli). Every `import` statement of every module counts, those inside functions too (a lazy import hides a cycle; it
does not remove it), except under `if TYPE_CHECKING:`. An edge goes to the module named (`from X import Y` to the
submodule X.Y when there is one); a package's own `__init__` running first is not counted (every module would
otherwise depend on `mate/__init__.py`)."""

from __future__ import annotations

import ast
from pathlib import Path

import mate

ROOT = Path(mate.__file__).resolve().parent


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix('').parts)
    if parts[-1] == '__init__':
        parts.pop()
    return '.'.join(parts)


MODULES = {module_name(path): path for path in ROOT.rglob('*.py')}


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == 'TYPE_CHECKING') or \
        (isinstance(test, ast.Attribute) and test.attr == 'TYPE_CHECKING')


def imports_of(name: str) -> set[str]:
    """The modules of the package that module `name` imports."""
    path = MODULES[name]
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    found = set()

    def visit(node):
        if isinstance(node, ast.If) and _type_checking(node):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            for alias in node.names:
                found.add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split('.')
                base = base[:len(base) - node.level + 1]
                origin = '.'.join(base + ([node.module] if node.module else []))
            else:
                origin = node.module or ''
            submodules = [f'{origin}.{alias.name}' for alias in node.names if f'{origin}.{alias.name}' in MODULES]
            found.update(submodules)
            if len(submodules) < len(node.names):
                found.add(origin)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text()))
    return {module for module in found if module in MODULES and module != name}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on_stack, result, counter = {}, {}, [], set(), [], [0]

    def connect(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                result.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return result


def test_the_import_graph_has_no_cycle():
    graph = {name: imports_of(name) for name in MODULES}
    found = cycles(graph)
    assert not found, 'import cycles:\n' + '\n'.join(
        ' <-> '.join(component) + '\n    ' + '; '.join(f'{a} -> {b}' for a in component for b in sorted(graph[a])
                                                     if b in component) for component in found)


def test_the_check_finds_a_cycle():
    assert cycles({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}}) == [['a', 'b', 'c']]
    assert cycles({'a': {'b'}, 'b': set()}) == []


def test_the_core_imports_nothing_from_the_rest():
    for name in MODULES:
        if name.startswith('mate.core'):
            outside = {m for m in imports_of(name) if m != 'mate' and not m.startswith('mate.core')
                       and m not in ('mate.constants', 'mate.config', 'mate.config.schema', 'mate.config.loader')}
            assert not outside, (name, outside)


OUTSIDE = ('spec training', 'spec environment', 'spec agents', 'spec `', 'agents-and-wrappers', 'decisions.md',
           '(spec §', 'shared/spec/')


def test_no_module_cites_a_document_outside_the_repository():
    """Docstrings cite the paper or the project's own docs (docs/...), never the specification files the package
    was written from, which are not part of the repository; a docs/ page a module names exists."""
    import re

    for name, path in MODULES.items():
        text = path.read_text()
        cited = [phrase for phrase in OUTSIDE if phrase in text]
        assert not cited, f'{name} cites {cited}'
        assert not re.search(r'(?<!paper\'s )(?<!paper )§', text), f'{name} cites a section of no document'
        for page in re.findall(r'docs/[\w/-]+\.md', text):
            assert (ROOT.parent / page).exists(), f'{name} names {page}, which does not exist'


def private_imports(name: str) -> list[str]:
    """The private names (`_x`, not dunders) that module `name` imports from another module of the package."""
    path = MODULES[name]
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            base = package.split('.')
            origin = '.'.join(base[:len(base) - node.level + 1] + ([node.module] if node.module else []))
        else:
            origin = node.module or ''
        if origin == name or not (origin == 'mate' or origin.startswith('mate.')):
            continue
        found += [f'{origin}.{alias.name}' for alias in node.names
                  if alias.name.startswith('_') and not alias.name.startswith('__')]
    return found


def test_no_module_imports_another_modules_private_names():
    """What a module shares is public; a private name is its own (docs/contributors/architecture.md)."""
    found = {name: private_imports(name) for name in MODULES}
    assert not {name: names for name, names in found.items() if names}


def test_the_private_name_check_sees_relative_and_lazy_imports(tmp_path, monkeypatch):
    module = tmp_path / 'probe.py'
    module.write_text('def f():\n    from .core.device import _secret, BLOCK\n    from ..x import __version__\n')
    monkeypatch.setitem(MODULES, 'mate.probe', module)
    assert private_imports('mate.probe') == ['mate.core.device._secret']


LAYERS = (
    ('support', ('mate.version', 'mate.constants', 'mate.config', 'mate.messages', 'mate.spaces',
                 'mate.cli', 'mate.tools')),
    ('core', ('mate.core',)),
    ('game', ('mate.envs',)),
    ('players', ('mate.agents', 'mate.teams')),
    ('wrappers', ('mate.wrappers',)),
    ('policies', ('mate.policies',)),
    ('evaluation', ('mate.evaluation', 'mate.envs.single_team_vector')),
    ('learn', ('mate.learn',)),
    ('above', ('mate.benchmark', 'mate.integrations', 'mate.pretrained')),
    ('commands', ('mate.cli.main', 'mate.tools.bench', 'mate.__main__', 'mate')),
)
"""The layers of docs/contributors/architecture.md, lowest first, each by its modules' names (a package stands for
its submodules; the longest prefix decides)."""

def layer_of(name: str) -> int:
    """The index in `LAYERS` of module `name` (KeyError for a module no layer names)."""
    best = max(((len(prefix), index) for index, (_, prefixes) in enumerate(LAYERS) for prefix in prefixes
                if name == prefix or name.startswith(prefix + '.')), default=None)
    if best is None:
        raise KeyError(f'{name} is in no layer of tests/test_imports.py LAYERS (add it where it belongs)')
    return best[1]


def climbing_imports() -> dict[tuple[str, str], tuple[str, str]]:
    """Every import of a module of a higher layer: (importer, imported) -> their layers' names."""
    return {(name, other): (LAYERS[layer_of(name)][0], LAYERS[layer_of(other)][0])
            for name in MODULES for other in imports_of(name) if layer_of(other) > layer_of(name)}


def test_every_module_has_a_layer():
    assert all(layer_of(name) >= 0 for name in MODULES)


def test_no_import_climbs_the_layers():
    """Data flows one way, lowest layer first; lazy imports count (a lazy import hides a dependency, it does not
    remove it)."""
    assert climbing_imports() == {}


def test_the_layer_check_sees_a_climbing_import(tmp_path, monkeypatch):
    module = tmp_path / 'world_probe.py'
    module.write_text('def f():\n    from ..policies import policy\n')
    monkeypatch.setitem(MODULES, 'mate.core.world_probe', module)
    assert climbing_imports()[('mate.core.world_probe', 'mate.policies.policy')] == ('core', 'policies')


TOP_LEVEL = {'__init__', '__main__', 'version', 'constants', 'spaces', 'messages'}
"""The modules at the package's top level: the game's vocabulary and package support; everything else lives in the
folder of its layer (docs/contributors/architecture.md)."""


def test_the_top_level_holds_only_the_vocabulary_and_support():
    found = {path.stem for path in ROOT.glob('*.py')}
    assert found == TOP_LEVEL, (f'new top-level modules {sorted(found - TOP_LEVEL)}: put each in the folder of '
                                f'its layer (envs, evaluation, cli, tools, policies, ...); '
                                f'gone: {sorted(TOP_LEVEL - found)}')
