"""tests/learn need PyTorch (the train extra). Without it every module here is reported as skipped, with the
extra that installs it (and CI, which installs every extra, fails on the skip: tests/conftest.py)."""

import importlib.util

import pytest

if importlib.util.find_spec('torch') is None:
    from conftest import missing_extra_reason

    class _NeedsTorch(pytest.Module):
        """A test module that is not imported (it imports torch at the top): its collection is a skip."""

        def collect(self):
            pytest.skip(missing_extra_reason('torch'), allow_module_level=True)

    def pytest_pycollect_makemodule(module_path, parent):
        return _NeedsTorch.from_parent(parent, path=module_path)
