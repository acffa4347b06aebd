"""The refinement's line shape reads at most ``MAX_ROWS`` rows of the stored noise std (issue 42:
a lazy set of many points is not loaded whole for a median over points)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from ami_xr import names
from ami_xr.ami import line_noise
from ami_xr.ami.line_noise import MAX_ROWS, line_noise_shape

P, F = names.POINT, names.FREQUENCY


def _std(n_point: int, groups: list[str] | None = None):
    f = np.linspace(1.0, 100.0, 300)
    trend_a = (1.0 + f / 10.0) ** -1.0
    trend_b = np.linspace(1.0, 3.0, f.size)
    level = np.exp(np.linspace(-2.0, 2.0, n_point))[:, None]  # every point its own level
    g = np.array(groups) if groups is not None else np.array(["a"] * n_point)
    sd = level * np.where((g == "a")[:, None], trend_a[None, :], trend_b[None, :])
    ds = xr.Dataset({names.FRF_LINE_NOISE_STD: ((P, F), sd)}, coords={F: f})
    coords = {F: f} if groups is None else {F: f, line_noise.NOISE_GROUP: (P, g)}
    frf = xr.DataArray(np.zeros(sd.shape), dims=(P, F), coords=coords)
    return ds, frf, trend_a / np.median(trend_a), trend_b / np.median(trend_b)


def test_many_points_give_the_shape_from_a_subset():
    ds, frf, a, _ = _std(5 * MAX_ROWS)
    shape, group = line_noise_shape(ds, frf)
    assert group is None
    np.testing.assert_allclose(shape, a, rtol=1e-12)


def test_groups_each_keep_their_shape_and_every_point_its_group():
    n = 3 * MAX_ROWS
    groups = ["b"] * 5 + ["a"] * (n - 5)  # a small group is still read
    ds, frf, a, b = _std(n, groups)
    shapes, group = line_noise_shape(ds, frf)
    assert group.shape == (n,) and set(group[:5]) == {1} and set(group[5:]) == {0}
    np.testing.assert_allclose(shapes[0], a, rtol=1e-12)
    np.testing.assert_allclose(shapes[1], b, rtol=1e-12)


def test_a_lazy_std_gives_the_same_shape_reading_few_rows(monkeypatch):
    pytest.importorskip("dask")
    ds, frf, a, _ = _std(4 * MAX_ROWS)
    lazy = ds.chunk({P: 64})
    read = []
    rows = line_noise.ch.rows

    def counted(da, index):
        read.append(len(index))
        return rows(da, index)

    monkeypatch.setattr(line_noise.ch, "rows", counted)
    eager, _ = line_noise_shape(ds, frf)
    shape, _ = line_noise_shape(lazy, frf)
    np.testing.assert_array_equal(shape, eager)
    assert read and max(read) <= MAX_ROWS
