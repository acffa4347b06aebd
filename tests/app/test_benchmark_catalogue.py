"""scripts/benchmark_catalogue.py (issue 10, item 7) runs and prints its table, totals, targets."""

from __future__ import annotations

import runpy

from ..reference import REPO

SCRIPT = REPO / "scripts" / "benchmark_catalogue.py"


def test_benchmark_catalogue_quick(capsys):
    main = runpy.run_path(str(SCRIPT), run_name="benchmark_catalogue")["main"]
    assert main(["--quick", "--cases", "2"]) == 0
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
    assert main(["--quick", "--cases", "1", "--seed", "1", "--method", "per_frf"]) == 0
    out = capsys.readouterr().out
    assert "seed 1, ami_xr.identify(frf, method='per_frf')" in out
    # noise-free only: no noisy totals, two noise-free targets
    assert "all noisy" not in out
    assert len(out.split("Targets (issue 10)\n")[1].splitlines()) == 2
