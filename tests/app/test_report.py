"""Plots (ami_xr.plot), the modal table and the HTML report (ami_xr.report)."""

from __future__ import annotations

import stat

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami import identify
from ami_xr.app.report import FIGURES, format_modal_table, modal_table, report
from ami_xr.errors import AmiXrValueError

from ..reference import normal_file_mode

pytest.importorskip("matplotlib")

ALL_PNGS = {f"{stem}.png" for stem in FIGURES}


@pytest.fixture(scope="module")
def benchmark_result(paper_benchmark_noisy) -> xr.Dataset:
    """The identified paper benchmark (15 % noise, seed 0)."""
    _, g, _ = paper_benchmark_noisy
    return identify(g)


@pytest.fixture(scope="module")
def chain_result(small_random_system) -> xr.Dataset:
    """An identified random chain without point coordinates (labels 0..n-1)."""
    g, _ = small_random_system
    for coord in ("point_x", "point_y", "point_z"):
        if coord in g.coords:
            g = g.drop_vars(coord)
    return identify(g)


def _pngs(folder):
    return {p.name for p in folder.glob("*.png")}


def test_every_figure_for_the_benchmark(tmp_path, benchmark_result):
    index = report(benchmark_result, tmp_path / "rep")
    assert index.name == "index.html"
    assert _pngs(index.parent) == ALL_PNGS
    page = index.read_text()
    for stem in FIGURES:
        assert f"{stem}.png" in page
    assert "Not produced" not in page
    assert (index.parent / "modal_table.csv").read_text().startswith("mode,")
    # every PNG is a real image
    for png in index.parent.glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(index.parent.glob(".*.tmp"))


@pytest.mark.slow
def test_every_figure_without_point_coordinates(tmp_path, chain_result):
    assert not any(c in chain_result.coords for c in ("point_x", "point_y", "point_z"))
    index = report(chain_result, tmp_path / "rep")
    assert _pngs(index.parent) == ALL_PNGS


def test_mode_shape_along_structure_when_coordinates_given(chain_result):
    n = chain_result.sizes[names.POINT]
    with_x = chain_result.assign_coords(point_x=(names.POINT, np.linspace(0, 1, n), {"units": "m"}))
    fig_x = with_x.ami.plot_mode_vectors()
    fig = chain_result.ami.plot_mode_vectors()
    assert len(fig_x.axes) == 3 * chain_result.sizes[names.MODE]
    assert len(fig.axes) == 2 * chain_result.sizes[names.MODE]


def test_missing_optional_variables_are_noted(tmp_path, benchmark_result):
    optional = [v for v in benchmark_result.data_vars if v not in (names.FRF, names.EIGENVALUE)]
    bare = benchmark_result.drop_vars(optional)
    index = report(bare, tmp_path / "bare")
    pngs = _pngs(index.parent)
    assert {"bode.png", "nyquist.png", "modal_table.png"} <= pngs
    assert "mode_vectors.png" not in pngs and "subtraction.png" not in pngs
    page = index.read_text()
    assert "Not produced" in page and "mode_vector" in page


def test_plain_frf_dataset_gives_bode_and_notes(tmp_path, frf_dataset):
    index = report(frf_dataset, tmp_path / "frf")
    assert _pngs(index.parent) == {"bode.png"}
    assert "No modes identified" in index.read_text()


def test_plot_functions_return_figures_and_save(tmp_path, benchmark_result):
    for name in (
        "plot_bode",
        "plot_nyquist",
        "plot_subtraction",
        "plot_mode_vectors",
        "plot_mac",
        "plot_modal_table",
    ):
        path = tmp_path / f"{name}.png"
        fig = getattr(benchmark_result.ami, name)(path=path)
        assert fig.axes and path.stat().st_size > 1000
    fig = ami_xr.plot_bode(benchmark_result, points=["tip"])
    assert len(fig.axes) == 2


def test_plots_do_not_touch_global_matplotlib_state(benchmark_result):
    import matplotlib

    backend = matplotlib.get_backend()
    ami_xr.plot_mac(benchmark_result)
    assert matplotlib.get_backend() == backend


def test_plot_errors_name_what_is_missing(frf_dataset):
    with pytest.raises(AmiXrValueError, match="natural_frequency"):
        ami_xr.plot_nyquist(frf_dataset)
    with pytest.raises(AmiXrValueError, match="subtraction_noise_floor"):
        ami_xr.plot_subtraction(frf_dataset)
    with pytest.raises(AmiXrValueError, match="mode_vector"):
        ami_xr.plot_mode_vectors(frf_dataset)
    with pytest.raises(AmiXrValueError, match="not among the points"):
        ami_xr.plot_bode(frf_dataset, points=["nope"])


def test_modal_table_rows_and_text(benchmark_result):
    rows = modal_table(benchmark_result)
    lam = np.atleast_1d(benchmark_result[names.EIGENVALUE].values)
    assert len(rows) == lam.size
    for row, lk in zip(rows, lam, strict=True):
        # the table applies these same formulas to the same eigenvalues: a rounding or two (the
        # default rel 1e-6 is loose; a unit error is O(1))
        assert row["frequency_rad_s"] == pytest.approx(abs(lk))
        assert row["frequency_hz"] == pytest.approx(abs(lk) / (2 * np.pi))
        # as above; rel 1e-6 is far above the few roundings
        assert row["damping_percent"] == pytest.approx(-100 * lk.real / abs(lk), rel=1e-6)
        assert row["detected_in"]
    text = format_modal_table(benchmark_result)
    assert "f [Hz]" in text and "w [rad/s]" in text and "zeta [%]" in text
    assert "detected in" in text and "flags" in text
    assert len(text.splitlines()) == lam.size + 2


# --- atomic, normal-mode files ------------------------------------------------------------------
def test_report_files_get_the_normal_file_mode(tmp_path, benchmark_result):
    index = report(benchmark_result, tmp_path / "rep", figures=("mac",))
    files = sorted(index.parent.iterdir())
    assert [p.name for p in files] == ["index.html", "mac.png", "modal_table.csv"]
    for p in files:
        assert stat.S_IMODE(p.stat().st_mode) == normal_file_mode(), p.name
    saved = ami_xr.plot_mac(benchmark_result, path=tmp_path / "mac.svg")
    assert saved.axes and (tmp_path / "mac.svg").read_text().lstrip().startswith("<?xml")
    assert stat.S_IMODE((tmp_path / "mac.svg").stat().st_mode) == normal_file_mode()


def test_failure_mid_report_leaves_files_intact_and_no_temporary(
    tmp_path, benchmark_result, monkeypatch
):
    from matplotlib.figure import Figure

    index = report(benchmark_result, tmp_path / "rep", figures=("mac",))
    before = {p.name: p.read_bytes() for p in index.parent.iterdir()}
    real_savefig = Figure.savefig

    def half_write_then_fail(self, fh, *args, **kwargs):
        real_savefig(self, fh, *args, **kwargs)
        fh.truncate(10)
        raise KeyboardInterrupt

    monkeypatch.setattr(Figure, "savefig", half_write_then_fail)
    with pytest.raises(KeyboardInterrupt):
        report(benchmark_result, tmp_path / "rep", figures=("mac",))
    with pytest.raises(KeyboardInterrupt):
        ami_xr.plot_mac(benchmark_result, path=index.parent / "mac.png")
    assert {p.name: p.read_bytes() for p in index.parent.iterdir()} == before
