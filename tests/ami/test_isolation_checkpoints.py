"""Issue 42 item 7: the SIMO isolation, one compiled call for all restarts before, was the
longest stretch of identify without an interrupt checkpoint (2.6 s wall at 1000 points x 4096
lines). The engine now returns between restarts once its work budget is spent and the labeled
layer holds a checkpoint there; a counting hook in place of
:func:`ami_xr.interrupt.checkpoint` sees them (counts, not time), as in
``test_checkpoints_scale.py``.
"""

from __future__ import annotations

import warnings

import ami_xr
from ami_xr.kernels import isolate as ki
from ami_xr.simulate.spread import many_points

from .test_checkpoints_scale import count_checkpoints


def _in_isolation(code):
    return "isolation" if code.co_name == "_isolate" and "kernels" in code.co_filename else None


def test_simo_isolation_reaches_a_checkpoint_between_restarts(monkeypatch):
    ds, _ = many_points(200, 1024, 12, noise=0.02, seed=0)
    seen = count_checkpoints(monkeypatch, _in_isolation)
    monkeypatch.setattr(ki, "BETWEEN_WORK", 1)  # back to the caller before every restart
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = ami_xr.identify(ds)
    assert out.sizes["mode"] >= 10
    # the starting modes come from the subtraction; every change of the model (merge, prune, an
    # added or split mode) is a restart: at least one after the first
    assert seen["isolation"] >= 1, seen
