"""Import a Python file that is not part of the package (a tool of docs/tools/ or tests/tools/) as a
module, for the tests that call its functions."""

import importlib.util
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[1]


def load_module(path: Path, name: str | None = None):
    """The module of the file at `path`, executed once per call (named `name`, default the file's stem)."""
    spec = importlib.util.spec_from_file_location(name or Path(path).stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def load_script(name: str):
    """docs/tools/NAME.py (or tests/tools/NAME.py) as a module."""
    for folder in ('docs/tools', 'tests/tools'):
        if (REPOSITORY / folder / f'{name}.py').exists():
            return load_module(REPOSITORY / folder / f'{name}.py')
    raise FileNotFoundError(f'no docs/tools/{name}.py or tests/tools/{name}.py')
