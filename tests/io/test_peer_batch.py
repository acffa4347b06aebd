"""``batch`` over a folder of files other tools wrote (issue 40): every file converts or is refused
with a message naming the file, the dataset and the reason, and nothing stray is written.

The folder: pyuff's own test files (``sample_data/pyuff/`` and the four in ``sample_data/``,
MIT, see ``sample_data/README.md``) and two files made here by pyuff's writer: a test's FRFs with
the modes someone fitted (datasets 58 + 55), and power spectral densities (58, function type 9).
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.app.batch import batch
from ami_xr.io.formats import read_any, write_any
from ami_xr.io.reference_modes import REFERENCE_MAC

from ..reference import REPO
from .pyuff_records import frf_record, read_sets, write_sets

pyuff = pytest.importorskip("pyuff")

SAMPLE = REPO / "sample_data"
COPIED = [
    *sorted((SAMPLE / "pyuff").glob("*.uff")),
    *(SAMPLE / n for n in ("measurement.uff", "non_ascii_header.uff")),
    *(SAMPLE / n for n in ("uff55_translation.uff", "uff55_translation_rotation.uff")),
]
NODES = {"tip": 1, "m1": 2, "m2": 3, "m3": 4}

# file -> (status, what the message must say)
EXPECTED = {
    "time-history-not-all-columns-filled.uff": (
        "failed",
        "the time records (dataset 58, function type 1) hold responses at 1 DOF(s) ['0'] and no "
        "force record",
    ),
    "binary8byte.uff": ("failed", "(dataset 58, function type 1) hold responses at 1 DOF(s)"),
    "1858.uff": ("failed", "found datasets 1858 (dataset 58 qualifiers) x2"),
    "heat_engine_housing.uff": ("failed", "2414 (analysis data (FE results))"),
    "mesh_test_uff2412_mixed.uff": ("failed", "18 (coordinate systems), 15 (nodes), 2412"),
    "TestLab 161 164 18 15 82.uff": ("failed", "82 (trace lines) x3"),
    "dataset_milestone_in_header.uff": (
        "failed",
        "dataset 58 #1 (DOF 1/1) is incomplete: its header declares 2508876 values",
    ),
    "uff55 sample_test record10.uff": ("failed", "a modes file (1 mode(s), no FRFs)"),
    "uff55_translation.uff": ("failed", "a modes file (3 mode(s), no FRFs)"),
    "uff55_translation_rotation.uff": ("failed", "a modes file (1 mode(s), no FRFs)"),
    "non_ascii_header.uff": ("failed", "6 lines; the single-mode fit needs at least 8"),
    "psd.uff": ("failed", "found datasets 58 (power spectral density, function type 9) x4"),
    "measurement.uff": ("ok", ""),
    "frf_and_modes.uff": ("ok", ""),
}


def _frf_record(point, values, freq, func=4):
    return frf_record(
        values,
        freq,
        rsp_node=NODES[point],
        id1=f"{point} / tip",
        func_type=func,
        ord_data_type=6 if func == 4 else 4,
        ordinate_spec_data_type=8,
        ordinate_axis_units_lab="m",
    )


def _fitted_mode(k, truth):
    shape = truth[names.MODE_VECTOR].isel({names.MODE: k}).values
    shape = np.real(shape * np.exp(-1j * np.angle(shape[np.argmax(np.abs(shape))])))
    zeros = np.zeros(len(NODES))
    return pyuff.prepare_55(
        model_type=1,
        id1="modes fitted by another tool",
        analysis_type=2,
        data_ch=2,
        spec_data_type=8,
        data_type=2,
        n_data_per_node=3,
        node_nums=list(NODES.values()),
        load_case=1,
        mode_n=k + 1,
        freq=float(truth[names.NATURAL_FREQUENCY][k]),
        modal_m=1.0,
        modal_damp_vis=float(truth[names.DAMPING_RATIO][k]),
        modal_damp_his=0.0,
        r1=zeros,
        r2=zeros,
        r3=shape,
    )


@pytest.fixture(scope="module")
def peer_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("peer")
    for path in COPIED:
        shutil.copy(path, folder / path.name)
    frf = ami_xr.open_dataset(SAMPLE / "benchmark_frf_clean.nc").load()
    truth = ami_xr.open_dataset(SAMPLE / "benchmark_truth.nc").load()
    freq = frf[names.FREQUENCY].values
    records = [_frf_record(p, frf[names.FRF].sel(point=p).values, freq) for p in NODES]
    write_sets(folder / "frf_and_modes.uff", records + [_fitted_mode(k, truth) for k in range(4)])
    psd = [_frf_record(p, np.abs(frf[names.FRF].sel(point=p).values) ** 2, freq, 9) for p in NODES]
    write_sets(folder / "psd.uff", psd)
    return folder, truth


@pytest.fixture(scope="module")
def summary(peer_folder, tmp_path_factory):
    folder, _ = peer_folder
    out = tmp_path_factory.mktemp("peer_out")
    return batch(folder, out, progress=False), out


def test_every_peer_file_converts_or_is_refused_naming_the_dataset_and_the_reason(summary):
    result, out = summary
    rows = {r["file"]: r for r in result.rows}
    assert sorted(rows) == sorted(EXPECTED)
    for name, (status, said) in EXPECTED.items():
        row = rows[name]
        assert row["status"] in ((status, "capped") if status == "ok" else (status,)), row
        assert said in row["message"], (name, row["message"])
        if status == "failed" and "Error: frequency" not in row["message"]:
            assert row["message"].split(": ", 2)[1] == name  # the file named first
    written = sorted(p.name for p in out.rglob("*") if p.is_file())
    ok = sorted(f"{n[: -len('.uff')]}.modes.nc" for n, r in rows.items() if r["status"] != "failed")
    assert written == sorted([*ok, "batch_summary.csv"])  # no stray output
    assert int(rows["measurement.uff"]["modes"]) >= 5


def test_the_files_own_modes_are_kept_as_the_reference_set(summary, peer_folder):
    result, out = summary
    _, truth = peer_folder
    modes = ami_xr.open_dataset(out / "frf_and_modes.modes.nc").load()
    np.testing.assert_allclose(
        modes["reference_" + names.NATURAL_FREQUENCY].values,
        truth[names.NATURAL_FREQUENCY].values,
        rtol=1e-5,  # dataset 55 holds the frequency in E13.5
    )
    found = np.sort(modes[names.NATURAL_FREQUENCY].values)
    np.testing.assert_allclose(found, truth[names.NATURAL_FREQUENCY].values, rtol=1e-3)
    assert (modes[REFERENCE_MAC].max(names.MODE).values > 0.9).all()


@pytest.mark.parametrize(
    "name", ["uff55 sample_test record10.uff", "uff55_translation.uff", "measurement.uff"]
)
def test_a_readable_peer_file_converts_value_by_value(peer_folder, tmp_path, name):
    folder, _ = peer_folder
    path = folder / name
    sets = read_sets(path)
    ds = read_any(path)
    back = ami_xr.open_dataset(write_any(ds, tmp_path / "x.nc")).load()
    if names.FRF in ds:
        want = np.stack([np.asarray(s["data"]) for s in sets if s["type"] == 58])
        np.testing.assert_allclose(back[names.FRF].values, want, rtol=1e-12)
        assert back.attrs[names.ATTR_RESPONSE_UNITS] == ds.attrs[names.ATTR_RESPONSE_UNITS]
        return
    shapes = [s for s in sets if s["type"] == 55]
    if shapes[0]["analysis_type"] == 3:  # complex modes: the eigenvalue as written
        eig = [complex(s["eig"]) for s in shapes]
        np.testing.assert_allclose(back[names.EIGENVALUE].values, eig, rtol=1e-12)
    else:  # normal modes: frequency and damping as written
        freq = [float(s["freq"]) for s in shapes]
        np.testing.assert_allclose(back[names.NATURAL_FREQUENCY].values, freq, rtol=1e-12)
        zeta = [float(s.get("modal_damp_vis", 0.0)) for s in shapes]
        np.testing.assert_allclose(back[names.DAMPING_RATIO].values, zeta, atol=1e-12)
    n_dof = len(shapes[0]["node_nums"]) * int(shapes[0]["n_data_per_node"])
    assert back.sizes[names.POINT] == n_dof
