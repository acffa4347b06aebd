"""LabVIEW LVM reader and the real impact-hammer measurement."""

from __future__ import annotations

import runpy
from pathlib import Path

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError

from ..reference import HAMMER_LVM, REPO

HEADER = """LabVIEW Measurement\t
Writer_Version\t2
Reader_Version\t2
Separator\tTab
Decimal_Separator\t{decimal}
Multi_Headings\tYes
X_Columns\tNo
Time_Pref\tAbsolute
***End_of_Header***\t
\t
"""
SEGMENT = """Channels\t2\t\t
Samples\t{n}\t{n}\t
Y_Unit_Label\tNewtons\tm/s^2\t
X_Dimension\tTime\tTime\t
X0\t{x0}\t{x0}\t
Delta_X\t{dx}\t{dx}\t
***End_of_Header***\t\t\t
X_Value\tForce (Trigger)\tAcceleration (Trigger)\tComment
"""


def _write(path: Path, segments, decimal=".", dx=0.001, dxs=None) -> Path:
    text = HEADER.format(decimal=decimal)
    for i, data in enumerate(segments):
        text += SEGMENT.format(n=len(data), x0=float(i), dx=dxs[i] if dxs else dx)
        for f, a in data:
            row = f"\t{f:.6f}\t{a:.6f}"
            text += (row.replace(".", ",") if decimal == "," else row) + "\n"
        text += "\n"
    path.write_text(text)
    return path


def _data(n, seed):
    rng = np.random.default_rng(seed)
    return np.round(rng.standard_normal((n, 2)), 6)


def test_reads_segments_as_records(tmp_path):
    segs = [_data(50, 1), _data(50, 2), _data(50, 3)]
    ds = ami_xr.read_lvm(_write(tmp_path / "a.lvm", segs))
    assert ds[names.RESPONSE].dims == (names.RECORD, names.POINT, names.TIME)
    assert ds[names.FORCE].dims == (names.RECORD, names.TIME)
    # values written with 6 decimals and parsed back: the parser's float() is correctly rounded, so
    # bit-identical to the same decimal literals
    np.testing.assert_array_equal(ds[names.FORCE].values, np.array(segs)[:, :, 0])
    np.testing.assert_array_equal(ds[names.RESPONSE].values[:, 0], np.array(segs)[:, :, 1])
    # k * dt from the header's Delta_X vs k * 0.001: one or two roundings (the default rtol 1e-7 is
    # loose; a wrong dt is off by O(1))
    np.testing.assert_allclose(ds[names.TIME].values, np.arange(50) * 0.001)
    # parsed from the header, no arithmetic
    np.testing.assert_array_equal(ds[names.RECORD_START].values, [0.0, 1.0, 2.0])
    assert ds.attrs[names.ATTR_FORCE_UNITS] == "N"
    assert ds.attrs[names.ATTR_RESPONSE_UNITS] == "m/s^2"
    assert ds.attrs[names.ATTR_QUANTITY] == "acceleration"
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "Acceleration (Trigger)"
    assert ds.attrs[names.ATTR_SOURCE_FILE].endswith("a.lvm")
    ami_xr.validate(ds)


def test_single_segment_and_decimal_comma(tmp_path):
    seg = _data(20, 4)
    ds = ami_xr.read_lvm(_write(tmp_path / "c.lvm", [seg], decimal=","), points=["tip"])
    assert ds[names.RESPONSE].dims == (names.POINT, names.TIME)
    assert list(ds[names.POINT].values) == ["tip"]
    np.testing.assert_array_equal(ds[names.FORCE].values, seg[:, 0])


def test_force_channel_choice(tmp_path):
    path = _write(tmp_path / "a.lvm", [_data(10, 1)])
    ds = ami_xr.read_lvm(
        path,
        force_channel="Acceleration (Trigger)",
        response_quantity="displacement",
        response_units="m",
    )
    np.testing.assert_array_equal(ds[names.FORCE].values, _data(10, 1)[:, 1])
    with pytest.raises(AmiXrValueError, match="force_channel"):
        ami_xr.read_lvm(path, force_channel="Voltage")
    with pytest.raises(AmiXrValueError, match="force_channel"):
        ami_xr.read_lvm(path, force_channel=5)


