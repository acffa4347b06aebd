"""Modal quality indicators (MPC, MPD, complexity) and phase normalisation of mode vectors."""

from __future__ import annotations

import numpy as np
import pytest

from ami_xr.core.modal import complexity, mpc, mpd, phase_normalised


def _naive_mpc(col):
    """Pappa et al. (1993) from the 2 x 2 scatter eigenvalues, written out term by term."""
    x, y = col.real, col.imag
    sxx, syy, sxy = x @ x, y @ y, x @ y
    if sxy == 0:
        l1, l2 = max(sxx, syy), min(sxx, syy)
    else:
        eta = (syy - sxx) / (2 * sxy)
        r = sxy * np.sqrt(eta**2 + 1)
        l1, l2 = (sxx + syy) / 2 + abs(r), (sxx + syy) / 2 - abs(r)
    return ((l1 - l2) / (l1 + l2)) ** 2


def _naive_mpd(col):
    """Weighted mean angle to the best line through 0, the line found by brute force."""
    angles = np.linspace(0, np.pi, 200001)
    d = np.exp(1j * angles)
    # best line: least sum of squared distances |Im(conj(d) phi)|^2
    err = np.array([np.sum(np.imag(np.conj(di) * col) ** 2) for di in d[::100]])
    best = d[::100][np.argmin(err)]
    dev = np.degrees(np.arccos(np.abs(np.real(np.conj(best) * col)) / np.abs(col)))
    return np.sum(np.abs(col) * dev) / np.sum(np.abs(col))


REAL = np.array([1.0, -0.5, 0.25, 2.0, -1.5])


@pytest.mark.parametrize("phase", [0.0, 0.3, np.pi / 2, -2.0, np.pi])
def test_real_mode_is_collinear_whatever_its_overall_phase(phase):
    phi = (REAL * np.exp(1j * phase))[:, None]
    np.testing.assert_allclose(mpc(phi), [1.0], atol=1e-14)
    np.testing.assert_allclose(mpd(phi), [0.0], atol=1e-5)
    np.testing.assert_allclose(complexity(phi), [0.0], atol=1e-14)


def test_ninety_degree_split_gives_zero_collinearity():
    phi = np.array([[1.0, 1j, -1.0, -1j]]).T
    np.testing.assert_allclose(mpc(phi), [0.0], atol=1e-15)
    np.testing.assert_allclose(complexity(phi), [1.0], atol=1e-15)
    # points on two perpendicular lines of equal weight: half deviate 0, half 90 degrees
    np.testing.assert_allclose(mpd(np.array([[2.0, 2j]]).T), [45.0], atol=1e-9)


def test_against_naive_reference_on_random_complex_modes():
    rng = np.random.default_rng(3)
    phi = rng.normal(size=(7, 4)) + 1j * rng.normal(size=(7, 4)) * [0.0, 0.1, 0.5, 1.0]
    phi[:, 0] *= np.exp(0.7j)
    np.testing.assert_allclose(mpc(phi), [_naive_mpc(phi[:, k]) for k in range(4)], rtol=1e-12)
    np.testing.assert_allclose(mpd(phi), [_naive_mpd(phi[:, k]) for k in range(4)], atol=0.05)
    np.testing.assert_allclose(complexity(phi), 1 - mpc(phi))
    assert np.all((mpc(phi) >= 0) & (mpc(phi) <= 1))


def test_nan_points_left_out_and_empty_mode_is_nan():
    phi = np.array([[1.0, np.nan], [np.nan, np.nan], [-2.0, np.nan]], dtype=complex) * 1j
    assert mpc(phi)[0] == pytest.approx(1.0)
    assert mpd(phi)[0] == pytest.approx(0.0, abs=1e-6)
    assert np.isnan(mpc(phi)[1]) and np.isnan(mpd(phi)[1]) and np.isnan(complexity(phi)[1])


def test_phase_normalised_largest_component_real_positive():
    phi = np.column_stack([REAL * np.exp(-0.5j * np.pi), [1, 2j, -3, 0.5, np.nan]])
    out = phase_normalised(phi)
    assert out[3, 0] == pytest.approx(2.0)  # largest |.| of column 0, now real positive
    assert out[2, 1] == pytest.approx(3.0)
    np.testing.assert_allclose(np.abs(out), np.abs(phi))
    np.testing.assert_allclose(out[:, 0].imag, 0.0, atol=1e-15)  # a real mode becomes real
    assert np.isnan(out[4, 1])
    unit = phase_normalised(phi, unit=True)
    np.testing.assert_allclose(unit, out / np.abs(phi)[[3, 2], [0, 1]])
    assert unit[3, 0] == 1.0 and unit[2, 1] == 1.0


def test_indicators_are_scale_free_for_tiny_and_huge_vectors():
    phi = np.array([[1.0, 0.5j, -0.3 + 0.2j], [0.2, 1j, 1.0]]).T
    for scale in (1e-160, 1e160):
        np.testing.assert_allclose(mpc(phi * scale), mpc(phi), rtol=1e-12)
        np.testing.assert_allclose(mpd(phi * scale), mpd(phi), rtol=1e-12)


# --- identify adds the indicators (additive: mode_vector itself keeps its phase) ------------


def _proportional_frf():
    from ami_xr.simulate.modal import frf, modal_model

    k = 1.0e4 * np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    m = np.eye(3)
    model = modal_model(m, 1e-4 * k + 0.2 * m, k, drive_point=0)
    return frf(model, np.linspace(0.0, 40.0, 801))


def test_identify_adds_quality_indicators_with_units():
    import ami_xr
    from ami_xr import names

    result = ami_xr.identify(_proportional_frf())
    phi = result[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
    assert result.sizes[names.MODE] == 3
    for name, units, fn in (
        (names.MPC, "1", mpc),
        (names.MPD, "degree", mpd),
        (names.COMPLEXITY, "1", complexity),
    ):
        var = result[name]
        assert var.dims == (names.MODE,)
        assert var.attrs[names.ATTR_UNITS] == units
        assert var.attrs[names.ATTR_LONG_NAME]
        np.testing.assert_allclose(var.values, fn(phi))
    # proportional damping: real (normal) modes
    assert np.all(result[names.MPC].values > 0.999)
    assert np.all(result[names.MPD].values < 1.0)
    norm = result[names.MODE_VECTOR_NORMALISED].transpose(names.POINT, names.MODE).values
    np.testing.assert_allclose(norm, phase_normalised(phi, unit=True))
    assert result[names.MODE_VECTOR_NORMALISED].attrs[names.ATTR_UNITS] == "1"
    big = norm[np.argmax(np.abs(norm), axis=0), np.arange(3)]
    np.testing.assert_array_equal(big, 1.0)  # largest component exactly 1
    np.testing.assert_allclose(np.abs(norm), np.abs(phi) / np.abs(phi).max(axis=0))
    np.testing.assert_allclose(norm.imag, 0.0, atol=1e-6)  # a real mode becomes real
