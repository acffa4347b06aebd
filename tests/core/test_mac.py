"""The one MAC (ami_xr.core.modal.mac_matrix) against a naive loop, and its zero vector."""

from __future__ import annotations

import numpy as np

from ami_xr.core.modal import mac_matrix


def _naive(phi):
    k = phi.shape[1]
    out = np.empty((k, k))
    for a in range(k):
        for b in range(k):
            x, y = phi[:, a], phi[:, b]
            out[a, b] = abs(np.vdot(x, y)) ** 2 / (np.vdot(x, x).real * np.vdot(y, y).real)
    return out


def test_mac_matches_a_naive_loop():
    rng = np.random.default_rng(0)
    phi = rng.standard_normal((6, 4)) + 1j * rng.standard_normal((6, 4))
    mac = mac_matrix(phi)
    np.testing.assert_allclose(mac, _naive(phi), rtol=1e-12)
    np.testing.assert_allclose(np.diag(mac), 1.0, rtol=1e-12)
    assert np.all((mac >= 0) & (mac <= 1 + 1e-12))
    # scale and phase of a vector do not matter
    np.testing.assert_allclose(mac_matrix(phi * [1, 2j, -3, 0.5]), mac, rtol=1e-12)


def test_zero_vector_has_an_undefined_mac_and_leaves_the_others_alone():
    phi = np.array([[1.0, 0.0, 1.0], [0.0, 0.0, 1.0]], complex)
    with np.errstate(all="raise"):  # no warning either
        mac = mac_matrix(phi)
    assert np.all(np.isnan(mac[1])) and np.all(np.isnan(mac[:, 1]))
    np.testing.assert_allclose(mac[np.ix_([0, 2], [0, 2])], [[1.0, 0.5], [0.5, 1.0]])
