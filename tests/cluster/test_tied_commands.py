"""A benchmark job's command (`mate train ...` in its own session) dies with the process that ran the job: when a
Ray worker is killed, Ray runs the job again, and the first command must not go on writing the same run directory."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from mate.benchmark.runner import tied_to_parent

PARENT = """
import subprocess, sys, time
from mate.benchmark.runner import tied_to_parent
sleeper = [sys.executable, '-c', 'import time; time.sleep(300)']
tied = subprocess.Popen(tied_to_parent(sleeper), start_new_session=True)
plain = subprocess.Popen(sleeper, start_new_session=True)
print(tied.pid, plain.pid, flush=True)
time.sleep(300)
"""
"""A job's process: one command tied to it, one started plainly (as before), both in sessions of their own."""


def running(pid: int) -> bool:
    """Whether process `pid` exists and is not a zombie."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = Path(f'/proc/{pid}/stat')
    return not (stat.exists() and stat.read_text().rpartition(')')[2].split()[0] == 'Z')


def test_a_tied_command_dies_with_its_parent_and_a_plain_one_does_not():
    if not sys.platform.startswith('linux'):
        assert tied_to_parent(['x', 'y']) == ['x', 'y']        # elsewhere the command is left as it is
        return
    parent = subprocess.Popen([sys.executable, '-c', PARENT], stdout=subprocess.PIPE, text=True)
    tied, plain = map(int, parent.stdout.readline().split())
    try:
        assert running(tied) and running(plain)
        parent.send_signal(signal.SIGKILL)                     # the job's process dies without a word
        parent.wait()
        deadline = time.monotonic() + 60
        while running(tied) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert not running(tied)
        assert running(plain)                                  # an untied command outlives its parent
    finally:
        for pid in (tied, plain):
            if running(pid):
                os.kill(pid, signal.SIGKILL)
        parent.stdout.close()


def test_a_tied_command_keeps_its_output_and_exit_status():
    result = subprocess.run(tied_to_parent([sys.executable, '-c', 'import sys; print("ran"); sys.exit(3)']),
                            capture_output=True, text=True)
    assert result.returncode == 3 and result.stdout == 'ran\n'
