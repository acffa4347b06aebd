"""scripts/benchmark_mimo.py (issue 13, item 4) runs and prints its table."""

from __future__ import annotations

import runpy

import pytest

from ..reference import REPO

SCRIPT = REPO / "scripts" / "benchmark_mimo.py"


def _main():
    return runpy.run_path(str(SCRIPT), run_name="benchmark_mimo")["main"]


def test_benchmark_mimo_quick(capsys):
    assert _main()(["--quick"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert "2 seeds per noise level" in lines[0]
    header = next(line for line in lines if line.lstrip().startswith("noise"))
    for column in ("split", "refs", "found", "pair", "fn err", "zeta err", "dpc", "susp", "sep"):
        assert column in header, column
    assert "t ratio" in header and "err/CRB" in header
    rows = lines[lines.index(header) + 1 : -1]
    # noise 1 % and 5 % x split 0 and 0.1 % x references [2], [2, 3], [2, 3, 4]
    assert len(rows) == 12
    assert all(row.endswith("n/a (no multi-reference CRB)") for row in rows)
    cells = [row.split() for row in rows]
    assert [c[0] for c in cells] == ["1%"] * 6 + ["5%"] * 6
    assert [c[1] for c in cells[:6]] == ["0%"] * 3 + ["0.1%"] * 3
    assert [c[2] for c in cells[:3]] == ["2", "2,3", "2,3,4"]
    # two drive points separate the exactly repeated pairs at 1 % noise: 6 of 6 modes found,
    # both members of the first pair, flagged repeated_root_separated; one reference cannot
    one, two = cells[0], cells[1]
    assert two[3] == "6.00/6" and float(two[4]) == 1.0 and int(two[11]) > 0
    assert float(one[4]) == 0.0 and int(one[11]) == 0


def test_benchmark_mimo_rejects_bad_seeds():
    with pytest.raises(SystemExit):
        _main()(["--seeds", "0"])
