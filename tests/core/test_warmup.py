"""A cold first run compiles the step in a helper process while it compiles the reset (mate.core.warmup):
the step then loads from the cache, and the episode is the same as without the helper."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from mate.core import warmup

EPISODE = """
import numpy as np
import mate
env = mate.make('MATE-2v4-9-v0')
(camera_obs, target_obs), _ = env.reset(seed=3)
rng = np.random.default_rng(0)
trace = [float(camera_obs.sum() + target_obs.sum())]
for _ in range(30):
    (camera_obs, target_obs), *_ = env.step((rng.uniform(-1, 1, (2, 2)), rng.uniform(-1, 1, (4, 2))))
    trace.append(float(camera_obs.sum() + target_obs.sum()))
"""
"""30 seeded steps of random actions; `trace` holds the observation sums."""

# Records which of mate's functions compile in this process, then plays the episode.
FIRST_STEPS = """
import json, sys
from numba.core import event

compiled = []

class Record(event.Listener):
    def on_start(self, ev):
        compiled.append(ev.data['dispatcher'].py_func.__qualname__)
    def on_end(self, ev):
        pass

event.register('numba:compile', Record())
""" + EPISODE + """
json.dump(dict(compiled=compiled, trace=trace), sys.stdout)
"""


def play_cold(cache_dir, parallel: str) -> dict:
    env = {**os.environ, 'NUMBA_CACHE_DIR': str(cache_dir), 'MATE_PARALLEL_COMPILE': parallel,
           'MATE_COMPILE_NOTICE': '0'}
    done = subprocess.run([sys.executable, '-c', FIRST_STEPS], capture_output=True, text=True, env=env, check=True)
    return json.loads(done.stdout)


def reference_trace() -> list[float]:
    namespace = {}
    exec(EPISODE, namespace)
    return namespace['trace']


@pytest.mark.slow
def test_cold_first_run_compiles_the_step_aside_and_plays_the_same_episode(tmp_path):
    result = play_cold(tmp_path, parallel='1')
    assert '_reset_rows' in result['compiled'], result['compiled']       # a cold cache: this process compiles
    assert '_step_rows' not in result['compiled'], result['compiled']    # ... but loads the helper's step
    assert any(tmp_path.rglob('engine._step_rows*.nbi'))
    assert result['trace'] == reference_trace()


def test_switched_off_or_after_the_first_reset_nothing_is_started(monkeypatch):
    started = []
    monkeypatch.setattr(warmup, '_start_helper', lambda *dtypes: started.append(dtypes))
    observations = np.zeros((1, 2, 3)), np.zeros((1, 4, 3), dtype=np.float32)
    monkeypatch.setattr(warmup, '_tried', False)
    monkeypatch.setenv('MATE_PARALLEL_COMPILE', '0')
    assert warmup.compiling_step_aside(*observations) is warmup._NOTHING
    monkeypatch.setattr(warmup, '_tried', False)
    monkeypatch.setenv('MATE_PARALLEL_COMPILE', '1')
    context = warmup.compiling_step_aside(*observations)
    if warmup._wanted():        # more than one core: a listener that starts the helper on a compile
        assert context is not warmup._NOTHING
        with context:
            pass
    assert warmup.compiling_step_aside(*observations) is warmup._NOTHING   # only the first reset
    assert started == []        # nothing compiled inside the context: no helper
