"""The console script leaves without the interpreter's last full garbage collection (issue 42
campaign): after a Ctrl-C honoured within a second, that collection of a 1000-point identify's
objects took another 1.8-2.3 s on a loaded machine (honoured after 2.2-2.5 s in 5 of 56 signal
cases). ``run()`` freezes the objects before ``sys.exit``; atexit handlers still run."""

from __future__ import annotations

import subprocess
import sys

from ..reference import REPO
from .proc import H

CHILD = (
    "import atexit, gc, sys\n"
    "atexit.register(lambda: print('frozen at exit:', gc.get_freeze_count() > 0, flush=True))\n"
    "from ami_xr.app.cli import run\n"
    "sys.argv = ['ami-xr', 'identify', 'missing.nc', '-q']\n"
    "run()\n"
)


def test_run_freezes_the_objects_before_it_exits(tmp_path):
    done = subprocess.run(
        [sys.executable, "-c", CHILD], cwd=tmp_path, capture_output=True, text=True,
        env=H.env(REPO), timeout=120,
    )
    assert done.returncode == 1, done.stderr  # the missing file: one line, exit 1
    assert done.stderr.strip().startswith("ami-xr identify: error:"), done.stderr
    assert "frozen at exit: True" in done.stdout, done.stdout
