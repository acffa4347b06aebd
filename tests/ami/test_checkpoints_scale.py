"""Issue 42 item 7: interrupt checkpoints inside identify at 1000 points, not only between phases.

The compressed path's passes over the data, the residues of every point at the eigenvalues
found, the per-point noise level and the repeated-root statistic each ran over all points in
one call, the longest of them several seconds without a checkpoint (a Ctrl-C of the command
line waited for it). Now each works in blocks of at most 256 points with a checkpoint between;
a counting hook in place of :func:`ami_xr.interrupt.checkpoint` sees them (counts, not time).
"""

from __future__ import annotations

import sys
import warnings
from collections import Counter

import ami_xr
from ami_xr import interrupt
from ami_xr.simulate.spread import many_points

WATCHED = ("_map_sum", "_residue_block", "per_row", "map_reduce")


def count_checkpoints(monkeypatch, label_of) -> Counter:
    """Replace :func:`ami_xr.interrupt.checkpoint` by a counting hook: each checkpoint is
    counted under ``label_of(code)`` of the nearest calling frame whose code object it labels
    (not None); the real checkpoint still runs. Returns the live counter."""
    seen: Counter = Counter()
    real = interrupt.checkpoint

    def counting() -> None:
        frame = sys._getframe(1)
        while frame is not None:
            label = label_of(frame.f_code)
            if label is not None:
                seen[label] += 1
                break
            frame = frame.f_back
        real()

    monkeypatch.setattr(interrupt, "checkpoint", counting)
    return seen


def test_identify_at_1000_points_checkpoints_inside_each_pass(monkeypatch):
    ds, _ = many_points(1000, 1024, 12, noise=0.02, seed=0)
    seen = count_checkpoints(
        monkeypatch, lambda code: code.co_name if code.co_name in WATCHED else None
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = ami_xr.identify(ds)
    assert out.sizes["mode"] >= 10
    # 1000 points in blocks of 256: 4 per pass (compression: 2 passes; residues; the noise
    # level and the repeated-root statistic)
    assert seen["_map_sum"] >= 8, seen
    assert seen["_residue_block"] >= 4, seen
    assert seen["per_row"] >= 4, seen
    assert seen["map_reduce"] >= 4, seen
