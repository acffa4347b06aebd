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
from ami_xr.app.report import report
from ami_xr.errors import AmiXrValueError

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


@pytest.fixture(scope="module")
def hammer_report(tmp_path_factory, hammer_result) -> Path:
    """The full report of the hammer test (default figures), written once for the tests that
    read it."""
    return report(hammer_result, tmp_path_factory.mktemp("hammer") / "rep")


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
    tmp_path, hammer_report, simulated_result
):
    made = {p.stem for p in hammer_report.parent.glob("*.png")}  # figures=None, the default
    assert {"coherence", "force_spectrum", "hits"} <= made
    index = report(simulated_result, tmp_path / "sim", figures=("bode",))
    page = index.read_text()
    assert "<h2>Measurement</h2>" not in page and "coherence" not in page


def test_coherence_figure_labels_and_legend(hammer_result):
    from ami_xr.plot import measurement as plot_measurement

    fig = plot_measurement.plot_coherence(hammer_result)
    (ax,) = fig.axes
    assert ax.get_xlabel() == "frequency [Hz]" and ax.get_ylabel() == "coherence [-]"
    assert ax.get_legend() is not None
    assert ax.get_ylim()[1] <= 1.1


def test_force_spectrum_figure_in_db_with_units(hammer_result):
    from ami_xr.plot import measurement as plot_measurement

    fig = plot_measurement.plot_force_spectrum(hammer_result, frequency_range=(0, 500))
    (ax,) = fig.axes
    assert "dB" in ax.get_ylabel() and "N^2/Hz" in ax.get_ylabel()
    assert ax.get_xlabel() == "frequency [Hz]"
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "-10 dB" in labels and "-20 dB" in labels
    (line,) = _data_lines(ax)
    assert line.get_xdata().max() <= 500


def test_hits_figure_marks_rejected_hits_with_reason(hammer_result):
    from ami_xr.plot import measurement as plot_measurement

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


