"""Streaming memory: a lazily opened record's time axis costs O(1) memory, not 8 B per sample.

``ami_xr.open_dataset(path, chunks=...)`` replaces a uniform stored ``time`` coordinate by an
``xarray.indexes.RangeIndex``; ``validate``, ``frf`` and ``sample_interval`` then read its start
and step and never compute the values. These tests check the values against the stored ones,
that nothing on the streaming path materialises the axis, and the fallbacks.
"""

from __future__ import annotations

import tracemalloc

import netCDF4
import numpy as np
import pytest
import xarray as xr
from xarray.indexes import PandasIndex, RangeIndex
from xarray.indexes.range_index import RangeCoordinateTransform

import ami_xr
from ami_xr import names
from ami_xr.dsp.windows import sample_interval
from ami_xr.errors import SchemaError

from ..reference import forbid_compute

dask = pytest.importorskip("dask")

RECORD_FS = 1000.0  # Hz, the sampling rate of the long test records


def _record(n: int, *, t0: float = 0.0, seed: int = 0) -> xr.Dataset:
    rng = np.random.default_rng(seed)
    ds = ami_xr.make_time_dataset(
        rng.standard_normal((2, n)), fs=RECORD_FS, force=rng.standard_normal(n), drive_point=0
    )
    if t0:
        # keep attrs explicitly: arithmetic drops them on older xarray (seen on 2025.4)
        ds = ds.assign_coords(
            {names.TIME: (ds[names.TIME] + t0).assign_attrs(ds[names.TIME].attrs)}
        )
    return ds


def _stored_time(path) -> np.ndarray:
    from ami_xr.io import cf

    with netCDF4.Dataset(path) as nc:
        disk = cf.on_disk_name(nc.getncattr(cf.ATTR_CF_ADDED), names.TIME)  # elapsed_time
        return np.asarray(nc.variables[disk][:], np.float64)


@pytest.fixture
def computed_positions(monkeypatch):
    """How many time values each computation of a RangeIndex coordinate produced."""
    sizes: list[int] = []
    forward = RangeCoordinateTransform.forward

    def counting(self, dim_positions):
        sizes.append(int(np.size(dim_positions[self.dim])))
        return forward(self, dim_positions)

    monkeypatch.setattr(RangeCoordinateTransform, "forward", counting)
    return sizes


@pytest.mark.parametrize("t0", [0.0, 12.345, -3.0])
def test_lazy_open_gives_range_index_equal_to_stored_values(tmp_path, t0):
    n = 50_001
    path = ami_xr.to_netcdf(_record(n, t0=t0), tmp_path / "rec.nc")
    lazy = ami_xr.open_dataset(path, chunks={names.TIME: 4096})
    index = lazy.xindexes[names.TIME]
    assert isinstance(index, RangeIndex) and index.size == n
    stored = _stored_time(path)
    scale = np.abs(stored).max()
    # the RangeIndex computes start + k * step; the stored values were computed as t0 + k / fs: they
    # differ by a few roundings of the largest time (atol relative to it: values near t = 0 have no
    # relative accuracy to offer)
    np.testing.assert_allclose(lazy[names.TIME].values, stored, rtol=0, atol=1e-12 * scale)
    assert lazy[names.TIME].dtype == np.float64
    eager = ami_xr.open_dataset(path)
    assert lazy[names.TIME].attrs == eager[names.TIME].attrs == {names.ATTR_UNITS: "s"}
    # eager opens are unchanged: an ordinary index holding exactly the stored values
    assert isinstance(eager.xindexes[names.TIME], PandasIndex)
    # an eager open reads the stored values: no arithmetic
    np.testing.assert_array_equal(eager[names.TIME].values, stored)
    # positional slices stay O(1) RangeIndexes with the right values
    part = lazy.isel({names.TIME: slice(1000, 3000)})
    assert isinstance(part.xindexes[names.TIME], RangeIndex)
    # as above: start + k * step vs the stored values, a few roundings of the largest time
    np.testing.assert_allclose(part[names.TIME].values, stored[1000:3000], atol=1e-12 * scale)
    # data variables are read identically; only the time coordinate differs by the rounding above
    # (times are far from 0 except at the first samples, which agree exactly)
    xr.testing.assert_allclose(lazy.compute(), eager, rtol=1e-12)


