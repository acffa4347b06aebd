"""Issue 24 item 8: the default segment length on a long record says how few lines it leaves
and which ``nperseg`` gives a few hundred."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr.errors import AssumptionWarning


def _random_test(n: int, fs: float = 1000.0):
    rng = np.random.default_rng(2)
    force = rng.standard_normal(n)
    t = np.arange(256) / fs
    h = np.exp(-30 * t) * np.sin(2 * np.pi * 80 * t)
    return ami_xr.make_time_dataset(
        np.convolve(force, h)[:n], fs=fs, force=force, response_quantity="displacement"
    )


def test_a_long_record_with_the_default_nperseg_warns():
    ds = _random_test(60_000)  # 60 s at 1 kHz: 256-sample segments give 129 lines 3.9 Hz apart
    with pytest.warns(AssumptionWarning, match=r"nperseg=256 gives 129 lines .*nperseg=4096"):
        g = ami_xr.frf(ds)
    assert g.sizes["frequency"] == 129


@pytest.mark.parametrize("kwargs", [{"nperseg": 256}, {"nperseg": 4096}])
def test_a_given_nperseg_is_not_questioned(kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)
        ami_xr.frf(_random_test(60_000), **kwargs)


def test_a_short_record_is_not_warned():
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)
        ami_xr.frf(_random_test(2048))  # 8 segments of 256 already


def test_the_advice_points_to_identify_for_the_lightest_damped_mode():
    """The segment length that resolves a mode depends on its damping, which frf does not
    know: its advice says that identify names it (tests/ami/test_resolution_flag.py)."""
    with pytest.warns(AssumptionWarning, match=r"under_resolved\) and names the nperseg"):
        ami_xr.frf(_random_test(60_000))
