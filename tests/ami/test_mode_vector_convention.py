"""Issue 24 item 3: mode vectors in one (displacement) convention whatever the FRF quantity."""

from __future__ import annotations

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami.global_fit import ATTR_MODE_VECTOR_CONVENTION


@pytest.fixture(scope="module")
def three_kinds():
    g, truth = ami_xr.simulate.random_system(
        n_points=6, n_modes=6, noise=1e-4, seed=11, n_frequencies=1024
    )
    kinds = {
        "displacement": g,
        "velocity": ami_xr.convert_quantity(g, "velocity"),
        "acceleration": ami_xr.convert_quantity(g, "acceleration"),
    }
    return {q: ami_xr.identify(ds) for q, ds in kinds.items()}, truth


def _close_up_to_sign(a, b):
    return min(np.linalg.norm(a - b), np.linalg.norm(a + b)) / np.linalg.norm(a)


@pytest.mark.parametrize("quantity", ["velocity"])
def test_identify_gives_the_same_mode_vectors_from_receptance_and_mobility(three_kinds, quantity):
    results, truth = three_kinds
    ref, other = results["displacement"], results[quantity]
    fn_ref = ref[names.NATURAL_FREQUENCY].values
    fn = other[names.NATURAL_FREQUENCY].values
    compared = 0
    for k, f0 in enumerate(fn_ref):
        if np.sort(np.abs(fn_ref - f0))[1] < 0.05 * f0:
            continue  # a close pair: which of the two is which is not this test's subject
        j = int(np.argmin(np.abs(fn - f0)))
        assert abs(fn[j] - f0) < 1e-3 * f0
        a = ref[names.MODE_VECTOR].isel(mode=k).values
        b = other[names.MODE_VECTOR].isel(mode=j).values
        tol = 0.01  # before the fix: |lam|^(1/2) times larger and 45 deg off
        assert _close_up_to_sign(a, b) < tol, (f0, a, b)
        compared += 1
    assert compared >= 3
    # units of the displacement convention, stated on the variable
    assert other[names.MODE_VECTOR].attrs["units"] == ref[names.MODE_VECTOR].attrs["units"]
    assert other[names.MODE_VECTOR].attrs["units"] == "sqrt(m/N)"
    assert "displacement" in other[names.MODE_VECTOR].attrs[ATTR_MODE_VECTOR_CONVENTION]


@pytest.mark.parametrize("quantity", ["displacement", "velocity", "acceleration"])
def test_global_fit_at_the_true_poles_gives_the_true_mode_vectors(quantity):
    """The convention alone: residues at the exact eigenvalues from each FRF type, eq. 8 on
    the receptance residues, equal the simulator's (eq. 8) mode vectors."""
    g, truth = ami_xr.simulate.random_system(
        n_points=6, n_modes=6, noise=0.0, seed=11, n_frequencies=1024
    )
    ds = g if quantity == "displacement" else ami_xr.convert_quantity(g, quantity, dc="drop")
    ds = ds.assign({names.EIGENVALUE: truth[names.EIGENVALUE]})
    # accelerance = sum lam^2 A / (i w - lam) + a constant: the residual terms carry it
    out = ami_xr.global_fit(ds, band="all", residual_terms=True)
    for k in range(truth.sizes["mode"]):
        a = truth[names.MODE_VECTOR].isel(mode=k).values
        b = out[names.MODE_VECTOR].isel(mode=k).values
        assert _close_up_to_sign(a, b) < 1e-3, (quantity, k)
    assert out[names.MODE_VECTOR].attrs["units"] == "sqrt(m/N)"


def test_uff55_states_the_convention(three_kinds, tmp_path):
    pytest.importorskip("pyuff")
    results, _ = three_kinds
    path = tmp_path / "modes.uff"
    ami_xr.write_uff(results["velocity"], path)
    text = path.read_text()
    assert "displacement mode vectors, eq. 8" in text
    assert "units sqrt(m/N)" in text
