"""Every public name of mate, mate.wrappers, mate.agents, mate.learn and mate.integrations is on an
API page (a `::: path` directive that resolves to that very object) and has a docstring as
mkdocstrings reads it (griffe's static analysis, the text the site shows)."""

from __future__ import annotations

import importlib
import re
import types

import pytest

from .markdown_blocks import ROOT

API_PAGES = sorted((ROOT / 'docs' / 'api').glob('*.md'))
DIRECTIVE = re.compile(r'^::: (?P<path>[\w.]+)\s*$', re.M)


def public_names() -> dict[str, object]:
    """'module.name' -> object, for every public name of the five modules."""
    import mate
    import mate.integrations.pettingzoo
    import mate.integrations.rllib
    names = {f'mate.{name}': getattr(mate, name) for name in dir(mate)
             if not name.startswith('_') and not isinstance(getattr(mate, name), types.ModuleType)}
    for module in (mate.wrappers, mate.agents, mate.learn, mate.integrations.pettingzoo, mate.integrations.rllib):
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


def directives() -> list[str]:
    return [match['path'] for page in API_PAGES for match in DIRECTIVE.finditer(page.read_text())]


def test_api_pages_exist():
    assert {page.stem for page in API_PAGES} == {'mate', 'wrappers', 'agents', 'learn', 'integrations'}


def test_every_public_name_is_on_an_api_page():
    documented: dict[str, list[object]] = {}
    for path in directives():
        documented.setdefault(path.rsplit('.', 1)[-1], []).append(resolve(path))
    missing = [name for name, value in public_names().items()
               if not any(value is other for other in documented.get(name.rsplit('.', 1)[-1], []))]
    assert not missing, f'public names on no page of docs/api/: {missing}'


def test_directives_name_real_objects():
    for path in directives():
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
