"""Interrupts land at safe points (issue 25 item 1): never inside a kernel call.

The kernel here is a Python stand-in whose module is named like a kernel module
(``ami_xr.kernels.*``): a signal arriving while it runs is held, as one arriving while numba's
dispatcher is on the stack, and raised at the next checkpoint, after the piece is done.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
import types
from pathlib import Path

import pytest

from ami_xr import interrupt, progress

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")

REPO = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(REPO)}


def _kernel_module():
    """A module named like a kernel module holding a 'kernel' that signals its own process."""
    mod = types.ModuleType("ami_xr.kernels._fake_for_test")
    code = textwrap.dedent(
        """
        import os, signal
        log = []
        def kernel(signum):
            log.append("start")
            os.kill(os.getpid(), signum)   # arrives while the 'kernel' runs
            for _ in range(1000):          # bytecodes: Python would run the handler here
                pass
            log.append("end")
        """
    )
    exec(compile(code, "<fake kernel>", "exec"), mod.__dict__)
    return mod


@pytest.mark.parametrize(
    ("signum", "raised"),
    [(signal.SIGINT, KeyboardInterrupt), (signal.SIGTERM, interrupt.Terminated)],
)
def test_a_signal_inside_a_kernel_is_raised_at_the_next_checkpoint(signum, raised):
    mod = _kernel_module()
    interrupt.reset()
    with interrupt.armed():
        mod.kernel(signum)  # not raised inside
        assert mod.log == ["start", "end"]
        assert interrupt.pending() == signum
        with pytest.raises(raised):
            progress.detail("1/2 FRFs")  # the count between two pieces is a checkpoint
    assert interrupt.exit_code() == 128 + signum
    interrupt.reset()


def test_a_signal_outside_kernels_is_raised_at_once():
    interrupt.reset()
    with interrupt.armed(), pytest.raises(KeyboardInterrupt):
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(10**6):  # the handler runs here: nothing of numba on the stack
            pass
    interrupt.reset()


def test_armed_splits_the_per_frf_kernels_and_restores_handlers():
    before = signal.getsignal(signal.SIGINT)
    assert not progress.active()
    with interrupt.armed():
        assert progress.active()  # kernels called in pieces, a checkpoint between two
    assert signal.getsignal(signal.SIGINT) is before
    assert not progress.active()


CHILD = """
import os, sys, time
import numpy as np
import ami_xr.kernels.subtract as ks

# the subtraction kernel, wrapped by a slow stand-in whose module is a kernel module
ns = {"real": ks.subtract_batch, "time": time, "log": open(sys.argv[2], "a")}
exec(compile('''
def slow(*args):
    # compiled (or loaded) before the piece: numba's compile events are checkpoints, and the
    # cache may be cold (another checkout of the same version rewrote its index)
    real(*[a.copy() if hasattr(a, "copy") else a for a in args])
    log.write("start\\\\n"); log.flush()
    t = time.perf_counter()
    while time.perf_counter() - t < 0.3:
        pass
    out = real(*args)
    log.write("end\\\\n"); log.flush()
    return out
''', "<slow kernel>", "exec"), ns)
ns["__name__"] = "ami_xr.kernels.subtract"
import types
slow = types.FunctionType(ns["slow"].__code__, ns, "slow")
ks.subtract_batch = slow
import ami_xr.app.cli as cli
sys.argv = ["ami-xr", "identify", sys.argv[1], "-q", "-o", sys.argv[3]]
cli.run()
"""


@pytest.mark.parametrize(
    "signum", [signal.SIGINT, pytest.param(signal.SIGTERM, marks=pytest.mark.slow)]
)
def test_identify_stops_between_kernel_pieces(tmp_path, signum):
    """End to end: the CLI holds a signal that arrives during a (slow) kernel piece, stops after
    that piece, exits 130/143 with one line and writes no output."""
    src = REPO / "sample_data" / "benchmark_frf.nc"
    log, out = tmp_path / "log.txt", tmp_path / "m.nc"
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(src), str(log), str(out)],
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if log.exists() and log.read_text().count("start") >= 1:
            break
        time.sleep(0.02)
    time.sleep(0.1)  # inside the piece
    sent = time.monotonic()
    proc.send_signal(signum)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("no exit within 60 s of the signal")
    took = time.monotonic() - sent
    lines = log.read_text().split()
    assert proc.returncode == 128 + signum, err
    assert lines.count("start") == lines.count("end"), "interrupted inside a kernel piece"
    assert "error" not in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists()
    assert not list(tmp_path.glob(".*.tmp"))
    assert took < 30  # generous: the run itself takes minutes on a loaded machine
