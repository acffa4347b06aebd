"""Files a colleague can read: no machine paths, CF metadata (issue 12, item 4)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

from ami_xr import names, provenance
from ami_xr.io.netcdf import open_dataset, to_netcdf


def _no_folder_in(path, folder) -> None:
    data = path.read_bytes()
    for text in {str(folder), str(folder.resolve())}:
        assert text.encode() not in data, f"{path.name} holds the machine path {text}"


def test_written_files_hold_file_names_not_machine_paths(tmp_path, frf_dataset):
    first = to_netcdf(frf_dataset, tmp_path / "p.nc", parameters={"input": str(tmp_path / "a")})
    back = open_dataset(first)
    assert back.attrs[names.ATTR_SOURCE_FILE] == str(first)  # in memory: where it was read
    second = to_netcdf(back, tmp_path / "q.nc", function="ami_xr.cli.convert")
    for path in (first, second):
        _no_folder_in(path, tmp_path)
    again = open_dataset(second)
    records = provenance.history(again)
    assert records[0]["parameters"] == {"input": "a"}
    assert records[1][names.ATTR_SOURCE_FILE] == "p.nc"
    with xr.open_dataset(second, engine="netcdf4") as raw:
        assert raw.attrs[names.ATTR_SOURCE_FILE] == "p.nc"


def test_add_history_stores_the_file_name():
    out = provenance.add_history(xr.Dataset(), "f", {"n": 1}, source_file="/some/dir/run1.lvm")
    assert out.attrs[names.ATTR_SOURCE_FILE] == "run1.lvm"
    (record,) = json.loads(out.attrs[names.ATTR_HISTORY])
    assert record[names.ATTR_SOURCE_FILE] == "run1.lvm"
    assert provenance.file_name("relative/x.nc") == "x.nc"


def test_lvm_and_uff_readers_write_no_machine_path(tmp_path, frf_dataset):
    pytest.importorskip("pyuff")
    from ami_xr.io.uff import read_uff, write_uff

    uff = tmp_path / "g.uff"
    write_uff(frf_dataset, uff)
    ds = read_uff(uff)
    assert ds.attrs[names.ATTR_SOURCE_FILE] == "g.uff"
    out = to_netcdf(ds, tmp_path / "g.nc")
    _no_folder_in(out, tmp_path)
    assert np.array_equal(open_dataset(out).frf.values, ds.frf.values)
