"""Extreme but valid FRFs (issue 9, items 4 and 9): any representable scale identifies to the
same modes with results scaled exactly; heavily damped clean FRFs get a true zero-modes message.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami.subtract import power_of_two_scale
from ami_xr.errors import NoModesWarning
from ami_xr.simulate.modal import frf as model_frf
from ami_xr.simulate.modal import modal_model

# How each output scales with the FRF (everything else is scale-free); the refinement's
# objective sum_j (n_rows / 2) log rss_j shifts by n_points * n_rows * ln(scale), n_rows = 2 F.
LINEAR = {
    names.FRF,
    names.SUB_RESIDUE,
    names.SUB_NOISE_FLOOR,
    names.RESIDUE,
    names.RESIDUE_STD,
    names.FRF_SYNTHESIZED,
    names.FRF_RESIDUAL,
    names.FRF_NOISE_STD,
    names.RESIDUAL_COEFFICIENT,
    "ami_residue",
    "noise_model_level",  # identify's noise model (issue 37), in FRF units
}
SQRT = {names.MODE_VECTOR, names.MODE_VECTOR_STD, "ami_mode_vector"}


def _scaled(ds, scale):
    out = ds.copy()
    out[names.FRF] = ds[names.FRF] * scale
    return out


def _assert_scaled_results(base, scaled, scale, rtol):
    for name, var in base.variables.items():
        a, b = np.asarray(var.values), np.asarray(scaled[name].values)
        if a.dtype.kind not in "fc":
            np.testing.assert_array_equal(b, a, err_msg=name)
            continue
        factor = scale if name in LINEAR else np.sqrt(scale) if name in SQRT else 1.0
        np.testing.assert_allclose(b / factor, a, rtol=rtol, atol=0, err_msg=name)


@pytest.fixture(scope="module")
def noisy():
    return ami_xr.simulate.random_system(5, seed=1, noise=0.01, n_frequencies=800)[0]


def test_power_of_two_scale_is_one_for_usual_magnitudes():
    # the no-op that keeps results on data in any usual unit bit-identical
    assert power_of_two_scale(np.array([1e-70, 1e-8, 1.0, 1e70])).tolist() == [1.0] * 4
    s = power_of_two_scale(np.array([1e-300, 1e300, 0.0, np.nan]))
    assert np.all(np.frexp(s[:2])[0] == 0.5) and np.all(np.frexp(s[:2])[1] % 2 == 1)
    assert s[2:].tolist() == [1.0, 1.0]


@pytest.mark.parametrize("scale", [2.0**-996, 2.0**996])
@pytest.mark.parametrize("residual_terms", [False, True])
def test_identify_power_of_two_scaled_frf_scales_results_exactly(noisy, scale, residual_terms):
    base = ami_xr.identify(noisy, residual_terms=residual_terms)
    scaled = ami_xr.identify(_scaled(noisy, scale), residual_terms=residual_terms)
    assert scaled.sizes[names.MODE] == base.sizes[names.MODE] > 0
    # the kernels are equivariant under a power-of-two scale, so only rounding of the
    # renormalised data (a different power of two than the original) is left
    _assert_scaled_results(base, scaled, scale, rtol=1e-9)
    shift = 2 * noisy.sizes[names.FREQUENCY] * noisy.sizes[names.POINT] * np.log(scale)
    for key in (names.ATTR_REFINE_COST_START, names.ATTR_REFINE_COST):
        if key in base.attrs:
            assert scaled.attrs[key] == pytest.approx(base.attrs[key] + shift, rel=1e-9)


@pytest.mark.parametrize("scale", [1e-300, 1e300])
def test_identify_and_subtract_of_an_frf_times_1e300(noisy, scale):
    # used to raise ZeroDivisionError (1e-300: sigma^2 underflows) or find 0 modes (1e300:
    # |Y|^2 overflows); decimal scales round the data, hence the looser tolerance
    sub = ami_xr.subtract(_scaled(noisy, scale))
    _assert_scaled_results(ami_xr.subtract(noisy), sub, scale, rtol=1e-6)
    base = ami_xr.identify(noisy, refine=False)
    scaled = ami_xr.identify(_scaled(noisy, scale), refine=False)
    assert scaled.sizes[names.MODE] == base.sizes[names.MODE]
    np.testing.assert_allclose(
        scaled[names.EIGENVALUE].values, base[names.EIGENVALUE].values, rtol=1e-6
    )


def _one_mode(zeta: float):
    """A clean single-degree-of-freedom receptance at 10 Hz with damping ratio ``zeta``."""
    wn = 2 * np.pi * 10.0
    model = modal_model([[1.0]], [[2 * zeta * wn]], [[wn**2]], drive_point=0)
    return model_frf(model, np.linspace(0.0, 100.0, 1024))


def _warnings_of(function, *args, **kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = function(*args, **kwargs)
    return out, [str(w.message) for w in caught if issubclass(w.category, NoModesWarning)]


@pytest.mark.parametrize("zeta", [0.3, 0.5])
def test_heavy_damping_zero_modes_message_is_true(zeta):
    out, messages = _warnings_of(ami_xr.identify, _one_mode(zeta))
    assert out.sizes.get(names.MODE, 0) == 0
    assert out.attrs[names.ATTR_AMI_STOP_REASON] == names.STOP_NO_ACCEPTED_FIT
    assert out[names.SUB_STOP_REASON].values.tolist() == [names.STOP_NO_ACCEPTED_FIT]
    text = " ".join(messages)
    assert "no FRF has a peak significantly above its noise floor" not in text
    assert "1 of 1 FRF(s) have a peak significantly above the noise floor" in text
    assert "zeta_max=0.25" in text and "raise zeta_max" in text
    # and the advice works
    found, messages = _warnings_of(ami_xr.identify, _one_mode(zeta), zeta_max=0.6)
    assert not messages
    np.testing.assert_allclose(found[names.DAMPING_RATIO].values, [zeta], rtol=1e-6)


def test_pure_noise_still_says_no_significant_peak():
    ds = _one_mode(0.02)
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(ds[names.FRF].shape) + 1j * rng.standard_normal(ds[names.FRF].shape)
    out, messages = _warnings_of(
        ami_xr.subtract, ds.assign({names.FRF: ds[names.FRF].copy(data=noise)})
    )
    assert out.attrs[names.ATTR_AMI_STOP_REASON] == names.STOP_NO_SIGNIFICANT_PEAK
    assert any("no FRF has a peak significantly above its noise floor" in m for m in messages)
