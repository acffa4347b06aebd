"""scripts/benchmark_mimo.py (issues 13 and 22) runs and prints its tables."""

from __future__ import annotations

import runpy
import warnings

import pytest

from ..reference import REPO

SCRIPT = REPO / "scripts" / "benchmark_mimo.py"


def _module():
    return runpy.run_path(str(SCRIPT), run_name="benchmark_mimo")


def _main():
    return _module()["main"]


@pytest.mark.slow
def test_benchmark_mimo_quick(capsys):
    assert _main()(["--quick", "--ring-only"]) == 0
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
    cells = [row.split() for row in rows]
    assert [c[0] for c in cells] == ["1%"] * 6 + ["5%"] * 6
    assert [c[1] for c in cells[:6]] == ["0%"] * 3 + ["0.1%"] * 3
    assert [c[2] for c in cells[:3]] == ["2", "2,3", "2,3,4"]
    # two drive points separate the exactly repeated pairs at 1 % noise: 6 of 6 modes found,
    # both members of the first pair, flagged repeated_root_separated; one reference cannot
    one, two = cells[0], cells[1]
    assert two[3] == "6.00/6" and float(two[4]) == 1.0 and int(two[11]) > 0
    assert float(one[4]) == 0.0 and int(one[11]) == 0
    # errors over the multi-reference bound: finite, of the order of 1 (efficient: 1)
    for c in cells:
        assert c[-4] == "fn" and c[-2] == "zeta"
        assert 0.1 < float(c[-3]) < 5 and 0.1 < float(c[-1]) < 5
    # more references never find fewer modes
    for i in range(0, 12, 3):
        assert float(cells[i + 2][3].split("/")[0]) >= float(cells[i][3].split("/")[0])


@pytest.mark.slow
def test_measured_like_all_references_find_at_least_the_best_single_one():
    mod = _module()
    truth, clean = mod["measured_like_truth"]()
    assert truth.sizes["mode"] == 8 and clean.sizes["reference"] == 3
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        got = mod["measured_like_seed"](truth, clean, 0.01, 0)
    assert got["all"] >= max(got["single"])
    assert len(got["fn_crb"]) == got["all"]


def test_benchmark_mimo_rejects_bad_seeds():
    with pytest.raises(SystemExit):
        _main()(["--seeds", "0"])
