"""The rule every ``ami-xr`` subcommand follows (issue 9, items 2, 4 and 8).

Outputs are checked before any work: never one of the inputs (also through a symlink or a hard
link), the suffix of the format written, never a read-only file silently replaced, a folder
where a folder goes. Every error is one line and exit 1 (an unexpected one says how to see its
traceback), Ctrl-C is one line and exit 130. Each test also checks that the input files are
byte for byte unchanged and that no output or temporary file is left.
"""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.app import cli
from ami_xr.app import options as cli_options
from ami_xr.app.cli import (
    EXIT_BATCH_FAILURES,
    EXIT_ERROR,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    main,
)
from ami_xr.io import formats

REPO = Path(__file__).resolve().parents[2]
ENV = {
    **os.environ,
    "PYTHONPATH": os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]),
}
HAMMER = REPO.parent / "shared" / "data" / "impact_hammer.lvm"


# --- data and helpers ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def frf_dataset() -> xr.Dataset:
    """Small benchmark FRFs (4 points x 129 lines)."""
    _, g, _ = ami_xr.simulate.benchmark(n_samples=256)
    return g.load()


def _time_dataset() -> xr.Dataset:
    """Random-excitation force and two responses: a valid input of ``ami-xr frf``."""
    rng = np.random.default_rng(0)
    n = 2048
    force = rng.standard_normal(n)
    lag = np.arange(64)
    responses = [np.convolve(force, np.exp(-lag / 8) * np.sin(lag * k / 3), "same") for k in (1, 2)]
    time = xr.DataArray(np.arange(n) / 1024.0, dims=names.TIME, attrs={"units": "s"})
    return xr.Dataset(
        {
            names.RESPONSE: ((names.POINT, names.TIME), np.stack(responses)),
            names.FORCE: ((names.TIME,), force),
        },
        coords={names.POINT: ["a", "b"], names.TIME: time},
        attrs={
            names.ATTR_DRIVE_POINT: "a",
            "response_quantity": "displacement",
            "response_units": "m",
            "force_units": "N",
        },
    )


@pytest.fixture
def files(tmp_path, frf_dataset) -> Path:
    """A folder with g.nc (FRFs) and t.nc (time histories); the tests run in it."""
    ami_xr.to_netcdf(frf_dataset, tmp_path / "g.nc")
    ami_xr.to_netcdf(_time_dataset(), tmp_path / "t.nc")
    return tmp_path


