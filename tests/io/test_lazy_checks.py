"""Issue 42 items 4 and 6: the input checks of identify reduce a lazy FRF chunk by chunk.

``ami_xr.ami.common.check_frf`` (and through it ``schema.parts.check_finite``) computes only
reductions of a dask-backed FRF: no task result is ever the whole array. A lazy FRF in several
chunks along ``frequency`` is rechunked by the tool (xarray refused a core dim in several
chunks).
"""

from __future__ import annotations

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami import common

dask = pytest.importorskip("dask")
from dask.callbacks import Callback  # noqa: E402


class _Largest(Callback):
    """Records the largest task result (bytes) of the computations it watches."""

    def __init__(self) -> None:
        super().__init__()
        self.largest = 0

    def _posttask(self, key, result, dsk, state, worker_id) -> None:
        self.largest = max(self.largest, int(getattr(result, "nbytes", 0) or 0))


@pytest.fixture(scope="module")
def frf():
    g, _ = ami_xr.simulate.random_system(
        n_points=40, noise=0.02, seed=2, n_frequencies=1024
    )
    return g


def test_check_frf_never_materialises_a_lazy_frf(frf):
    lazy = frf.chunk({names.POINT: 4})
    whole = lazy[names.FRF].nbytes
    with _Largest() as seen, dask.config.set(scheduler="sync"):
        checked = common.check_frf(lazy, "identify")
    assert dask.is_dask_collection(checked[names.FRF].data)  # still lazy
    assert 0 < seen.largest <= whole / 8, (seen.largest, whole)


def test_bad_values_of_a_lazy_frf_are_named_per_point_without_materialising(frf):
    values = frf[names.FRF].values.copy()
    values[7, 100] = np.nan
    values[31, 3:5] = np.inf
    lazy = frf.assign({names.FRF: frf[names.FRF].copy(data=values)}).chunk({names.POINT: 4})
    with _Largest() as seen, dask.config.set(scheduler="sync"):
        with pytest.raises(ami_xr.errors.SchemaError, match=r"found 3 NaN or inf .* at 2 point"):
            common.check_frf(lazy, "identify")
    assert seen.largest <= lazy[names.FRF].nbytes / 8
    eager = []
    from ami_xr.schema.parts import check_finite

    check_finite(frf[names.FRF].copy(data=values), "frf", eager)
    assert "7: 1" in eager[0] and "31: 2" in eager[0]


def test_a_lazy_frf_in_frequency_chunks_is_rechunked_by_the_tool(frf, tmp_path):
    path = tmp_path / "frf.nc"
    ami_xr.to_netcdf(frf, path)
    lazy = ami_xr.open_dataset(path, chunks={names.POINT: 10, names.FREQUENCY: 100})
    checked = common.check_frf(lazy, "identify")
    assert len(checked[names.FRF].chunks[1]) == 1
    assert checked[names.FRF].chunks[0] == (10, 10, 10, 10)
    out = ami_xr.identify(lazy, refine=False)
    assert out.sizes.get(names.MODE, 0) >= 1
    lazy.close()
