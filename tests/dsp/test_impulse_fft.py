"""The labeled impulse_to_frf / apply_window (ami_xr/dsp/impulse.py, windows.py) against
references; their kernels are tested in tests/kernels/test_fft_kernels.py."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.fft
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import windows as kw

from ..reference import PAPER_DT as DT
from ..reference import PAPER_N as N
from ..reference import TWO_MODE_LAM as LAM
from ..reference import TWO_MODE_RES as RES
from ..reference import assert_fft_ratio_close, frf_from_residues, impulse_responses, rel_err

POINTS = ["tip", "m1"]


def time_dataset(force=None, **attrs):
    return ami_xr.make_time_dataset(
        impulse_responses(LAM, RES, N, DT),
        fs=1.0 / DT,
        points=POINTS,
        drive_point="tip",
        force=force,
        **attrs,
    )


# --- kernels ----------------------------------------------------------------------------------


# --- labeled impulse_to_frf -------------------------------------------------------------------


def test_impulse_to_frf_dataset_follows_the_data_model():
    ds = time_dataset()
    out = ami_xr.impulse_to_frf(ds)
    ami_xr.validate(out, kind="frf")
    assert out[names.FRF].dims == (names.POINT, names.FREQUENCY)
    assert out[names.FRF].dtype == np.complex128
    assert list(out[names.POINT].values) == POINTS
    # k / (n dt): one or two roundings against scipy's formula
    np.testing.assert_allclose(out[names.FREQUENCY].values, scipy.fft.rfftfreq(N, DT), rtol=1e-15)
    assert out[names.FREQUENCY].attrs[names.ATTR_UNITS] == "Hz"
    assert out[names.FRF].attrs[names.ATTR_UNITS] == "m/N"
    a = out.attrs
    assert a[names.ATTR_SOURCE] == names.SOURCE_IMPULSE
    # dt recovered from the time coordinate (one difference/division): an ulp or two
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
        impulse_responses(LAM, RES, N, DT),
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
    want = frf_from_residues(omega, LAM, RES, out.attrs[names.ATTR_DT], N)
    # FFT of 4096 samples (norm-wise ~eps log2 n) vs the closed-form geometric sum (1 - exp(lam dt)
    # costs ~2 digits): 1e-12 norm-wise; an error in dt or scaling is O(1)
    assert rel_err(out[names.FRF].values, want) < 1e-12


def test_impulse_to_frf_exponential_window_records_the_decay():
    ds = time_dataset()
    beta = kw.exponential_decay_rate(N, fs=1.0 / DT, end_value=0.01)
    out = ami_xr.impulse_to_frf(ds, window="exponential", end_value=0.01)
    # beta = -log(end) fs / (n - 1) from the window parameters vs from the kernel: a few roundings;
    # 1e-12 because fs comes from the time coordinate (differences of t ~ 60 s)
    # beta from end_value vs from the time coordinate's sampling: a few roundings
    assert out.attrs[names.ATTR_EXP_DECAY] == pytest.approx(beta, rel=1e-12)
    omega = 2 * np.pi * out[names.FREQUENCY].values
    # FFT of 4096 samples (norm-wise ~eps log2 n) vs the closed-form geometric sum (1 - exp(lam dt)
    # costs ~2 digits): 1e-12 norm-wise; an error in dt or scaling is O(1)
    # FFT vs closed form, norm-wise, as above
    assert rel_err(out[names.FRF].values, frf_from_residues(omega, LAM - beta, RES, DT, N)) < 1e-12
    # windowing first with apply_window gives the same FRF and the same recorded decay
    two_step = ami_xr.impulse_to_frf(ami_xr.apply_window(ds, "exponential", end_value=0.01))
    # the window applied in a separate pass (same products, same FFT): equal up to pocketfft's
    # batch-dependent SIMD path; no near-zero bins (lightly damped modes, no nulls below Nyquist)
    np.testing.assert_allclose(two_step[names.FRF].values, out[names.FRF].values, rtol=1e-13)
    # same recipe, see above
    assert two_step.attrs[names.ATTR_EXP_DECAY] == pytest.approx(beta, rel=1e-12)
    assert out[names.FRF].attrs["window"] == "exponential"
    # decays accumulate: window before and during the conversion
    twice = ami_xr.impulse_to_frf(
        ami_xr.apply_window(ds, "exponential", decay=0.1), window="exponential", decay=0.2
    )
    # 0.1 + 0.2: one rounding
    assert twice.attrs[names.ATTR_EXP_DECAY] == pytest.approx(0.3, rel=1e-14)
    assert twice[names.FRF].attrs["window"] == "exponential*exponential"
    # FFT of 4096 samples (norm-wise ~eps log2 n) vs the closed-form geometric sum (1 - exp(lam dt)
    # costs ~2 digits): 1e-12 norm-wise; an error in dt or scaling is O(1)
    # FFT vs closed form, norm-wise
    assert rel_err(twice[names.FRF].values, frf_from_residues(omega, LAM - 0.3, RES, DT, N)) < 1e-12


def test_impulse_to_frf_hann_window_matches_numpy():
    ds = time_dataset()
    out = ami_xr.impulse_to_frf(ds, window="hann", sym=True)
    want = DT * np.fft.rfft(impulse_responses(LAM, RES, N, DT) * np.hanning(N), axis=-1)
    # FFT of 4096 samples (norm-wise ~eps log2 n) vs the closed-form geometric sum (1 - exp(lam dt)
    # costs ~2 digits): 1e-12 norm-wise; an error in dt or scaling is O(1)
    # the same FFT with the same window: norm-wise rounding ~eps log2(n); 1e-13 allows for another
    # SIMD path
    assert rel_err(out[names.FRF].values, want) < 1e-13
    assert out[names.FRF].attrs["window_amplitude_correction"] == pytest.approx(
        # a sum of 4096 terms in [0, 1], possibly in another order: ~sqrt(n) eps typical
        N / np.hanning(N).sum(),
        rel=1e-14,
    )


def test_impulse_to_frf_with_measured_force():
    rng = np.random.default_rng(3)
    force = np.zeros(N)
    force[:6] = np.hanning(8)[1:7] / DT  # short hammer pulse
    force[6:] = 1e-4 * rng.standard_normal(N - 6)
    ds = time_dataset(force=force)
    out = ami_xr.impulse_to_frf(ds)
    assert_fft_ratio_close(out[names.FRF].values, impulse_responses(LAM, RES, N, DT), force)
    assert out.attrs[names.ATTR_SOURCE] == names.SOURCE_ESTIMATED
    assert names.ATTR_DT not in out.attrs and names.ATTR_NSAMPLES not in out.attrs
    ami_xr.validate(out, kind="frf")
    # hammer-test processing: force window on the force, exponential on both
    fw = ami_xr.apply_window(ds, "force", width=6, taper=3, variables=[names.FORCE])
    assert names.ATTR_EXP_DECAY not in fw.attrs
    out2 = ami_xr.impulse_to_frf(fw, window="exponential", end_value=0.05)
    we = kw.get_window("exponential", N, end_value=0.05)
    wf = kw.get_window("force", N, width=6, taper=3)
    assert_fft_ratio_close(
        out2[names.FRF].values, impulse_responses(LAM, RES, N, DT) * we, force * wf * we
    )


def test_impulse_to_frf_dask_chunks_equal_in_memory():
    ds = time_dataset()
    eager = ami_xr.impulse_to_frf(ds, window="exponential", decay=0.2)
    for chunks in ({names.POINT: 1}, {names.POINT: 1, names.TIME: 1000}):
        lazy = ami_xr.impulse_to_frf(ds.chunk(chunks), window="exponential", decay=0.2)
        assert lazy[names.FRF].chunks is not None  # stays lazy
        assert lazy[names.FRF].chunks[0] == (1, 1)  # point chunks kept
        # dask hands the kernel whole time rows (point chunks only), so the same FFTs run on fewer
        # rows at a time: equal up to pocketfft's batch-dependent SIMD path (an ulp)
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
    # FFT of 4096 samples (norm-wise ~eps log2 n) vs the closed-form geometric sum (1 - exp(lam dt)
    # costs ~2 digits): 1e-12 norm-wise; an error in dt or scaling is O(1)
    # FFT of the simulator's sampled impulse response vs the closed form from its eigen-
    # decomposition (cond ~ 10): norm-wise 1e-12
    assert rel_err(out[names.FRF].values, frf_from_residues(omega, lam, res, DT, N)) < 1e-12


def test_input_dataset_is_not_modified():
    ds = time_dataset()
    before = ds.copy(deep=True)
    ami_xr.impulse_to_frf(ds, window="exponential", decay=0.1)
    ami_xr.apply_window(ds, "exponential", decay=0.1)
    # input untouched: no arithmetic on ds
    xr.testing.assert_identical(ds, before)


def test_accessor_methods():
    ds = time_dataset()
    # the accessor calls the same function with the same arguments: the same operations in the
    # same order, so values and coordinates are bit-identical (attrs differ only in the history)
    xr.testing.assert_equal(
        ds.ami.impulse_to_frf(window="hann"), ami_xr.impulse_to_frf(ds, window="hann")
    )
    xr.testing.assert_equal(ds.ami.apply_window("flattop"), ami_xr.apply_window(ds, "flattop"))


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
    # window times data, one product per element in the same order as numpy: bit-identical
    np.testing.assert_array_equal(
        out[names.RESPONSE].values, impulse_responses(LAM, RES, N, DT) * w
    )
    attrs = out[names.RESPONSE].attrs
    assert attrs["window"] == "hann"
    # sums of 4096 terms in [0, 1] against the closed forms: ~sqrt(n) eps typical
    assert attrs["window_amplitude_correction"] == pytest.approx(2.0, rel=1e-14)
    assert attrs["window_energy_correction"] == pytest.approx(np.sqrt(8 / 3), rel=1e-14)
    assert attrs[names.ATTR_UNITS] == "m"
    assert json.loads(attrs["window_parameters"]) == [{"name": "hann", "n": N, "sym": False}]
    assert names.ATTR_EXP_DECAY not in out.attrs
    # the coordinate is copied, not computed
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
    # the product window multiplied in another order (two passes vs one) and summed over 4096 terms:
    # a few ulp per term, 1e-12 leaves room for the summation order
    assert fa["window_amplitude_correction"] == pytest.approx(N / product.sum(), rel=1e-12)
    assert fa["window_energy_correction"] == pytest.approx(
        np.sqrt(N / (product**2).sum()), rel=1e-12
    )
    assert out[names.RESPONSE].attrs["window"] == "exponential"
    beta = kw.exponential_decay_rate(N, fs=1 / DT, end_value=0.1)
    # the Dataset decay follows the response; each variable keeps its own
    # beta = -log(end) fs / (n - 1) from the window parameters vs from the kernel: a few roundings;
    # 1e-12 because fs comes from the time coordinate (differences of t ~ 60 s)
    # beta from end_value vs from the time coordinate's sampling: a few roundings
    assert out.attrs[names.ATTR_EXP_DECAY] == pytest.approx(beta, rel=1e-12)
    assert out[names.FORCE].attrs[names.ATTR_EXP_DECAY] == pytest.approx(beta, rel=1e-12)
    only_force = ami_xr.apply_window(ds, "exponential", decay=1.0, variables=[names.FORCE])
    assert names.ATTR_EXP_DECAY not in only_force.attrs


def test_apply_window_dask_equals_in_memory():
    ds = time_dataset()
    eager = ami_xr.apply_window(ds, "flattop")
    lazy = ami_xr.apply_window(ds.chunk({names.POINT: 1, names.TIME: 512}), "flattop")
    assert lazy[names.RESPONSE].chunks is not None
    # a window is one product per element: chunking changes no operation, so bit-identical
    xr.testing.assert_identical(lazy.compute(), eager)


def test_apply_window_keeps_dim_order():
    ds = time_dataset().transpose(names.TIME, names.POINT)
    out = ami_xr.apply_window(ds, "hann")
    assert out[names.RESPONSE].dims == (names.TIME, names.POINT)
    # one product per element, only transposed: bit-identical
    np.testing.assert_array_equal(
        out[names.RESPONSE].values,
        (impulse_responses(LAM, RES, N, DT) * kw.get_window("hann", N)).T,
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
