"""Issue 12 (item 1) and issue 11 (item 1, figures): ``ami-xr report --frequency-range`` and
``--figures``; figures drawn at the size the page shows them, with a fixed layout (one draw per
save), no garbage-collector passes while drawing; ``scripts/bench_report.py`` runs."""

from __future__ import annotations

import gc
import re
import runpy
import struct
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami import identify
from ami_xr.app.cli import EXIT_ERROR, EXIT_OK, EXIT_USAGE, main
from ami_xr.app.report import FIGURES, MEASUREMENT_FIGURES, report
from ami_xr.errors import AmiXrValueError

from ..reference import REPO

pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def result(small_random_system) -> xr.Dataset:
    g, _ = small_random_system
    return identify(g)


@pytest.fixture(scope="module")
def result_file(tmp_path_factory, result) -> Path:
    path = tmp_path_factory.mktemp("report_options") / "modes.nc"
    ami_xr.to_netcdf(result, path)
    return path


def _png_width(data: bytes) -> int:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">I", data[16:20])[0]


# --- ami-xr report --figures / --frequency-range --------------------------------------------------
def test_figures_option_draws_only_the_figures_asked_for(tmp_path, result_file, capsys):
    out = tmp_path / "rep"
    code = main(["report", str(result_file), "-o", str(out), "--figures", "bode", "mac"])
    assert code == EXIT_OK
    assert {p.stem for p in out.glob("*.png")} == {"bode", "mac"}
    page = (out / "index.html").read_text()
    assert re.findall(r"alt='([a-z_]+)\.png'", page) == ["bode", "mac"]
    for stem in ("nyquist", "subtraction", "mode_vectors", "modal_table"):
        assert f"alt='{stem}.png'" not in page
    assert "wrote report to" in capsys.readouterr().out


def test_frequency_range_option_limits_the_bode_axes(tmp_path, result_file, monkeypatch):
    from ami_xr.plot import modal as plot

    drawn = []
    real = plot.plot_bode

    def recording(ds, **kwargs):
        fig = real(ds, **kwargs)
        drawn.append(fig)
        return fig

    monkeypatch.setattr(plot, "plot_bode", recording)
    f = ami_xr.open_dataset(result_file)[names.FREQUENCY].values
    lo, hi = float(f[len(f) // 4]), float(f[len(f) // 2])
    argv = ["report", str(result_file), "-o", str(tmp_path / "rep"), "--figures", "bode"]
    assert main([*argv, "--frequency-range", str(lo), str(hi)]) == EXIT_OK
    (fig,) = drawn
    for ax in fig.axes:
        assert ax.get_xlim() == pytest.approx((lo, hi))
    # without the option: the whole band
    drawn.clear()
    assert main(argv) == EXIT_OK
    assert drawn[0].axes[0].get_xlim() == pytest.approx((f[0], f[-1]))


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--figures", "bode", "nope"], "argument --figures: invalid choice: 'nope'"),
        (["--figures"], "argument --figures"),
        (["--frequency-range", "5", "1"], "argument --frequency-range: expected 0 <= FMIN < FMAX"),
        (["--frequency-range", "-1", "5"], "argument --frequency-range"),
        (["--frequency-range", "1", "inf"], "argument --frequency-range"),
        (["--frequency-range", "1", "abc"], "argument --frequency-range: invalid float value"),
        (["--frequency-range", "1"], "argument --frequency-range: expected 2 arguments"),
    ],
)
def test_bad_option_values_are_usage_errors_naming_the_option(
    tmp_path, result_file, capsys, extra, named
):
    out = tmp_path / "rep"
    with pytest.raises(SystemExit) as exit_info:
        main(["report", str(result_file), "-o", str(out), *extra])
    assert exit_info.value.code == EXIT_USAGE
    assert named in capsys.readouterr().err
    assert not out.exists()


def test_frequency_range_outside_the_data_is_refused_before_any_work(
    tmp_path, result_file, result, capsys
):
    out = tmp_path / "rep"
    argv = ["report", str(result_file), "-o", str(out), "--frequency-range", "1e6", "2e6"]
    assert main(argv) == EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "frequency_range" in err[0] and "fewer than 2" in err[0]
    assert not out.exists()
    with pytest.raises(AmiXrValueError, match="frequency_range"):
        report(result, out, frequency_range=(1e6, 2e6))
    assert not out.exists()


