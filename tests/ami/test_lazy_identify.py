"""Issue 42 item 6: no step of ``identify`` materialises the FRF of a lazy input.

A lazily opened set (dask, chunked along ``point``) is identified with a dask callback that
refuses any task whose result is larger than a few chunks (far below the FRF's size), and with
the client's own allocations traced (``tracemalloc``: the sync scheduler runs the tasks in this
process, so a whole-FRF array on the client would show there too). Before this change the
noise model (``ami/whitening``: its rows and the per-point level), the repeated-root statistic
(``ami/repeated``) and the noise-spike rule (``ami/spikes``) each took ``.values`` of the whole
FRF or residual; a 10^5-point set on a 2 GB worker died of it. The same statistics on numpy
and on chunked dask arrays agree to rounding.
"""

from __future__ import annotations

import tracemalloc
import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami import chunked as ch
from ami_xr.ami import repeated as rp
from ami_xr.ami import spikes
from ami_xr.ami.whitening import VAR_LEVEL
from ami_xr.simulate.spread import many_points

dask = pytest.importorskip("dask")
from dask.callbacks import Callback  # noqa: E402

N_POINTS, N_LINES, CHUNK = 4000, 512, 200


class TooLarge(AssertionError):
    """A task computed more than the guard allows at once."""


class SizeGuard(Callback):
    """Raises :class:`TooLarge` as soon as a task's result exceeds ``limit`` bytes (a local
    scheduler runs callbacks; identify's computes all go through it)."""

    def __init__(self, limit: int) -> None:
        super().__init__()
        self.limit = limit
        self.largest = 0
        self.computes = 0

    def _start(self, dsk) -> None:
        self.computes += 1

    def _posttask(self, key, result, dsk, state, worker_id) -> None:
        size = sum(int(getattr(r, "nbytes", 0) or 0) for r in _leaves(result))
        self.largest = max(self.largest, size)
        if size > self.limit:
            raise TooLarge(f"task {key!r}: {size} bytes at once (limit {self.limit})")


def _leaves(result):
    if isinstance(result, (tuple, list)):
        for r in result:
            yield from _leaves(r)
    else:
        yield result


