"""The shipped sample data are CF-1.11 files as ami_xr.to_netcdf writes them, and
``scripts/make_sample_data.py --check`` notices a file that is not (issue 33, item 14)."""

from __future__ import annotations

import importlib.util
import re
import shutil
import sys
from pathlib import Path

import pytest
import xarray as xr

import ami_xr

REPO = Path(__file__).resolve().parents[2]
SAMPLE = REPO / "sample_data"


def _script():
    """scripts/make_sample_data.py as a module (loaded from its path: no sys.path edits)."""
    spec = importlib.util.spec_from_file_location(
        "make_sample_data", REPO / "scripts" / "make_sample_data.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


SCRIPT = _script()
needs_samples = pytest.mark.skipif(
    not all((SAMPLE / name).exists() for name in SCRIPT.FILES), reason="sample_data/ absent"
)


@needs_samples
@pytest.mark.parametrize("name", SCRIPT.FILES)
def test_shipped_file_is_cf_as_stored(name):
    with xr.open_dataset(SAMPLE / name, decode_cf=False) as ds:
        assert ds.attrs["Conventions"] == "CF-1.11"
        assert ds.attrs["title"] and ds.attrs["history"]
        for key, var in ds.variables.items():
            where = f"{name}: {key}"
            # before: a string 'point' dimension coordinate, units sqrt(m/N), no long_name
            assert not (key in ds.dims and var.dtype.kind in "USO"), f"{where}: string dim coord"
            assert "sqrt(" not in str(var.attrs.get("units", "")), where
            assert "long_name" in var.attrs, f"{where}: no long_name"


@needs_samples
def test_shipped_files_equal_a_regeneration(tmp_path):
    SCRIPT.write_sample_data(tmp_path)
    assert SCRIPT.compare(tmp_path, SAMPLE) == []
    assert SCRIPT.compare_stored(tmp_path, SAMPLE) == []


def test_check_reports_a_file_the_writer_would_not_write(tmp_path):
    fresh, shipped = tmp_path / "fresh", tmp_path / "shipped"
    SCRIPT.write_sample_data(fresh)
    shutil.copytree(fresh, shipped)
    # the same values written by plain xarray, as the sample data were before: no Conventions,
    # no title, a string point dimension coordinate
    plain = ami_xr.open_dataset(fresh / "benchmark_impulse.nc")
    plain.attrs = {k: v for k, v in plain.attrs.items() if not isinstance(v, (list, dict))}
    (shipped / "benchmark_impulse.nc").unlink()
    plain.drop_vars([v for v in plain.variables if plain[v].dtype.kind == "c"]).to_netcdf(
        shipped / "benchmark_impulse.nc"
    )
    assert SCRIPT.compare(fresh, shipped) == []  # the values alone do not tell
    problems = SCRIPT.compare_stored(fresh, shipped)
    assert any("'Conventions' missing" in p for p in problems), problems
    assert any("'title' missing" in p for p in problems), problems
    assert all(p.startswith("benchmark_impulse.nc") for p in problems), problems
    assert SCRIPT.check(shipped) == 1


def test_check_ignores_timestamps_and_versions(tmp_path):
    SCRIPT.write_sample_data(tmp_path / "a")
    SCRIPT.write_sample_data(tmp_path / "b")
    netCDF4 = pytest.importorskip("netCDF4")
    with netCDF4.Dataset(tmp_path / "b" / "benchmark_truth.nc", "a") as nc:
        nc.history = re.sub(r"\d{4}-\d\d-\d\dT", "1999-01-01T", nc.history)
        nc.source = "ami_xr 9.9.9"  # another version
    with netCDF4.Dataset(tmp_path / "b" / "benchmark_truth.nc") as nc:
        assert nc.history.startswith("1999-01-01T")
    assert SCRIPT.compare_stored(tmp_path / "a", tmp_path / "b") == []


def test_check_says_when_the_cf_checker_is_missing(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "compliance_checker", None)
    monkeypatch.setitem(sys.modules, "compliance_checker.runner", None)
    SCRIPT.write_sample_data(tmp_path)
    assert SCRIPT.cf_problems(tmp_path) is None
    assert SCRIPT.check(tmp_path) == 0
    assert "CF check skipped: compliance_checker is not installed" in capsys.readouterr().out


def test_check_runs_the_cf_checker_when_installed(tmp_path):
    pytest.importorskip("compliance_checker")
    SCRIPT.write_sample_data(tmp_path)
    assert SCRIPT.cf_problems(tmp_path) == []
    xr.Dataset({"x": ("n", [1.0, 2.0])}).to_netcdf(tmp_path / "benchmark_truth.nc", mode="w")
    problems = SCRIPT.cf_problems(tmp_path)
    assert len(problems) == 1 and problems[0].startswith("benchmark_truth.nc: not CF-1.11")
