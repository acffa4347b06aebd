"""The layout and the ID lines of a UFF file survive ami_xr's round trip (issue 40): a roving-hammer
file is written back with its response and reference DOFs where they were, and each record's ID
lines (channel names, dates) come back on the same DOF. Checked with pyuff reading both files."""

from __future__ import annotations

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.errors import AssumptionWarning
from ami_xr.io.uff import read_uff, write_uff

from ..reference import REPO
from .pyuff_records import frf_record, read_sets, write_sets

pyuff = pytest.importorskip("pyuff")

FREQ = np.arange(1.0, 9.0)
HEADER = ("id1", "id2", "id3", "id4", "id5", "rsp_node", "rsp_dir", "ref_node", "ref_dir")


def _sets(path):
    return [s for s in read_sets(path) if s["type"] == 58]


def _header(record):
    return tuple(str(record[k]).strip() if k.startswith("id") else int(record[k]) for k in HEADER)


def test_a_roving_hammer_file_keeps_its_layout(tmp_path):
    source = REPO / "sample_data" / "measurement.uff"  # pyuff's: response node 1, hammer 1..3
    ds = read_uff(source)
    assert ds.attrs["uff_layout"].startswith("roving hammer")
    out = write_uff(ds, tmp_path / "again.uff", binary=True)
    before, after = _sets(source), _sets(out)
    assert [_header(r)[5:] for r in after] == [_header(r)[5:] for r in before]
    assert [_header(r)[:5] for r in after] == [_header(r)[:5] for r in before]
    for a, b in zip(before, after, strict=True):
        np.testing.assert_allclose(b["data"], a["data"], rtol=1e-6)
    back = read_uff(out)
    assert back.attrs[names.ATTR_DRIVE_POINT] == ds.attrs[names.ATTR_DRIVE_POINT]
    np.testing.assert_allclose(back[names.FRF].values, ds[names.FRF].values, rtol=1e-12)


def test_the_id_lines_of_each_record_come_back_on_its_dof(tmp_path):
    channels = ["Mic 01.0Scalar", "Acc 02.+Z", "Acc 03.+Z"]
    records = [
        frf_record(
            (np.arange(FREQ.size) + 1.0) * (k + 1) + 0.5j,
            FREQ,
            rsp_node=k + 1,
            id1=channels[k],
            id3=f"18-Apr-16 13:49:5{k}",
            id4="run 7",
        )
        for k in range(3)
    ]
    source = write_sets(tmp_path / "lab.uff", records)
    ds = read_uff(source)
    assert list(ds["uff_id1"].values) == channels
    assert list(ds["uff_id4"].values) == ["run 7"] * 3
    assert "uff_id2" not in ds.coords  # NONE everywhere: nothing to keep
    out = write_uff(ds, tmp_path / "again.uff")
    assert [_header(r) for r in _sets(out)] == [_header(r) for r in _sets(source)]
    shared = records[:1]  # one record: its ID line 1 is the Dataset's title
    one = write_sets(tmp_path / "one.uff", shared)
    assert read_uff(one).attrs["title"] == channels[0]


def test_a_dataset_55_stating_one_value_per_node_for_three_translations_is_read(tmp_path):
    """SDynPy writes record 6 of dataset 55 with 1 value per node for three translations (data
    characteristic 2); such a file is read with 3, and the repair is said."""
    truth = ami_xr.open_dataset(REPO / "sample_data" / "benchmark_truth.nc").load()
    labels = [f"{k + 1}+Z" for k in range(truth.sizes[names.POINT])]
    truth = truth.assign_coords({names.POINT: labels}).assign_attrs(drive_point=labels[0])
    good = write_uff(truth, tmp_path / "good.uff", include=("modes",))
    lines = good.read_text().split("\n")
    starts = [
        i
        for i in range(len(lines) - 1)
        if lines[i].strip() == "-1" and lines[i + 1].strip() == "55"
    ]
    assert len(starts) == truth.sizes[names.MODE]
    for i in starts:
        fields = lines[i + 7].split()
        assert fields[2] == "2" and fields[5] == "3"
        lines[i + 7] = "".join(f.rjust(10) for f in [*fields[:5], "1"])
    bad = tmp_path / "sdynpy_like.uff"
    bad.write_text("\n".join(lines))
    with pytest.warns(AssumptionWarning, match=r"record 6 states 1 value\(s\) per node for data "):
        back = read_uff(bad, kind="modes")
    want = read_uff(good, kind="modes")
    np.testing.assert_allclose(back[names.EIGENVALUE].values, want[names.EIGENVALUE].values)
    np.testing.assert_allclose(back[names.MODE_VECTOR].values, want[names.MODE_VECTOR].values)
