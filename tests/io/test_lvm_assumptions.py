"""Issue 12, items 2 and 3: the drive point an LVM reader assumes is reported and recorded, and
one rule (``excitation_of``) tells hammer hits from random excitation for Python and the CLI."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.dsp.frf import frf_from_options
from ami_xr.dsp.timeseries import excitation_of
from ami_xr.errors import AmiXrValueError, AssumptionWarning
from ami_xr.io.formats import read_any

from ..reference import HAMMER_LVM
from .test_lvm import _write

N, DT = 1000, 0.001


def hit_rows(peak: float) -> list[tuple[float, float]]:
    """One hammer hit: a 5-sample half-sine force pulse and a decaying 50 Hz response."""
    t = np.arange(N) * DT
    force = np.zeros(N)
    force[10:15] = peak * np.sin(np.pi * (np.arange(5) + 0.5) / 5)
    resp = np.convolve(force, np.exp(-8 * t) * np.sin(2 * np.pi * 50 * t))[:N]
    return list(zip(force, resp, strict=True))


def random_rows(seed: int) -> list[tuple[float, float]]:
    rng = np.random.default_rng(seed)
    force = rng.standard_normal(N)
    return list(zip(force, np.convolve(force, [0.5, 0.3, 0.2])[:N], strict=True))


@pytest.fixture
def hits_lvm(tmp_path):
    return _write(tmp_path / "hits.lvm", [hit_rows(p) for p in (100.0, 110.0, 95.0)])


@pytest.fixture
def random_lvm(tmp_path):
    return _write(tmp_path / "random.lvm", [random_rows(s) for s in (1, 2, 3)])


def _quiet_read(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AssumptionWarning)
        return ami_xr.read_lvm(path, **kw)


# --- item 3: the drive point -----------------------------------------------------------------
def test_assumed_drive_point_is_warned_once_and_recorded(hits_lvm):
    with pytest.warns(AssumptionWarning, match=r"drive point assumed .*drive_point") as seen:
        ds = ami_xr.read_lvm(hits_lvm)
    assert sum(issubclass(w.category, AssumptionWarning) for w in seen) == 1
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "Acceleration (Trigger)"
    assert ds.attrs[names.ATTR_DRIVE_POINT_ASSUMED] == "the single response channel"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AssumptionWarning)
        g = ami_xr.impact_frf(ds)
    assert g.attrs[names.ATTR_DRIVE_POINT_ASSUMED] == "the single response channel"


def test_a_given_drive_point_is_not_reported(hits_lvm):
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)
        ds = ami_xr.read_lvm(hits_lvm, points=["tip"], drive_point="tip", force_channel=0)
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "tip"
    assert names.ATTR_DRIVE_POINT_ASSUMED not in ds.attrs
    assert list(ds[names.POINT].values) == ["tip"]


def test_a_drive_point_that_is_no_point_is_refused(hits_lvm):
    with pytest.raises(AmiXrValueError, match=r"drive_point: 'root' is not one of the points"):
        ami_xr.read_lvm(hits_lvm, points=["tip"], drive_point="root")


def test_read_any_passes_channel_options_to_lvm_and_refuses_them_elsewhere(hits_lvm, tmp_path):
    ds = read_any(hits_lvm, points=["tip"], drive_point="tip")
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "tip"
    nc = ami_xr.to_netcdf(_quiet_read(hits_lvm), tmp_path / "hits.nc")
    for kw, match in (
        ({"points": ["a"]}, "points: only for LabVIEW"),
        ({"force_channel": 0}, "force_channel: only"),
    ):
        with pytest.raises(AmiXrValueError, match=match):
            read_any(nc, **kw)
    again = read_any(nc, drive_point="Acceleration (Trigger)")
    assert again.attrs[names.ATTR_DRIVE_POINT] == "Acceleration (Trigger)"
    assert names.ATTR_DRIVE_POINT_ASSUMED not in again.attrs  # given now: no longer an assumption
    with pytest.raises(AmiXrValueError, match="drive_point: 'x' is not one of the points"):
        read_any(nc, drive_point="x")


# --- item 2: one rule for the excitation ----------------------------------------------------
def test_excitation_rule_looks_at_the_force_not_the_record_dim(hits_lvm, random_lvm):
    hits, rand = _quiet_read(hits_lvm), _quiet_read(random_lvm)
    assert names.RECORD in hits.dims and names.RECORD in rand.dims
    assert excitation_of(hits) == "impact"
    assert excitation_of(rand) == "random"  # random blocks as records: not hits
    assert excitation_of(hits.isel({names.RECORD: 0})) == "impact"  # one hit, no record dim
    assert excitation_of(hits.drop_vars(names.FORCE)) == "random"


@pytest.mark.skipif(not HAMMER_LVM.is_file(), reason="shared/data folder absent")
def test_the_measured_hammer_file_is_an_impact_test():
    assert excitation_of(_quiet_read(HAMMER_LVM)) == "impact"


def test_frf_warns_on_hammer_hits_and_points_to_impact_frf(hits_lvm, random_lvm):
    with pytest.warns(
        AssumptionWarning, match=r"short pulse .*18 segments of 256 samples.*impact_frf"
    ):
        ami_xr.frf(_quiet_read(hits_lvm))
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)
        ami_xr.frf(_quiet_read(random_lvm))


def test_frf_from_options_without_excitation_uses_the_same_rule(hits_lvm, random_lvm):
    hits, rand = _quiet_read(hits_lvm), _quiet_read(random_lvm)
    xr.testing.assert_equal(frf_from_options(hits, {}), ami_xr.impact_frf(hits))
    xr.testing.assert_equal(frf_from_options(rand, {}), ami_xr.frf(rand))
    with pytest.raises(AmiXrValueError, match="excitation: expected one of"):
        frf_from_options(hits, {"excitation": "sweep"})
