"""Time histories in MATLAB files for ``ami-xr frf`` (issue 40 item 4)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io

import ami_xr
from ami_xr import names
from ami_xr.app.cli import EXIT_ERROR, EXIT_OK, main
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.formats import read_any
from ami_xr.io.time_mat import holds_time_histories, read_time_mat

FS = 512.0


def _signals(n=8192):
    rng = np.random.default_rng(0)
    force = rng.standard_normal(n)
    kernel = np.exp(-np.arange(64) / 8.0) * np.sin(np.arange(64) / 3.0)
    resp = np.stack([np.convolve(force, kernel * g)[:n] for g in (1.0, 0.5, -2.0)])
    return force, resp


def test_force_and_response_with_fs(tmp_path, capsys):
    force, resp = _signals()
    path = tmp_path / "run1.mat"
    scipy.io.savemat(
        path,
        {
            "force": force,
            "response": resp.T,
            "fs": FS,
            "response_quantity": "acceleration",
            "points": ["a", "b", "c"],
        },
    )
    assert holds_time_histories(path)
    ts = read_time_mat(path, drive_point="a")
    assert list(ts[names.POINT].values) == ["a", "b", "c"]
    np.testing.assert_array_equal(ts[names.RESPONSE].values, resp)  # samples x channels read
    np.testing.assert_array_equal(ts[names.FORCE].values, force)
    assert ts.attrs[names.ATTR_QUANTITY] == "acceleration"
    out = tmp_path / "frf.nc"
    argv = ["frf", str(path), "-o", str(out), "--nperseg", "512", "--excitation", "random"]
    assert main(argv) == EXIT_OK
    g = ami_xr.open_dataset(out)
    ts = ami_xr.make_time_dataset(
        resp, fs=FS, force=force, points=["a", "b", "c"], response_quantity="acceleration"
    )
    want = ami_xr.frf(ts, nperseg=512)
    np.testing.assert_allclose(g[names.FRF].values, want[names.FRF].values, rtol=1e-12)


def test_channel_matrix_with_names_units_and_a_time_vector(tmp_path):
    force, resp = _signals()
    data = np.column_stack([resp[0], force, resp[1]])  # samples x channels, force second
    t = np.arange(force.size) / FS
    path = tmp_path / "run2.mat"
    meas = {
        "data": data,
        "t": t,
        "channel_names": ["p1", "hammer", "p2"],
        "channel_units": ["m/s^2", "N", "m/s^2"],
    }
    scipy.io.savemat(path, {"meas": meas})
    ts = read_any(path, want="time")
    assert list(ts[names.POINT].values) == ["p1", "p2"]
    np.testing.assert_array_equal(ts[names.FORCE].values, force)
    assert ts.attrs[names.ATTR_QUANTITY] == "acceleration"
    assert ts[names.FORCE].attrs["channel"] == "hammer"
    assert ts.attrs[names.ATTR_SOURCE_FILE] == "run2.mat"
    # no force unit, no force name: the force channel must be given
    scipy.io.savemat(path, {"data": data, "fs": FS, "channel_names": ["p1", "x", "p2"]})
    with pytest.raises(AmiXrValueError, match="force_channel: cannot tell the force channel"):
        read_time_mat(path)
    ts = read_time_mat(path, force_channel="x", response_quantity="acceleration")
    assert list(ts[names.POINT].values) == ["p1", "p2"]


def test_a_mat_file_without_time_histories_is_refused_clearly(tmp_path, capsys):
    path = tmp_path / "run1.mat"
    scipy.io.savemat(path, {"H": np.ones((4, 2049), complex)})
    assert main(["frf", str(path), "-o", str(tmp_path / "g.nc")]) == EXIT_ERROR
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert "run1.mat: the file has no sampling rate; expected time histories as 'force'" in err
    assert "found: H (4, 2049)" in err
    scipy.io.savemat(path, {"fs": FS, "x": np.ones(10)})
    with pytest.raises(DataFileError, match="has no channels; expected time histories"):
        read_time_mat(path)
    rng = np.random.default_rng(0)
    force, response = rng.standard_normal((2, 100)), rng.standard_normal((3, 100))
    scipy.io.savemat(path, {"fs": FS, "force": force, "response": response})
    two = read_time_mat(path, drive_point=0)  # two force channels: a multi-reference record
    assert two[names.FORCE].dims == (names.REFERENCE, names.TIME)
    assert list(two[names.REFERENCE].values) == ["force0", "force1"]
    np.testing.assert_allclose(two[names.FORCE].values, force)


def test_an_frf_table_mat_is_still_an_frf_table(tmp_path):
    f = np.linspace(0, 100, 201)
    path = tmp_path / "frf.mat"
    h = np.ones((2, f.size)) * (1 + 1j)
    scipy.io.savemat(path, {"freq": f, "H": h, "fs": FS, "response_quantity": "displacement"})
    assert not holds_time_histories(path)
    g = read_any(path)
    assert names.FRF in g
