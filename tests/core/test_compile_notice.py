"""The one-line notice while the kernels compile: shown on a cold cache, once; not when they load
from the cache; never in output that is not a terminal unless asked for (MATE_COMPILE_NOTICE)."""

from __future__ import annotations

import io
import os
import subprocess
import sys

import pytest

from mate.core import jit

NOTICE_START = 'mate: compiling the simulation kernels'

# A reset and two steps: compiles (or loads) the reset and step entry points and everything they call.
FIRST_STEPS = ("import mate; env = mate.make('MATE-2v4-9-v0'); env.reset(seed=0); "
               "env.step(env.action_space.sample()); env.step(env.action_space.sample())")


def run_first_steps(cache_dir, notice: str | None) -> subprocess.CompletedProcess:
    env = {key: value for key, value in os.environ.items() if key != 'MATE_COMPILE_NOTICE'}
    env['NUMBA_CACHE_DIR'] = str(cache_dir)
    if notice is not None:
        env['MATE_COMPILE_NOTICE'] = notice
    return subprocess.run([sys.executable, '-c', FIRST_STEPS], capture_output=True, text=True, env=env, check=True)


@pytest.mark.slow
def test_notice_once_when_compiling_and_never_when_loading_from_the_cache(tmp_path):
    cold = run_first_steps(tmp_path, notice='1')
    assert cold.stderr.count(NOTICE_START) == 1, cold.stderr  # many kernels compiled, one line
    assert NOTICE_START not in cold.stdout
    assert any(tmp_path.rglob('*.nbi')), 'the cold run should have filled the cache'
    warm = run_first_steps(tmp_path, notice='1')
    assert NOTICE_START not in warm.stderr, warm.stderr


def test_output_that_is_not_a_terminal_gets_no_notice_unless_asked(monkeypatch):
    monkeypatch.delenv('MATE_COMPILE_NOTICE', raising=False)
    monkeypatch.setattr(sys, 'stderr', io.StringIO())  # captured, like pytest's capture or a pipe
    monkeypatch.delitem(sys.modules, 'ipykernel', raising=False)
    assert not jit.compile_notice_wanted()
    monkeypatch.setenv('MATE_COMPILE_NOTICE', '1')
    assert jit.compile_notice_wanted()


def test_a_terminal_gets_the_notice_unless_switched_off(monkeypatch):
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    monkeypatch.delenv('MATE_COMPILE_NOTICE', raising=False)
    monkeypatch.setattr(sys, 'stderr', Terminal())
    assert jit.compile_notice_wanted()
    monkeypatch.setenv('MATE_COMPILE_NOTICE', '0')
    assert not jit.compile_notice_wanted()