def _quiet_identify(ds, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ami_xr.identify(ds, **kw)


@pytest.fixture(scope="module")
def sets(tmp_path_factory):
    """The eager set and its files: as simulated (receptance, white noise), as accelerance
    (noise white in displacement: identify switches quantity) and with a stored noise std."""
    from ami_xr.dsp.quantity import convert_quantity

    ds, _ = many_points(N_POINTS, N_LINES, 12, noise=0.02, seed=0)
    folder = tmp_path_factory.mktemp("lazy")
    stored = ds.copy()
    level = 0.02 * float(np.abs(ds[names.FRF]).max())
    stored[names.FRF_LINE_NOISE_STD] = (ds[names.FRF].dims, np.full(ds[names.FRF].shape, level))
    out = {}
    for name, data in (
        ("plain", ds),
        ("accelerance", convert_quantity(ds, "acceleration")),
        ("stored_noise", stored),
    ):
        path = folder / f"{name}.nc"
        ami_xr.to_netcdf(data, path)
        out[name] = (data, path)
    _quiet_identify(ds.isel({names.POINT: slice(0, 400)}).chunk({names.POINT: 100}))  # imports
    return out


@pytest.mark.parametrize(
    "name",  # the other quantity and the stored noise floor: the slow tier
    ["plain", *(pytest.param(n, marks=pytest.mark.slow) for n in ("accelerance", "stored_noise"))],
)
def test_identify_of_a_lazy_set_computes_no_more_than_a_few_chunks_at_once(sets, name):
    eager, path = sets[name]
    lazy = ami_xr.open_dataset(path, chunks={names.POINT: CHUNK})
    whole = lazy[names.FRF].nbytes
    chunk = whole * CHUNK // N_POINTS
    guard = SizeGuard(limit=2 * chunk)  # a tenth of the FRF: two chunks
    tracemalloc.start()
    try:
        with guard, dask.config.set(scheduler="sync"):
            out = _quiet_identify(lazy)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
        lazy.close()
    assert guard.computes > 3 and 0 < guard.largest <= 2 * chunk
    assert peak < whole / 2, (peak, whole)  # nothing FRF-sized on the client either
    assert ch.is_lazy(out[names.FRF_RESIDUAL])  # the FRF-shaped outputs stay lazy
    ref = _quiet_identify(eager)
    assert out.sizes[names.MODE] == ref.sizes[names.MODE] >= 10
    np.testing.assert_allclose(
        out[names.EIGENVALUE].values, ref[names.EIGENVALUE].values, rtol=1e-7
    )
    assert (VAR_LEVEL in out) == (VAR_LEVEL in ref)
    if VAR_LEVEL in ref:
        np.testing.assert_allclose(out[VAR_LEVEL].values, ref[VAR_LEVEL].values, rtol=1e-9)
    assert out[names.QUALITY_FLAGS].values.tolist() == ref[names.QUALITY_FLAGS].values.tolist()


def _two_pole_arrays(n_points: int = 40, seed: int = 0):
    """FRFs of a pair split below its bandwidth, noise, fitted by one pole."""
    rng = np.random.default_rng(seed)
    omega = np.linspace(80.0, 120.0, 801)
    lam = -1.0 + 100j
    a1, a2 = rng.standard_normal((2, n_points)) * 1j

    def basis(x):
        return 1.0 / (1j * omega - x)

    data = np.outer(a1, basis(lam)) + np.outer(a2, basis(lam + 0.05j))
    data += 1e-3 * (rng.standard_normal(data.shape) + 1j * rng.standard_normal(data.shape))
    b = basis(lam)
    res = data @ np.conj(b) / np.vdot(b, b)
    return data - np.outer(res, b), omega, np.array([lam]), res[:, None], b[None], (b**2)[None]


@pytest.mark.parametrize("mass", [True, False])
def test_band_shift_on_chunks_equals_the_whole_array(mass):
    import dask.array as da

    residual, *rest = _two_pole_arrays()
    policy = rp.RepeatedPolicy(transducer_mass=mass)
    whole = rp.band_shift(residual, *rest, policy=policy)
    with dask.config.set(scheduler="sync"):
        # uneven chunks, one of a single point (a one-row R factor)
        parts = rp.band_shift(da.from_array(residual, chunks=(7, -1)), *rest, policy=policy)
        tiny = rp.band_shift(da.from_array(residual, chunks=(1, -1)), *rest, policy=policy)
    assert whole[1][0] > 50  # the split is seen
    for got in (parts, tiny):
        np.testing.assert_allclose(got[0], whole[0], rtol=1e-9)
        np.testing.assert_allclose(got[1], whole[1], rtol=1e-9)
        assert got[2].tolist() == whole[2].tolist()


def _spike_result():
    """A hand-made result: two narrow poles of opposite residue at one frequency (dropped
    together), a strong one seen at two points (kept), one seen at one point of four (dropped)."""
    f = np.arange(1.25, 101.0, 0.5)
    rng = np.random.default_rng(0)
    resid = (rng.standard_normal((4, f.size)) + 1j * rng.standard_normal((4, f.size))) * 1e-3
    w1, w2 = 2j * np.pi * 40.0, 2j * np.pi * 70
    lam = np.array([-0.001 + w1, -0.001 + w1, -0.01 + w2, -0.01 + w2 + 2j * np.pi * 10])
    res = np.array(
        [[0.5, -0.5, 1.0, 1.0], [0.5, -0.5, 1.0, 0], [0, 0, 0.5, 0], [0, 0, 0.0, 0]], complex
    )
    ds = ami_xr.make_frf_dataset(resid, f, frf_source="measured", response_quantity="displacement")
    dims = (names.POINT, names.FREQUENCY)
    return ds.assign(
        {
            names.FRF_RESIDUAL: (dims, resid),
            names.FRF_SYNTHESIZED: (dims, 2.0 * resid),
            names.EIGENVALUE: ((names.MODE,), lam),
            names.NATURAL_FREQUENCY: ((names.MODE,), np.abs(lam) / (2 * np.pi)),
            names.DAMPING_RATIO: ((names.MODE,), -lam.real / np.abs(lam)),
            names.RESIDUE: ((names.POINT, names.MODE), res),
        }
    ).assign_coords({names.MODE: [1, 2, 3, 4]})


def test_noise_spikes_of_a_lazy_result_are_found_and_moved_per_chunk():
    eager = _spike_result()
    lazy = eager.chunk({names.POINT: 1})
    with dask.config.set(scheduler="sync"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        drop, snr = spikes.spike_modes(lazy)
        kept = spikes.drop_noise_spikes(lazy.copy())
        ref = spikes.drop_noise_spikes(eager.copy())
    assert drop.tolist() == [True, True, False, True]
    np.testing.assert_allclose(snr, spikes.spike_modes(eager)[1], rtol=1e-12)
    assert kept.sizes[names.MODE] == ref.sizes[names.MODE] == 1
    for v in (names.FRF_RESIDUAL, names.FRF_SYNTHESIZED):
        assert ch.is_lazy(kept[v])  # moved lazily, not materialised
        np.testing.assert_allclose(kept[v].values, ref[v].values, rtol=1e-12, atol=1e-15)