@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda t: t.replace("LabVIEW Measurement", "Some Measurement", 1), "not a LabVIEW LVM"),
        (lambda t: t.split("***End_of_Header***")[0], "no '\\*\\*\\*End_of_Header\\*\\*\\*'"),
        (lambda t: t.replace("\t0.", "\tzero.", 1), "line"),
        (lambda t: t.replace("Separator\tTab", "Separator\tSemicolon"), "Separator"),
        (lambda t: t.replace("X_Value", "Y_Value"), "column titles"),
    ],
)
def test_malformed_files_name_the_file(tmp_path, mutate, match):
    path = _write(tmp_path / "bad.lvm", [_data(10, 1), _data(10, 2)])
    path.write_text(mutate(path.read_text()))
    with pytest.raises(DataFileError, match=match) as err:
        ami_xr.read_lvm(path)
    assert "bad.lvm" in str(err.value)


def test_segments_that_cannot_be_stacked(tmp_path):
    with pytest.raises(DataFileError, match="differ in samples"):
        ami_xr.read_lvm(_write(tmp_path / "n.lvm", [_data(10, 1), _data(12, 2)]))
    with pytest.raises(DataFileError, match="Delta_X"):
        ami_xr.read_lvm(
            _write(tmp_path / "d.lvm", [_data(10, 1), _data(10, 2)], dxs=[0.001, 0.002])
        )
    with pytest.raises(DataFileError, match="no such file"):
        ami_xr.read_lvm(tmp_path / "missing.lvm")


# --- the real hammer test ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def hammer():
    if not HAMMER_LVM.is_file():
        pytest.skip(f"real measurement data not available ({HAMMER_LVM})")
    return ami_xr.read_lvm(HAMMER_LVM)


def test_hammer_file_reads(hammer):
    assert hammer.sizes == {names.RECORD: 5, names.POINT: 1, names.TIME: 51200}
    fs = 1.0 / float(hammer[names.TIME][1] - hammer[names.TIME][0])
    # 1 / (t1 - t0) with t1 - t0 = 1 / 51200 parsed from the header: a few roundings (default rel
    # 1e-6 is loose; a wrong rate is off by O(1))
    assert fs == pytest.approx(51200.0)
    ami_xr.validate(hammer)


def test_hammer_bad_hits_found_and_frf_from_good_ones(hammer):
    est = ami_xr.impact_frf(hammer, exponential_end_value=0.01)
    rejected = est[names.HIT_REJECTED].values
    reasons = est[names.HIT_REJECT_REASON].values
    # booleans
    np.testing.assert_array_equal(rejected, [True, False, True, False, False])
    assert reasons[0].startswith("overload: force clipped")
    assert reasons[2].startswith("double impact")
    assert est.attrs[names.ATTR_N_AVERAGES] == 3
    # beta = -ln(end) fs / (n - 1) with fs from the time axis: a few roundings (default rel 1e-6)
    assert est.attrs[names.ATTR_EXP_DECAY] == pytest.approx(-np.log(0.01) * 51200 / 51199)
    assert est[names.FRF].attrs[names.ATTR_UNITS] == "m/s^2/N"
    ami_xr.validate(est)
    # three good hits agree: the coherence is high where the hammer puts energy in
    band = est.sel({names.FREQUENCY: slice(50.0, 3000.0)})
    assert float(band[names.COHERENCE].median()) > 0.95
    # the same FRF as averaging hits 1, 3, 4 by hand (no checks)
    good = ami_xr.impact_frf(
        hammer.isel(record=[1, 3, 4]),
        hit_checks=False,
        exponential_end_value=0.01,
        force_window=est.attrs[names.ATTR_FORCE_WINDOW_WIDTH],
    )
    # the same three hits averaged in the same order (rejected hits are skipped before any
    # arithmetic): bit-identical in practice, 1e-12 only allows for the FFT's batch size; the
    # averaged spectra of real hits have no exact zeros
    np.testing.assert_allclose(good[names.FRF].values, est[names.FRF].values, rtol=1e-12)


@pytest.mark.slow
def test_hammer_to_modes_script(hammer, capsys, tmp_path):
    script = REPO / "scripts" / "hammer_to_modes.py"
    main = runpy.run_path(str(script), run_name="hammer_to_modes")["main"]
    modes = tmp_path / "modes.nc"
    report = tmp_path / "report"
    assert main([str(HAMMER_LVM), "--modes", str(modes), "--report", str(report)]) == 0
    out = capsys.readouterr().out
    assert "overload" in out and "double impact" in out and "3 hit(s)" in out
    assert "modes identified by ami_xr.identify" in out
    identified = ami_xr.open_dataset(modes)
    assert identified.sizes["mode"] >= 1
    assert (report / "index.html").is_file()
