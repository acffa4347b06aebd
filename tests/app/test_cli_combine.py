"""``ami-xr combine``: one FRF set from run files (issue 40)."""

from __future__ import annotations

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.app.cli import EXIT_ERROR, EXIT_OK, main


def _runs(tmp_path, drive=3):
    f = np.linspace(1.0, 50.0, 60)
    paths = []
    for r in range(3):
        pts = [2 * r + 1, 2 * r + 2]
        h = np.stack([1.0 / (1e4 * (1 + p) - (2 * np.pi * f) ** 2 + 20j * f) for p in pts])
        g = ami_xr.make_frf_dataset(
            h, f, points=pts, response_quantity="displacement", frf_source="analytic"
        )
        g.attrs[names.ATTR_DRIVE_POINT] = drive
        g[names.FORCE_AUTOSPECTRUM] = (names.FREQUENCY, np.full(f.size, 1.0 + r))
        paths.append(str(ami_xr.to_netcdf(g, tmp_path / f"run{r}.nc")))
    return paths


def test_combine_writes_one_set(tmp_path, capsys):
    paths = _runs(tmp_path)
    out = tmp_path / "set.nc"
    assert main(["combine", *paths, "-o", str(out)]) == EXIT_OK
    said = capsys.readouterr().out
    assert "roving response" in said and "6 points" in said and "from 3 runs" in said
    g = ami_xr.open_dataset(out)
    assert list(g[names.POINT].values) == [1, 2, 3, 4, 5, 6]
    assert g.attrs[names.ATTR_DRIVE_POINT] == 3
    assert list(g["point_run"].values) == ["run0.nc"] * 2 + ["run1.nc"] * 2 + ["run2.nc"] * 2
    np.testing.assert_array_equal(g[names.FORCE_AUTOSPECTRUM].values[:, 0], [1.0, 2.0, 3.0])
    assert str(tmp_path) not in out.read_bytes().decode("latin-1")  # no machine paths
    record = ami_xr.provenance.history(g)[-1]
    assert record["function"] == "ami-xr combine"
    assert record["steps"][0]["function"] == "ami_xr.combine_runs"


def test_combine_refuses_a_run_with_another_drive_point(tmp_path, capsys):
    paths = _runs(tmp_path)
    other = _runs(tmp_path / "x" if (tmp_path / "x").mkdir() is None else tmp_path, drive=5)
    out = tmp_path / "set.nc"
    assert main(["combine", *paths[:2], other[2], "-o", str(out)]) == EXIT_ERROR
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert "ami-xr combine: error: run 'run2.nc': drive point 5, but run 'run0.nc' has 3" in err
    assert not out.exists()


@pytest.mark.parametrize("which", ["input", "missing"])
def test_combine_checks_paths_first(tmp_path, capsys, which):
    paths = _runs(tmp_path)
    if which == "input":
        argv = ["combine", *paths, "-o", paths[0]]
    else:
        argv = ["combine", *paths, str(tmp_path / "nope.nc"), "-o", str(tmp_path / "s.nc")]
    assert main(argv) == EXIT_ERROR
    err = capsys.readouterr().err
    assert ("nope.nc" in err and "no such file" in err) if which == "missing" else "-o" in err


def test_combine_help_names_every_option(capsys):
    with pytest.raises(SystemExit) as done:
        main(["combine", "--help"])
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    for option in ("--drive-point", "--layout", "-o", "roving hammer", "(default: auto)"):
        assert option in text
