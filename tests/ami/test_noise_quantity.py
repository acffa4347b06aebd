"""One noise model for every response quantity (issue 37): the same noisy measurement given as
receptance, mobility or accelerance gives the same modes, fitted where its noise is white."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami import whitening
from ami_xr.core import frf_noise as fn
from ami_xr.simulate import random_system, score_modes

QUANTITIES = ("displacement", "velocity", "acceleration")


def _system(seed=3):
    f = np.linspace(62.5 / 1024, 62.5, 1024)
    return random_system(7, "chain", seed=seed, frequency=f, max_frequency_hz=50.0)


def _noisy(frf, colour_power: int, alpha: float, seed: int):
    """The receptance plus complex noise white in the quantity of ``colour_power``."""
    h = frf[names.FRF].transpose(names.POINT, names.FREQUENCY).values
    jw = 2j * np.pi * frf[names.FREQUENCY].values
    sigma = alpha * np.abs(h * jw**colour_power).max(axis=1)
    rng = np.random.default_rng(seed)
    e = (rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape)) / np.sqrt(2)
    out = frf.copy()
    out[names.FRF] = (frf[names.FRF].dims, h + sigma[:, None] * e / jw**colour_power)
    out.attrs[names.ATTR_SOURCE] = names.SOURCE_MEASURED
    return out


def _given_as(ds, quantity):
    out = ami_xr.convert_quantity(ds, quantity)
    out.attrs[names.ATTR_SOURCE] = names.SOURCE_MEASURED
    return out


def _identify(ds):
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        out = ami_xr.identify(ds)
    return out, [str(w.message) for w in said]


def test_losses_pick_the_quantity_where_the_noise_is_white():
    rng = np.random.default_rng(0)
    f = np.linspace(0.0, 100.0, 2049)
    e = rng.standard_normal((4, f.size)) + 1j * rng.standard_normal((4, f.size))
    w = 2 * np.pi * np.maximum(f, f[1])
    losses, stds = fn.whitening_losses(e / (1j * w) ** 2, f, [0, 1, 2])
    assert min(losses, key=losses.get) == 2
    assert losses[2] < 1.3 < 10 < losses[1] < losses[0]
    assert stds[2].shape == (4, f.size - 1)  # the 0 Hz line is left out
    # a stored noise std is converted, not estimated
    losses, _ = fn.whitening_losses(e, f, [0, 1], sigma=np.ones((4, f.size)))
    assert losses[0] == pytest.approx(1.0) and losses[1] > 100


def test_roughness_of_a_smooth_frf_is_not_noise():
    frf, _ = _system()
    h = frf[names.FRF].transpose(names.POINT, names.FREQUENCY).values
    assert fn.noise_dominated_share(h) < 0.1
    assert fn.noise_dominated_share(_noisy(frf, 0, 0.01, 0)[names.FRF].values) > 0.9
    # the block-quantile estimate is unbiased on white noise (within its scatter)
    rng = np.random.default_rng(1)
    e = (rng.standard_normal((8, 4096)) + 1j * rng.standard_normal((8, 4096))) / np.sqrt(2)
    assert np.median(fn.block_roughness_std(e)) == pytest.approx(1.0, rel=0.1)


@pytest.mark.parametrize("colour", [0, 2])
def test_same_modes_in_every_quantity(colour):
    frf, truth = _system()
    noisy = _noisy(frf, colour, 0.02, seed=7)
    results = {q: _identify(_given_as(noisy, q)) for q in QUANTITIES}
    white = QUANTITIES[colour]
    ref = results[white][0]
    n_true = truth.sizes[names.MODE]
    for q, (out, said) in results.items():
        # fitted where the noise is white, reported as given
        assert out.attrs[whitening.ATTR_QUANTITY] == white
        assert out.attrs[names.ATTR_QUANTITY] == q
        assert out[names.FRF].attrs[names.ATTR_UNITS] == _given_as(noisy, q)[names.FRF].attrs[
            names.ATTR_UNITS
        ]
        assert (q != white) == any("closest to white" in m for m in said)
        score = score_modes(out, truth)
        assert score.n_found >= n_true - 1 and score.n_spurious == 0
        # the same poles and mode vectors whatever the presentation
        np.testing.assert_allclose(
            out[names.EIGENVALUE].values, ref[names.EIGENVALUE].values, rtol=1e-6
        )
        phi = out[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
        phi0 = ref[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
        np.testing.assert_allclose(np.abs(phi), np.abs(phi0), rtol=1e-5, atol=1e-12)
        # results in the quantity given: the synthesis follows the clean FRF there, far closer
        # than the data do, and the residual is data less synthesis
        clean = _given_as(frf, q)[names.FRF].transpose(*out[names.FRF].dims).values
        synth = out[names.FRF_SYNTHESIZED].values
        data = out[names.FRF].values
        assert np.abs(synth - clean).mean() < 0.5 * np.abs(data - clean).mean()
        np.testing.assert_allclose(
            data - synth, out[names.FRF_RESIDUAL].values, atol=1e-12 * np.abs(data).max()
        )


def test_residues_are_those_of_the_quantity_given():
    frf, truth = _system()
    noisy = _noisy(frf, 2, 0.005, seed=2)
    out, _ = _identify(_given_as(noisy, "displacement"))  # fitted as accelerance
    assert out.attrs[whitening.ATTR_QUANTITY] == "acceleration"
    s = score_modes(out, truth)
    est = out[names.RESIDUE].transpose(names.POINT, names.MODE).values[:, s.identified_index]
    true = truth[names.RESIDUE].sel(point=out[names.POINT].values)
    true = true.transpose(names.POINT, names.MODE).values[:, s.true_index]
    # receptance residues: within a few percent at the points where the mode is strong
    strong = np.abs(true) > 0.3 * np.abs(true).max(axis=0)
    assert np.median(np.abs(est - true)[strong] / np.abs(true)[strong]) < 0.05
    mac = np.abs(np.sum(est.conj() * true, 0)) ** 2 / (
        np.sum(np.abs(est) ** 2, 0) * np.sum(np.abs(true) ** 2, 0)
    )
    assert np.all(mac > 0.99)


def test_noise_free_data_stay_in_their_quantity():
    frf, truth = _system()
    acc = _given_as(frf, "acceleration")
    out, said = _identify(acc)
    assert out.attrs[whitening.ATTR_QUANTITY] == "acceleration"
    assert "curvature" in out.attrs[whitening.ATTR_SOURCE]
    assert not any("closest to white" in m for m in said)
    assert score_modes(out, truth).n_found == truth.sizes[names.MODE]


@pytest.mark.parametrize("colour", [0, 2])
def test_the_noise_model_is_recorded_in_the_quantity_given(tmp_path, colour):
    """``noise_model_level * noise_model_shape`` follows the true noise std of every line
    within 25 % (median over points), whatever the presentation; it survives the file."""
    frf, _ = _system()
    noisy = _noisy(frf, colour, 0.02, seed=7)
    h = noisy[names.FRF].transpose(names.POINT, names.FREQUENCY).values
    f = noisy[names.FREQUENCY].values
    w = 2 * np.pi * f
    sigma = 0.02 * np.abs(h * (1j * w) ** colour).max(axis=1)  # as _noisy draws it
    for q in QUANTITIES:
        out, _ = _identify(_given_as(noisy, q))
        true = sigma[:, None] * w ** (names.QUANTITY_POWER[q] - colour)
        level = out[whitening.VAR_LEVEL].transpose(names.POINT).values
        est = level[:, None] * out[whitening.VAR_SHAPE].values[None, :]
        ratio = np.median(est / true, axis=0)
        assert np.all(np.abs(np.log(ratio[8:-8])) < np.log(1.25)), (q, ratio.min(), ratio.max())
    path = tmp_path / "m.nc"
    ami_xr.to_netcdf(out, path)
    back = ami_xr.open_dataset(path)
    np.testing.assert_allclose(back[whitening.VAR_SHAPE].values, out[whitening.VAR_SHAPE].values)
    assert back.attrs[whitening.ATTR_QUANTITY] == out.attrs[whitening.ATTR_QUANTITY]


def test_the_bode_plot_draws_the_noise_model():
    pytest.importorskip("matplotlib")
    from ami_xr.plot.modal import plot_bode

    frf, _ = _system()
    out, _ = _identify(_given_as(_noisy(frf, 2, 0.02, seed=7), "displacement"))
    fig = plot_bode(out, points=[out[names.POINT].values[0]])
    labels = [line.get_label() for line in fig.axes[0].lines]
    assert "noise (model)" in labels
    drawn = fig.axes[0].lines[labels.index("noise (model)")].get_ydata()
    level = float(out[whitening.VAR_LEVEL].values[0])
    np.testing.assert_allclose(drawn, level * out[whitening.VAR_SHAPE].values)


def test_units_that_cannot_be_converted_keep_the_quantity():
    """Response units that do not state their derivative ("V"): the FRFs stay as given and the
    record says so; identification still runs."""
    frf, truth = _system()
    acc = _given_as(_noisy(frf, 0, 0.02, seed=7), "acceleration")  # noise white in displacement
    acc.attrs[names.ATTR_RESPONSE_UNITS] = "V"
    out, said = _identify(acc)
    assert out.attrs[whitening.ATTR_QUANTITY] == "acceleration"
    assert "not convertible" in out.attrs[whitening.ATTR_SOURCE]
    assert not any("closest to white" in m for m in said)
    assert out.sizes[names.MODE] > 0
