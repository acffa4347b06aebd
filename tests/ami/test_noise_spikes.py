"""No noise spike as a mode (issue 37 item 3): narrow poles the noise explains are dropped,
narrow modes that stand above the noise are kept."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami import spikes
from ami_xr.simulate import random_system, score_modes


def _with_noise(frf, level, seed):
    rng = np.random.default_rng(seed)
    h = frf[names.FRF].values
    sig = np.abs(h).max(axis=-1, keepdims=True) * level
    e = (rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape)) / np.sqrt(2)
    out = frf.copy()
    out[names.FRF] = (frf[names.FRF].dims, h + sig * e)
    out.attrs[names.ATTR_SOURCE] = names.SOURCE_MEASURED
    return out


def _identify(ds, **kw):
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        out = ami_xr.identify(ds, **kw)
    return out, [str(w.message) for w in said]


@pytest.mark.parametrize("seed", [0, *(pytest.param(s, marks=pytest.mark.slow) for s in (1, 2))])
def test_a_noisy_band_without_modes_gives_no_mode(seed):
    """Modes up to 32 Hz; over 60-75 Hz the noise is 20 times higher (a band of noise spikes,
    4 % of the peak). Before issue 37 item 3 each seed reported 3-6 modes of zeta 1e-5-6e-4
    there; now none, and the real modes below are unchanged."""
    f = np.linspace(0.05, 100.0, 2000)
    frf, truth = random_system(6, "chain", seed=seed, frequency=f, max_frequency_hz=40.0)
    level = 0.002 * np.where((f > 60) & (f < 75), 20.0, 1.0)
    out, said = _identify(_with_noise(frf, level, seed))
    fn = out[names.NATURAL_FREQUENCY].values
    assert not np.any(fn > 45.0), fn
    assert score_modes(out, truth).n_spurious == 0
    assert "noise_spike_rule" in out.attrs


def test_a_narrow_mode_above_the_noise_is_kept():
    """A 0.05 %-damped mode on lines 4x its half-power bandwidth apart, 1 % noise: kept."""
    f = np.linspace(0.2, 50.0, 250)
    frf, truth = random_system(
        5, "chain", seed=4, frequency=f, max_frequency_hz=40.0, damping=(0.0005, 0.0006)
    )
    widths = 2 * truth[names.DAMPING_RATIO].values * truth[names.NATURAL_FREQUENCY].values
    assert np.any(widths < 2 * (f[1] - f[0]))  # narrow in the rule's sense
    out, said = _identify(_with_noise(frf, 0.01, 0))
    score = score_modes(out, truth, tolerance=20.0)
    assert score.n_found == truth.sizes[names.MODE]
    assert not any("narrower than a line" in m for m in said)


def test_spike_modes_rule_on_a_hand_made_result():
    """Two narrow poles of opposite residue at one frequency between lines are dropped
    together, a strong narrow pole seen at two points is kept, and one seen at a single point
    of four is dropped."""
    f = np.arange(1.25, 101.0, 0.5)

    rng = np.random.default_rng(0)
    resid = (rng.standard_normal((4, f.size)) + 1j * rng.standard_normal((4, f.size))) * 1e-3
    w1, w2 = 2j * np.pi * 40.0, 2j * np.pi * 70
    lam = np.array([-0.001 + w1, -0.001 + w1, -0.01 + w2, -0.01 + w2 + 2j * np.pi * 10])
    res = np.array(
        [[0.5, -0.5, 1.0, 1.0], [0.5, -0.5, 1.0, 0], [0, 0, 0.5, 0], [0, 0, 0.0, 0]], complex
    )
    ds = ami_xr.make_frf_dataset(resid, f, frf_source="measured", response_quantity="displacement")
    ds = ds.assign(
        {
            names.FRF_RESIDUAL: ((names.POINT, names.FREQUENCY), resid),
            names.EIGENVALUE: ((names.MODE,), lam),
            names.NATURAL_FREQUENCY: ((names.MODE,), np.abs(lam) / (2 * np.pi)),
            names.DAMPING_RATIO: ((names.MODE,), -lam.real / np.abs(lam)),
            names.RESIDUE: ((names.POINT, names.MODE), res),
        }
    ).assign_coords({names.MODE: [1, 2, 3, 4]})
    drop, snr = spikes.spike_modes(ds)
    assert drop.tolist() == [True, True, False, True]
    assert snr[2] > 100 and snr[3] > 100  # the last is strong, but at one point only
    # each of the first two alone stands far above the noise: only together they cancel
    alone, _ = spikes.spike_modes(ds.isel({names.MODE: [0, 2]}))
    assert alone.tolist() == [False, False]


def test_a_pole_damped_above_zeta_max_is_no_mode():
    """A 50 %-damped pole (the tail of what lies beyond the band) is not reported when
    ``zeta_max`` is given: its contribution moves from the synthesis to the residual, the
    attribute lists it; a 2 %-damped one stays, and without ``zeta_max`` nothing is dropped."""
    f = np.arange(1.0, 50.0, 0.25)
    w = 2j * np.pi * f
    lam = np.array(
        [-0.02 * 2 * np.pi * 10 + 2j * np.pi * 10, -0.5 * 2 * np.pi * 40 + 2j * np.pi * 40]
    )
    res = np.array([[1.0j, 3.0j]])
    part = res[0][None, :, None] / (w[None, None, :] - lam[None, :, None])
    part = part + np.conj(res[0])[None, :, None] / (w[None, None, :] - np.conj(lam)[None, :, None])
    synth = part.sum(axis=1)
    ds = ami_xr.make_frf_dataset(synth, f, frf_source="measured", response_quantity="displacement")
    ds = ds.assign(
        {
            names.FRF_SYNTHESIZED: ((names.POINT, names.FREQUENCY), synth),
            names.FRF_RESIDUAL: ((names.POINT, names.FREQUENCY), np.zeros_like(synth)),
            names.EIGENVALUE: ((names.MODE,), lam),
            names.NATURAL_FREQUENCY: ((names.MODE,), np.abs(lam) / (2 * np.pi)),
            names.DAMPING_RATIO: ((names.MODE,), -lam.real / np.abs(lam)),
            names.RESIDUE: ((names.POINT, names.MODE), res),
        }
    ).assign_coords({names.MODE: [1, 2]})
    assert spikes.overdamped_modes(ds, 0.25).tolist() == [False, True]
    assert spikes.drop_noise_spikes(ds.copy()).sizes[names.MODE] == 2
    with pytest.warns(ami_xr.errors.AssumptionWarning, match="damped above zeta_max"):
        out = spikes.drop_noise_spikes(ds.copy(), 0.25)
    assert out.sizes[names.MODE] == 1
    np.testing.assert_allclose(out[names.EIGENVALUE].values, lam[:1], rtol=1e-12)
    assert out.attrs[spikes.ATTR_OVER_DROPPED] == f"{np.abs(lam[1]) / (2 * np.pi):.6g}"
    assert "zeta_max = 0.25" in out.attrs[spikes.ATTR_OVER_RULE]
    # what the dropped pole explained is now residual; synthesis + residual is still the data
    np.testing.assert_allclose(out[names.FRF_RESIDUAL].values, part[:, 1], rtol=1e-10)
    np.testing.assert_allclose(
        out[names.FRF_SYNTHESIZED].values + out[names.FRF_RESIDUAL].values, synth, rtol=1e-10
    )


def test_the_lab_sweep_reports_no_overdamped_pole():
    """A simulated sweep ending at 24 Hz below a 32 Hz mode, measured as velocity: before, a
    44 %-damped pole at 23.3 Hz (the refinement's model of that tail) was reported as a mode;
    now the four clean modes only."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
    try:
        import benchmark_lab_band as lb
    finally:
        sys.path.pop(0)
    est, truth, _ = lb._case(1, "sweep", "velocity")
    out, said = _identify(est)
    assert score_modes(out, truth).n_spurious == 0
    assert np.all(out[names.DAMPING_RATIO].values < 0.25)
    assert spikes.ATTR_OVER_DROPPED in out.attrs