# --- figures: what is drawn, sizes, legends, units, options --------------------------------------
def _png_size(path: Path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n"
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def _assert_legend_where_several_lines(fig):
    for ax in fig.axes:
        if ax.get_visible() and len(_data_lines(ax)) > 1:
            assert ax.get_legend() is not None, ax.get_title()


def test_mac_skipped_with_a_note_for_one_frf(tmp_path, hammer_result):
    index = report(hammer_result, tmp_path / "rep", figures=("mac", "bode"))
    assert not (index.parent / "mac.png").exists()
    page = index.read_text()
    assert "<b>mac</b>" in page and "2 or more points" in page


def test_figure_sizes_in_pixels(tmp_path, hammer_result, simulated_result):
    index = report(hammer_result, tmp_path / "hammer", figures=("bode", "mode_vectors", "nyquist"))
    width, _ = _png_size(index.parent / "bode.png")
    assert width >= 1000
    for stem in ("mode_vectors", "nyquist"):
        _, height = _png_size(index.parent / f"{stem}.png")
        assert height <= 2000, stem
    # many modes: the mode-vector figure grows sideways, not past ~2000 px in height
    many = simulated_result.isel({names.MODE: [0] * 22, names.MODE_2: [0] * 22})
    many = many.assign_coords({names.MODE: np.arange(1, 23), names.MODE_2: np.arange(1, 23)})
    fig = ami_xr.plot_mode_vectors(many)
    assert fig.get_size_inches()[1] * 110 <= 2000
    assert len(fig.axes) == 2 * 22


def test_bode_mode_labels_do_not_collide(hammer_result):
    fig = ami_xr.plot_bode(hammer_result)
    ax = fig.axes[0]
    fig.canvas.draw()
    boxes = [t.get_window_extent() for t in ax.texts]
    assert len(boxes) == hammer_result.sizes[names.MODE]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not a.overlaps(b)


def test_legend_on_every_panel_with_several_lines(hammer_result, simulated_result):
    n = simulated_result.sizes[names.POINT]
    with_x = simulated_result.assign_coords(
        point_x=(names.POINT, np.linspace(0, 1, n), {"units": "m"})
    )
    for fig in (
        ami_xr.plot_bode(simulated_result),
        ami_xr.plot_subtraction(simulated_result),
        ami_xr.plot_nyquist(hammer_result),
        ami_xr.plot_mode_vectors(with_x),
    ):
        _assert_legend_where_several_lines(fig)


def test_nyquist_fit_on_a_fine_grid_with_units(hammer_result):
    from ami_xr.plot.modal import FIT_OVERSAMPLING

    fig = ami_xr.plot_nyquist(hammer_result)
    ax = fig.axes[0]
    measured, fit = _data_lines(ax)[:2]
    n = len(measured.get_xdata())
    assert len(fit.get_xdata()) == FIT_OVERSAMPLING * (n - 1) + 1
    # the fine curve passes through frf_synthesized at every measured line
    synth = hammer_result[names.FRF_SYNTHESIZED].isel({names.POINT: 0}).values
    at_lines = (fit.get_xdata() + 1j * fit.get_ydata())[::FIT_OVERSAMPLING]
    gap = np.min(np.abs(at_lines[:, None] - synth[None, :]), axis=1)
    assert gap.max() < 1e-9 * np.abs(synth).max()
    assert ax.get_xlabel() == "Re FRF [m/s^2/N]" and ax.get_ylabel() == "Im FRF [m/s^2/N]"


def test_frequency_range_and_figure_choice(tmp_path, hammer_result):
    index = report(
        hammer_result, tmp_path / "rep", figures=("bode", "coherence"), frequency_range=(100, 500)
    )
    assert {p.stem for p in index.parent.glob("*.png")} == {"bode", "coherence"}
    fig = ami_xr.plot_bode(hammer_result, frequency_range=(100, 500))
    assert fig.axes[0].get_xlim() == pytest.approx((100, 500))
    shown = {t.get_text() for t in fig.axes[0].texts}
    fn = hammer_result[names.NATURAL_FREQUENCY].values
    inside = hammer_result[names.MODE].values[(fn >= 100) & (fn <= 500)]
    assert shown == {str(m) for m in inside}
    with pytest.raises(AmiXrValueError, match="frequency_range"):
        report(hammer_result, tmp_path / "bad", frequency_range=(500, 100))
    with pytest.raises(AmiXrValueError, match="unknown figures"):
        report(hammer_result, tmp_path / "bad", figures=("bode", "nope"))


def test_html_is_one_self_contained_file(hammer_report):
    import base64
    import re

    index = hammer_report
    page = index.read_text()
    sources = re.findall(r"<img src='([^']*)'", page)
    made = sorted(p.name for p in index.parent.glob("*.png"))
    assert len(sources) == len(made) >= 5
    for src in sources:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    # nothing refers to a file beside the page: moved alone, it still shows everything
    assert not re.findall(r"(?:src|href)='(?!data:)", page)
    link = re.search(r"href='data:text/csv;base64,([^']*)'", page).group(1)
    assert base64.b64decode(link) == (index.parent / "modal_table.csv").read_bytes()


def test_modal_table_shows_mpc_mpd_when_present(tmp_path, simulated_result):
    n = simulated_result.sizes[names.MODE]
    ds = simulated_result.assign(
        {
            names.MPC: ((names.MODE,), np.linspace(0.9, 1.0, n)),
            names.MPD: ((names.MODE,), np.linspace(1.0, 5.0, n)),
        }
    )
    index = report(ds, tmp_path / "rep", figures=("modal_table",))
    rows = _read_csv(index.parent / "modal_table.csv")
    assert [float(r["mpc"]) for r in rows] == list(ds[names.MPC].values)
    assert [float(r["mpd_deg"]) for r in rows] == list(ds[names.MPD].values)
    page = index.read_text()
    assert "<th>MPC [-]</th>" in page and "<th>MPD [deg]</th>" in page
