"""Issue 22 item 3: report, modal table, MAC, plots and the CLI (report, convert, batch) on
multi-reference results."""

from __future__ import annotations

import csv
import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names, simulate
from ami_xr.app.cli import main
from ami_xr.io.formats import read_any, write_any
from ami_xr.tables import modal_table, participation_table, repeated_pairs

pytest.importorskip("matplotlib")


def _frfs():
    """A grounded ring of 5 masses (two exactly repeated pairs), references on points 0 and
    1, 0.2 % noise: two references separate both pairs."""
    truth = simulate.symmetric_structure(0.0, n_masses=5)
    ds = simulate.frf(truth, np.linspace(5.0, 35.0, 500), references=[0, 1])
    rng = np.random.default_rng(0)
    g = ds[names.FRF]
    re = simulate.add_noise(g.real, 0.002, rng=rng, dim="frequency")
    im = simulate.add_noise(g.imag, 0.002, rng=rng, dim="frequency")
    return ds.assign({names.FRF: (re + 1j * im).assign_attrs(g.attrs)}), truth


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mimo")
    ds, truth = _frfs()
    write_any(ds, folder / "frf.nc")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = ami_xr.identify(ds)
    write_any(result, folder / "result.nc")
    return folder, result, truth


def test_tables_per_reference(files):
    _, result, truth = files
    rows = participation_table(result)
    part = result[names.PARTICIPATION].transpose(names.MODE, names.REFERENCE).values
    for k, row in enumerate(rows):  # |L_r| / max |L_r|, independently
        expected = np.abs(part[k]) / np.abs(part[k]).max()
        np.testing.assert_allclose([row["relative"][r] for r in (0, 1)], expected, rtol=1e-12)
        assert max(row["relative"].values()) == pytest.approx(1.0)
    # the modal table carries the multi-reference checks per mode
    table = modal_table(result)
    assert {"rank_one_ratio", "drive_point_consistency"} <= set(table[0])
    # both repeated pairs separated: two pairs at a 0 % split, orthogonal shapes
    pairs = repeated_pairs(result)
    assert len(pairs) == 2
    for p in pairs:
        assert abs(p["split_percent"]) < 1e-6
        assert p["mac"] < 0.05
        assert all(names.FLAG_REPEATED_ROOT_SEPARATED in f for f in p["flags"])
    # a single-reference result has no participation to tabulate
    with pytest.raises(ami_xr.errors.AmiXrValueError, match="participation"):
        participation_table(result.drop_vars(names.PARTICIPATION))


@pytest.mark.slow
def test_cli_report_all_references(files, tmp_path, capsys):
    folder, result, _ = files
    out = tmp_path / "report"
    assert main(["report", str(folder / "result.nc"), "-o", str(out)]) == 0
    page = (out / "index.html").read_text()
    assert "<h2>References</h2>" in page
    assert "|L| ref 0" in page and "|L| ref 1" in page
    assert "MAC within close or repeated pairs" in page
    for stem in ("bode", "nyquist"):  # the FRFs of each reference
        for r in (0, 1):
            assert (out / f"{stem}_reference_{r}.png").stat().st_size > 0
    for stem in ("participation", "reference_checks", "mode_vectors", "mac"):
        assert (out / f"{stem}.png").stat().st_size > 0
    with open(out / "participation.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == result.sizes[names.MODE]
    part = result[names.PARTICIPATION].transpose(names.MODE, names.REFERENCE).values
    got = np.array([[float(r["relative_0"]), float(r["relative_1"])] for r in rows])
    np.testing.assert_allclose(got, np.abs(part) / np.abs(part).max(axis=1)[:, None], rtol=1e-9)
    assert "Not produced" not in page


def test_cli_report_one_reference(files, tmp_path, capsys):
    folder, _, _ = files
    out = tmp_path / "report1"
    assert main(["report", str(folder / "result.nc"), "-o", str(out), "--reference", "1"]) == 0
    page = (out / "index.html").read_text()
    assert (out / "bode.png").exists() and not (out / "bode_reference_0.png").exists()
    assert "FRFs of reference <b>1</b>" in page and "|L| ref 0" in page
    capsys.readouterr()
    assert main(["report", str(folder / "result.nc"), "-o", str(out), "--reference", "7"]) != 0
    assert "reference: '7' is not one of the references [0, 1]" in capsys.readouterr().err


def test_report_refuses_a_reference_for_a_single_reference_result(tmp_path):
    g, _ = simulate.random_system(n_points=5, seed=1, n_frequencies=128)
    with pytest.raises(ami_xr.errors.AmiXrValueError, match="reference: 0 given"):
        ami_xr.report(g, tmp_path / "r", reference=0)


def test_cli_convert_multi_reference_round_trip(files, tmp_path):
    folder, result, _ = files
    uff = tmp_path / "result.uff"
    assert main(["convert", str(folder / "result.nc"), "-o", str(uff)]) == 0
    back_nc = tmp_path / "back.nc"
    assert main(["convert", str(uff), "-o", str(back_nc)]) == 0
    back = read_any(back_nc)
    assert back[names.FRF].dims == (names.REFERENCE, names.POINT, names.FREQUENCY)
    scale = float(np.abs(result[names.FRF]).max())
    diff = np.abs(back[names.FRF].values - result[names.FRF].values).max()
    assert diff < 1e-6 * scale  # ASCII dataset 58: ~7 significant digits
    np.testing.assert_allclose(
        back[names.NATURAL_FREQUENCY].values, result[names.NATURAL_FREQUENCY].values, rtol=2e-5
    )  # dataset 55 writes eigenvalues with 6 significant digits (E13.5)
    # dataset 55 holds the (shared) mode vectors, not the participation per reference
    assert names.MODE_VECTOR in back and names.PARTICIPATION not in back


@pytest.mark.slow
def test_cli_batch_multi_reference_with_report(files, tmp_path):
    folder, _, _ = files
    data = tmp_path / "in"
    data.mkdir()
    (data / "frf.nc").write_bytes((folder / "frf.nc").read_bytes())
    out = tmp_path / "out"
    code = main(["batch", str(data), "-o", str(out), "--report", "-q"])
    with open(out / "batch_summary.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert code == 0, rows
    assert rows[0]["status"] in ("ok", "processed"), rows
    pages = list(out.rglob("index.html"))
    assert len(pages) == 1 and "<h2>References</h2>" in pages[0].read_text()
