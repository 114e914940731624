"""The version of mate: the one place it is written (pyproject.toml reads it; `mate --version`, run files)."""

__version__ = '0.1.0'
