"""Readers check completeness: a file cut short is an error that says what is missing.

Truncated files are made by cutting real files: LVM text built as in ``test_lvm.py`` and UFF
files written by :func:`ami_xr.write_uff`, cut at several byte positions inside their data.
"""

from __future__ import annotations

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.errors import DataFileError
from ami_xr.io.datasets import make_frf_dataset

pytest.importorskip("pyuff")

LVM_HEADER = """LabVIEW Measurement\t
Writer_Version\t2
Reader_Version\t2
Separator\tTab
Decimal_Separator\t.
Multi_Headings\tYes
X_Columns\tNo
Time_Pref\tAbsolute
***End_of_Header***\t
\t
"""
LVM_SEGMENT = """Channels\t2\t\t
Samples\t{n}\t{n}\t
Y_Unit_Label\tNewtons\tm/s^2\t
X_Dimension\tTime\tTime\t
X0\t{x0}\t{x0}\t
Delta_X\t0.001\t0.001\t
***End_of_Header***\t\t\t
X_Value\tForce (Trigger)\tAcceleration (Trigger)\tComment
"""


def _lvm_text(n_segments: int, n: int) -> str:
    rng = np.random.default_rng(n_segments)
    text = LVM_HEADER
    for i in range(n_segments):
        text += LVM_SEGMENT.format(n=n, x0=float(i))
        for f, a in np.round(rng.standard_normal((n, 2)), 6):
            text += f"\t{f:.6f}\t{a:.6f}\n"
        text += "\n"
    return text


def _rows_start(text: str, segment: int) -> int:
    """Byte offset of the first data row of segment ``segment`` (0-based)."""
    at = -1
    for _ in range(segment + 1):
        at = text.index("X_Value", at + 1)
    return text.index("\n", at) + 1


def test_lvm_complete_file_reads(tmp_path):
    path = tmp_path / "ok.lvm"
    path.write_text(_lvm_text(1, 200))
    assert ami_xr.read_lvm(path).sizes[names.TIME] == 200


def test_lvm_one_segment_cut_short_names_the_counts(tmp_path):
    # The case: one segment whose header says more samples than the file holds.
    text = _lvm_text(1, 200)
    start = _rows_start(text, 0)
    keep = start + sum(len(r) + 1 for r in text[start:].split("\n")[:50])
    path = tmp_path / "cut.lvm"
    path.write_text(text[:keep])
    with pytest.raises(DataFileError, match="expected 200 samples, found 50") as err:
        ami_xr.read_lvm(path)
    msg = str(err.value)
    assert "cut.lvm" in msg and "segment 1" in msg and "'Force (Trigger)'" in msg


@pytest.mark.parametrize("fraction", [0.1, 0.3, 0.5, 0.77, 0.95])
def test_lvm_cut_inside_the_data_is_an_error(tmp_path, fraction):
    # Cut anywhere in the rows of the only segment (not inside its last row: a value cut
    # there still leaves 200 rows of which the last is short, reported as such elsewhere).
    text = _lvm_text(1, 200)
    start = _rows_start(text, 0)
    last_row = text.rindex("\n", 0, len(text) - 2)
    cut = start + int(fraction * (last_row - start))
    path = tmp_path / "cut.lvm"
    path.write_bytes(text.encode()[:cut])
    with pytest.raises(DataFileError, match=r"cut\.lvm.*expected 200 samples, found \d+"):
        ami_xr.read_lvm(path)


def test_lvm_truncated_last_segment_is_an_error_not_a_shorter_record(tmp_path):
    text = _lvm_text(3, 60)
    start = _rows_start(text, 2)
    path = tmp_path / "hits.lvm"
    path.write_text(text[: start + 20 * len("\t0.000000\t0.000000\n")])
    with pytest.raises(DataFileError, match=r"segment 3 .*expected 60 samples, found \d+"):
        ami_xr.read_lvm(path)


def _frf_dataset() -> object:
    f = np.linspace(0.5, 50.0, 40)
    frf = np.arange(1, 4)[:, None] / (1j * f - 20.0 + 1.0)
    return make_frf_dataset(
        frf,
        f,
        points=[1, 2, 3],
        drive_point=1,
        response_quantity="displacement",
        response_units="m",
        force_units="N",
        frf_source=names.SOURCE_ANALYTIC,
    )


@pytest.fixture(params=[False, True], ids=["ascii", "binary"])
def uff_bytes(request, tmp_path) -> bytes:
    path = ami_xr.write_uff(_frf_dataset(), tmp_path / "whole.uff", binary=request.param)
    assert ami_xr.read_uff(path).sizes[names.POINT] == 3
    return path.read_bytes()


@pytest.mark.parametrize("fraction", [0.1, 0.3, 0.5, 0.6, 0.8, 0.99])
def test_uff_cut_at_any_position_is_an_error(tmp_path, uff_bytes, fraction):
    # 0.5 is the case: it used to convert as 1 FRF of 3 with exit 0.
    path = tmp_path / "half.uff"
    path.write_bytes(uff_bytes[: int(fraction * len(uff_bytes))])
    with pytest.raises(DataFileError, match=r"half\.uff: truncated UFF file: dataset type 58"):
        ami_xr.read_uff(path)


def test_uff_cut_says_how_many_datasets_are_complete(tmp_path, uff_bytes):
    path = tmp_path / "half.uff"
    path.write_bytes(uff_bytes[: len(uff_bytes) // 2])
    with pytest.raises(DataFileError, match=r"only the 1 dataset\(s\) before it are complete"):
        ami_xr.read_uff(path)


def test_uff_cut_through_the_cli_exits_1(tmp_path, uff_bytes, capsys):
    from ami_xr.app.cli import main

    path = tmp_path / "half.uff"
    path.write_bytes(uff_bytes[: len(uff_bytes) // 2])
    assert main(["convert", str(path), "-o", str(tmp_path / "out.nc")]) == 1
    assert "truncated UFF file" in capsys.readouterr().err
    assert not (tmp_path / "out.nc").exists()


def test_uff_record_shorter_than_its_num_pts_is_an_error(tmp_path):
    # A record whose delimiters pair up but whose data lost a line (ASCII, 2 values a line).
    path = ami_xr.write_uff(_frf_dataset(), tmp_path / "whole.uff")
    lines = path.read_text().splitlines(keepends=True)
    tags = [i for i, line in enumerate(lines) if line.rstrip("\r\n") == "    -1"]
    second_record_data = tags[2] + 1 + 13  # after its opening tag and 13 header lines
    del lines[second_record_data + 3]
    path.write_text("".join(lines))
    with pytest.raises(DataFileError, match=r"declares 40 values \(num_pts\), found 38"):
        ami_xr.read_uff(path)


def test_uff_dataset_with_a_damaged_number_is_an_error(tmp_path, uff_bytes):
    # pyuff reads a dataset whose number line is garbled as an unknown type and skips it, so
    # the file read as 2 FRFs of 3.
    opening = b"    -1\n    58"
    second = uff_bytes.index(opening, uff_bytes.index(opening) + 1 + len(opening))
    buf = bytearray(uff_bytes)
    buf[second + len(b"    -1\n") + 1] = 0xD4
    path = tmp_path / "flip.uff"
    path.write_bytes(bytes(buf))
    with pytest.raises(DataFileError, match=r"flip\.uff: damaged UFF file: dataset \d"):
        ami_xr.read_uff(path)
