"""Issue 42 item 6: the compressed path reads a lazy FRF set as few times as it can.

* the noise scales of the compression are found once, in its first pass (each later pass
  reused them; before, every pass recomputed them from each chunk);
* the guard: a lazy set gives the in-memory set's results (rtol 1e-10).

Counts of calls on the synchronous scheduler, never time.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.core import compress as cz
from ami_xr.simulate.spread import many_points

dask = pytest.importorskip("dask")

CHUNK = 70


@pytest.fixture(scope="module")
def four_hundred():
    ds, _ = many_points(400, 256, 5, noise=0.02, seed=4)
    return ds


def _identify(ds, **kw):
    with warnings.catch_warnings(), dask.config.set(scheduler="synchronous"):
        warnings.simplefilter("ignore")
        return ami_xr.identify(ds, **kw)


def _counting(monkeypatch, module, name) -> list:
    calls: list = []
    real = getattr(module, name)

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)
    return calls


def test_noise_scales_are_found_once(monkeypatch, four_hundred):
    calls = _counting(monkeypatch, cz, "noise_scale")
    ds = four_hundred.chunk({names.POINT: CHUNK})
    n_chunks = len(ds.chunksizes[names.POINT])
    out = _identify(ds, compress=24)
    assert out.sizes[names.MODE] >= 4
    # the first pass, one call per chunk (two passes made two per chunk before)
    assert len(calls) == n_chunks, (len(calls), n_chunks)


def test_lazy_equals_in_memory_on_the_compressed_path(four_hundred):
    mem = _identify(four_hundred, compress=24)
    lazy = _identify(four_hundred.chunk({names.POINT: CHUNK}), compress=24)
    assert lazy.sizes[names.MODE] == mem.sizes[names.MODE] >= 4
    for v in (
        names.EIGENVALUE,
        names.RESIDUE,
        names.MODE_VECTOR,
        names.MODE_VECTOR_NORMALISED,
        names.FRF_SYNTHESIZED,
        names.FRF_RESIDUAL,
        names.FRF_NOISE_STD,
        names.DAMPING_RATIO,
    ):
        x, y = np.asarray(mem[v].values), np.asarray(lazy[v].values)
        np.testing.assert_allclose(y, x, rtol=1e-10, atol=1e-10 * np.max(np.abs(x)), err_msg=v)