def test_open_reads_no_values_and_holds_no_axis_array(tmp_path):
    n = 2_000_000  # a pandas index would be 16 MB
    path = ami_xr.to_netcdf(_record(n), tmp_path / "long.nc")
    tracemalloc.start()
    try:
        with dask.config.set(scheduler=forbid_compute):
            lazy = ami_xr.open_dataset(path, chunks={names.TIME: 2**16})
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert isinstance(lazy.xindexes[names.TIME], RangeIndex)
    assert peak < n * 8 / 8, f"opening allocated {peak / 2**20:.1f} MiB"


def test_validate_and_sampling_read_no_time_values(tmp_path, computed_positions):
    n = 100_000
    path = ami_xr.to_netcdf(_record(n), tmp_path / "rec.nc")
    lazy = ami_xr.open_dataset(path, chunks={names.TIME: 8192})
    computed_positions.clear()  # the open itself computes the probed positions only
    with dask.config.set(scheduler=forbid_compute):
        assert ami_xr.validate(lazy, "time", check_values=False) is lazy
        dt = sample_interval(lazy)
    assert computed_positions == []
    # the step of the range index, a few roundings of 1 / fs
    assert dt == pytest.approx(1 / RECORD_FS, rel=1e-12)
    ami_xr.validate(lazy, "time")  # the value scan reads data chunks, never the time axis
    assert computed_positions == []


def test_validate_reports_a_decreasing_range_axis():
    ds = _record(100)
    axis = xr.Coordinates.from_xindex(RangeIndex.linspace(1.0, 0.0, 100, dim=names.TIME))
    axis[names.TIME].attrs[names.ATTR_UNITS] = "s"
    bad = ds.drop_vars(names.TIME).assign_coords(axis)
    with pytest.raises(SchemaError, match=r"strictly increasing values, got a range with step"):
        ami_xr.validate(bad, "time")


def test_frf_from_lazy_file_equals_in_memory_without_materialising_time(
    tmp_path, computed_positions
):
    n = 60_000
    ds = _record(n, seed=3)
    path = ami_xr.to_netcdf(ds, tmp_path / "rec.nc")
    lazy = ami_xr.open_dataset(path, chunks={names.TIME: 7001})
    assert isinstance(lazy.xindexes[names.TIME], RangeIndex)
    computed_positions.clear()
    kw = dict(nperseg=512, noverlap=256)
    streamed = ami_xr.frf(lazy, "H1", **kw)
    assert max(computed_positions, default=0) == 0
    mem = ami_xr.frf(ds, "H1", **kw)
    assert streamed.attrs[names.ATTR_N_AVERAGES] == mem.attrs[names.ATTR_N_AVERAGES]
    for v in (names.FRF, names.COHERENCE):
        # the same samples and segments; only the sampling rate comes from the range index (a few
        # ulp), which scales the spectra identically on both sides up to that rounding; no FRF or
        # coherence value near zero (random data)
        np.testing.assert_allclose(streamed[v].values, mem[v].values, rtol=1e-12)


def _write_time(path, t: np.ndarray, dtype=np.float64) -> None:
    ds = _record(t.size)
    ds = ds.assign_coords({names.TIME: (names.TIME, t.astype(dtype), {names.ATTR_UNITS: "s"})})
    ami_xr.to_netcdf(ds, path)


@pytest.mark.parametrize(
    "case",
    ["second step off", "middle value off", "last value nan", "float32", "cumulative rounding"],
)
def test_non_uniform_time_falls_back_to_stored_values(tmp_path, case):
    n = 20_001
    t = np.arange(n) / RECORD_FS
    dtype = np.float64
    if case == "second step off":
        t[1] += 1e-7 / RECORD_FS
    elif case == "middle value off":
        t[10_000] += 1e-9  # lies on the probe stride
    elif case == "last value nan":
        t[-1] = np.nan
    elif case == "float32":
        dtype = np.float32
    elif case == "cumulative rounding":  # accumulated error far beyond rounding of i * dt
        t = np.cumsum(np.full(n, 1e-3 * (1 + 1e-9)))
    path = tmp_path / "t.nc"
    _write_time(path, t, dtype)
    lazy = ami_xr.open_dataset(path, chunks={names.TIME: 4096})
    assert isinstance(lazy.xindexes[names.TIME], PandasIndex)
    # non-uniform axes fall back to the stored values: read, not computed
    np.testing.assert_array_equal(lazy[names.TIME].values, _stored_time(path).astype(dtype))
    assert lazy[names.TIME].attrs == {names.ATTR_UNITS: "s"}
