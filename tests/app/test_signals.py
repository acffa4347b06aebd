"""Process-level signals of the ``ami-xr`` entry point (``ami_xr.app.cli.run``)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

# A command that is busy when the signal arrives: check_paths (the first thing main() does)
# is replaced by a sleep, so the test does not depend on how fast identification runs.
CHILD = """
import sys, time
import ami_xr.app.cli as cli
cli.check_paths = lambda args: (print("busy", flush=True), time.sleep(60))
sys.argv = ["ami-xr", "identify", "x.nc"]
cli.run()
"""


def _signal_busy_child(signum: int) -> subprocess.CompletedProcess:
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline().strip() == "busy"
    time.sleep(0.2)
    proc.send_signal(signum)
    try:
        out, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("ami-xr did not stop within 30 s of the signal")
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def test_sigterm_is_one_line_and_exit_143():
    done = _signal_busy_child(signal.SIGTERM)
    assert done.returncode == 143
    assert done.stderr.strip() == "ami-xr: terminated"


def test_ctrl_c_is_one_line_and_exit_130():
    done = _signal_busy_child(signal.SIGINT)
    assert done.returncode == 130
    assert done.stderr.strip() == "ami-xr identify: interrupted"
    assert "Traceback" not in done.stderr


def test_a_signal_dropped_inside_a_destructor_prints_no_traceback():
    # SIGTERM's SystemExit raised inside a __del__ cannot propagate; Python reports it through
    # sys.unraisablehook (a traceback on stderr). run() installs a hook that stays silent for it
    # and passes every other unraisable error on (the fault campaign found the traceback).
    from types import SimpleNamespace

    from ami_xr.app.cli import _unraisable

    seen = []
    hook = _unraisable(seen.append)
    hook(SimpleNamespace(exc_value=SystemExit(143)))
    hook(SimpleNamespace(exc_value=KeyboardInterrupt()))
    assert seen == []
    other = SimpleNamespace(exc_value=ValueError("a real bug"))
    hook(other)
    assert seen == [other]
