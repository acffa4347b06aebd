"""Issue 22 item 2 hooks in the pipeline: one reference flags a pair it cannot separate on the
SIMO path as on the multi-reference one; pipeline helpers are public; one mode-vector
convention after the exponential-window correction."""

from __future__ import annotations

import ast
import inspect
import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names, simulate
from ami_xr.ami import mimo, mimo_refit, pipeline
from ami_xr.core import flags
from ami_xr.io.datasets import make_frf_dataset, select_reference

from ..reference import damped_chain

F = np.linspace(0.05, 50.0, 1000)


def _noisy(ds, level, seed):
    rng = np.random.default_rng(seed)
    g = ds[names.FRF]
    re = simulate.add_noise(g.real, level, rng=rng, dim="frequency")
    im = simulate.add_noise(g.imag, level, rng=rng, dim="frequency")
    return ds.assign({names.FRF: (re + 1j * im).assign_attrs(g.attrs)})


def test_simo_and_one_reference_multi_reference_carry_the_same_flags():
    # a 0.5 % split pair at 0.1 % noise, without the refinement (which would separate it):
    # one reported mode whose band holds two shapes
    truth = simulate.symmetric_structure(0.005)
    ds = _noisy(simulate.frf(truth, F, references=[2]), 0.001, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        multi = ami_xr.identify(ds, refine=False)
        simo = ami_xr.identify(select_reference(ds, 2), refine=False)
    np.testing.assert_allclose(multi[names.EIGENVALUE].values, simo[names.EIGENVALUE].values)
    assert multi[names.QUALITY_FLAGS].values.tolist() == simo[names.QUALITY_FLAGS].values.tolist()
    flagged = flags.has(flags.decode(simo[names.QUALITY_FLAGS].values), names.FLAG_REPEATED_ROOT)
    fn = simo[names.NATURAL_FREQUENCY].values
    pair = float(truth[names.NATURAL_FREQUENCY].values[1])
    # the split pair is flagged (on the SIMO path too, which never flagged before issue 22)
    assert flagged[np.argmin(np.abs(fn - pair))]
    # the well separated single modes are not
    for f0 in (10.0, 30.0):
        assert not flagged[np.argmin(np.abs(fn - f0))]


@pytest.mark.parametrize("module", [mimo, mimo_refit])
def test_mimo_uses_no_private_name_of_the_pipeline_or_the_noise_model(module):
    tree = ast.parse(inspect.getsource(module))
    private = [
        n.attr
        for n in ast.walk(tree)
        if isinstance(n, ast.Attribute)
        and isinstance(n.value, ast.Name)
        and n.value.id in ("pl", "whitening")
        and n.attr.startswith("_")
    ]
    assert private == []
    assert callable(pipeline.reported) and callable(pipeline.given_back)


def _chain():
    return damped_chain()


def _windowed(truth, power, beta, f, references=None):
    """FRFs (response quantity of derivative ``power``) of ``truth`` as an exponential window
    of decay ``beta`` leaves them: the poles moved by -beta, the residues those of the
    unwindowed FRF (``lam^k`` times the receptance residues ``lam phi_j phi_r``)."""
    lam = truth[names.EIGENVALUE].values
    phi = truth[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
    s = 2j * np.pi * f
    refs = (
        [0]
        if references is None
        else [list(truth[names.POINT].values).index(r) for r in references]
    )
    g = np.zeros((len(refs), phi.shape[0], f.size), complex)
    for i, r in enumerate(refs):
        a = lam**power * lam * phi * phi[r]  # (P, K)
        g[i] = np.einsum("pk,kf->pf", a, 1 / (s[None, :] - (lam - beta)[:, None]))
        g[i] += np.einsum("pk,kf->pf", np.conj(a), 1 / (s[None, :] - np.conj(lam - beta)[:, None]))
    quantity = ("displacement", "velocity", "acceleration")[power]
    points = truth[names.POINT].values
    common = dict(response_quantity=quantity, frf_source=names.SOURCE_ANALYTIC)
    if references is None:
        ds = make_frf_dataset(g[0], f, points=points, drive_point=points[refs[0]], **common)
    else:
        ds = make_frf_dataset(g, f, points=points, references=references, **common)
    ds.attrs[names.ATTR_EXP_DECAY] = beta
    return ds


def _close_up_to_sign(a, b):
    return min(np.linalg.norm(a - b), np.linalg.norm(a + b)) / np.linalg.norm(b)


@pytest.mark.parametrize("power", [1])
def test_window_corrected_mode_vectors_of_mobility_are_the_receptance_convention(power):
    truth = _chain()
    f = np.linspace(0.0, 120.0, 1200)
    beta = 2.0  # 1/s: well above the lightest mode's |Re lam|
    true_phi = truth[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
    true_lam = truth[names.EIGENVALUE].values
    for refs in (None, [1, 4]):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = ami_xr.identify(_windowed(truth, power, beta, f, refs))
        assert out.attrs[names.ATTR_EXP_CORRECTED] == beta
        lam = out[names.EIGENVALUE].values
        np.testing.assert_allclose(np.sort_complex(lam), np.sort_complex(true_lam), rtol=1e-6)
        phi = out[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
        for k, lk in enumerate(true_lam):
            j = int(np.argmin(np.abs(lam - lk)))
            # before: mobility residues went into eq. 8 undivided (|lam|^(1/2) off, 45 deg)
            assert _close_up_to_sign(phi[:, j], true_phi[:, k]) < 1e-4, (refs, k)
        assert "displacement" in out[names.MODE_VECTOR].attrs["convention"]
        assert out[names.MODE_VECTOR].attrs[names.ATTR_UNITS] == "sqrt(m/N)"
