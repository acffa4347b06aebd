"""Exported modes read by SDynPy (issue 40): ami_xr writes the benchmark's modes as UFF 55 (modal
A = 1/lam, B = -1), SDynPy reads the file and rebuilds the FRFs from its shapes alone
(``ShapeArray.compute_frf``); printed: the largest difference from ami_xr's own synthesis (the
residues of the same modes), relative to the largest FRF value. Then the round trip tool -> UFF ->
SDynPy -> UFF -> tool: SDynPy writes its shapes back and ami_xr reads them.

Run where SDynPy is installed (``pip install sdynpy``; it is not an ami_xr dependency):
``python scripts/sdynpy_roundtrip.py``. Without it the script says so and exits 0.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from ami_xr import names  # noqa: E402
from ami_xr.errors import DataFileError  # noqa: E402
from ami_xr.io.netcdf import open_dataset  # noqa: E402
from ami_xr.io.uff import read_uff, write_uff  # noqa: E402

LIMIT = 1e-3  # issue 40: synthesis from the exported modes within 1e-3 of the tool's own


def _modes() -> tuple:
    """The benchmark's exact modes on UFF DOFs (points ``1+Z`` ... ``4+Z``, drive point 1+Z)."""
    truth = open_dataset(REPO / "sample_data" / "benchmark_truth.nc").load()
    labels = [f"{k + 1}+Z" for k in range(truth.sizes[names.POINT])]
    truth = truth.assign_coords({names.POINT: labels})
    truth.attrs[names.ATTR_DRIVE_POINT] = labels[0]
    return truth, labels


def _tool_frf(truth, freq: np.ndarray) -> np.ndarray:
    """Receptance H_p1 (point, frequency) from the residues: sum r/(iw - lam) + conj."""
    lam = truth[names.EIGENVALUE].values
    r = truth[names.RESIDUE].transpose(names.POINT, names.MODE).values
    s = 2j * np.pi * freq[:, None]
    return (r[:, None, :] / (s - lam) + r.conj()[:, None, :] / (s - lam.conj())).sum(-1)


def main() -> int:
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    os.environ.setdefault("MPLBACKEND", "Agg")
    try:
        import sdynpy as sdpy
    except ImportError:
        print("sdynpy is not installed: nothing to check (pip install sdynpy)")
        return 0
    start = time.process_time()
    truth, labels = _modes()
    freq = np.linspace(1.0, 20.0, 400)
    with tempfile.TemporaryDirectory() as tmp:
        path = write_uff(truth, Path(tmp) / "modes.uff", include=("modes",))
        shapes = sdpy.shape.from_unv(sdpy.uff.readunv(str(path)))
        nodes = np.arange(1, len(labels) + 1)
        responses = sdpy.coordinate_array(nodes, 3)
        reference = sdpy.coordinate_array([1], 3)
        frf = shapes.compute_frf(freq, responses, reference, displacement_derivative=0)
        theirs = np.asarray(frf.ordinate).reshape(len(labels), freq.size)
        ours = _tool_frf(truth, freq)
        error = np.abs(theirs - ours).max() / np.abs(ours).max()
        print(
            f"SDynPy read {shapes.size} modes of {path.name}; modal A read back: "
            f"{np.round(shapes.modal_mass.ravel()[:2], 6)} ..."
        )
        print(
            f"FRFs from SDynPy's shapes vs ami_xr's residues: max |diff| / max |H| = "
            f"{error:.2e} (limit {LIMIT:g})"
        )
        again = Path(tmp) / "sdynpy.uff"
        shapes.write_to_unv(str(again))
        record6 = again.read_text().splitlines()[7].split()
        print(
            f"SDynPy wrote its shapes back; dataset 55 record 6 (model, analysis, data "
            f"characteristic, specific type, data type, values per node): {record6}"
        )
        try:
            back = read_uff(again, kind="modes")
        except DataFileError as err:
            print(f"tool -> UFF -> SDynPy -> UFF -> tool: refused by ami_xr: {err}")
            print(f"cpu {time.process_time() - start:.1f} s")
            return 0 if error < LIMIT else 1
        order_b = np.argsort(back[names.NATURAL_FREQUENCY].values)
        order_t = np.argsort(truth[names.NATURAL_FREQUENCY].values)
        f_back = back[names.NATURAL_FREQUENCY].values[order_b]
        f_true = truth[names.NATURAL_FREQUENCY].values[order_t]
        z_diff = (
            back[names.DAMPING_RATIO].values[order_b] - truth[names.DAMPING_RATIO].values[order_t]
        )
        # residues rebuilt from what came back (lam phi_p phi_drive: ami_xr's convention)
        phi = back[names.MODE_VECTOR].sel({names.POINT: labels}).values[:, order_b]
        lam = back[names.EIGENVALUE].values[order_b]
        r_back = lam * phi * phi[0]
        r_true = truth[names.RESIDUE].transpose(names.POINT, names.MODE).values[:, order_t]
        print(
            f"tool -> UFF -> SDynPy -> UFF -> tool: frequencies max rel diff "
            f"{np.abs(f_back / f_true - 1).max():.2e}, damping max diff "
            f"{np.abs(z_diff).max():.2e}, residues max |diff| / max |r| "
            f"{np.abs(r_back - r_true).max() / np.abs(r_true).max():.2e}, "
            f"{back.sizes[names.POINT]} DOFs"
        )
    print(f"cpu {time.process_time() - start:.1f} s")
    return 0 if error < LIMIT else 1


if __name__ == "__main__":
    sys.exit(main())
