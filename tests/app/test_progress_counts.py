"""Counts inside identify's phases on the progress bar: FRFs done by the per-FRF kernels, the
refinement's modes and iterations; never a change of the results, no split without a bar."""

from __future__ import annotations

import sys
import warnings

import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr import progress as pg
from ami_xr.app.cli import EXIT_OK, main
from ami_xr.kernels import isolate as ki
from ami_xr.kernels import subtract as ks


@pytest.fixture(scope="module")
def frf():
    g, _ = ami_xr.simulate.random_system(
        n_points=6, n_modes=6, noise=0.02, seed=4, n_frequencies=1200
    )
    return g


class Listener:
    """A progress callback that also takes the counts inside each phase."""

    def __init__(self):
        self.calls, self.details = [], []

    def __call__(self, *args):
        self.calls.append(args)

    def detail(self, text):
        self.details.append((self.calls[-1][0], text))


def _identify(ds, progress=False, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ami_xr.identify(ds, progress=progress, **kw)


def _values(result: xr.Dataset) -> xr.Dataset:
    # the history records the time of the call; everything else must be identical
    attrs = {k: v for k, v in result.attrs.items() if k != names.ATTR_HISTORY}
    return result.assign_attrs(attrs).drop_attrs(deep=False).assign_attrs(attrs)


@pytest.mark.parametrize("method", ["simo", "per_frf"])
def test_counts_never_change_the_results(frf, method):
    quiet = _identify(frf, method=method)
    listener = Listener()
    loud = _identify(frf, listener, method=method)
    assert listener.details  # counted: the kernels ran in blocks of FRFs
    xr.testing.assert_identical(_values(quiet), _values(loud))
    for name in quiet.data_vars:
        assert quiet[name].attrs == loud[name].attrs


@pytest.mark.parametrize("method", ["simo", "per_frf"])
def test_frfs_counted_in_subtract_and_isolate(frf, method):
    listener = Listener()
    _identify(frf, listener, method=method)
    n = frf.sizes[names.POINT]
    sub = [t for p, t in listener.details if p == "subtract"]
    assert sub == [f"{k}/{n} FRFs" for k in range(n + 1)]
    iso = [t for p, t in listener.details if p == "isolate"]
    # per-FRF isolation counts FRFs; the SIMO isolation is one joint fit (no FRF count)
    assert iso == ([f"{k}/{n} FRFs" for k in range(n + 1)] if method == "per_frf" else [])


def test_refine_counts_modes_and_iterations(frf):
    listener = Listener()
    result = _identify(frf, listener)
    ref = [t for p, t in listener.details if p == "refine"]
    assert ref[0].startswith("fit, ") and ref[0].endswith("iteration 1")
    counts = [int(t.rsplit(" ", 1)[1]) for t in ref if "iteration " in t]
    assert counts == list(range(1, len(counts) + 1))  # one count per iteration, in order
    last = ref[-1]
    n_iter = result.attrs[names.ATTR_REFINE_ITERATIONS]
    assert last == f"standard errors, {result.sizes[names.MODE]} modes, {n_iter} iterations"
    assert len(counts) == n_iter


def test_no_listener_no_split_and_no_counts(frf, monkeypatch):
    calls = {"subtract": 0, "isolate": 0}

    def counting(kernel, key):
        def wrapped(data, *args):
            calls[key] += 1
            return kernel(data, *args)

        return wrapped

    monkeypatch.setattr(ks, "_subtract_batch", counting(ks._subtract_batch, "subtract"))
    monkeypatch.setattr(ki, "isolate_batch", counting(ki.isolate_batch, "isolate"))
    plain = []  # a callback without detail(): phases only, one kernel call per phase, as before
    for progress in (False, lambda *a: plain.append(a)):
        calls.update(subtract=0, isolate=0)
        _identify(frf, progress, method="per_frf")
        assert calls == {"subtract": 1, "isolate": 1}
        assert not pg.active()
    assert [c[0] for c in plain] == ["subtract", "isolate", "global_fit", "refine", "done"]
    calls.update(subtract=0, isolate=0)
    _identify(frf, Listener(), method="per_frf")
    assert calls == {"subtract": frf.sizes[names.POINT], "isolate": frf.sizes[names.POINT]}


def test_by_rows_joins_blocks(monkeypatch):
    import numpy as np

    monkeypatch.setattr(pg, "MAX_CALLS", 3)
    seen = []
    rows = np.arange(14.0).reshape(7, 2)

    def kernel(a, k, b):
        return a * k, b + 1

    token = pg._DETAIL.set(seen.append)
    try:
        a, b = pg.by_rows(kernel, (rows, 2.0, np.arange(7)), rowwise=(0, 2))
    finally:
        pg._DETAIL.reset(token)
    np.testing.assert_array_equal(a, rows * 2.0)
    np.testing.assert_array_equal(b, np.arange(7) + 1)
    assert seen == ["0/7 FRFs", "3/7 FRFs", "6/7 FRFs", "7/7 FRFs"]


@pytest.mark.parametrize("with_tqdm", [True, False])
def test_phase_bar_draws_the_counts(monkeypatch, capsys, with_tqdm):
    if not with_tqdm:
        monkeypatch.setattr(pg, "_tqdm", lambda: None)
    elif pg._tqdm() is None:
        pytest.skip("tqdm not installed")
    monkeypatch.setattr(pg, "TICK_SECONDS", 0.0)
    bar = pg.PhaseBar("identify: 1 FRFs x 25601 lines")
    bar("refine", 3, 4)
    bar.detail("fit, 22 modes, iteration 7")
    bar("done", 4, 4)
    err = capsys.readouterr().err
    assert "identify: 1 FRFs x 25601 lines (refine: fit, 22 modes, iteration 7)" in err
    assert "3/4" in err and "4/4" in err


def test_cli_bar_counts_inside_the_phases_of_one_long_frf(frf, tmp_path, monkeypatch, capsys):
    # one FRF: what the CLI draws on a terminal (here without the delay, plain bar)
    path = tmp_path / "one.nc"
    # the drive point's FRF (a drive point naming no point of the file is an error, issue 42)
    ami_xr.to_netcdf(frf.sel({names.POINT: [frf.attrs[names.ATTR_DRIVE_POINT]]}), path)
    monkeypatch.setattr(pg, "DELAY_SECONDS", 0.0)
    monkeypatch.setattr(pg, "TICK_SECONDS", 0.0)
    monkeypatch.setattr(pg, "_tqdm", lambda: None)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert main(["identify", str(path)]) == EXIT_OK
    err = capsys.readouterr().err
    assert "(subtract: 1/1 FRFs): [" not in err  # one FRF: nothing to split
    assert "(refine: fit, " in err and ", iteration 1): [" in err and "3/4" in err
    assert "(done): [" in err and "4/4" in err
    capsys.readouterr()
    assert main(["identify", str(path), "-q"]) == EXIT_OK
    assert "[" not in capsys.readouterr().err
