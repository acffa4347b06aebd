"""Time histories in text tables for ``ami-xr frf`` (issue 40, item 4): channels with a sampling
rate, the force channel(s) and units by a small header convention or by options, several force
channels and volt channels with a sensitivity (also in ``make_time_dataset``)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

import ami_xr
from ami_xr import names
from ami_xr.app.cli import EXIT_ERROR, EXIT_OK, main
from ami_xr.errors import AmiXrValueError, DataFileError, SchemaError
from ami_xr.io.datasets import ATTR_SENSITIVITY
from ami_xr.io.readers import read_any
from ami_xr.io.time_table import holds_time_histories, read_time_csv

FS = 1024.0
N = 8192


def _fir(k: int) -> np.ndarray:
    """A short decaying impulse response (a known system to estimate)."""
    t = np.arange(64) / FS
    return np.exp(-40.0 * t) * np.sin(2 * np.pi * (60.0 + 25.0 * k) * t)


def _record(n_force: int, seed: int = 0):
    """Random forces and the responses of two points to them (a known linear system)."""
    rng = np.random.default_rng(seed)
    forces = rng.standard_normal((n_force, N))
    h = {(p, f): _fir(p + 2 * f) for p in range(2) for f in range(n_force)}
    responses = np.array(
        [
            sum(scipy.signal.lfilter(h[p, f], [1.0], forces[f]) for f in range(n_force))
            for p in range(2)
        ]
    )
    return forces, responses, h


def _write(path, header, columns, lines=(), sep=","):
    rows = [sep.join(repr(float(v)) for v in row) for row in np.array(columns).T]
    path.write_text("\n".join([*lines, sep.join(header), *rows]) + "\n", encoding="utf-8")
    return path


def test_a_table_with_a_time_column_reads_as_time_histories(tmp_path):
    forces, responses, _ = _record(1)
    t = np.arange(N) / FS
    path = _write(
        tmp_path / "run1.csv",
        ["time [s]", "hammer [N]", "a1 [m/s²]", "a2 [m/s^2]"],
        [t, forces[0], *responses],
        ["# drive_point: a1", "# a test on the bench"],
    )
    assert holds_time_histories(path)
    ds = read_any(path)
    assert ds[names.RESPONSE].dims == (names.POINT, names.TIME)
    assert list(ds[names.POINT].values) == ["a1", "a2"]
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "a1"
    assert ds.attrs[names.ATTR_QUANTITY] == "acceleration"
    assert ds.attrs[names.ATTR_RESPONSE_UNITS] == "m/s^2"
    assert ds[names.FORCE].attrs["channel"] == "hammer"
    np.testing.assert_allclose(ds[names.TIME].values, t, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(ds[names.FORCE].values, forces[0])
    np.testing.assert_array_equal(ds[names.RESPONSE].values, responses)
    assert ds.attrs[names.ATTR_SOURCE_FILE] == "run1.csv"


def test_fs_line_volts_and_sensitivity(tmp_path):
    forces, responses, _ = _record(1)
    volts = 0.00225  # V/N of the hammer, 0.0102 V/(m/s^2) of a2
    path = _write(
        tmp_path / "run2.txt",
        ["hammer [V]", "a1 [g]", "a2 [V]"],
        [forces[0] * volts, responses[0], responses[1] * 0.0102],
        ["# fs: 1024", "# sensitivity: hammer=0.00225, a2=0.0102", "# response_units: g"],
        sep="\t",
    )
    ds = read_any(path, drive_point="a1")
    np.testing.assert_allclose(ds[names.FORCE].values, forces[0], rtol=1e-12)
    np.testing.assert_allclose(ds[names.RESPONSE].values, responses, rtol=1e-12)
    assert ds.attrs[names.ATTR_FORCE_UNITS] == "N"
    assert ds.attrs[names.ATTR_RESPONSE_UNITS] == "g"
    assert ds.attrs[ATTR_SENSITIVITY] == "force: 0.00225 V/N; a2: 0.0102 V/g"
    assert float(ds[names.TIME][1]) == pytest.approx(1 / FS)


def test_a_volt_channel_without_its_sensitivity_is_refused_naming_it(tmp_path, capsys):
    forces, responses, _ = _record(1)
    path = _write(
        tmp_path / "run3.csv",
        ["hammer [V]", "a1 [g]", "a2 [g]"],
        [forces[0], *responses],
        ["# fs: 1024"],
    )
    with pytest.raises(DataFileError, match=r"channel 'hammer' is in volts; give its sensitivity"):
        read_time_csv(path)
    assert main(["frf", str(path), "-o", str(tmp_path / "g.nc")]) == EXIT_ERROR
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "'hammer' is in volts" in err
    sens = read_time_csv(path, sensitivity={"hammer": 0.002}, force_channel="hammer")
    np.testing.assert_allclose(sens[names.FORCE].values, forces[0] / 0.002)
    path = _write(
        tmp_path / "run4.csv", ["F [N]", "a1 [V]"], [forces[0], responses[0]], ["# fs: 1024"]
    )
    with pytest.raises(DataFileError, match=r"'a1' is in volts; give its sensitivity"):
        read_time_csv(path)
    with pytest.raises(DataFileError, match=r"response channel 'a1' is in volts; say the units"):
        read_time_csv(path, sensitivity={"a1": 0.01})


def test_no_sampling_rate_or_no_force_is_refused_clearly(tmp_path):
    path = _write(tmp_path / "x.csv", ["a [g]", "b [g]"], [np.ones(8), np.ones(8)])
    with pytest.raises(DataFileError, match=r"x\.csv: no time column and no sampling rate"):
        read_time_csv(path)
    with pytest.raises(AmiXrValueError, match="cannot tell the force channel of x.csv"):
        read_time_csv(path, fs=100.0)
    assert not holds_time_histories(path)  # no time column and no fs line: an FRF table?
    with pytest.raises(DataFileError, match="no frequency column"):
        read_any(path)


def test_two_force_channels_give_multi_reference_frfs_of_the_known_system(tmp_path):
    forces, responses, h = _record(2, seed=3)
    path = _write(
        tmp_path / "mimo.csv",
        ["t", "F1 [N]", "F2 [N]", "a [m/s^2]", "b [m/s^2]"],
        [np.arange(N) / FS, *forces, *responses],
        ["# force_channel: F1, F2", "# drive_point: a"],
    )
    ds = read_any(path, want="time")
    assert ds[names.FORCE].dims == (names.REFERENCE, names.TIME)
    assert list(ds[names.REFERENCE].values) == ["F1", "F2"]
    g = ami_xr.frf(ds, nperseg=512)
    assert g[names.FRF].dims[:2] == (names.REFERENCE, names.POINT)
    f = g[names.FREQUENCY].values
    for p, point in enumerate(("a", "b")):
        for r, ref in enumerate(("F1", "F2")):
            _, true = scipy.signal.freqz(h[p, r], worN=f, fs=FS)
            got = g[names.FRF].sel({names.REFERENCE: ref, names.POINT: point}).values
            band = (f > 20) & (f < 400)
            err = np.abs(got[band] - true[band]) / np.abs(true[band]).max()
            assert np.median(err) < 0.05, (point, ref, np.median(err))
    # the same channels named by the option (the command line's --force-channel F1,F2)
    out = tmp_path / "mimo_frf.nc"
    argv = ["frf", str(path), "-o", str(out), "--force-channel", "F1,F2", "--nperseg", "512"]
    assert main(argv) == EXIT_OK
    assert ami_xr.open_dataset(out)[names.FRF].sizes[names.REFERENCE] == 2


def test_make_time_dataset_with_several_forces_and_volts():
    forces, responses, _ = _record(2)
    ds = ami_xr.make_time_dataset(
        responses * np.array([[0.01], [1.0]]),
        fs=FS,
        force=forces * 0.002,
        references=["F1", "F2"],
        points=["a", "b"],
        response_quantity="acceleration",
        sensitivity={"F1": 0.002, "F2": 0.002, "a": 0.01},
    )
    np.testing.assert_allclose(ds[names.FORCE].values, forces, rtol=1e-12)
    np.testing.assert_allclose(ds[names.RESPONSE].values, responses, rtol=1e-12)
    assert ds.attrs[ATTR_SENSITIVITY] == "F1: 0.002 V/N; F2: 0.002 V/N; a: 0.01 V/m/s^2"
    with pytest.raises(AmiXrValueError, match=r"force: expected shape \(2, 8192\)"):
        ami_xr.make_time_dataset(responses, fs=FS, force=forces[0], references=["F1", "F2"])
    with pytest.raises(AmiXrValueError, match="sensitivity: 'c' is no channel"):
        ami_xr.make_time_dataset(responses, fs=FS, force=forces[0], sensitivity={"c": 1.0})
    with pytest.raises(AmiXrValueError, match="sensitivity: channel 'force': expected volts"):
        ami_xr.make_time_dataset(responses, fs=FS, force=forces[0], sensitivity={"force": -1})
    with pytest.raises(SchemaError, match="references"):
        ami_xr.make_time_dataset(
            responses, fs=FS, force=forces, references=["F1", "F1"], points=["a", "b"]
        )
