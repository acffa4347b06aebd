"""Modes sorted by frequency with contiguous labels; no silent cap (the flags the refinement
supersedes: tests/ami/test_flags.py)
(issue 10, items 2 and 5)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami import common as c
from ami_xr.core import flags
from ami_xr.errors import ConvergenceWarning
from ami_xr.io.formats import read_any

from ..reference import SHARED_DATA


def test_max_modes_cap_warns_and_is_recorded():
    ds, truth = ami_xr.simulate.random_system(seed=1, n_points=5, n_frequencies=1024)
    assert truth.sizes[names.MODE] > 2
    # without the refinement the candidate cap decides the mode count: warned and recorded
    # (with it, the refinement completes the model and the cap is superseded: test_overlap.py)
    with pytest.warns(ConvergenceWarning, match=r"cap of max_modes=2 candidates"):
        out = ami_xr.identify(ds, max_modes=2, refine=False)
    assert "subtract:max_modes" in flags.run_status(out.attrs).entries
    assert "max_modes" in set(out[names.SUB_STOP_REASON].values.astype(str))


def test_no_cap_no_warning_and_empty_record():
    ds, _ = ami_xr.simulate.random_system(seed=1, n_points=5, n_frequencies=1024)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConvergenceWarning)
        s = ami_xr.subtract(ds)
    assert s.attrs[names.ATTR_AMI_CAPPED] == 0


def test_identify_labels_sorted_and_contiguous():
    """A case whose refinement drops a mode: labels used to keep the gap (1, 2, 3, 4, 6, ...)."""
    ds, _ = ami_xr.simulate.random_system(
        seed=3, closely_spaced=True, noise=0.02, n_frequencies=2000
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = ami_xr.identify(ds, method="per_frf")
    n = out.sizes[names.MODE]
    np.testing.assert_array_equal(out[names.MODE].values, np.arange(1, n + 1))
    np.testing.assert_array_equal(out[names.MODE_2].values, np.arange(1, n + 1))
    assert np.all(np.diff(out[names.NATURAL_FREQUENCY].values) >= 0)
    before = out[names.MODE_LABEL_UNSORTED].values
    assert before.size == n and np.any(before != np.arange(1, n + 1))  # the gap was there


def _modes(fn, flags):
    n = len(fn)
    labels = np.array([1, 2, 4][:n])
    mac = np.arange(n * n, dtype=float).reshape(n, n)
    return xr.Dataset(
        {
            names.NATURAL_FREQUENCY: ((names.MODE,), np.asarray(fn, float)),
            names.QUALITY_FLAGS: ((names.MODE,), np.array(flags, dtype=str)),
            names.MAC: ((names.MODE, names.MODE_2), mac),
            names.RESIDUE: ((names.POINT, names.MODE), np.ones((2, n)) * np.asarray(fn)),
        },
        coords={names.MODE: labels, names.MODE_2: labels, names.POINT: [0, 1]},
    )


def test_sort_modes_reorders_every_mode_variable():
    ds = _modes([30.0, 10.0, 20.0], ["a", "b", "c"])
    out = c.sort_modes(ds)
    np.testing.assert_array_equal(out[names.NATURAL_FREQUENCY].values, [10.0, 20.0, 30.0])
    np.testing.assert_array_equal(out[names.MODE].values, [1, 2, 3])
    np.testing.assert_array_equal(out[names.MODE_LABEL_UNSORTED].values, [2, 4, 1])
    np.testing.assert_array_equal(out[names.QUALITY_FLAGS].values, ["b", "c", "a"])
    np.testing.assert_array_equal(out[names.RESIDUE].values[0], [10.0, 20.0, 30.0])
    # MAC rows and columns follow: old (mode 2, mode 4) is new (1, 2)
    assert out[names.MAC].values[0, 1] == ds[names.MAC].values[1, 2]


def test_drop_outside_band():
    out, dropped = c.drop_outside_band(_modes([30.0, 10.0, 20.0], ["", "", ""]), 15.0, 35.0)
    np.testing.assert_array_equal(out[names.NATURAL_FREQUENCY].values, [30.0, 20.0])
    np.testing.assert_array_equal(dropped, [10.0])
    assert out.sizes[names.MODE_2] == 2


@pytest.mark.skipif(not (SHARED_DATA / "measurement.uff").exists(), reason="no shared data")
def test_measurement_uff_sorted_contiguous():
    ds = read_any(SHARED_DATA / "measurement.uff")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = ami_xr.identify(ds)
    n = out.sizes[names.MODE]
    np.testing.assert_array_equal(out[names.MODE].values, np.arange(1, n + 1))
    assert np.all(np.diff(out[names.NATURAL_FREQUENCY].values) > 0)
    # the subtraction ends on its cap of examined peaks there; the refinement then completes
    # the model by its statistics, so the cap is recorded as superseded, not silent
    caps = flags.run_status(out.attrs, names.ATTR_AMI_CAPPED_SUPERSEDED) | flags.run_status(
        out.attrs
    )
    assert "subtract:max_rejected_peaks" in caps.entries
