"""Issue 24 item 5: a modes file where FRFs are wanted is a clear error naming the commands that
take it, and an unexpected exception in the CLI is labelled a bug."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.app.cli import EXIT_ERROR, main
from ami_xr.io import formats
from ami_xr.io.kinds import ModesFileError, file_kind, refuse_other_kind


@pytest.fixture
def modes_file(tmp_path, frf_dataset, frf_truth):
    """What ``ami-xr identify -o MODES.nc`` writes, in small: the FRFs plus three modes (the
    fixture's FRFs hold two, so identifying them again finds a different count)."""
    lam = np.concatenate([frf_truth[names.EIGENVALUE].values, [-1.0 + 250j]])
    phi = np.ones((frf_dataset.sizes[names.POINT], 3), complex)
    ds = frf_dataset.assign(
        {
            names.EIGENVALUE: ((names.MODE,), lam, {names.ATTR_UNITS: "rad/s"}),
            names.MODE_VECTOR: ((names.POINT, names.MODE), phi),
            names.RESIDUE: ((names.POINT, names.MODE), phi * lam),
        }
    ).assign_coords({names.MODE: [1, 2, 3]})
    ds.attrs[names.ATTR_HISTORY] = json.dumps([{"function": "ami_xr.identify"}])
    path = tmp_path / "MODES.nc"
    ami_xr.to_netcdf(ds, path)
    return path


def test_file_kind(frf_dataset, frf_truth, paper_benchmark_clean):
    assert file_kind(frf_dataset) == "frf"
    assert file_kind(paper_benchmark_clean[0]) == "time"
    assert file_kind(frf_truth) == "modes"
    assert file_kind(frf_dataset.merge(frf_truth)) == "modes"
    assert file_kind(xr.Dataset()) == "unknown"


def test_read_any_refuses_a_modes_file_only_where_frfs_are_wanted(modes_file):
    with pytest.raises(
        ModesFileError, match=r"MODES.nc: a modes file \(written by ami-xr identify"
    ):
        formats.read_any(modes_file, want="frf")
    with pytest.raises(ValueError, match="ami-xr report .*ami-xr convert"):
        formats.read_any(modes_file, want="time")
    assert file_kind(formats.read_any(modes_file)) == "modes"  # report and convert take it


def test_refuse_other_kind_passes_frfs(frf_dataset):
    refuse_other_kind(frf_dataset, "g.nc", "frf")  # no error


def test_identify_on_a_modes_file_says_what_it_is(modes_file, tmp_path, capsys):
    """A modes file without FRFs is refused; one with FRFs (issue 40) is identified, its modes
    kept as the reference set (tests/app/test_identify_reference_modes.py)."""
    only = ami_xr.open_dataset(modes_file).drop_vars(names.FRF)
    modes_only = ami_xr.to_netcdf(only, tmp_path / "ONLY.nc")
    code = main(["identify", str(modes_only), "-o", str(tmp_path / "x.uff")])
    err = capsys.readouterr().err
    assert code == EXIT_ERROR
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "a modes file" in lines[0] and "ami-xr report" in lines[0]
    assert "conflicting sizes" not in err and "unexpected" not in err
    assert not (tmp_path / "x.uff").exists()
    assert main(["identify", str(modes_file), "-o", str(tmp_path / "x.nc")]) == 0
    assert "reference modes from MODES.nc" in capsys.readouterr().out
    assert ami_xr.open_dataset(tmp_path / "x.nc").sizes["reference_mode"] == 3


def test_an_exception_from_inside_a_library_is_labelled_a_bug(
    modes_file, tmp_path, capsys, monkeypatch
):
    def read_any(path, **kwargs):
        raise ValueError("conflicting sizes for dimension 'mode'")

    monkeypatch.setattr(formats, "read_any", read_any)
    assert main(["identify", str(modes_file)]) == EXIT_ERROR
    line = capsys.readouterr().err.strip()
    assert line.startswith("ami-xr identify: error: unexpected ValueError: conflicting sizes")
    assert "please report" in line and line.endswith("(run with -v for the traceback)")
