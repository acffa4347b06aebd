"""Issue 12 on the command line: the drive point and channel options of ``ami-xr frf``, one
excitation rule shared with Python, and help texts without "(default: None)"."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.app.cli import EXIT_OK, main
from ami_xr.dsp.frf import frf_from_options

from ..io.test_lvm import _write
from ..io.test_lvm_assumptions import _quiet_read, hit_rows, random_rows

COMMANDS = ("demo", "simulate", "frf", "identify", "report", "convert", "batch")


def _help(command: str, capsys) -> str:
    with pytest.raises(SystemExit):
        main([command, "--help"])
    return " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("command", COMMANDS)
def test_help_never_shows_default_none(command, capsys):
    text = _help(command, capsys)
    assert "(default: None)" not in text
    assert "(default:" in text  # the defaults that exist are still shown


def test_help_states_the_defaults_of_unset_options_and_the_average_vocabulary(capsys):
    text = _help("frf", capsys)
    for shown in (
        "(default: hann)",
        "(default: nperseg)",
        "(default: H1)",
        "(default: linear)",
        "not scipy.signal.csd's average, which means mean or median",
        "auto: impact when the force is a short pulse",
    ):
        assert shown in text
    assert "--drive-point" in text and "--points" in text and "--force-channel" in text


def test_frf_reports_the_assumed_drive_point_on_one_line_and_in_the_file(tmp_path, capsys):
    lvm = _write(tmp_path / "hits.lvm", [hit_rows(p) for p in (100.0, 110.0, 95.0)])
    out = tmp_path / "hits_frf.nc"
    assert main(["frf", str(lvm), "-o", str(out)]) == EXIT_OK
    captured = capsys.readouterr()
    lines = [s for s in captured.err.splitlines() if "drive point" in s]
    assert len(lines) == 1
    assert lines[0].startswith("ami-xr frf: warning: AssumptionWarning: hits.lvm: drive point")
    assert "--drive-point" in lines[0]
    assert "excitation: impact" in captured.out
    g = ami_xr.open_dataset(out)
    assert g.attrs[names.ATTR_DRIVE_POINT_ASSUMED] == "the single response channel"
    assert g.attrs[names.ATTR_DRIVE_POINT] == "Acceleration (Trigger)"


def test_frf_channel_options_are_used_recorded_and_assume_nothing(tmp_path, capsys):
    lvm = _write(tmp_path / "hits.lvm", [hit_rows(p) for p in (100.0, 110.0, 95.0)])
    out = tmp_path / "hits_frf.nc"
    argv = ["frf", str(lvm), "-o", str(out), "--force-channel", "0", "--points", "tip"]
    assert main([*argv, "--drive-point", "tip"]) == EXIT_OK
    assert "AssumptionWarning" not in capsys.readouterr().err
    g = ami_xr.open_dataset(out)
    assert g.attrs[names.ATTR_DRIVE_POINT] == "tip"
    assert names.ATTR_DRIVE_POINT_ASSUMED not in g.attrs
    assert list(g[names.POINT].values) == ["tip"]
    last = json.loads(g.attrs[names.ATTR_HISTORY])[-1]["parameters"]
    assert last["force_channel"] == 0 and last["points"] == ["tip"]
    assert last["drive_point"] == "tip" and last["excitation"] == "impact"
    assert main([*argv, "--drive-point", "root", "-o", str(tmp_path / "x.nc")]) == 1
    assert "error: drive_point: 'root' is not one of the points" in capsys.readouterr().err


def test_frf_points_and_force_channel_are_refused_for_netcdf_input(tmp_path, capsys):
    lvm = _write(tmp_path / "hits.lvm", [hit_rows(p) for p in (100.0, 110.0, 95.0)])
    nc = ami_xr.to_netcdf(_quiet_read(lvm), tmp_path / "hits.nc")
    assert main(["frf", str(nc), "-o", str(tmp_path / "f.nc"), "--points", "a"]) == 1
    assert "error: points: only for LabVIEW .lvm input" in capsys.readouterr().err


@pytest.mark.parametrize("kind", ["hits", "random"])
def test_cli_auto_and_python_agree(kind, tmp_path, capsys):
    """The same file through ``ami-xr frf`` and through Python without an excitation: one rule,
    one result (random records are no longer taken for hits because they have a record dim)."""
    rows = [hit_rows(p) for p in (100.0, 110.0, 95.0)] if kind == "hits" else None
    rows = rows or [random_rows(s) for s in (1, 2, 3)]
    lvm = _write(tmp_path / f"{kind}.lvm", rows)
    out = tmp_path / f"{kind}_frf.nc"
    assert main(["frf", str(lvm), "-o", str(out)]) == EXIT_OK
    expected = "impact" if kind == "hits" else "random"
    assert f"excitation: {expected}" in capsys.readouterr().out
    cli = ami_xr.open_dataset(out)
    python = frf_from_options(_quiet_read(lvm), {})
    assert (names.HIT_REJECTED in cli) == (kind == "hits") == (names.HIT_REJECTED in python)
    np.testing.assert_array_equal(cli[names.FRF].values, python[names.FRF].values)
    xr.testing.assert_equal(cli[names.FREQUENCY], python[names.FREQUENCY])