def _snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every entry under ``folder`` (hidden ones included): file bytes, None for a folder."""
    return {
        str(p.relative_to(folder)): None if p.is_dir() else p.read_bytes()
        for p in sorted(folder.rglob("*"))
    }


def _one_error_line(err: str, command: str, *, expected: str = "") -> str:
    """stderr holds no traceback and exactly one error line of ``command``; return it."""
    lines = [line for line in err.splitlines() if line.strip()]
    assert not any("Traceback" in line for line in lines), err
    assert all(line.startswith(f"ami-xr {command}: ") for line in lines), err
    errors = [line for line in lines if line.startswith(f"ami-xr {command}: error: ")]
    assert len(errors) == 1, err
    assert expected in errors[0], errors[0]
    return errors[0]


def _refused(args: list[str], folder: Path, capsys, *, expected: str) -> str:
    """``ami-xr ARGS`` exits 1 with one error line and leaves ``folder`` exactly as it was."""
    before = _snapshot(folder)
    assert main(args) == EXIT_ERROR
    line = _one_error_line(capsys.readouterr().err, args[0], expected=expected)
    assert _snapshot(folder) == before
    return line


@pytest.fixture
def no_identify(monkeypatch):
    """Make any identification fail loudly: the checks must come before it."""

    def identify(*args, **kwargs):
        raise AssertionError("the identification ran before the outputs were checked")

    monkeypatch.setattr(ami_xr, "identify", identify)


# --- rule 1: outputs are checked before any work -------------------------------------------------
def test_frf_refuses_to_write_over_its_netcdf_input(files, capsys):
    line = _refused(
        ["frf", str(files / "t.nc"), "-o", str(files / "t.nc")], files, capsys, expected="input"
    )
    assert "t.nc" in line


@pytest.mark.skipif(not HAMMER.is_file(), reason="shared/data folder absent")
def test_frf_refuses_to_write_over_its_lvm_input(tmp_path, capsys):
    lvm = tmp_path / "imp.lvm"
    lvm.write_bytes(HAMMER.read_bytes())
    _refused(["frf", str(lvm), "-o", str(lvm)], tmp_path, capsys, expected="input")


def test_output_through_a_symlink_or_hard_link_is_the_input(files, capsys):
    os.symlink(files / "g.nc", files / "link.nc")
    os.link(files / "g.nc", files / "hard.nc")
    for output in ("link.nc", "hard.nc"):
        line = _refused(
            ["convert", str(files / "g.nc"), "-o", str(files / output)],
            files,
            capsys,
            expected="is the input",
        )
        assert output in line and "g.nc" in line


def test_batch_refuses_its_input_folder_as_output_in_any_spelling(tmp_path, capsys):
    (tmp_path / "in").mkdir()
    os.symlink(tmp_path / "in", tmp_path / "alias")
    for output in ("in", "alias", "in/./"):
        with pytest.raises(SystemExit) as stop:
            main(["batch", str(tmp_path / "in"), "-o", str(tmp_path / output)])
        assert stop.value.code == EXIT_USAGE
        assert "is the input folder DIR" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["alias", "in"]


@pytest.mark.parametrize(
    "args",
    [
        ["identify", "{g}", "-o", "{g}", "-q"],
        ["convert", "{g}", "-o", "{g}"],
        ["report", "{g}", "-o", "{g}"],
    ],
    ids=["identify", "convert", "report"],
)  # batch DIR -o DIR is a usage error (exit 2): the test above
def test_no_command_writes_over_its_input(files, capsys, no_identify, args):
    args = [a.format(g=files / "g.nc", dir=files) for a in args]
    line = _refused(args, files, capsys, expected="")
    assert str(files / "g.nc") in line or "is the input" in line


def test_two_outputs_of_one_run_must_differ(tmp_path, capsys):
    out = str(tmp_path / "a.nc")
    args = ["simulate", "beam-absorbers", "-o", out, "--truth-output", out]
    _refused(args, tmp_path, capsys, expected="also the output")


@pytest.mark.parametrize(
    "args",
    [
        ["simulate", "random", "-o", "{dir}/x.lvm"],
        ["simulate", "beam-absorbers", "-o", "{dir}/x.nc", "--time-output", "{dir}/t.uff"],
        ["frf", "{dir}/t.nc", "-o", "{dir}/f.lvm"],
        ["frf", "{dir}/t.nc", "-o", "{dir}/f.uff"],
    ],
    ids=["simulate-lvm", "simulate-time-uff", "frf-lvm", "frf-uff"],
)
def test_netcdf_writers_refuse_another_suffix(files, capsys, args):
    args = [a.format(dir=files) for a in args]
    _refused(args, files, capsys, expected="expected a .nc file name")


def test_identify_refuses_an_unknown_suffix_before_identifying(files, capsys, no_identify):
    args = ["identify", str(files / "g.nc"), "-o", str(files / "m.csv")]
    _refused(args, files, capsys, expected="expected a .nc, .uff or .unv")


def test_read_only_output_is_refused_not_replaced(files, capsys):
    ro = files / "ro.nc"
    ro.write_bytes(b"keep me")
    ro.chmod(0o444)
    try:
        line = _refused(
            ["convert", str(files / "g.nc"), "-o", str(ro)], files, capsys, expected="read-only"
        )
        assert "0444" in line
        assert stat.S_IMODE(ro.stat().st_mode) == 0o444
    finally:
        ro.chmod(0o644)


def test_file_output_in_a_missing_folder_is_refused_before_reading(files, capsys, monkeypatch):
    def read_any(path):
        raise AssertionError("the input was read before the output was checked")

    monkeypatch.setattr(formats, "read_any", read_any)
    args = ["convert", str(files / "g.nc"), "-o", str(files / "no" / "x.nc")]
    _refused(args, files, capsys, expected="does not exist")


def test_demo_refuses_an_existing_file_before_identifying(tmp_path, capsys, no_identify):
    (tmp_path / "afile").write_text("mine")
    _refused(["demo", "-o", str(tmp_path / "afile")], tmp_path, capsys, expected="not a folder")


def test_demo_refuses_a_read_only_folder_or_modes_file_before_identifying(
    tmp_path, capsys, no_identify
):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        _refused(["demo", "-o", str(folder)], tmp_path, capsys, expected="not writable")
    finally:
        folder.chmod(0o755)
    modes = folder / "modes.nc"
    modes.write_bytes(b"earlier result")
    modes.chmod(0o444)
    try:
        _refused(["demo", "-o", str(folder), "--no-report"], tmp_path, capsys, expected="read-only")
    finally:
        modes.chmod(0o644)


def test_the_rule_table_lists_every_subcommand():
    import argparse

    parser = cli.build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert set(cli_options.PATHS) == set(action.choices)


def test_writable_existing_output_is_still_replaced(files, capsys):
    out = files / "c.nc"
    out.write_bytes(b"old")
    assert main(["convert", str(files / "g.nc"), "-o", str(out)]) == EXIT_OK
    assert ami_xr.open_dataset(out)[names.FRF].shape == (4, 129)


# --- rule 2: errors are one line ----------------------------------------------------------------
def _write(ds: xr.Dataset, path: Path) -> Path:
    return ami_xr.to_netcdf(ds, path)  # no schema check: bad Datasets are written as they are


@pytest.mark.parametrize(
    "case",
    ["wrong_dims", "one_line", "no_lines"],
)
def test_convert_to_uff_of_a_bad_file_is_one_line(files, frf_dataset, capsys, case):
    bad = {
        "wrong_dims": frf_dataset.rename({names.POINT: "pt"}),
        "one_line": frf_dataset.isel({names.FREQUENCY: slice(0, 1)}),
        "no_lines": frf_dataset.isel({names.FREQUENCY: slice(0, 0)}),
    }[case]
    src = _write(bad, files / f"{case}.nc")
    _refused(["convert", str(src), "-o", str(files / f"{case}.uff")], files, capsys, expected="")


def test_identify_of_a_tiny_frf_is_one_line_or_works(files, frf_dataset, capsys):
    tiny = frf_dataset.copy()
    tiny[names.FRF] = frf_dataset[names.FRF] * 1e-300
    src = _write(tiny, files / "tiny.nc")
    before = _snapshot(files)
    code = main(["identify", str(src), "-q"])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if code != EXIT_OK:  # helper F4 makes the numerics cope; until then: one line
        assert code == EXIT_ERROR
        _one_error_line(err, "identify")
    assert _snapshot(files) == before


def test_demo_with_a_stray_sample_file_is_one_line(tmp_path, frf_dataset, capsys, monkeypatch):
    (tmp_path / "sample_data").mkdir()
    _write(frf_dataset.drop_vars(names.FREQUENCY), tmp_path / "sample_data" / "my_frf.nc")
    monkeypatch.chdir(tmp_path)
    line = _refused(["demo", "-o", str(tmp_path / "out")], tmp_path, capsys, expected="my_frf.nc")
    assert "--simulate" in line


@pytest.mark.parametrize("verbose", [False, True])
def test_unexpected_error_is_one_line_with_the_hint(files, capsys, monkeypatch, verbose):
    def read_any(path):
        raise KeyError("boom")

    monkeypatch.setattr(formats, "read_any", read_any)
    args = ["convert", str(files / "g.nc"), "-o", str(files / "x.nc")]
    assert main([*args, "-v"] if verbose else args) == EXIT_ERROR
    err = capsys.readouterr().err
    if verbose:
        assert "Traceback" in err and "KeyError" in err
        assert err.strip().splitlines()[-1].startswith("ami-xr convert: error: unexpected KeyError")
    else:
        line = _one_error_line(err, "convert", expected="unexpected KeyError: 'boom'")
        assert line.endswith("(run with -v for the traceback)")
    assert not (files / "x.nc").exists()


def test_ctrl_c_is_one_line_and_exit_130(files, capsys, monkeypatch):
    def read_any(path):
        raise KeyboardInterrupt

    monkeypatch.setattr(formats, "read_any", read_any)
    before = _snapshot(files)
    assert main(["convert", str(files / "g.nc"), "-o", str(files / "x.nc")]) == EXIT_INTERRUPTED
    assert capsys.readouterr().err.strip() == "ami-xr convert: interrupted"
    assert _snapshot(files) == before


def test_exit_codes_are_defined_once_and_documented():
    assert (EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_BATCH_FAILURES, EXIT_INTERRUPTED) == (
        0,
        1,
        2,
        3,
        130,
    )
    epilog = cli.build_parser().epilog
    for code in ("0 ok", "1 error", "2 usage", "3 batch", "130 interrupted"):
        assert code in epilog


def test_the_installed_entry_point_shows_no_traceback(files, frf_dataset):
    """Through ``python -m ami_xr.app.cli``: the KeyError of issue 9 as one line, exit 1."""
    src = _write(frf_dataset.rename({names.POINT: "pt"}), files / "bad.nc")
    before = _snapshot(files)
    proc = subprocess.run(
        [sys.executable, "-m", "ami_xr.app.cli", "convert", str(src), "-o", str(files / "bad.uff")],
        capture_output=True,
        text=True,
        timeout=300,
        env=ENV,
    )
    assert proc.returncode == EXIT_ERROR
    _one_error_line(proc.stderr, "convert")
    assert _snapshot(files) == before


# --- item 3 (issue 12 item 8): identify of time data points to ami-xr frf ------------------------
@pytest.mark.parametrize("name", ["t.nc", "rec.lvm"])
def test_identify_of_time_data_says_to_run_frf_first(files, capsys, name):
    if name.endswith(".lvm"):  # an LVM file always holds time histories: refused unread
        (files / name).write_text("not read")
    line = _refused(["identify", str(files / name)], files, capsys, expected="ami-xr frf")
    assert name in line
