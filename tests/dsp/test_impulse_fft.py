"""FFT-to-FRF kernels and the labeled impulse_to_frf / apply_window against references."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.fft
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import fft as kfft
from ami_xr.kernels import windows as kw
from ami_xr.kernels.modal_basis import mode_contribution

# Two modes, two points: the paper's record (60 s, 2^12 samples) for a realistic grid.
N = 4096
DT = 60.0 / N
LAM = np.array([-0.05 + 10.0j, -0.4 + 31.0j])
RES = np.array([[0.3 - 0.2j, 0.1 + 0.1j], [0.05j, -0.2 + 0.02j]])  # (point, mode)
POINTS = ["tip", "m1"]


def impulse_responses(lam=LAM, residue=RES, n=N, dt=DT):
    """h_j(t_k) = 2 Re sum_m A_jm exp(lam_m k dt), shape (point, n)."""
    t = np.arange(n) * dt
    return 2 * np.real((residue[:, :, None] * np.exp(lam[None, :, None] * t)).sum(axis=1))


def exact_frf(omega, lam=LAM, residue=RES, dt=DT, n=N):
    return np.array(
        [
            sum(mode_contribution(omega, lam[m], residue[j, m], dt, n) for m in range(lam.size))
            for j in range(residue.shape[0])
        ]
    )


def rel_err(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


def time_dataset(force=None, **attrs):
    return ami_xr.make_time_dataset(
        impulse_responses(), fs=1.0 / DT, points=POINTS, drive_point="tip", force=force, **attrs
    )


# --- kernels ----------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 7, 64, 1001])
def test_rfft_frequencies_match_scipy(n):
    np.testing.assert_allclose(
        kfft.rfft_frequencies(n, 0.01), scipy.fft.rfftfreq(n, 0.01), rtol=1e-15, atol=0
    )


def test_impulse_to_frf_matches_numpy_reference():
    rng = np.random.default_rng(0)
    y = rng.standard_normal((2, 3, 101))
    w = kw.get_window("hann", 101)
    got = kfft.impulse_to_frf(y, 0.02, window=w)
    np.testing.assert_allclose(got, 0.02 * np.fft.rfft(y * w, axis=-1), rtol=1e-13, atol=1e-15)
    assert got.shape == (2, 3, 51) and got.dtype == np.complex128
    np.testing.assert_allclose(
        kfft.impulse_to_frf(y[0, 0], 0.02), 0.02 * np.fft.rfft(y[0, 0]), rtol=1e-13, atol=1e-15
    )


@pytest.mark.parametrize(("n", "dt"), [(N, DT), (1001, 0.02), (64, 0.5)])
def test_impulse_to_frf_of_modal_response_is_the_exact_discrete_basis(n, dt):
    got = kfft.impulse_to_frf(impulse_responses(n=n, dt=dt), dt)
    omega = 2 * np.pi * kfft.rfft_frequencies(n, dt)
    assert got.shape == (2, n // 2 + 1)
    assert rel_err(got, exact_frf(omega, dt=dt, n=n)) < 1e-12


def test_exponential_window_shifts_every_eigenvalue_by_beta():
    beta = kw.exponential_decay_rate(N, fs=1.0 / DT, end_value=0.01)
    w = kw.get_window("exponential", N, end_value=0.01)
    got = kfft.impulse_to_frf(impulse_responses(), DT, window=w)
    omega = 2 * np.pi * kfft.rfft_frequencies(N, DT)
    # same residues, eigenvalues lam - beta: identification must add beta back to Re(lam)
    assert rel_err(got, exact_frf(omega, lam=LAM - beta)) < 1e-12
    assert rel_err(got, exact_frf(omega)) > 1e-3


def test_frf_from_force_matches_numpy_reference_and_broadcasts():
    rng = np.random.default_rng(1)
    y = rng.standard_normal((3, 64))
    f = rng.standard_normal(64)
    wy, wf = kw.get_window("exponential", 64, end_value=0.1), kw.get_window("force", 64, width=5)
    got = kfft.frf_from_force(y, f, window=wy, force_window=wf)
    want = np.fft.rfft(y * wy) / np.fft.rfft(f * wf)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    per_row = kfft.frf_from_force(y, np.tile(f, (3, 1)), window=wy, force_window=wf)
    np.testing.assert_allclose(per_row, got, rtol=1e-15)


def test_discrete_unit_impulse_force_gives_the_impulse_formula():
    f = np.zeros(N)
    f[0] = 1.0 / DT  # unit area
    y = impulse_responses()
    np.testing.assert_allclose(kfft.frf_from_force(y, f), kfft.impulse_to_frf(y, DT), rtol=1e-13)


def test_kernel_inputs_are_not_modified():
    y = impulse_responses()
    y0 = y.copy()
    kfft.impulse_to_frf(y, DT, window=kw.get_window("hann", N))
    np.testing.assert_array_equal(y, y0)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: kfft.impulse_to_frf(np.ones(8), 0.0), "dt"),
        (lambda: kfft.impulse_to_frf(np.ones(8), float("nan")), "dt"),
        (lambda: kfft.impulse_to_frf(np.ones(8) + 0j, 0.1), "y:"),
        (lambda: kfft.impulse_to_frf(np.ones((2, 0)), 0.1), "y:"),
        (lambda: kfft.impulse_to_frf(np.ones(8), 0.1, window=np.ones(7)), "window"),
        (lambda: kfft.frf_from_force(np.ones((2, 8)), np.ones(7)), "f:"),
        (lambda: kfft.frf_from_force(np.ones((2, 8)), np.ones((3, 8))), "f:"),
        (lambda: kfft.frf_from_force(np.ones(8), np.ones((2, 8))), "f:"),
        (lambda: kfft.frf_from_force(np.ones(8), np.zeros(8)), "f:.*zero"),
        (
            lambda: kfft.frf_from_force(np.ones(8), np.ones(8), force_window=np.ones(3)),
            "force_window",
        ),
        (lambda: kfft.rfft_frequencies(0, 0.1), "n:"),
    ],
)
def test_kernel_bad_inputs_name_the_argument(call, match):
    with pytest.raises(AmiXrValueError, match=match):
        call()


# --- labeled impulse_to_frf -------------------------------------------------------------------


def test_impulse_to_frf_dataset_follows_the_data_model():
    ds = time_dataset()
    out = ami_xr.impulse_to_frf(ds)
    ami_xr.validate(out, kind="frf")
    assert out[names.FRF].dims == (names.POINT, names.FREQUENCY)
    assert out[names.FRF].dtype == np.complex128
    assert list(out[names.POINT].values) == POINTS
    np.testing.assert_allclose(out[names.FREQUENCY].values, scipy.fft.rfftfreq(N, DT), rtol=1e-15)
    assert out[names.FREQUENCY].attrs[names.ATTR_UNITS] == "Hz"
    assert out[names.FRF].attrs[names.ATTR_UNITS] == "m/N"
    a = out.attrs
    assert a[names.ATTR_SOURCE] == names.SOURCE_IMPULSE
    assert a[names.ATTR_DT] == pytest.approx(DT, rel=1e-15)
    assert a[names.ATTR_NSAMPLES] == N
    assert a[names.ATTR_DRIVE_POINT] == "tip"
    assert a[names.ATTR_FRF_TYPE] == "receptance"
    assert a[names.ATTR_RESPONSE_UNITS] == "m" and a[names.ATTR_FORCE_UNITS] == "N"
    assert names.ATTR_EXP_DECAY not in a
    assert json.loads(a[names.ATTR_HISTORY])[-1]["function"] == "impulse_to_frf"
    assert names.TIME not in out.coords


@pytest.mark.parametrize(
    ("quantity", "units", "frf_type"),
    [("velocity", "m/s", "mobility"), ("acceleration", "m/s^2", "accelerance")],
)
def test_impulse_to_frf_carries_quantity_and_units(quantity, units, frf_type):
    ds = ami_xr.make_time_dataset(
        impulse_responses(),
        fs=1 / DT,
        points=POINTS,
        drive_point="tip",
        response_quantity=quantity,
        response_units=units,
        force_units="kN",
    )
    out = ami_xr.impulse_to_frf(ds)
    assert out.attrs[names.ATTR_FRF_TYPE] == frf_type
    assert out.attrs[names.ATTR_QUANTITY] == quantity
    assert out[names.FRF].attrs[names.ATTR_UNITS] == f"{units}/kN"
    ami_xr.validate(out, kind="frf")


def test_impulse_to_frf_equals_mode_contribution():
    out = ami_xr.impulse_to_frf(time_dataset())
    omega = 2 * np.pi * out[names.FREQUENCY].values
    assert rel_err(out[names.FRF].values, exact_frf(omega, dt=out.attrs[names.ATTR_DT])) < 1e-12


def test_impulse_to_frf_exponential_window_records_the_decay():
    ds = time_dataset()
    beta = kw.exponential_decay_rate(N, fs=1.0 / DT, end_value=0.01)
    out = ami_xr.impulse_to_frf(ds, window="exponential", end_value=0.01)
    assert out.attrs[names.ATTR_EXP_DECAY] == pytest.approx(beta, rel=1e-12)
    omega = 2 * np.pi * out[names.FREQUENCY].values
    assert rel_err(out[names.FRF].values, exact_frf(omega, lam=LAM - beta)) < 1e-12
    # windowing first with apply_window gives the same FRF and the same recorded decay
    two_step = ami_xr.impulse_to_frf(ami_xr.apply_window(ds, "exponential", end_value=0.01))
    np.testing.assert_allclose(two_step[names.FRF].values, out[names.FRF].values, rtol=1e-13)
    assert two_step.attrs[names.ATTR_EXP_DECAY] == pytest.approx(beta, rel=1e-12)
    assert out[names.FRF].attrs["window"] == "exponential"
    # decays accumulate: window before and during the conversion
    twice = ami_xr.impulse_to_frf(
        ami_xr.apply_window(ds, "exponential", decay=0.1), window="exponential", decay=0.2
    )
    assert twice.attrs[names.ATTR_EXP_DECAY] == pytest.approx(0.3, rel=1e-14)
    assert twice[names.FRF].attrs["window"] == "exponential*exponential"
    assert rel_err(twice[names.FRF].values, exact_frf(omega, lam=LAM - 0.3)) < 1e-12


def test_impulse_to_frf_hann_window_matches_numpy():
    ds = time_dataset()
    out = ami_xr.impulse_to_frf(ds, window="hann", sym=True)
    want = DT * np.fft.rfft(impulse_responses() * np.hanning(N), axis=-1)
    assert rel_err(out[names.FRF].values, want) < 1e-13
    assert out[names.FRF].attrs["window_amplitude_correction"] == pytest.approx(
        N / np.hanning(N).sum(), rel=1e-14
    )


def assert_fft_ratio_close(got, y, f):
    """``got`` equals ``rfft(y) / rfft(f)`` to the rounding error of the two FFTs.

    A length-n FFT has a norm-wise relative rounding error of about eps * log2(n) (Higham,
    *Accuracy and Stability of Numerical Algorithms*, ch. 24), so one bin of Y = rfft(y) may be
    off by eps * log2(n) * ||Y|| = eps * log2(n) * sqrt(n) * ||y|| in absolute terms, and
    likewise F. To first order the ratio is then off by (dY + |Y / F| dF) / |F| in each bin: an
    elementwise relative tolerance would fail (CPU-dependently) wherever |F| is small. The
    factor 10 covers the constants of the bound.
    """
    n = y.shape[-1]
    big_y, big_f = np.fft.rfft(y, axis=-1), np.fft.rfft(f)
    unit = 10 * np.finfo(np.float64).eps * np.log2(n) * np.sqrt(n)
    d_y = unit * np.linalg.norm(y, axis=-1, keepdims=True)
    d_f = unit * np.linalg.norm(f)
    want = big_y / big_f
    tol = (d_y + np.abs(want) * d_f) / np.abs(big_f)
    err = np.abs(got - want)
    assert np.all(err <= tol), f"max error / bound = {np.max(err / tol):.3g}"


def test_impulse_to_frf_with_measured_force():
    rng = np.random.default_rng(3)
    force = np.zeros(N)
    force[:6] = np.hanning(8)[1:7] / DT  # short hammer pulse
    force[6:] = 1e-4 * rng.standard_normal(N - 6)
    ds = time_dataset(force=force)
    out = ami_xr.impulse_to_frf(ds)
    assert_fft_ratio_close(out[names.FRF].values, impulse_responses(), force)
    assert out.attrs[names.ATTR_SOURCE] == names.SOURCE_ESTIMATED
    assert names.ATTR_DT not in out.attrs and names.ATTR_NSAMPLES not in out.attrs
    ami_xr.validate(out, kind="frf")
    # hammer-test processing: force window on the force, exponential on both
    fw = ami_xr.apply_window(ds, "force", width=6, taper=3, variables=[names.FORCE])
    assert names.ATTR_EXP_DECAY not in fw.attrs
    out2 = ami_xr.impulse_to_frf(fw, window="exponential", end_value=0.05)
    we = kw.get_window("exponential", N, end_value=0.05)
    wf = kw.get_window("force", N, width=6, taper=3)
    assert_fft_ratio_close(out2[names.FRF].values, impulse_responses() * we, force * wf * we)


def test_impulse_to_frf_dask_chunks_equal_in_memory():
    ds = time_dataset()
    eager = ami_xr.impulse_to_frf(ds, window="exponential", decay=0.2)
    for chunks in ({names.POINT: 1}, {names.POINT: 1, names.TIME: 1000}):
        lazy = ami_xr.impulse_to_frf(ds.chunk(chunks), window="exponential", decay=0.2)
        assert lazy[names.FRF].chunks is not None  # stays lazy
        assert lazy[names.FRF].chunks[0] == (1, 1)  # point chunks kept
        xr.testing.assert_allclose(lazy.compute(), eager, rtol=1e-15, atol=0)
        assert lazy.attrs[names.ATTR_EXP_DECAY] == eager.attrs[names.ATTR_EXP_DECAY]


def test_impulse_to_frf_from_the_simulator():
    sim = ami_xr.simulate
    required = ("modal_model", "impulse_response")
    if not all(hasattr(sim, f) for f in required):
        pytest.skip("simulator not available")
    m = np.diag([1.0, 2.0])
    k = np.array([[300.0, -100.0], [-100.0, 200.0]])
    c = np.array([[0.4, -0.1], [-0.1, 0.3]])
    model = sim.modal_model(m, c, k, drive_point=0)
    ts = sim.impulse_response(model, (60.0, N))
    out = ami_xr.impulse_to_frf(ts)
    omega = 2 * np.pi * out[names.FREQUENCY].values
    lam = model[names.EIGENVALUE].values
    res = sim.residues(model)[names.RESIDUE].transpose(names.POINT, names.MODE).values
    assert rel_err(out[names.FRF].values, exact_frf(omega, lam, res)) < 1e-12


def test_input_dataset_is_not_modified():
    ds = time_dataset()
    before = ds.copy(deep=True)
    ami_xr.impulse_to_frf(ds, window="exponential", decay=0.1)
    ami_xr.apply_window(ds, "exponential", decay=0.1)
    xr.testing.assert_identical(ds, before)


def test_accessor_methods():
    ds = time_dataset()
    xr.testing.assert_allclose(
        ds.ami.impulse_to_frf(window="hann"), ami_xr.impulse_to_frf(ds, window="hann")
    )
    xr.testing.assert_allclose(ds.ami.apply_window("flattop"), ami_xr.apply_window(ds, "flattop"))


@pytest.mark.parametrize(
    ("mutate", "kwargs", "match"),
    [
        (lambda ds: ds.expand_dims(record=2).transpose("record", ...), {}, "record"),
        (lambda ds: ds.drop_attrs(deep=False), {}, "excitation|force"),
        (lambda ds: ds.rename({names.RESPONSE: "x"}), {}, "response"),
        (lambda ds: ds.assign_coords(time=ds.time.values**1.01), {}, "time"),
        (lambda ds: ds, {"window": "force"}, "window"),
        (lambda ds: ds, {"window": "kaiser"}, "window"),
        (lambda ds: ds, {"decay": 0.1}, "decay"),
        (lambda ds: ds, {"window": "exponential"}, "decay, end_value"),
        (lambda ds: ds, {"window": "exponential", "end_value": 2.0}, "end_value"),
        (lambda ds: ds, {"window": "hann", "decay": 1.0}, "decay"),
        (lambda ds: ds.assign_attrs(drive_point="nowhere"), {}, "drive_point"),
    ],
)
def test_impulse_to_frf_bad_inputs(mutate, kwargs, match):
    ds = mutate(time_dataset())
    with pytest.raises(ValueError, match=match):
        ami_xr.impulse_to_frf(ds, **kwargs)


def test_impulse_to_frf_rejects_non_dataset():
    with pytest.raises(AmiXrValueError, match="ds"):
        ami_xr.impulse_to_frf(time_dataset()[names.RESPONSE])


# --- labeled apply_window ---------------------------------------------------------------------


def test_apply_window_values_and_attrs():
    ds = time_dataset()
    out = ami_xr.apply_window(ds, "hann")
    w = kw.get_window("hann", N)
    np.testing.assert_array_equal(out[names.RESPONSE].values, impulse_responses() * w)
    attrs = out[names.RESPONSE].attrs
    assert attrs["window"] == "hann"
    assert attrs["window_amplitude_correction"] == pytest.approx(2.0, rel=1e-14)
    assert attrs["window_energy_correction"] == pytest.approx(np.sqrt(8 / 3), rel=1e-14)
    assert attrs[names.ATTR_UNITS] == "m"
    assert json.loads(attrs["window_parameters"]) == [{"name": "hann", "n": N, "sym": False}]
    assert names.ATTR_EXP_DECAY not in out.attrs
    xr.testing.assert_identical(out[names.TIME], ds[names.TIME])
    assert json.loads(out.attrs[names.ATTR_HISTORY])[-1]["function"] == "apply_window"


def test_apply_window_chain_corrections_are_of_the_product():
    ds = time_dataset(force=np.r_[1.0 / DT, np.zeros(N - 1)])
    out = ami_xr.apply_window(ds, "exponential", end_value=0.1)
    out = ami_xr.apply_window(out, "force", width=20, taper=5, variables=names.FORCE)
    product = kw.get_window("exponential", N, end_value=0.1) * kw.get_window(
        "force", N, width=20, taper=5
    )
    fa = out[names.FORCE].attrs
    assert fa["window"] == "exponential*force"
    assert fa["window_amplitude_correction"] == pytest.approx(N / product.sum(), rel=1e-12)
    assert fa["window_energy_correction"] == pytest.approx(
        np.sqrt(N / (product**2).sum()), rel=1e-12
    )
    assert out[names.RESPONSE].attrs["window"] == "exponential"
    beta = kw.exponential_decay_rate(N, fs=1 / DT, end_value=0.1)
    # the Dataset decay follows the response; each variable keeps its own
    assert out.attrs[names.ATTR_EXP_DECAY] == pytest.approx(beta, rel=1e-12)
    assert out[names.FORCE].attrs[names.ATTR_EXP_DECAY] == pytest.approx(beta, rel=1e-12)
    only_force = ami_xr.apply_window(ds, "exponential", decay=1.0, variables=[names.FORCE])
    assert names.ATTR_EXP_DECAY not in only_force.attrs


def test_apply_window_dask_equals_in_memory():
    ds = time_dataset()
    eager = ami_xr.apply_window(ds, "flattop")
    lazy = ami_xr.apply_window(ds.chunk({names.POINT: 1, names.TIME: 512}), "flattop")
    assert lazy[names.RESPONSE].chunks is not None
    xr.testing.assert_identical(lazy.compute(), eager)


def test_apply_window_keeps_dim_order():
    ds = time_dataset().transpose(names.TIME, names.POINT)
    out = ami_xr.apply_window(ds, "hann")
    assert out[names.RESPONSE].dims == (names.TIME, names.POINT)
    np.testing.assert_array_equal(
        out[names.RESPONSE].values, (impulse_responses() * kw.get_window("hann", N)).T
    )


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        (("kaiser",), {}, "window"),
        (("hann", "frequency"), {}, "dim"),
        (("hann",), {"variables": ["nope"]}, "variables"),
        (("hann",), {"variables": []}, "variables"),
        (("exponential",), {}, "decay, end_value"),
        (("exponential",), {"decay": -1.0}, "decay"),
        (("force",), {}, "width"),
        (("force",), {"width": N + 1}, "width"),
        (("hann",), {"taper": 3}, "taper"),
    ],
)
def test_apply_window_bad_inputs(args, kwargs, match):
    with pytest.raises(AmiXrValueError, match=match):
        ami_xr.apply_window(time_dataset(), *args, **kwargs)


def test_apply_window_needs_a_uniform_coordinate_for_exponential():
    ds = time_dataset()
    ds = ds.assign_coords(time=ds.time.values**1.01)
    with pytest.raises(AmiXrValueError, match="time"):
        ami_xr.apply_window(ds, "exponential", decay=1.0)
    ami_xr.apply_window(ds, "hann")  # the cosine windows do not need the sampling rate
    with pytest.raises(AmiXrValueError, match="time"):
        ami_xr.apply_window(ds.drop_vars(names.TIME), "exponential", decay=1.0)


def test_apply_window_rejects_a_record_windowed_at_another_length():
    ds = ami_xr.apply_window(time_dataset(), "hann")
    with pytest.raises(AmiXrValueError, match="response"):
        ami_xr.apply_window(ds.isel(time=slice(0, 100)), "hann")
