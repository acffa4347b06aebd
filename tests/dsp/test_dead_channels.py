"""Dead channels (issue 9, item 6): a force or response channel that is zero or constant is an
error naming the channel, in memory and while streaming a file; an impact hit without a force
pulse is rejected with a reason."""

from __future__ import annotations

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.dsp.hits import check_hits
from ami_xr.errors import AmiXrValueError

from ..reference import two_point_time_dataset

FS = 256.0


def _time_ds(force, response, **attrs):
    return two_point_time_dataset(force, response, FS, **attrs)


@pytest.fixture
def signals():
    rng = np.random.default_rng(0)
    return rng.standard_normal(2048), rng.standard_normal((2, 2048))


@pytest.mark.parametrize("value", [0.0, 1.5])
@pytest.mark.parametrize("function", [ami_xr.frf, ami_xr.impact_frf])
def test_dead_force_channel_is_an_error(signals, function, value):
    _, y = signals
    ds = _time_ds(np.full(y.shape[1], value), y)
    with pytest.raises(AmiXrValueError, match=r"force: the force channel is zero/constant"):
        function(ds)


def test_dead_response_channel_names_the_point(signals):
    f, y = signals
    y = y.copy()
    y[1] = 0.0
    with pytest.raises(AmiXrValueError, match=r"response: .*point\(s\) \[1\].*drop_sel"):
        ami_xr.frf(_time_ds(f, y))


def test_dead_channel_found_while_streaming_a_file(signals, tmp_path):
    f, y = signals
    path = tmp_path / "dead.nc"
    ami_xr.to_netcdf(_time_ds(np.zeros_like(f), y), path)
    lazy = ami_xr.open_dataset(path, chunks={names.TIME: 500})
    with pytest.raises(AmiXrValueError, match=r"force: the force channel is zero/constant"):
        ami_xr.frf(lazy, nperseg=256)
    good = tmp_path / "good.nc"
    ami_xr.to_netcdf(_time_ds(f, y), good)
    out = ami_xr.frf(ami_xr.open_dataset(good, chunks={names.TIME: 500}), nperseg=256)
    assert np.all(np.isfinite(out[names.FRF].values))


def test_hit_check_rejects_a_zero_force_hit():
    rng = np.random.default_rng(1)
    force = np.zeros((1, 1, 512))
    response = rng.standard_normal((1, 2, 512))
    rejected, reasons, peak, _ = check_hits(force, response)
    assert rejected.tolist() == [True]
    assert reasons[0].startswith("no force") and peak[0] == 0.0


def test_impact_hit_without_a_pulse_is_rejected_and_listed():
    # two hits: a real pulse, and a force stuck at an offset (constant, not below the median
    # ratio, zero noise), which used to be accepted and averaged in
    n = 1024
    t = np.arange(n)
    good = np.where(t < 8, np.sin(np.pi * t / 8), 0.0)
    force = np.stack([good, np.full(n, 0.5)])
    rng = np.random.default_rng(2)
    response = rng.standard_normal((2, 2, n))
    ds = ami_xr.make_time_dataset(
        response,
        fs=FS,
        force=force,
        points=[0, 1],
        drive_point=0,
        response_quantity="displacement",
        response_units="m",
        force_units="N",
    )
    out = ami_xr.impact_frf(ds)
    assert out[names.HIT_REJECTED].values.tolist() == [False, True]
    assert str(out[names.HIT_REJECT_REASON].values[1]).startswith("no force")
