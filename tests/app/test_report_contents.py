"""What the report holds for a test-lab engineer (issue 12): a modal_table.csv a spreadsheet reads,
no machine path, measurement-quality figures (coherence, force spectrum, hits), figure sizes,
legends and units, and one self-contained index.html."""

from __future__ import annotations

import csv
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami import identify
from ami_xr.report import report

pytest.importorskip("matplotlib")

HAMMER = Path("/work/shared/data/impact_hammer.lvm")


@pytest.fixture(scope="module")
def simulated_result(small_random_system) -> xr.Dataset:
    """An identified random chain (5 points, simulated), with a fake absolute source path."""
    g, _ = small_random_system
    res = identify(g)
    return res.assign_attrs({names.ATTR_SOURCE_FILE: "/home/someone/secret/lab/chain.nc"})


@pytest.fixture(scope="module")
def hammer_result() -> xr.Dataset:
    """The measured hammer test, read_lvm -> impact_frf -> identify (band up to 2 kHz)."""
    if not HAMMER.exists():
        pytest.skip("shared measurement data not present")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the single FRF converges slowly; not what is tested
        raw = ami_xr.read_lvm(HAMMER)
        frf = ami_xr.impact_frf(raw).sel({names.FREQUENCY: slice(0, 2000)})
        return identify(frf)


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


# --- modal_table.csv ------------------------------------------------------------------------------
def test_csv_has_one_numeric_column_per_real_quantity(tmp_path, simulated_result):
    index = report(simulated_result, tmp_path / "rep", figures=("modal_table",))
    rows = _read_csv(index.parent / "modal_table.csv")
    lam = np.atleast_1d(simulated_result[names.EIGENVALUE].values)
    assert len(rows) == lam.size
    numeric = [
        "frequency_hz",
        "frequency_rad_s",
        "damping_ratio",
        "damping_percent",
        "eigenvalue_real_rad_s",
        "eigenvalue_imag_rad_s",
    ]
    for row, lk in zip(rows, lam, strict=True):
        for key in numeric:
            float(row[key])  # a spreadsheet's number, not a Python repr
        assert "j" not in "".join(row[k] for k in numeric)
        # written with repr(float): exact round trip
        assert float(row["eigenvalue_real_rad_s"]) == lk.real
        assert float(row["eigenvalue_imag_rad_s"]) == lk.imag
    assert "eigenvalue" not in rows[0]


def test_csv_has_std_columns_when_the_dataset_has_stds(tmp_path, simulated_result):
    assert names.NATURAL_FREQUENCY_STD in simulated_result
    index = report(simulated_result, tmp_path / "rep", figures=("modal_table",))
    rows = _read_csv(index.parent / "modal_table.csv")
    fstd = np.atleast_1d(simulated_result[names.NATURAL_FREQUENCY_STD].values)
    zstd = np.atleast_1d(simulated_result[names.DAMPING_RATIO_STD].values)
    lstd = np.atleast_1d(simulated_result[names.EIGENVALUE_STD].values)
    for row, f, z, s in zip(rows, fstd, zstd, lstd, strict=True):
        assert float(row["frequency_hz_std"]) == f
        assert math.isclose(float(row["damping_percent_std"]), 100 * z, rel_tol=1e-12)
        assert float(row["eigenvalue_real_std_rad_s"]) == s.real
        assert float(row["eigenvalue_imag_std_rad_s"]) == s.imag
    bare = simulated_result.drop_vars(
        [names.NATURAL_FREQUENCY_STD, names.DAMPING_RATIO_STD, names.EIGENVALUE_STD]
    )
    index = report(bare, tmp_path / "bare", figures=("modal_table",))
    header = _read_csv(index.parent / "modal_table.csv")[0]
    assert not [k for k in header if k.endswith("_std") or "_std_" in k]


def test_csv_reads_as_floats_with_pandas(tmp_path, simulated_result):
    pd = pytest.importorskip("pandas")
    index = report(simulated_result, tmp_path / "rep", figures=("modal_table",))
    table = pd.read_csv(index.parent / "modal_table.csv")
    for col in ("frequency_hz", "damping_ratio", "eigenvalue_real_rad_s", "frequency_hz_std"):
        assert table[col].dtype == np.float64


def test_no_machine_path_in_the_html(tmp_path, simulated_result):
    index = report(simulated_result, tmp_path / "rep", figures=("modal_table",))
    page = index.read_text()
    assert "/home/someone" not in page and "secret" not in page
    assert "<title>ami_xr report: chain.nc</title>" in page
    assert str(tmp_path) not in page