def test_help_lists_every_figure_report_accepts(capsys, tmp_path, monkeypatch):
    with pytest.raises(SystemExit):
        main(["report", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--frequency-range FMIN FMAX" in text
    from ami_xr.app.report import GEOMETRY_FIGURES

    for stem in (*MEASUREMENT_FIGURES, *FIGURES, *GEOMETRY_FIGURES):
        assert stem in text
    monkeypatch.chdir(tmp_path)
    # a geometry figure name passes the option check (exit 1: the input file is missing)
    assert main(["report", "in.nc", "-o", "r", "--figures", "mode_shapes"]) == 1
    assert list(tmp_path.iterdir()) == []


def test_building_the_parser_imports_no_report_module():
    import subprocess

    code = (
        "import sys; from ami_xr.app.cli import build_parser; build_parser(); "
        "print('ami_xr.report' in sys.modules, 'xarray' in sys.modules)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["False", "False"]


# --- figures at the size shown, fixed layout, fast drawing ----------------------------------------
@pytest.mark.slow
def test_figures_are_drawn_no_wider_than_the_page_shows_them(tmp_path, result):
    from ami_xr.plot.common import PAGE_WIDTH_PX

    many = result.isel({names.MODE: [0] * 8, names.MODE_2: [0] * 8})
    many = many.assign_coords({names.MODE: np.arange(1, 9), names.MODE_2: np.arange(1, 9)})
    index = report(many, tmp_path / "rep")
    widths = {p.stem: _png_width(p.read_bytes()) for p in index.parent.glob("*.png")}
    assert set(widths) == set(FIGURES)
    assert max(widths.values()) <= PAGE_WIDTH_PX
    assert widths["bode"] >= 1000  # and still a wide Bode plot
    # the page is that wide: images are shown 1:1, not scaled down by the browser
    assert f"max-width:{PAGE_WIDTH_PX}px" in index.read_text()


@pytest.mark.slow
def test_figures_have_a_fixed_layout_drawn_once(result):
    from ami_xr.plot import measurement as plot_measurement
    from ami_xr.plot import modal as plot
    from ami_xr.plot.common import png_bytes

    n = result.sizes[names.POINT]
    with_x = result.assign_coords(point_x=(names.POINT, np.linspace(0, 1, n), {"units": "m"}))
    figures = [f(result) for f in (plot.plot_bode, plot.plot_nyquist, plot.plot_subtraction)]
    figures += [plot.plot_mode_vectors(with_x), plot.plot_mac(result)]
    figures += [plot.plot_modal_table(result)]
    coherence = result.assign({names.COHERENCE: np.abs(result[names.FRF]) ** 0})
    figures += [plot_measurement.plot_coherence(coherence)]
    for fig in figures:
        assert fig.get_layout_engine() is None
        draws = []
        real = fig.draw
        fig.draw = lambda renderer, _real=real, _draws=draws: (_draws.append(1), _real(renderer))
        png_bytes(fig)
        # a layout engine makes savefig draw twice (measure, then render): here once
        assert len(draws) == 1


def test_log_magnitude_axes_have_no_minor_ticks(result):
    from ami_xr.plot import modal as plot

    for fig in (plot.plot_bode(result), plot.plot_subtraction(result)):
        ax = fig.axes[0]
        assert ax.get_yscale() == "log"
        assert len(ax.yaxis.get_minorticklocs()) == 0


def test_gc_paused_restores_the_collector_state():
    from ami_xr.plot.common import gc_paused

    assert gc.isenabled()
    with gc_paused():
        assert not gc.isenabled()
    assert gc.isenabled()
    with pytest.raises(RuntimeError), gc_paused():
        raise RuntimeError
    assert gc.isenabled()
    gc.disable()
    try:
        with gc_paused():
            pass
        assert not gc.isenabled()  # left off, as it was
    finally:
        gc.enable()


def test_saved_png_is_fast_to_encode_and_carries_no_software_tag(tmp_path, result):
    from ami_xr.plot import modal as plot
    from ami_xr.plot.common import PNG_OPTIONS, png_bytes

    assert PNG_OPTIONS["pil_kwargs"]["compress_level"] == 1
    data = png_bytes(plot.plot_mac(result))
    assert b"matplotlib" not in data
    path = tmp_path / "mac.png"
    plot.plot_mac(result, path=path)
    assert b"matplotlib" not in path.read_bytes()


# --- scripts/bench_report.py ----------------------------------------------------------------------
@pytest.mark.slow
def test_bench_report_runs_and_prints_every_figure(capsys):
    main_ = runpy.run_path(str(REPO / "scripts" / "bench_report.py"), run_name="bench_report")
    assert main_["main"](["--repeat", "1", "--no-demo"]) == 0
    out = capsys.readouterr().out
    for stem in FIGURES:
        assert re.search(rf"^  {stem} +\d+\.\d+ s +\d+\.\d+ s$", out, re.M), stem
    assert "all (report())" in out and "target <= 1.5 s" in out
