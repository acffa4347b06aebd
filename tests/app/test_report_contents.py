"""What the report holds for a test-lab engineer (issue 12): a modal_table.csv a spreadsheet reads,
no machine path, measurement-quality figures (coherence, force spectrum, hits), figure sizes,
legends and units, and one self-contained index.html."""

from __future__ import annotations

import csv
import html
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


# --- measurement contents: estimator, averages, hits, coherence, force spectrum -----------------
def _data_lines(ax) -> list:
    """Lines that carry data (more than two vertices: not axhline/axvline marks)."""
    return [line for line in ax.get_lines() if len(line.get_xdata()) > 2]


def test_hammer_report_shows_what_the_engineer_checks_first(tmp_path, hammer_result):
    index = report(hammer_result, tmp_path / "rep", figures=("coherence", "force_spectrum", "hits"))
    page = index.read_text()
    assert "FRF estimator: <b>H1</b>" in page
    assert f"Number of averages: <b>{hammer_result.attrs['n_averages']}</b>" in page
    rejected = hammer_result[names.HIT_REJECTED].values
    assert rejected.any()
    assert f"Impact hits: {rejected.size}, of which {int(rejected.sum())} rejected." in page
    for reason in hammer_result[names.HIT_REJECT_REASON].values[rejected]:
        assert html.escape(str(reason)) in page  # every rejected hit marked with its reason
    for stem in ("coherence", "force_spectrum", "hits"):
        assert f"<h2>{stem.replace('_', ' ')}</h2>" in page
    # the measurement comes before the modal table
    assert page.index("<h2>Measurement</h2>") < page.index("<h2>Modal table</h2>")


def test_measurement_figures_by_default_only_when_their_inputs_exist(
    tmp_path, hammer_result, simulated_result
):
    index = report(hammer_result, tmp_path / "hammer", figures=None)
    made = {p.stem for p in index.parent.glob("*.png")}
    assert {"coherence", "force_spectrum", "hits"} <= made
    index = report(simulated_result, tmp_path / "sim", figures=("bode",))
    page = index.read_text()
    assert "<h2>Measurement</h2>" not in page and "coherence" not in page


def test_coherence_figure_labels_and_legend(hammer_result):
    from ami_xr import plot_measurement

    fig = plot_measurement.plot_coherence(hammer_result)
    (ax,) = fig.axes
    assert ax.get_xlabel() == "frequency [Hz]" and ax.get_ylabel() == "coherence [-]"
    assert ax.get_legend() is not None
    assert ax.get_ylim()[1] <= 1.1


def test_force_spectrum_figure_in_db_with_units(hammer_result):
    from ami_xr import plot_measurement

    fig = plot_measurement.plot_force_spectrum(hammer_result, frequency_range=(0, 500))
    (ax,) = fig.axes
    assert "dB" in ax.get_ylabel() and "N^2/Hz" in ax.get_ylabel()
    assert ax.get_xlabel() == "frequency [Hz]"
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "-10 dB" in labels and "-20 dB" in labels
    (line,) = _data_lines(ax)
    assert line.get_xdata().max() <= 500


def test_hits_figure_marks_rejected_hits_with_reason(hammer_result):
    from ami_xr import plot_measurement

    fig = plot_measurement.plot_hits(hammer_result)
    (ax,) = fig.axes
    assert ax.get_ylabel() == "peak force [N]"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["averaged", "rejected"]
    notes = {t.get_text() for t in ax.texts}
    assert notes == {"overload", "double impact"}
    n_hits = hammer_result.sizes[names.RECORD]
    assert len(ax.patches) == n_hits
    assert f"{n_hits - int(hammer_result[names.HIT_REJECTED].sum())} of {n_hits} averaged" in (
        ax.get_title()
    )


def test_html_modal_table_lists_std_columns(tmp_path, simulated_result):
    index = report(simulated_result, tmp_path / "rep", figures=("modal_table",))
    page = index.read_text()
    for header in ("std f [Hz]", "std zeta [%]", "std Re(lambda) [rad/s]"):
        assert f"<th>{header}</th>" in page
