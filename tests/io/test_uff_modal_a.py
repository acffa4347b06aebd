"""UFF 55 export with modal A and B stated (issue 40 item 2): another tool rebuilds the FRFs
from the exported modes alone, and the 58 and 55 datasets hold the same DOFs."""

from __future__ import annotations

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.io.uff import read_uff, write_uff
from ami_xr.io.uff.write import MODAL_A_LINE, modal_a_b

pyuff = pytest.importorskip("pyuff")

POINTS = ["1+Z", "2+Z", "3-Y", "4+X"]
DRIVE = "2+Z"


@pytest.fixture(scope="module")
def result():
    """An identification result on a 4-point chain (1 % noise), with UFF point labels."""
    from ..reference import damped_chain

    truth = damped_chain(POINTS[:4] + ["5+Z"]).sel({names.POINT: POINTS})
    truth = ami_xr.simulate.residues(truth, DRIVE)
    f = np.linspace(0.5, 70.0, 700)
    g = ami_xr.simulate.frf(truth, f)
    h = g[names.FRF].values
    rng = np.random.default_rng(1)
    noise = rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape)
    g[names.FRF].values = h + 0.003 * np.abs(h).max(axis=1, keepdims=True) * noise
    return ami_xr.identify(g)


def _eq4(residue: np.ndarray, lam: np.ndarray, f: np.ndarray) -> np.ndarray:
    iw = 2j * np.pi * f[:, None, None]
    return (residue / (iw - lam) + residue.conj() / (iw - lam.conj())).sum(-1).T


def _node_dof(label: str) -> tuple[int, int, float]:
    node, sign, axis = int(label[0]), label[1], label[2]
    return node, "XYZ".index(axis) + 1, -1.0 if sign == "-" else 1.0


def test_pyuff_reads_modal_a_and_rebuilds_the_frfs(result, tmp_path):
    path = write_uff(result, tmp_path / "modes.uff")
    sets = pyuff.UFF(str(path)).read_sets()
    modes = [s for s in sets if s["type"] == 55]
    frfs = [s for s in sets if s["type"] == 58 and s["func_type"] == 4]
    lam = result[names.EIGENVALUE].values
    assert len(modes) == lam.size
    a = np.array([m["modal_a"] for m in modes])
    b = np.array([m["modal_b"] for m in modes])
    assert np.all(a != 0)
    # written with 6 significant digits (%13.5e)
    np.testing.assert_allclose(a, 1 / lam, rtol=1e-5)
    np.testing.assert_allclose(b, -1.0, rtol=1e-5)
    assert all(m["id4"].strip() == MODAL_A_LINE for m in modes)

    # synthesis from the file alone: H_jP = sum psi_j psi_P / (a (iw - lam)) + conj
    eig = np.array([m["eig"] for m in modes])
    psi = np.zeros((len(POINTS), len(modes)), complex)
    for k, m in enumerate(modes):
        nodes = list(m["node_nums"].astype(int))
        for i, lab in enumerate(POINTS):
            node, comp, sign = _node_dof(lab)
            psi[i, k] = sign * m[f"r{comp}"][nodes.index(node)]
    drive = POINTS.index(DRIVE)
    f = result[names.FREQUENCY].values
    theirs = _eq4(psi * psi[drive] / a, eig, f)
    ours = _eq4(result[names.RESIDUE].values, lam, f)
    err = np.abs(theirs - ours).max() / np.abs(ours).max()
    print(f"synthesis from the exported modes vs ami_xr: {err:.2e} of the peak")
    assert err < 1e-3, err

    # the same DOFs in 58 (responses) and 55 (non-zero values)
    dof58 = {(int(s["rsp_node"]), int(s["rsp_dir"])) for s in frfs}
    dof55 = set()
    for m in modes:
        for comp in (1, 2, 3):
            for node, v in zip(m["node_nums"].astype(int), m[f"r{comp}"], strict=True):
                if v != 0:
                    dof55.add((node, comp))
    assert {(n, abs(d)) for n, d in dof58} == dof55


def test_read_uff_scales_a_peer_files_shapes_by_its_modal_a(result, tmp_path):
    """A file from another tool with psi scaled to modal A = 2j (not 1/lam) reads back as
    ami_xr's mode vectors (lam Phi_j Phi_k = psi_j psi_k / A, up to sign)."""
    path = write_uff(result, tmp_path / "modes.uff", include=("modes",))
    sets = pyuff.UFF(str(path)).read_sets()
    peer = tmp_path / "peer.uff"
    out = pyuff.UFF(str(peer))
    for s in sets:
        s = dict(s)
        lam = s["eig"]
        a = 2j
        scale = np.sqrt(a * lam)  # psi = sqrt(a lam) Phi gives psi psi / a = lam Phi Phi
        for c in ("r1", "r2", "r3"):
            s[c] = np.asarray(s[c]) * scale
        s.update(modal_a=a, modal_b=-lam * a, id1="peer modes")
        out.write_sets(s, mode="add")
    back = read_uff(peer, kind="modes")
    # a modes-only file lists DOFs in + directions: 3-Y is -(3+Y)
    plus = [lab.replace("-", "+") for lab in POINTS]
    signs = np.array([-1.0 if "-" in lab else 1.0 for lab in POINTS])[:, None]
    phi = signs * back[names.MODE_VECTOR].sel({names.POINT: plus}).values
    want = result[names.MODE_VECTOR].values
    lam = result[names.EIGENVALUE].values
    np.testing.assert_allclose(lam * phi * phi[1], lam * want * want[1], rtol=1e-4, atol=0)


def test_modal_a_b_of_a_bad_eigenvalue_states_nothing():
    assert modal_a_b(0j) == (0j, 0j)
    assert modal_a_b(complex(np.nan, 1.0)) == (0j, 0j)
    a, b = modal_a_b(-1 + 10j)
    assert a == pytest.approx(1 / (-1 + 10j)) and b == -1
