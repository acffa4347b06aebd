"""combine_runs: one FRF set from the runs of a roving test (issue 40 item 3)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import AssumptionWarning
from ami_xr.io.combine import POINT_RUN, RUN, RunMismatchError, combine_runs

from ..reference import sampled_response

FS = 256.0
N_SAMPLES = 2**15  # 128 s per run
NPERSEG = 1024  # 0.25 Hz lines, 32 averages (one per period)
BURN_IN = 4  # periods left out: 16 s, > 20 time constants of the slowest mode
N_POINTS = 20
DRIVE = 17
POINTS = list(range(1, N_POINTS + 1))


def _structure():
    """A 4-DOF chain (modes near 9, 26, 40 and 50 Hz, zeta 1.5-3 %) seen at 20 points: each
    point a linear interpolation between two neighbouring masses (like sensors along a beam)."""
    m = np.diag([1.0, 1.2, 0.9, 1.1])
    springs = [2.0e4, 3.0e4, 2.5e4, 2.2e4]
    k = np.zeros((4, 4))
    for i, s in enumerate(springs):
        k[i, i] += s
        if i + 1 < 4:
            k[i, i] += springs[i + 1]
            k[i, i + 1] = k[i + 1, i] = -springs[i + 1]
    c = 2.5 * m + 1e-4 * k
    x = np.linspace(0.0, 3.0, N_POINTS)  # positions between DOF 0 and DOF 3
    out = np.zeros((N_POINTS, 4))
    for j, xj in enumerate(x):
        i = min(int(xj), 2)
        out[j, i], out[j, i + 1] = 1 - (xj - i), xj - i
    truth = ami_xr.simulate.modal_model(m, c, k, point_labels=POINTS, output=out, drive_point=DRIVE)
    return truth


def _run(truth, points, seed: int, force_rms: float, noise: float) -> xr.Dataset:
    """One shaker run with periodic random excitation (a flat spectrum of random phases
    repeating every ``NPERSEG`` samples: no leakage with a boxcar window), its own force level,
    phases and output noise (``noise`` times each channel's rms), responses at ``points``; the
    first ``BURN_IN`` periods (the start transient) are not recorded."""
    rng = np.random.default_rng(seed)
    spectrum = np.exp(2j * np.pi * rng.random(NPERSEG // 2 + 1))
    spectrum[0] = spectrum[-1] = 1.0  # real; power at 0 Hz and Nyquist too: no 0/0 line
    period = np.fft.irfft(spectrum, NPERSEG)
    f = np.tile(period * force_rms / period.std(), N_SAMPLES // NPERSEG + BURN_IN)
    lam = truth[names.EIGENVALUE].values
    res = truth[names.RESIDUE].sel({names.POINT: points}).values
    y = sampled_response(f, lam, res, 1 / FS)[:, BURN_IN * NPERSEG :]
    f = f[BURN_IN * NPERSEG :]
    y += noise * y.std(axis=1, keepdims=True) * rng.standard_normal(y.shape)
    ts = ami_xr.make_time_dataset(
        y,
        fs=FS,
        force=f,
        points=points,
        drive_point=DRIVE if DRIVE in points else None,
        response_quantity="displacement",
        response_units="m",
    )
    return ami_xr.frf(ts, nperseg=NPERSEG, noverlap=0, window="boxcar", detrend="none")


@pytest.fixture(scope="module")
def roving():
    """The 10-run roving test (two sensors per run) and the same test as one run."""
    truth = _structure()
    runs = []
    for r in range(10):
        pts = POINTS[2 * r : 2 * r + 2]
        g = _run(truth, pts, seed=100 + r, force_rms=0.5 + 0.2 * r, noise=0.1 * (1 + 0.1 * r))
        g.attrs[names.ATTR_DRIVE_POINT] = DRIVE  # where the shaker is, measured or not
        runs.append(g)
    one = _run(truth, POINTS, seed=7, force_rms=1.0, noise=0.15)
    return truth, runs, one


def _identify(ds):
    return ami_xr.identify(ds, fmin=4.0, fmax=60.0)


def test_ten_runs_give_the_modes_of_one_run_within_sigma(roving):
    truth, runs, one = roving
    labels = [f"run{r:02d}.nc" for r in range(10)]
    combined = combine_runs(runs, run_labels=labels)
    ami_xr.validate(combined)
    assert list(combined[names.POINT].values) == POINTS
    assert combined.attrs[names.ATTR_DRIVE_POINT] == DRIVE
    assert list(combined[POINT_RUN].values) == [lab for lab in labels for _ in range(2)]
    # each run's force kept: its own autospectrum, levels (0.5 + 0.2 r)^2 apart
    gff = combined[names.FORCE_AUTOSPECTRUM]
    assert gff.dims == (RUN, names.FREQUENCY)
    level = gff.sel({names.FREQUENCY: slice(5, 60)}).mean(names.FREQUENCY).values
    expected = (0.5 + 0.2 * np.arange(10)) ** 2 * 2 / FS  # one-sided density of white noise
    np.testing.assert_allclose(level, expected, rtol=0.1)  # 200 lines x 63 averages: ~1 %
    for var in (names.COHERENCE, names.FRF_LINE_NOISE_STD, names.CROSS_SPECTRUM):
        np.testing.assert_array_equal(
            combined[var].sel({names.POINT: [5, 6]}).values, runs[2][var].values
        )
    assert "run_attributes" not in combined.attrs  # every run states the same attributes

    a, b = _identify(combined), _identify(one)
    fa, fb = a[names.NATURAL_FREQUENCY].values, b[names.NATURAL_FREQUENCY].values
    ft = truth[names.NATURAL_FREQUENCY].values
    assert fa.size == fb.size == ft.size == 4
    sa, sb = a[names.NATURAL_FREQUENCY_STD].values, b[names.NATURAL_FREQUENCY_STD].values
    za, zb = a[names.DAMPING_RATIO].values, b[names.DAMPING_RATIO].values
    dza, dzb = a[names.DAMPING_RATIO_STD].values, b[names.DAMPING_RATIO_STD].values
    # statistical: two independent estimates of the same modes, their difference within 3
    # combined sigma for the frequencies, 3.5 for the damping ratios (8 comparisons; measured:
    # see docs/data-model.md "A roving test from its runs")
    print(  # pytest -s shows the figures docs/data-model.md quotes
        f"|f_runs - f_one| / sigma {np.round(np.abs(fa - fb) / np.hypot(sa, sb), 2)}, "
        f"|zeta_runs - zeta_one| / sigma {np.round(np.abs(za - zb) / np.hypot(dza, dzb), 2)}, "
        f"|f_runs - f_truth| / sigma {np.round(np.abs(fa - ft) / sa, 2)}"
    )
    assert np.all(np.abs(fa - fb) < 3 * np.hypot(sa, sb)), (fa, fb, sa, sb)
    assert np.all(np.abs(za - zb) < 3.5 * np.hypot(dza, dzb)), (za, zb, dza, dzb)
    # and the combined set's within 3 sigma of the truth (no leakage: periodic excitation)
    assert np.all(np.abs(fa - ft) < 3 * sa), (fa, ft, sa)
    va, vb = a[names.MODE_VECTOR].values, b[names.MODE_VECTOR].values
    mac = np.abs(np.einsum("pm,pm->m", va.conj(), vb)) ** 2 / (
        np.linalg.norm(va, axis=0) ** 2 * np.linalg.norm(vb, axis=0) ** 2
    )
    assert np.all(mac > 0.99), mac


def test_netcdf_round_trip(roving, tmp_path):
    _, runs, _ = roving
    parts = [r.assign_attrs(operator=who) for r, who in zip(runs[:3], "AAB", strict=True)]
    combined = combine_runs(parts)
    assert json.loads(combined.attrs["run_attributes"]) == {
        "operator": {"run0": "A", "run1": "A", "run2": "B"}
    }
    assert json.loads(combined["run_history"].values[1])[0]["function"] == "ami_xr.frf"
    path = ami_xr.to_netcdf(combined, tmp_path / "set.nc")
    back = ami_xr.open_dataset(path)
    xr.testing.assert_identical(back.drop_attrs(), combined.drop_attrs())
    assert back.attrs[names.ATTR_DRIVE_POINT] == DRIVE


def test_runs_without_drive_point_take_the_others_with_a_warning(roving):
    _, runs, _ = roving
    parts = [r.copy() for r in runs[:3]]
    for p in parts[1:]:
        del p.attrs[names.ATTR_DRIVE_POINT]
    with pytest.warns(AssumptionWarning, match="run1, run2 state no drive point"):
        out = combine_runs(parts)
    assert out.attrs["combine_drive_point_assumed"] == "run1,run2"
    # the argument says it: no warning
    assert combine_runs(parts, drive_point=DRIVE).attrs[names.ATTR_DRIVE_POINT] == DRIVE


def test_disagreeing_drive_point_names_the_run(roving):
    _, runs, _ = roving
    parts = [r.copy() for r in runs[:3]]
    parts[2].attrs[names.ATTR_DRIVE_POINT] = 3
    with pytest.raises(RunMismatchError, match=r"run 'c': drive point 3, but run 'a' has 17"):
        combine_runs(parts, run_labels=["a", "b", "c"])
    with pytest.raises(ValueError, match="run 'run0': drive point 17, but the drive_point arg"):
        combine_runs(runs[:2], drive_point=5)


@pytest.mark.parametrize(
    "change, match",
    [
        (lambda d: d.isel({names.FREQUENCY: slice(0, 100)}), "run 'run1': frequency lines"),
        (lambda d: d.assign_attrs(response_units="mm"), "run 'run1': attribute 'response_units'"),
        (lambda d: d.assign_coords({names.POINT: [1, 9]}), "run 'run1': point 1 was measured in"),
    ],
)
def test_runs_that_are_not_one_set_are_refused(roving, change, match):
    _, runs, _ = roving
    with pytest.raises(RunMismatchError, match=match):
        combine_runs([runs[0], change(runs[1])])


def test_bad_arguments():
    with pytest.raises(ValueError, match="parts: expected a non-empty sequence"):
        combine_runs([])
    with pytest.raises(ValueError, match=r"parts\[0\]: expected an FRF Dataset or a file path"):
        combine_runs([3])
    with pytest.raises(ValueError, match="layout: expected one of"):
        one = ami_xr.make_frf_dataset(
            np.ones((1, 3), complex), [1.0, 2, 3], response_quantity="displacement"
        )
        combine_runs([one], layout="x")


def test_roving_hammer_by_reciprocity():
    """One sensor at point 2, the hammer at points 1..4: the set's points are the hammer
    positions, its drive point the sensor's point, FRFs unchanged (H_2p = H_p2)."""
    truth = _structure()
    f = np.linspace(1.0, 60.0, 120)
    h = ami_xr.simulate.frf(ami_xr.simulate.residues(truth, 2), f)[names.FRF]
    runs = []
    for p in (1, 2, 3, 4):
        g = ami_xr.make_frf_dataset(
            h.sel({names.POINT: [p]}).values, f, points=[2], drive_point=2, frf_source="analytic",
            response_quantity="displacement",
        )
        g.attrs[names.ATTR_DRIVE_POINT] = p  # where the hammer hit (unmeasured unless p = 2)
        g[names.FORCE_AUTOSPECTRUM] = (names.FREQUENCY, np.full(f.size, float(p)))
        g = g.assign_coords(point_x=(names.POINT, [0.5], {"units": "m"}))  # the sensor's place
        runs.append(g)
    out = combine_runs(runs)
    assert out.attrs["combine_layout"].startswith("roving hammer")
    assert list(out[names.POINT].values) == [1, 2, 3, 4]
    assert out.attrs[names.ATTR_DRIVE_POINT] == 2
    np.testing.assert_array_equal(out[names.FRF].values, h.sel({names.POINT: [1, 2, 3, 4]}).values)
    assert out[names.FORCE_AUTOSPECTRUM].dims == (RUN, names.FREQUENCY)
    assert "point_x" not in out.coords  # not the hammer positions' coordinates
    runs[3] = runs[3].assign_coords({names.POINT: [3]})
    with pytest.raises(RunMismatchError, match="run 'run3': response point 3, but the set's is 2"):
        combine_runs(runs, layout="roving_hammer")


def test_lines_a_run_left_undefined_stay_undefined(roving):
    """A run whose estimate is NaN at a line (recorded by ami_xr.frf in
    frf_undefined_frequencies) combines; the set records the union of those lines."""
    _, runs, _ = roving
    parts = [r.copy(deep=True) for r in runs[:3]]
    parts[1][names.FRF].values[:, 0] = np.nan
    parts[1].attrs.update(frf_undefined_frequencies=np.array([0.0]), frf_undefined_reason="Gff 0")
    out = combine_runs(parts)
    np.testing.assert_array_equal(out.attrs["frf_undefined_frequencies"], [0.0])
    assert out.attrs["frf_undefined_reason"] == "run run1: Gff 0"
    assert np.isnan(out[names.FRF].values[2:4, 0]).all()
