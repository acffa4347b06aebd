"""Issue 42 ("scale that holds"): identify with ``compress="off"`` on a lazy FRF set.

With compression off every phase runs on every point. A lazily opened set (dask, chunked along
``point``) is identified under a dask callback that records every task whose result is larger
than two chunks, with the phase that asked for it (the ami_xr frames of the compute's caller).
Before this change four computes built the whole FRF at once: the SIMO isolation's data, the
global fit's synthesized FRFs, the refinement's data and its synthesized FRFs. The global fit and
the refinement's outputs are now made per chunk (residues gathered, model FRFs and residuals
lazy); what is left is the two joint fits that hold every FRF in memory by design (the SIMO
isolation kernel and the maximum-likelihood refinement): each loads the FRF once, and says so.
The lazy results equal the eager ones.
"""

from __future__ import annotations

import traceback
import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami import chunked as ch
from ami_xr.simulate.spread import many_points

dask = pytest.importorskip("dask")
from dask.callbacks import Callback  # noqa: E402

N_POINTS, N_LINES, CHUNK = 240, 512, 40
LOADED = ch.ATTR_LAZY_LOADED


class LargeTasks(Callback):
    """Records ``(where, bytes)`` of each task whose result is over ``limit`` bytes; ``where``
    is the innermost ami_xr function (not a helper) that started the compute."""

    def __init__(self, limit: int) -> None:
        super().__init__()
        self.limit = limit
        self.where = ""
        self.large: list[tuple[str, int]] = []

    def _start(self, dsk) -> None:
        helpers = ("/ami/chunked.py", "/ami/common.py")  # a phase's helpers: name the phase
        frames = [
            f
            for f in traceback.extract_stack()
            if "/ami_xr/" in f.filename and not f.filename.endswith(helpers)
        ]
        self.where = f"{frames[-1].filename.rsplit('/', 2)[-1]}:{frames[-1].name}" if frames else ""

    def _posttask(self, key, result, dsk, state, worker_id) -> None:
        parts = result if isinstance(result, (tuple, list)) else (result,)
        size = sum(int(getattr(r, "nbytes", 0) or 0) for r in parts)
        if size > self.limit:
            self.large.append((self.where, size))


