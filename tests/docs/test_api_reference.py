"""Every public name of mate, mate.wrappers, mate.agents, mate.learn, mate.integrations and mate.benchmark is on an
API page (a `::: path` directive that resolves to that very object) and has a docstring as
mkdocstrings reads it (griffe's static analysis, the text the site shows).

`mate.integrations.rllib` imports Ray: without the rllib extra its names are checked by name, from
the module's `__all__` as griffe reads it, instead of by identity.
"""

from __future__ import annotations

import importlib
import re
import types

import pytest

from .markdown_blocks import ROOT

API_PAGES = sorted((ROOT / 'docs' / 'api').glob('*.md'))
RLLIB = 'mate.integrations.rllib'


def _have_ray() -> bool:
    try:
        import ray.rllib  # noqa: F401
    except ImportError:
        return False
    return True


HAVE_RAY = _have_ray()
DIRECTIVE = re.compile(r'^::: (?P<path>[\w.]+)\s*$', re.M)


def public_names() -> dict[str, object]:
    """'module.name' -> object, for every public name of the six modules."""
    import mate
    import mate.benchmark
    import mate.integrations.pettingzoo
    modules = [mate.wrappers, mate.agents, mate.learn, mate.integrations.pettingzoo, mate.benchmark]
    if HAVE_RAY:
        modules.append(importlib.import_module(RLLIB))
    modules.append(importlib.import_module('mate.integrations.torchrl'))   # the torchrl extra (in the test extra)
    names = {f'mate.{name}': getattr(mate, name) for name in dir(mate)
             if not name.startswith('_') and not isinstance(getattr(mate, name), types.ModuleType)}
    for module in modules:
        names.update({f'{module.__name__}.{name}': getattr(module, name) for name in module.__all__})
    return names


def resolve(path: str) -> object:
    """The object a dotted path names: the longest importable module prefix, then attributes."""
    parts = path.split('.')
    for split in range(len(parts), 0, -1):
        try:
            value = importlib.import_module('.'.join(parts[:split]))
        except ImportError:
            continue
        for attribute in parts[split:]:
            value = getattr(value, attribute)
        return value
    raise ImportError(path)


def directives(importable_only: bool = False) -> list[str]:
    """The paths of every `::: path` line of the API pages (without Ray: not the RLlib ones, if asked)."""
    paths = [match['path'] for page in API_PAGES for match in DIRECTIVE.finditer(page.read_text())]
    if importable_only and not HAVE_RAY:
        paths = [path for path in paths if not path.startswith(RLLIB)]
    return paths


def test_api_pages_exist():
    assert {page.stem for page in API_PAGES} == {'mate', 'wrappers', 'agents', 'learn', 'integrations', 'benchmark'}


def test_every_public_name_is_on_an_api_page():
    documented: dict[str, list[object]] = {}
    for path in directives(importable_only=True):
        documented.setdefault(path.rsplit('.', 1)[-1], []).append(resolve(path))
    missing = [name for name, value in public_names().items()
               if not any(value is other for other in documented.get(name.rsplit('.', 1)[-1], []))]
    assert not missing, f'public names on no page of docs/api/: {missing}'


def test_directives_name_real_objects():
    for path in directives(importable_only=True):
        resolve(path)  # raises for a typo


@pytest.fixture(scope='module')
def griffe_package():
    import griffe  # the docs extra; CI installs it
    loader = griffe.GriffeLoader(search_paths=[str(ROOT)])
    package = loader.load('mate')
    loader.resolve_aliases(implicit=True, external=False)
    return package


def test_every_documented_name_has_a_docstring(griffe_package):
    undocumented = []
    for path in directives():
        item = griffe_package[path.removeprefix('mate.')] if path != 'mate' else griffe_package
        docstring = item.docstring
        if docstring is None or not docstring.value.strip():
            undocumented.append(path)
    assert not undocumented, f'no docstring (as mkdocstrings reads it): {undocumented}'


def test_rllib_names_are_on_the_api_page(griffe_package):
    exported = [str(name) for name in griffe_package['integrations.rllib'].exports]
    documented = {path.rsplit('.', 1)[-1] for path in directives() if path.startswith(RLLIB + '.')}
    assert exported and not set(exported) - documented, sorted(set(exported) - documented)
