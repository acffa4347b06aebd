"""ami_xr.simulate.symmetric_structure, and exact truth at repeated roots (simulate.modal)."""

from __future__ import annotations

import numpy as np
import pytest

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.simulate import eigen, modal, symmetric_structure
from ami_xr.simulate.symmetric import ring_matrices


def _matrices(split: float):
    """M, C, K of symmetric_structure(split) rebuilt here from the docstring's recipe."""
    m, k0 = ring_matrices(6)
    n = 6
    w = np.sqrt(3948.0 + 2 * 7900.0 * (1 - np.cos(2 * np.pi / n)))
    v = np.cos(2 * np.pi * np.arange(n) / n) * np.sqrt(2.0 / n)
    k = k0 + w**2 * ((1 + split) ** 2 - 1) * np.outer(v, v)
    return m, 2 * 0.01 / w * k, k


def _direct(m, c, k, f):
    """H(w) = (K - w^2 M + i w C)^-1 at each frequency: (f, point, reference)."""
    w = 2 * np.pi * np.asarray(f)
    return np.array([np.linalg.inv(k - x**2 * m + 1j * x * c) for x in w])


@pytest.mark.parametrize("split", [0.0, 0.001])
def test_pair_repeated_or_split_by_the_asked_amount(split):
    truth = symmetric_structure(split)
    fn = truth[names.NATURAL_FREQUENCY].values
    lo, hi = truth.attrs["split_pair"]
    assert (lo, hi) == (2, 3)
    assert truth.attrs["repeated_pairs"] == [2, 3, 4, 5]
    assert truth.attrs["split"] == split
    got = fn[hi - 1] / fn[lo - 1] - 1
    assert got == pytest.approx(split, abs=1e-12)
    # the other pair stays exactly repeated; the single modes do not move
    assert fn[4] / fn[3] - 1 == pytest.approx(0.0, abs=1e-12)
    ref = symmetric_structure(0.0)[names.NATURAL_FREQUENCY].values
    np.testing.assert_allclose(fn[[0, 1, 3, 4, 5]], ref[[0, 1, 3, 4, 5]], rtol=1e-12)
    np.testing.assert_allclose(
        fn, [10.0, 17.32, 17.32 * (1 + split), 26.46, 26.46, 30.0], rtol=1e-3
    )


@pytest.mark.parametrize("split", [0.0, 0.001])
def test_frfs_from_truth_equal_the_direct_solution(split):
    truth = symmetric_structure(split)
    points = truth[names.POINT].values.tolist()
    f = np.array([3.0, 12.0, 17.3, 17.3238, 17.33, 17.341, 26.46, 28.0, 30.0, 45.0])
    g = modal.frf(truth, f, references=points)[names.FRF]
    g = g.transpose(names.FREQUENCY, names.POINT, names.REFERENCE).values
    h = _direct(*_matrices(split), f)
    err = np.abs(g - h).max(axis=(1, 2)) / np.abs(h).max(axis=(1, 2))
    assert np.all(err < 1e-10), err


def test_repeated_root_mode_vectors_made_orthogonal():
    """Without the orthogonalisation of a repeated root the pair's FRFs are off by O(1)."""
    m, c, k = _matrices(0.0)
    lam, phi = modal.state_space_modes(m, c, k)
    b = 2 * lam[1] * m + c
    cross = phi[:, 1] @ b @ phi[:, 2]
    assert abs(cross) < 1e-10 * abs(phi[:, 1] @ b @ phi[:, 1])
    # an arbitrary (non-orthogonal) basis of the eigenspace is put right
    v = phi[:, 1:3] @ np.array([[1.0, 0.7 + 0.2j], [0.3, 1.0]])
    w = eigen._b_orthogonal(v.copy(), b)
    assert abs(w[:, 0] @ b @ w[:, 1]) < 1e-12 * abs(w[:, 0] @ b @ w[:, 0])
    # isotropic vectors (phi^T B phi = 0) are mixed first
    iso = phi[:, 1:3] / np.sqrt(phi[:, 1:3].T @ b @ phi[:, 1:3]).diagonal()
    v = np.stack([iso[:, 0] + 1j * iso[:, 1], iso[:, 0] - 1j * iso[:, 1]], axis=1)
    assert abs(v[:, 0] @ b @ v[:, 0]) < 1e-12
    w = eigen._b_orthogonal(v.copy(), b)
    d = w.T @ b @ w
    assert abs(d[0, 1]) < 1e-12 * min(abs(d[0, 0]), abs(d[1, 1]))


def test_labels_drive_point_and_bad_input():
    truth = symmetric_structure(0.001, point_labels=list("abcdef"), drive_point="b")
    assert truth[names.POINT].values.tolist() == list("abcdef")
    assert truth.attrs[names.ATTR_DRIVE_POINT] == "b"
    assert names.RESIDUE in truth
    eight = symmetric_structure(0.01, n_masses=8, pair=2)
    assert eight.attrs["split_pair"] == [4, 5]
    assert eight.attrs["repeated_pairs"] == [2, 3, 4, 5, 6, 7]
    fn = eight[names.NATURAL_FREQUENCY].values
    assert fn[4] / fn[3] - 1 == pytest.approx(0.01, abs=1e-12)
    with pytest.raises(AmiXrValueError, match="split"):
        symmetric_structure(-0.1)
    with pytest.raises(AmiXrValueError, match="split"):
        symmetric_structure(0.6)
    with pytest.raises(AmiXrValueError, match="pair"):
        symmetric_structure(pair=3)
    with pytest.raises(AmiXrValueError, match="n_masses"):
        symmetric_structure(n_masses=2)
    with pytest.raises(AmiXrValueError, match="damping_ratio"):
        symmetric_structure(damping_ratio=0.0)
