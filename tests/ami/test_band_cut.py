"""``identify(ds.sel(frequency=slice(a, b)))`` equals ``identify(ds, fmin=a, fmax=b)`` wherever
``[a, b]`` lies inside the valid band (issue 20, item 4): the excitation band of the cut data
is the whole cut, so both analyse the same lines."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.dsp import band as bd

from ..reference import HAMMER_LVM

FC = 20.0  # Hz: the force falls as 1 / (1 + (f / FC)^8), 20 dB below its maximum at 35.5 Hz


def _measured():
    """A simulated FRF made "measured": a band-limited force (FRF noise grows as the force falls)
    and coherence 0.99 up to 45 Hz (0.4 above)."""
    ds, truth = ami_xr.simulate.random_system(seed=1, n_points=5, n_frequencies=1024)
    f = ds[names.FREQUENCY].values
    gff = 1.0 / (1.0 + (f / FC) ** 8)
    rng = np.random.default_rng(0)
    peak = float(np.abs(ds[names.FRF]).max())
    shape = ds[names.FRF].shape
    noise = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    coh = np.where(f <= 45.0, 0.99, 0.4) * np.ones((ds.sizes[names.POINT], 1))
    ds = ds.assign(
        {
            names.FRF: ds[names.FRF] + 1e-3 * peak * noise / np.sqrt(gff),
            names.FORCE_AUTOSPECTRUM: ((names.FREQUENCY,), gff),
            names.COHERENCE: ((names.POINT, names.FREQUENCY), coh),
        }
    )
    return ds, truth


def _identify(ds, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ami_xr.identify(ds, **kw)


def _same_modes(one, two):
    lam1 = np.sort_complex(one[names.EIGENVALUE].values)
    lam2 = np.sort_complex(two[names.EIGENVALUE].values)
    assert lam1.size == lam2.size, (lam1, lam2)
    np.testing.assert_allclose(lam1, lam2, rtol=1e-8, atol=0)


@pytest.mark.parametrize("a, b", [(2.0, 30.0), (8.0, 35.0)])
def test_sel_equals_fmin_fmax_on_a_simulated_measurement(a, b):
    ds, _ = _measured()
    whole = bd.analysis_band(ds)
    assert whole.fmin <= a and b <= whole.fmax  # the cut lies inside the valid band
    cut = ds.sel({names.FREQUENCY: slice(a, b)})
    band = bd.analysis_band(cut)
    f = cut[names.FREQUENCY].values
    assert (band.fmin, band.fmax, band.rule) == (f[0], f[-1], bd.RULE_EXCITATION)
    by_sel = _identify(cut)
    by_limits = _identify(ds, fmin=a, fmax=b)
    assert by_sel.sizes[names.MODE] >= 2
    _same_modes(by_sel, by_limits)
    # the same lines analysed: the cut's band is its own first and last line, the user's [a, b]
    assert (by_sel.attrs[names.ATTR_BAND_FMIN], by_sel.attrs[names.ATTR_BAND_FMAX]) == (f[0], f[-1])
    assert (by_limits.attrs[names.ATTR_BAND_FMIN], by_limits.attrs[names.ATTR_BAND_FMAX]) == (a, b)
    np.testing.assert_array_equal(by_sel[names.FREQUENCY], by_limits[names.FREQUENCY])


@pytest.mark.slow
@pytest.mark.skipif(not HAMMER_LVM.is_file(), reason="../shared/data (measured files) is absent")
def test_sel_equals_fmin_fmax_on_the_hammer_test():
    """The case of issue 20: sliced to 20-4885 Hz the band was 20-1614 Hz and 12 modes came out
    instead of 21; now the cut's band is the whole cut and the modes are the same."""
    ts = ami_xr.read_lvm(HAMMER_LVM, drive_point="Acceleration (Trigger)")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        h = ami_xr.impact_frf(ts).load()
    a, b = 20.0, 4885.0
    cut = h.sel({names.FREQUENCY: slice(a, b)})
    band = bd.analysis_band(cut)
    assert (band.fmin, band.fmax) == (a, b)
    whole = bd.analysis_band(h)
    assert whole.fmin <= a and 4800.0 < whole.fmax
    by_sel = _identify(cut)
    by_limits = _identify(h, fmin=a, fmax=b)
    assert by_sel.sizes[names.MODE] >= 15
    _same_modes(by_sel, by_limits)
