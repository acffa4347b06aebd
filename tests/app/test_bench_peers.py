"""scripts/bench_peers.py (issue 11, item 2): its fixed system set, its matching, its ami_xr-only
run and its one-line exit when the peer (sdypy-EMA, the optional ``bench`` extra) is missing.

No timing is checked; sdypy-EMA itself is never needed here.
"""

from __future__ import annotations

import runpy
import sys

import numpy as np
import pytest

from ..reference import REPO

SCRIPT = REPO / "scripts" / "bench_peers.py"


@pytest.fixture(scope="module")
def bench():
    return runpy.run_path(str(SCRIPT), run_name="bench_peers")


def test_system_set_is_fixed_and_in_range(bench):
    full = bench["systems"](32, seed=0)
    assert full == bench["systems"](32, seed=0)  # deterministic from the seed
    assert full != bench["systems"](32, seed=1)
    assert [s.topology for s in full[:4]] == ["chain", "grid", "chain", "grid"]
    for s in full:
        assert 5 <= s.n_points <= 50 and 3000 <= s.n_lines <= 6000
        assert 4 <= s.n_modes <= min(12, s.n_points)
        assert s.noise in (0.01, 0.02, 0.03, 0.05)
    quick = bench["systems"](2, seed=0, quick=True)
    assert all(s.n_points <= 8 and s.n_lines <= 800 for s in quick)


def test_build_cuts_the_band_to_the_true_modes(bench):
    s = bench["systems"](2, seed=0, quick=True)[1]
    frf, lam = s.build()
    f = frf["frequency"].values
    assert frf.sizes == {"point": s.n_points, "frequency": s.n_lines}
    assert f[0] == 0.0 and lam.size == s.n_modes
    fn = np.abs(lam) / (2 * np.pi)
    assert fn.max() < f[-1]
    again, lam2 = s.build()
    np.testing.assert_array_equal(again["frf"].values, frf["frf"].values)  # same noise too
    np.testing.assert_array_equal(lam, lam2)


def test_score_matches_one_to_one_within_half_the_half_power_bandwidth(bench):
    lam = np.array([-1 + 100j, -2 + 200j])
    # one estimate near each mode, a second near mode 1 (spurious), one too far from mode 2
    ident = np.array([-1.1 + 100.2j, -1 + 100.5j, -2 + 202.5j])
    r = bench["score"](ident, lam, seconds=0.5)
    assert (r.found, r.spurious, r.seconds) == (1, 2, 0.5)
    fn_err = abs(abs(ident[0]) - abs(lam[0])) / abs(lam[0])
    assert r.fn_error == pytest.approx(fn_err)
    assert np.isnan(bench["score"](np.array([]), lam, 0.0).fn_error)


def test_stable_poles_keeps_poles_stable_over_the_last_orders(bench):
    good = -0.5 + 2j * np.pi * 10.0  # 10 Hz, zeta ~ 0.008
    drift = -0.5 + 2j * np.pi * 20.0
    orders = [
        np.array([good * (1 + 1e-5 * k), np.conj(good), drift * (1 + 0.01 * k), -1 - 1j])
        for k in range(8)
    ]
    kept = bench["stable_poles"](orders, lower=1.0, upper=30.0)
    assert kept.tolist() == [0]  # the drifting pole, the conjugate and the pole at 0.16 Hz go


def test_quick_run_ami_xr_only(bench, capsys):
    assert bench["main"](["--quick", "--no-peer"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert "2 random systems (seed 0, quick)" in lines[0] and "cpu_count" in lines[0]
    header = next(line for line in lines if line.startswith("system"))
    for column in ("pts", "lines", "modes", "noise", "t ami", "found", "fn err", "zeta err"):
        assert column in header
    assert "sdypy" not in header
    rows = [line for line in lines if line.startswith(("00-chain", "01-grid"))]
    assert len(rows) == 2
    for line, s in zip(rows, bench["systems"](2, seed=0, quick=True), strict=True):
        cells = line.split()
        assert [int(c) for c in cells[1:4]] == [s.n_points, s.n_lines, s.n_modes]
        assert int(cells[6]) == s.n_modes  # ami_xr finds every mode of these tiny systems
    total = next(line for line in lines if "ami_xr.identify" in line)
    n_true = sum(s.n_modes for s in bench["systems"](2, seed=0, quick=True))
    assert f"found {n_true:4d}/{n_true}" in total
    assert "ratio" not in out


def test_missing_peer_one_line_and_exit_code_2(bench, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "sdypy", None)  # import sdypy.EMA -> ImportError
    monkeypatch.setitem(sys.modules, "sdypy.EMA", None)
    assert bench["import_peer"]() is None
    assert bench["main"](["--quick"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1
    assert "sdypy-EMA is not installed" in captured.err
    assert "pip install ami_xr[bench]" in captured.err
