"""The excitation-band rule does not depend on how the data were cut (issue 20, item 4).

Unit tests of :mod:`ami_xr.dsp.band` on synthetic force and coherence spectra: the windows
have a constant relative width, the force's reference is its smoothed maximum, and the band
of any cut ``[a, b]`` inside the band of the whole record is the whole cut.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from ami_xr import names
from ami_xr.dsp import band as bd


def _spectra(n: int = 6001, df: float = 1.0, seed: int = 0):
    """A hammer-like record: the force flat, then falling (20 dB below its maximum near
    5.7 kHz), with a 2 dB ripple and one-line notches; coherence 0.99 with antiresonance dips
    of 40 lines (0.5) at 1.6 and 3.1 kHz, 0.3 below 8 Hz and above 5 kHz."""
    rng = np.random.default_rng(seed)
    f = np.arange(n) * df
    gff = 1.0 / (1.0 + (f / 1800.0) ** 4) * 10 ** (0.1 * rng.uniform(-1, 1, n))
    gff[rng.choice(n, 40, replace=False)] *= 1e-3  # notches: the running median ignores them
    coh = np.full(n, 0.99)
    coh[(f < 8) | (f > 5000)] = 0.3
    for dip in (1600.0, 3100.0):
        coh[np.abs(f - dip) < 20] = 0.5
    ds = xr.Dataset(
        {
            names.FORCE_AUTOSPECTRUM: (names.FREQUENCY, gff),
            names.COHERENCE: ((names.POINT, names.FREQUENCY), coh[None, :]),
        },
        coords={names.FREQUENCY: f, names.POINT: ["a"]},
    )
    return ds


def _naive_valid(f, gff, coh):
    """The rule written out line by line (windows: |f_j - f_i| <= f_i / 32, >= 2 lines a side,
    lines above 0 Hz only)."""
    pos = np.flatnonzero(f > 0)
    fp, gp, cp = f[pos], gff[pos], coh[pos]
    smooth, frac = np.empty(pos.size), np.empty(pos.size)
    for i in range(pos.size):
        inside = np.flatnonzero(np.abs(fp - fp[i]) <= fp[i] / 32)
        lo = max(0, min(inside[0], i - 2))
        hi = min(pos.size, max(inside[-1] + 1, i + 3))
        smooth[i] = np.median(gp[lo:hi])
        frac[i] = np.mean(cp[lo:hi] >= bd.COHERENCE_MIN)
    ok = np.zeros(f.size, bool)
    # with a coherence the force may fall to FORCE_FLOOR_DB (issue 37)
    ok[pos] = (smooth >= smooth.max() * 10 ** (-bd.FORCE_FLOOR_DB / 10)) & (frac >= 0.5)
    return ok


def test_valid_lines_match_the_rule_written_out():
    ds = _spectra(n=1501, df=4.0)
    f = ds[names.FREQUENCY].values
    gff, coh = ds[names.FORCE_AUTOSPECTRUM].values, ds[names.COHERENCE].values
    ok, rule = bd.valid_lines(f, gff, coh)
    np.testing.assert_array_equal(ok, _naive_valid(f, gff, coh[0]))
    assert "maximum" in rule and "20 dB" in rule and "40 dB" in rule


def test_window_width_is_relative_and_at_least_five_lines():
    f = np.arange(1, 20001) * 0.5
    lo, hi = bd._windows(f)
    width = hi - lo
    assert width[0] == 3  # cut off at the lower end: 2 lines on the right only
    assert width[10] == 5  # 5.5 Hz: +-0.17 Hz holds no other line; 2 a side
    i = np.searchsorted(f, 3200.0)
    assert width[i] == 2 * 200 + 1  # +-100 Hz on 0.5 Hz lines


def test_longest_run_and_tie():
    assert bd.longest_run(np.array([0, 1, 1, 0, 1, 1, 1, 0], bool)) == (4, 6)
    assert bd.longest_run(np.array([1, 1, 0, 1, 1], bool)) == (0, 1)
    assert bd.longest_run(np.zeros(4, bool)) is None


def test_band_of_the_whole_record():
    ds = _spectra()
    band = bd.analysis_band(ds)
    assert band.rule == bd.RULE_EXCITATION
    # below 8 Hz coherence 0.3: the first passing line is where half the window is above 0.8
    assert 8.0 <= band.fmin <= 12.0
    # the force is 20 dB below its maximum near 1800 * (100 - 1)^(1/4) = 5.7 kHz, the
    # coherence ends at 5 kHz: the coherence ends the band (half-window past 5 kHz)
    assert 5000.0 <= band.fmax <= 5000.0 + 5000.0 / 32 + 1


@pytest.mark.parametrize(
    "a, b", [(20.0, 4885.0), (12.0, 4990.0), (300.0, 1000.0), (1500.0, 3200.0), (4000.0, 4999.0)]
)
def test_a_cut_inside_the_band_is_its_own_band(a, b):
    ds = _spectra()
    cut = ds.sel({names.FREQUENCY: slice(a, b)})
    band = bd.analysis_band(cut)
    f = cut[names.FREQUENCY].values
    assert (band.fmin, band.fmax) == (f[0], f[-1])
    assert bd.is_whole(cut, band)


def test_cutting_never_removes_a_line_the_whole_record_passes():
    """Lower maximum, same windows away from the new ends: every line that passes on the whole
    record passes on the cut (the cut may pass more: its maximum is lower)."""
    ds = _spectra(seed=3)
    f = ds[names.FREQUENCY].values
    whole, _ = bd.valid_lines(f, ds[names.FORCE_AUTOSPECTRUM].values, ds[names.COHERENCE].values)
    for a, b in ((2000.0, 6000.0), (0.0, 3000.0), (2500.0, 5800.0)):
        keep = (f >= a) & (f <= b)
        cut, _ = bd.valid_lines(
            f[keep], ds[names.FORCE_AUTOSPECTRUM].values[keep], ds[names.COHERENCE].values[:, keep]
        )
        edge = (f[keep] < a + a / 32 + 3) | (f[keep] > b - b / 32 - 3)  # windows cut off here
        assert np.all(cut[whole[keep] & ~edge])


def test_the_old_reference_moved_the_new_one_does_not():
    """Cut to 2-6 kHz, the lowest lines lie several dB below the whole record's maximum (the
    earlier reference, their median, moved with them); the band of the cut still starts at
    2 kHz and ends where the whole record's does (the coherence ends both)."""
    ds = _spectra()
    whole = bd.analysis_band(ds)
    cut = bd.analysis_band(ds.sel({names.FREQUENCY: slice(2000.0, 6000.0)}))
    assert cut.fmin == 2000.0
    assert abs(cut.fmax - whole.fmax) <= 5000.0 / 32 + 1


