"""The stability chart (ami_xr.plot_stability), its place in the report and ``--stability``."""

from __future__ import annotations

import csv
import warnings

import numpy as np
import pytest

pytest.importorskip("matplotlib")

import ami_xr  # noqa: E402
from ami_xr import names  # noqa: E402
from ami_xr.app.cli import EXIT_OK, main  # noqa: E402
from ami_xr.errors import AmiXrValueError  # noqa: E402
from ami_xr.simulate import random_system  # noqa: E402

FAKE_HZ = 11.65  # no mode of the system there: a spurious reference mode, found in no variant


@pytest.fixture(scope="module")
def result():
    ds, _ = random_system(5, weak_mode=True, noise=0.03, seed=0, n_frequencies=1024)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = ami_xr.identify(ds)
    lam = ref[names.EIGENVALUE].values.copy()
    lam[1] = complex(-0.01 * 2 * np.pi * FAKE_HZ, 2 * np.pi * FAKE_HZ)
    ref[names.EIGENVALUE] = ref[names.EIGENVALUE].copy(data=lam)
    ref[names.NATURAL_FREQUENCY] = ref[names.NATURAL_FREQUENCY].copy(data=np.abs(lam) / 2 / np.pi)
    return ami_xr.stability(ds, ref, pfa=(1e-2, 1e-5), band_trim=(0.0, 0.2))


def _markers(ax, label):
    (line,) = [h for h in ax.get_lines() if h.get_label() == label]
    return line


def test_rows_markers_labels_and_units(result):
    fig = ami_xr.plot_stability(result)
    ax = fig.axes[0]
    variants = result[names.STABILITY_VARIANT].values.tolist()
    assert [t.get_text() for t in ax.get_yticklabels()] == variants
    assert ax.get_xlabel() == "frequency [Hz]"
    assert "variant" in ax.get_ylabel()
    assert ax.get_xscale() == "linear"  # the band starts at 0 Hz
    found = result[names.STABILITY_FOUND].values
    missed = result[names.STABILITY_IN_BAND].values & ~found
    filled = _markers(ax, "mode found again")
    empty = _markers(ax, "missed (inside the band)")
    assert len(filled.get_xdata()) == found.sum()
    assert len(empty.get_xdata()) == missed.sum() == 4  # the spurious mode, in every variant
    assert empty.get_markerfacecolor() == "none"
    np.testing.assert_allclose(empty.get_xdata(), FAKE_HZ, rtol=1e-4)  # |lam| / 2 pi
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend == ["variant's band", "mode found again", "missed (inside the band)"]
    texts = [t.get_text() for t in ax.texts]
    assert texts == ["1: 1", "2: 0", "3: 1", "4: 1"]  # mode label: stability fraction
    twin = fig.axes[1]
    units = result[names.FRF].attrs.get(names.ATTR_UNITS, "")
    assert twin.get_ylabel() == f"sum over points |FRF| [{units}]"
    assert "solid" in ax.get_title()


def test_log_axis_and_saving(result, tmp_path):
    clipped = result.sel({names.FREQUENCY: slice(1.0, None)})
    clipped = clipped.assign_coords(
        {names.STABILITY_FMIN: np.maximum(clipped[names.STABILITY_FMIN], 1.0)}
    )
    fig = ami_xr.plot_stability(clipped, path=tmp_path / "s.png")
    assert fig.axes[0].get_xscale() == "log"
    assert (tmp_path / "s.png").stat().st_size > 0
    assert ami_xr.plot_stability(clipped, log=False).axes[0].get_xscale() == "linear"


def test_missing_inputs_raise(result):
    with pytest.raises(AmiXrValueError, match="stability_found"):
        ami_xr.plot_stability(result.drop_vars(names.STABILITY_FOUND))


def test_report_has_the_figure_and_the_column(result, tmp_path):
    index = ami_xr.report(result, tmp_path / "r", figures=("stability", "modal_table"))
    page = index.read_text()
    assert (tmp_path / "r" / "stability.png").is_file()
    assert "stability.png" in page and "stability [-]" in page
    rows = list(csv.DictReader((tmp_path / "r" / "modal_table.csv").open()))
    assert [float(r["stability_fraction"]) for r in rows] == [1.0, 0.0, 1.0, 1.0]
    # by default: drawn when the result has stability_found, not otherwise
    plain = result.drop_dims(names.STABILITY_VARIANT).drop_vars(
        [names.STABILITY_FRACTION, names.STABILITY_FREQUENCY_SPREAD]
    )
    ami_xr.report(plain, tmp_path / "p", figures=("stability", "modal_table"))
    assert not (tmp_path / "p" / "stability.png").exists()
    assert "stability [-]" not in (tmp_path / "p" / "index.html").read_text()


def test_cli_identify_stability(tmp_path, capsys):
    ds, _ = random_system(5, noise=0.01, seed=1, n_frequencies=512)
    ami_xr.to_netcdf(ds, tmp_path / "f.nc")
    out = tmp_path / "m.nc"
    assert (
        main(["identify", str(tmp_path / "f.nc"), "-o", str(out), "--stability", "-q"]) == EXIT_OK
    )
    printed = capsys.readouterr().out
    assert "stability" in printed and "found/in band" in printed
    back = ami_xr.open_dataset(out)
    assert back.sizes[names.STABILITY_VARIANT] == 8
    np.testing.assert_array_equal(back[names.STABILITY_FRACTION].values, 1.0)
    assert main(["identify", str(tmp_path / "f.nc"), "-o", str(tmp_path / "n.nc"), "-q"]) == 0
    assert names.STABILITY_FRACTION not in ami_xr.open_dataset(tmp_path / "n.nc")
