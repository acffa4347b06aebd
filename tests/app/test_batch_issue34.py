"""Issue 34, batch folders and resume: an output folder inside the inputs, ``-o`` equal to the
input, a read-only summary, and an input changed in place with the same size and mtime."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import ami_xr
import ami_xr.ami
from ami_xr import names
from ami_xr.app.batch import SUMMARY_NAME, batch
from ami_xr.app.cli import EXIT_ERROR, EXIT_USAGE, main
from ami_xr.errors import DataFileError


def quick_identify(ds, **options):
    """Stands in for the identification (the tests are about files, not modes): one mode whose
    frequency is the mean magnitude of the FRFs, so a changed input gives a changed result."""
    level = float(np.mean(np.abs(ds[names.FRF].values)))
    return xr.Dataset({names.EIGENVALUE: ("mode", np.array([2j * np.pi * level]))})


@pytest.fixture(autouse=True)
def _quick(monkeypatch):
    monkeypatch.setattr(ami_xr.ami, "identify", quick_identify)


def _frf(seed: int):
    g, _ = ami_xr.simulate.random_system(
        n_points=5, n_modes=5, noise=0.01, seed=seed, n_frequencies=64
    )
    return g


@pytest.fixture
def campaign(tmp_path) -> Path:
    """day1/a.nc, day1/b.nc and day2/c.nc."""
    root = tmp_path / "camp"
    (root / "day1").mkdir(parents=True)
    (root / "day2").mkdir()
    for rel, seed in (("day1/a.nc", 1), ("day1/b.nc", 2), ("day2/c.nc", 3)):
        ami_xr.to_netcdf(_frf(seed), root / rel)
    return root


def _rows(summary) -> dict[str, dict]:
    return {row["file"]: row for row in summary.rows}


# --- item 1: an output folder inside the input tree ---------------------------------------------
def test_output_folder_holding_measurements_still_processes_them(campaign, capsys):
    out = campaign / "day1"
    rows = _rows(batch(campaign, out, progress=False))
    assert set(rows) == {"day1/a.nc", "day1/b.nc", "day2/c.nc"}
    assert {r["status"] for r in rows.values()} == {"ok"}
    notice = [line for line in capsys.readouterr().err.splitlines() if "inside" in line]
    assert len(notice) == 1 and "day1" in notice[0], notice
    # the re-run takes its own outputs for outputs, never for measurements
    rows = _rows(batch(campaign, out, progress=False))
    assert set(rows) == {"day1/a.nc", "day1/b.nc", "day2/c.nc"}
    assert {r["status"] for r in rows.values()} == {"up to date"}


def test_output_equal_to_the_input_is_a_usage_error(campaign, capsys):
    before = sorted(p.relative_to(campaign) for p in campaign.rglob("*"))
    for output in (campaign, campaign / "." / "day1" / ".."):
        with pytest.raises(SystemExit) as stop:
            main(["batch", str(campaign), "-o", str(output), "-q"])
        assert stop.value.code == EXIT_USAGE
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith("ami-xr batch: error:") and "-o" in lines[0]
        assert "input" in lines[0] and "Traceback" not in err
    assert sorted(p.relative_to(campaign) for p in campaign.rglob("*")) == before


# --- item 2: a read-only batch_summary.csv ------------------------------------------------------
@pytest.fixture
def read_only_summary(campaign, tmp_path):
    out = tmp_path / "out"
    batch(campaign, out, progress=False)
    summary = out / SUMMARY_NAME
    text = summary.read_text()
    summary.chmod(0o444)
    ami_xr.to_netcdf(_frf(9), campaign / "day2" / "c.nc")  # something to redo
    yield out, summary, text
    summary.chmod(0o644)


def test_read_only_summary_is_refused_before_any_work(campaign, read_only_summary):
    out, summary, text = read_only_summary
    outputs = {p: p.stat().st_mtime_ns for p in out.rglob("*.modes.nc")}
    with pytest.raises(DataFileError, match=r"batch_summary\.csv.*read-only"):
        batch(campaign, out, progress=False)
    assert summary.read_text() == text
    assert stat.S_IMODE(summary.stat().st_mode) == 0o444
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.modes.nc")} == outputs


def test_cli_read_only_summary_is_one_error_line(campaign, read_only_summary, capsys):
    out, summary, text = read_only_summary
    assert main(["batch", str(campaign), "-o", str(out), "-q"]) == EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ami-xr batch: error:"), err
    assert "batch_summary.csv" in err[0] and "read-only" in err[0]
    assert summary.read_text() == text


# --- item 3: an input changed in place with the same size and mtime -----------------------------
def test_input_changed_with_the_same_size_and_mtime_is_redone(campaign, tmp_path):
    out = tmp_path / "out"
    first = _rows(batch(campaign, out, progress=False))["day1/a.nc"]
    path = campaign / "day1" / "a.nc"
    st = path.stat()
    g = _frf(1)
    # same layout, same attributes: same size (copy keeps the variable's attributes)
    ami_xr.to_netcdf(g.assign(frf=g[names.FRF].copy(data=g[names.FRF].values * 3)), path)
    assert path.stat().st_size == st.st_size
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))  # a copy tool that preserves times
    rows = _rows(batch(campaign, out, progress=False))
    assert rows["day1/a.nc"]["status"] == "ok"
    assert rows["day1/a.nc"]["frequencies_hz"] != first["frequencies_hz"]
    assert rows["day2/c.nc"]["status"] == "up to date"
    # and once redone it is up to date again
    assert _rows(batch(campaign, out, progress=False))["day1/a.nc"]["status"] == "up to date"