def _record(f, gff, coh):
    return xr.Dataset(
        {
            names.FORCE_AUTOSPECTRUM: (names.FREQUENCY, gff),
            names.COHERENCE: ((names.POINT, names.FREQUENCY), coh[None, :]),
        },
        coords={names.FREQUENCY: f, names.POINT: ["a"]},
    )


def test_a_long_coherence_gap_inside_the_band_keeps_both_sides():
    """A quiet range between modes (coherence 0.3 over 400-900 Hz, force flat): the band
    spans both sides of it; the longest run (the rule before issue 37) kept only 900-2000."""
    f = np.arange(0.0, 2001.0)
    coh = np.where((f > 400) & (f < 900), 0.3, 0.99)
    coh[f < 5] = 0.1
    band = bd.analysis_band(_record(f, np.ones(f.size), coh))
    assert band.fmin <= 10.0 and band.fmax == 2000.0
    assert bd.longest_run(bd.valid_lines(f, np.ones(f.size), coh[None])[0])[0] > 850


def test_a_weak_force_at_the_low_end_joins_the_band_where_the_coherence_holds():
    """A sweep's force 28 dB below its peak at 2-8 Hz, the response clean there (coherence
    0.99 without a gap): the lowest modes are in the band. Without the coherence (the force
    rule alone) they are not. Past a gap (coherence 0.3 at 1-2 Hz) nothing more joins."""
    f = np.arange(0.0, 50.0, 0.05)
    gff = np.where(f < 8.0, 10 ** (-2.8), 1.0)
    coh = np.where(f < 1.0, 0.99, np.where(f < 2.0, 0.3, 0.99))
    band = bd.analysis_band(_record(f, gff, coh))
    assert 1.9 <= band.fmin <= 2.3 and band.fmax == f[-1]
    alone = bd.analysis_band(_record(f, gff, coh).drop_vars(names.COHERENCE))
    assert alone.fmin >= 7.5


def test_a_weak_force_at_the_top_never_joins_the_band():
    """A force rolling off 30 dB past 30 Hz (a sweep's end, a hammer tip) with the coherence
    still high there (the structure answers the harmonics): the band ends with the force's
    20 dB point."""
    f = np.arange(0.0, 50.0, 0.05)
    gff = np.where(f > 30.0, 1e-3, 1.0)
    band = bd.analysis_band(_record(f, gff, np.full(f.size, 0.99)))
    assert 29.0 <= band.fmax <= 31.0


def test_the_coherence_of_the_points_that_respond_judges_a_line():
    # second highest over the points: two clean points carry a line, one does not
    coh = np.array([[0.1, 0.9, 0.95], [0.2, 0.1, 0.9], [0.95, 0.1, 0.1], [np.nan, 0.2, 0.3]])
    np.testing.assert_allclose(bd.clean_coherence(coh), [0.2, 0.2, 0.9])
    np.testing.assert_allclose(bd.clean_coherence(coh[:2]), [0.2, 0.9, 0.95])  # of two: highest
    np.testing.assert_allclose(bd.clean_coherence(coh[:1]), [0.1, 0.9, 0.95])


def test_a_mode_clean_at_two_points_of_six_stays_in_the_band():
    # a velocity sensor's FRFs: above 25 Hz only points 4 and 5 stand clear of their noise (a
    # mode there, the others near its nodes); the median over points used to cut the band
    f = np.linspace(0.0, 64.0, 4097)
    coh = np.full((6, f.size), 0.95)
    coh[:4, f > 25.0] = 0.05
    gff = np.ones(f.size)
    ok, _ = bd.valid_lines(f, gff, coh, n_averages=15)
    assert ok[(f > 30.0) & (f < 60.0)].all()
    coh[4, f > 25.0] = 0.05  # one clean point is not enough (crosstalk on one channel)
    ok, _ = bd.valid_lines(f, gff, coh, n_averages=15)
    assert not ok[(f > 30.0) & (f < 60.0)].any()
