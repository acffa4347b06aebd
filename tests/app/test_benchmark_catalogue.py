"""scripts/benchmark_catalogue.py (issue 10, item 7) runs and prints its table, totals, targets."""

from __future__ import annotations

import runpy

import pytest

import ami_xr

from ..reference import REPO

SCRIPT = REPO / "scripts" / "benchmark_catalogue.py"


def test_benchmark_catalogue_quick(capsys):
    main = runpy.run_path(str(SCRIPT), run_name="benchmark_catalogue")["main"]
    assert main(["--quick", "--cases", "2", "--cluster-cases", "0"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    header = next(line for line in lines if line.startswith("case"))
    for column in ("pts", "modes", "ident", "found", "spur", "fn med", "fn max", "zeta max"):
        assert column in header
    # one row per case (noise 0 % and 1 %: the catalogue's first two), printed as it finished
    assert any(line.startswith("00-chain-0%") for line in lines)
    assert any(line.startswith("01-chain-1%") for line in lines)
    assert "Catalogue: 2 cases, seed 0, ami_xr.identify(frf)" in out
    # totals per noise level, over the noisy cases and overall
    for label in ("noise 0 %", "noise 1 %", "all noisy", "all "):
        assert any(line.startswith(label) for line in lines), label
    assert "found identifiable" in out and "error/CRB fn median" in out
    assert "relative error max fn" in out
    # a line per target, each met or NOT met
    targets = lines[lines.index("Targets (issue 10)") + 1 :]
    assert len(targets) == 6
    assert all(t.endswith((" met", "NOT met")) for t in targets)
    assert "noise-free: 100 % of modes found" in targets[0]


def test_benchmark_catalogue_method_option(capsys):
    main = runpy.run_path(str(SCRIPT), run_name="benchmark_catalogue")["main"]
    args = ["--quick", "--cases", "1", "--seed", "1", "--method", "per_frf", "--cluster-cases", "0"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "seed 1, ami_xr.identify(frf, method='per_frf')" in out
    # noise-free only: no noisy totals, two noise-free targets
    assert "all noisy" not in out
    assert len(out.split("Targets (issue 10)\n")[1].splitlines()) == 2


@pytest.mark.slow
def test_benchmark_catalogue_overlap_cases_and_bins(capsys):
    """One noise-free impulse-response overlap case (and one old case): its row, the per-bin
    lines phrased as the issue's targets, and the issue-20 target lines; the LSCF column when
    sdypy-EMA is installed, else said to be absent."""
    script = runpy.run_path(str(SCRIPT), run_name="benchmark_catalogue")
    main = script["main"]
    # cluster case 16 is the first impulse-response case (noise 0, overlap 0.15)
    case = ami_xr.simulate.cluster_catalogue(17)[16]
    assert case.source == "impulse_response" and case.noise == 0
    row = script["run_case"](case, {}, None, None)
    assert row["source"] == "impulse_response" and row["overlap"].size == row["modes"]
    assert row["found_mask"].sum() == row["found"]
    stats = script["bin_stats"]([row], False)
    assert sum(d["modes"] for d in stats.values()) == row["modes"]
    assert sum(d["found"] for d in stats.values()) == row["found"]
    lines = script["bin_lines"]("noise-free impulse", stats, False, False)
    assert lines and all("found, spurious" in ln and "max rel err" in ln for ln in lines)
    # the whole section through main, one tiny overlap case
    assert main(["--quick", "--cases", "1", "--cluster-cases", "1"]) == 0
    out = capsys.readouterr().out
    assert "Overlap cases (issue 20): 1 clustered systems" in out
    assert any(line.startswith("C00-ana-ov0.15") for line in out.splitlines())
    assert "noise-free analytic, overlap <0.25" in out
    targets = out.split("Targets (issue 20)\n")[1].splitlines()
    assert targets[0].startswith("  noise-free: 100 % of modes in every overlap bin")
    assert all(t.endswith((" met", "NOT met")) for t in targets)
    lscf = "LSCF column: sdypy-EMA" in out
    assert lscf or "no LSCF column" in out
    assert ("(LSCF " in out) == lscf
    assert any("at least as many modes as LSCF" in t for t in targets) == lscf
