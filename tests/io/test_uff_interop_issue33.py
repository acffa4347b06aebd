"""UFF files other tools read back as this tool wrote them (issue 33, items 7 and 13): the
dataset-58 abscissa keeps its step in pyuff's reader, and pyuff's own print() output does not
reach the tool's standard output."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.io.uff import read_uff, write_uff
from ami_xr.io.uff.quiet import quiet
from ami_xr.io.uff.write import real_field

pyuff = pytest.importorskip("pyuff")

#: 321 lines up to 34.1333... Hz: a step pyuff's %13.5e writes as 1.06667e-01.
N = 321
STEP = 34.13333333333333 / 320
FREQ = np.arange(N) * STEP


def _frf(freq=FREQ, points=("1+Z", "2+Z")) -> xr.Dataset:
    rng = np.random.default_rng(7)
    shape = (len(points), freq.size)
    return ami_xr.make_frf_dataset(
        rng.normal(size=shape) + 1j * rng.normal(size=shape),
        freq,
        points=list(points),
        drive_point=points[0],
        response_quantity="acceleration",
        response_units="m/s^2",
    )


def _pyuff_58(path) -> list[dict]:
    return [s for s in pyuff.UFF(str(path)).read_sets() if s["type"] == 58]


# --- item 7: the abscissa step ----------------------------------------------------------------
@pytest.mark.parametrize("binary", [False, True])
def test_pyuff_rebuilds_the_frequency_axis_of_an_export(tmp_path, binary):
    path = write_uff(_frf(), tmp_path / "f.uff", binary=binary)
    records = _pyuff_58(path)
    assert len(records) == 2
    for record in records:
        # before: step 1.06667e-01, last line 34.1334016 Hz (6.8e-5 Hz off)
        assert abs(record["abscissa_inc"] - STEP) < 1e-11
        assert abs(record["x"][-1] - FREQ[-1]) < 1e-8
        np.testing.assert_allclose(record["x"], FREQ, rtol=0, atol=1e-8)


def test_pyuff_rebuilds_the_time_axis_of_an_export(tmp_path):
    fs = 3000.0  # dt = 3.333...e-4 s: 6 digits are not enough either
    rng = np.random.default_rng(1)
    ts = ami_xr.make_time_dataset(
        rng.normal(size=(1, 2, 4096)),
        fs=fs,
        force=rng.normal(size=(1, 4096)),
        points=["1+Z", "2+Z"],
        drive_point="1+Z",
        response_quantity="acceleration",
        response_units="m/s^2",
    )
    records = _pyuff_58(write_uff(ts, tmp_path / "t.uff"))
    for record in records:
        # 8 significant digits fit (3.3333333E-4): 1.4e-8 s off at the end, was 1.4e-6 s
        assert abs(record["x"][-1] - 4095 / fs) < 2e-8


def test_the_tool_reads_its_export_back_unchanged(tmp_path):
    back = read_uff(write_uff(_frf(), tmp_path / "f.uff"))
    np.testing.assert_allclose(back[names.FREQUENCY].values, FREQ, rtol=0, atol=1e-8)


def test_the_abscissa_record_keeps_its_columns(tmp_path):
    path = write_uff(_frf(), tmp_path / "f.uff")
    lines = path.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip() == "58")
    record7 = lines[start + 7]
    assert len(record7) == 69  # 3I10, 3E13.5
    assert record7[43:56] == " .10666666667"
    assert float(record7[30:43]) == 0.0 and float(record7[56:69]) == 0.0


@pytest.mark.parametrize(
    "value", [0.10666666666666667, 1 / 1024, 0.5, 0.0, -1.234567891234e-3, 1e-5 / 3, 12345.6789012]
)
def test_real_field_is_the_most_precise_text_in_13_columns(value):
    text = real_field(value)
    assert len(text) == 13 and text[0] == " "
    assert abs(float(text) - value) <= 2e-8 * abs(value)  # 8 significant digits at least
    # never less precise than pyuff's own %13.5e
    assert abs(float(text) - value) <= abs(float(f"{value:13.5e}") - value)


# --- item 13: pyuff's print() output ----------------------------------------------------------
def _with_groups(path):
    """Append a dataset 2467 (groups), whose pyuff reader prints every group it parses."""
    group = (
        f"{'-1':>6}\n{'2467':>6}\n"
        + "".join(f"{v:10d}" for v in (1, 0, 0, 0, 0, 0, 0, 2))
        + "\n"
        + f"{'GROUP1':<40}\n"
        + "".join(f"{v:10d}" for v in (8, 1, 0, 0, 8, 2, 0, 0))
        + "\n"
        + f"{'-1':>6}\n"
    )
    with open(path, "a") as fh:
        fh.write(group)
    return path


def test_reading_prints_nothing_that_pyuff_prints(tmp_path, capsys):
    path = _with_groups(write_uff(_frf(), tmp_path / "f.uff"))
    capsys.readouterr()
    pyuff.UFF(str(path)).read_sets()
    assert "GROUP1" in capsys.readouterr().out  # pyuff alone prints
    ds = read_uff(path)
    assert ds[names.FRF].shape == (2, N)
    assert capsys.readouterr().out == ""


def test_writing_prints_nothing(tmp_path, capsys):
    write_uff(_frf(), tmp_path / "f.uff")
    assert capsys.readouterr().out == ""


def test_convert_of_a_file_pyuff_prints_on_writes_only_the_tool_output(tmp_path, capsys):
    from ami_xr.app.cli import main

    path = _with_groups(write_uff(_frf(), tmp_path / "f.uff"))
    capsys.readouterr()
    assert main(["convert", str(path), "-o", str(tmp_path / "f.nc")]) == 0
    out = capsys.readouterr().out
    assert "GROUP1" not in out and "<" not in out


def test_quiet_keeps_other_threads_output(capsys):
    printed = threading.Event()
    done = threading.Event()

    def other():
        printed.wait()
        print("from the other thread")
        done.set()

    thread = threading.Thread(target=other)
    thread.start()
    with quiet() as sink:
        print("from pyuff")
        printed.set()
        done.wait(5)
    thread.join()
    assert sink.getvalue() == "from pyuff\n"
    assert capsys.readouterr().out == "from the other thread\n"