def _quiet(func, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return func(*args, **kw)


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """The eager set, its file opened lazily, and the eager phases' outputs."""
    ds, _ = many_points(N_POINTS, N_LINES, 12, noise=0.02, seed=0)
    path = tmp_path_factory.mktemp("lazy_off") / "set.nc"
    ami_xr.to_netcdf(ds, path)
    lazy = ami_xr.open_dataset(path, chunks={names.POINT: CHUNK})
    iso = _quiet(ami_xr.isolate, _quiet(ami_xr.subtract, ds))
    fitted = _quiet(ami_xr.global_fit, iso)
    yield ds, lazy, iso, fitted
    lazy.close()


def _with_lazy_frf(result, lazy):
    """``result`` of an eager phase with its FRF-shaped variables replaced by lazy ones."""
    frf = lazy[names.FRF]
    out = result.assign({names.FRF: frf})
    for v in (names.FRF_SYNTHESIZED, names.FRF_RESIDUAL):
        if v in out:
            out[v] = out[v].chunk({names.POINT: CHUNK})
    return out


def _guarded(func, *args, **kw):
    """``func(*args, **kw)`` on the sync scheduler with a :class:`LargeTasks` guard at two
    chunks of the FRF; returns the result and the large tasks ``[(where, fraction of FRF)]``."""
    whole = N_POINTS * N_LINES * 16
    guard = LargeTasks(limit=2 * whole * CHUNK // N_POINTS)
    with guard, dask.config.set(scheduler="sync"):
        out = _quiet(func, *args, **kw)
    return out, [(where, size / whole) for where, size in guard.large]


@pytest.mark.parametrize("noise_floor", [True, False])
def test_global_fit_of_a_lazy_set_fits_per_chunk_and_equals_the_eager_fit(case, noise_floor):
    _, lazy, iso, fitted = case
    given = _with_lazy_frf(iso, lazy)
    ref = fitted
    if not noise_floor:  # the noise floor is then estimated from the FRFs, per chunk
        given = given.drop_vars(names.SUB_NOISE_FLOOR)
        ref = _quiet(ami_xr.global_fit, iso.drop_vars(names.SUB_NOISE_FLOOR))
    out, large = _guarded(ami_xr.global_fit, given)
    assert large == []
    for v in (names.FRF_SYNTHESIZED, names.FRF_RESIDUAL):
        assert ch.is_lazy(out[v]), v
        np.testing.assert_allclose(
            out[v].values, ref[v].values, rtol=0, atol=1e-12 * abs(ref[v]).max().item()
        )
    for v in (names.RESIDUE, names.MODE_VECTOR, names.DRIVE_POINT_SNR, names.MAC):
        np.testing.assert_allclose(out[v].values, ref[v].values, rtol=1e-10, atol=0)
    assert out[names.QUALITY_FLAGS].values.tolist() == ref[names.QUALITY_FLAGS].values.tolist()


def test_refine_of_a_lazy_set_loads_the_frf_once_and_keeps_its_outputs_lazy(case):
    _, lazy, _, fitted = case
    out, large = _guarded(ami_xr.refine, _with_lazy_frf(fitted, lazy))
    ref = _quiet(ami_xr.refine, fitted)
    assert [where for where, _ in large] == ["refine.py:_start_values"]
    assert out.attrs[LOADED] == "refine"
    for v in (names.FRF_SYNTHESIZED, names.FRF_RESIDUAL):
        assert ch.is_lazy(out[v]), v
        scale = abs(ref[v]).max().item()
        np.testing.assert_allclose(out[v].values, ref[v].values, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(
        out[names.EIGENVALUE].values, ref[names.EIGENVALUE].values, rtol=1e-12
    )
    np.testing.assert_allclose(out[names.RESIDUE].values, ref[names.RESIDUE].values, rtol=1e-10)


@pytest.mark.parametrize("refine", [True, False])
def test_identify_uncompressed_on_a_lazy_set_loads_only_for_its_joint_fits(case, refine):
    eager, lazy, _, _ = case
    out, large = _guarded(ami_xr.identify, lazy, compress="off", refine=refine)
    ref = _quiet(ami_xr.identify, eager, compress="off", refine=refine)
    joint = ["isolate.py:_isolate_simo_modes"] + (["refine.py:_start_values"] if refine else [])
    assert [where for where, _ in large] == joint  # each once, nothing else of the FRF's size
    assert all(0.99 < fraction < 1.01 for _, fraction in large)
    assert out.attrs[LOADED] == ",".join(p.split(".")[0] for p in joint)
    assert ch.is_lazy(out[names.FRF_RESIDUAL]) and ch.is_lazy(out[names.FRF_SYNTHESIZED])
    assert out.sizes[names.MODE] == ref.sizes[names.MODE] >= 9
    np.testing.assert_allclose(
        out[names.EIGENVALUE].values, ref[names.EIGENVALUE].values, rtol=1e-9
    )
    np.testing.assert_allclose(
        out[names.MODE_VECTOR].values, ref[names.MODE_VECTOR].values, rtol=1e-7
    )
    assert out[names.QUALITY_FLAGS].values.tolist() == ref[names.QUALITY_FLAGS].values.tolist()
    atol = 1e-9 * abs(ref[names.FRF]).max().item()  # the data's scale
    np.testing.assert_allclose(
        out[names.FRF_RESIDUAL].values, ref[names.FRF_RESIDUAL].values, rtol=0, atol=atol
    )
    assert LOADED not in ref.attrs


def test_a_large_lazy_load_is_told(case, monkeypatch):
    _, lazy, _, fitted = case
    monkeypatch.setattr(ch, "LOAD_WARN_BYTES", 1000)
    with pytest.warns(ami_xr.errors.AssumptionWarning, match="refine: .* loaded into memory"):
        ami_xr.refine(_with_lazy_frf(fitted, lazy))


def test_identify_per_frf_on_a_lazy_set_loads_nothing(case):
    # the per-FRF isolation runs per chunk of points: no phase then holds every FRF
    eager, lazy, _, _ = case
    kw = dict(compress="off", method="per_frf", refine=False)
    out, large = _guarded(ami_xr.identify, lazy, **kw)
    ref = _quiet(ami_xr.identify, eager, **kw)
    assert large == [] and LOADED not in out.attrs
    assert ch.is_lazy(out[names.FRF_RESIDUAL])
    assert out.sizes[names.MODE] == ref.sizes[names.MODE] >= 9
    np.testing.assert_allclose(
        out[names.EIGENVALUE].values, ref[names.EIGENVALUE].values, rtol=1e-9
    )


def test_a_lazy_set_in_tiny_units_is_scaled_back_per_chunk(case, tmp_path):
    # an FRF far below ordinary units is identified scaled by a power of two and the results
    # scaled back: the lazy outputs stay lazy (the scaling back loaded them before)
    eager, _, _, _ = case
    tiny = eager.assign({names.FRF: eager[names.FRF] * 1e-90})  # below 2^-250: scaled
    path = tmp_path / "tiny.nc"
    ami_xr.to_netcdf(tiny, path)
    kw = dict(compress="off", method="per_frf", refine=False)
    with ami_xr.open_dataset(path, chunks={names.POINT: CHUNK}) as lazy:
        out, large = _guarded(ami_xr.identify, lazy, **kw)
        ref = _quiet(ami_xr.identify, tiny, **kw)
        assert large == []
        assert ch.is_lazy(out[names.FRF_RESIDUAL]) and ch.is_lazy(out[names.FRF_SYNTHESIZED])
        np.testing.assert_allclose(
            out[names.EIGENVALUE].values, ref[names.EIGENVALUE].values, rtol=1e-9
        )
        atol = 1e-9 * abs(ref[names.FRF]).max().item()
        np.testing.assert_allclose(
            out[names.FRF_RESIDUAL].values, ref[names.FRF_RESIDUAL].values, rtol=0, atol=atol
        )
