"""Feedback during long work: identify's phase progress (callback counts, the bar on stderr)."""

from __future__ import annotations

import sys
import threading
import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr import progress as pg
from ami_xr.errors import AmiXrValueError

ALL = ["subtract", "isolate", "global_fit", "refine"]


@pytest.fixture(scope="module")
def frf():
    g, _ = ami_xr.simulate.random_system(
        n_points=5, n_modes=5, noise=0.01, seed=4, n_frequencies=400
    )
    return g


def _record(ds, **kw):
    calls = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = ami_xr.identify(ds, progress=lambda *a: calls.append(a), **kw)
    return calls, result


def test_callback_gets_every_phase_with_counts(frf):
    calls, _ = _record(frf)
    assert calls == [(p, i, 4) for i, p in enumerate(ALL)] + [("done", 4, 4)]
    calls, _ = _record(frf, refine=False)
    assert calls == [(p, i, 3) for i, p in enumerate(ALL[:3])] + [("done", 3, 3)]


def test_no_modes_skips_to_done(frf):
    rng = np.random.default_rng(0)
    noise = frf.copy()
    noise[names.FRF] = frf[names.FRF].copy(
        data=1e-3
        * (rng.normal(size=frf[names.FRF].shape) + 1j * rng.normal(size=frf[names.FRF].shape))
    )
    calls, result = _record(noise)
    if result.sizes.get(names.MODE, 0):
        pytest.skip("noise produced a mode")
    assert calls == [("subtract", 0, 4), ("isolate", 1, 4), ("done", 4, 4)]


def test_progress_never_changes_the_results(frf):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        quiet = ami_xr.identify(frf)
    _, loud = _record(frf)
    xr.testing.assert_identical(quiet.drop_attrs(), loud.drop_attrs())


def test_bad_progress_named_before_work(frf):
    with pytest.raises(AmiXrValueError, match="progress: expected"):
        ami_xr.identify(frf, progress="yes")


@pytest.mark.parametrize("with_tqdm", [True, False])
def test_progress_true_draws_counted_phases_with_frf_counts(frf, capsys, monkeypatch, with_tqdm):
    if not with_tqdm:
        monkeypatch.setattr(pg, "_tqdm", lambda: None)
    elif pg._tqdm() is None:
        pytest.skip("tqdm not installed")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ami_xr.identify(frf, progress=True)
    err = capsys.readouterr().err
    assert "identify: 5 FRFs x 400 lines" in err
    assert "4/4" in err
    assert "(refine)" in err or "(done)" in err
    assert not [
        t
        for t in threading.enumerate()
        if t.name != "MainThread" and t.daemon and t.is_alive() and "tick" in repr(t)
    ]


def test_on_terminal_only_on_a_tty_and_delayed(monkeypatch, capsys):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    assert pg.on_terminal(True) is False
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert pg.on_terminal(False) is False
    bar = pg.on_terminal(True, "identify")
    assert isinstance(bar, pg.PhaseBar) and bar.delay == pg.DELAY_SECONDS
    # work shorter than the delay draws nothing, with and without tqdm
    for tqdm in (pg._tqdm, lambda: None):
        monkeypatch.setattr(pg, "_tqdm", tqdm)
        bar = pg.PhaseBar("identify", delay=60.0)
        for i, p in enumerate(ALL):
            bar(p, i, 4)
        bar("done", 4, 4)
    assert capsys.readouterr().err == ""


def test_phase_bar_closes_on_error(monkeypatch, capsys):
    monkeypatch.setattr(pg, "_tqdm", lambda: None)
    bar = pg.PhaseBar("work")
    with pytest.raises(RuntimeError):
        with pg.phases(bar, "work", ["a", "b"]) as step:
            step("a")
            raise RuntimeError("boom")
    assert bar._bar is None  # closed, its ticking thread stopped
    err = capsys.readouterr().err
    assert "work (a): [" in err and "0/2" in err and err.endswith("\n")


def test_live_bar_redraws_during_a_long_step(monkeypatch, capsys):
    monkeypatch.setattr(pg, "_tqdm", lambda: None)
    monkeypatch.setattr(pg, "TICK_SECONDS", 0.005)
    with pg.Progress("long", total=2, live=True) as bar:
        bar.update()
        threading.Event().wait(0.2)
        bar.update()
    err = capsys.readouterr().err
    # drawn at the start, at each update, and by the ticker in between
    assert err.count("\r") > 3
    assert "1/2" in err and "2/2" in err and " s" in err


def test_cli_bar_takes_the_label_of_the_work(frf, capsys, monkeypatch):
    # what the CLI passes: on_terminal() -> an unlabelled PhaseBar (here without the delay)
    monkeypatch.setattr(pg, "DELAY_SECONDS", 0.0)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ami_xr.identify(frf, progress=pg.on_terminal(True))
    assert "identify: 5 FRFs x 400 lines" in capsys.readouterr().err
