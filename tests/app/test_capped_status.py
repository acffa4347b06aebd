"""Issue 24 item 1: a capped (incomplete) identification is not reported as a success."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

import ami_xr
from ami_xr import names
from ami_xr.app.batch import STATUS_CAPPED, STATUS_OK, SUMMARY_NAME, batch
from ami_xr.app.cli import EXIT_BATCH_CAPPED, EXIT_BATCH_FAILURES, EXIT_OK, main


def _frf(seed: int):
    g, _ = ami_xr.simulate.random_system(
        n_points=5, n_modes=5, noise=0.01, seed=seed, n_frequencies=512
    )
    return g


@pytest.fixture
def folder(tmp_path) -> Path:
    root = tmp_path / "plates"
    root.mkdir()
    ami_xr.to_netcdf(_frf(1), root / "a.nc")
    ami_xr.to_netcdf(_frf(2), root / "b.nc")
    return root


def test_batch_reports_a_capped_file_as_capped_not_ok(folder, tmp_path):
    # max_modes=1 on five-mode systems without the refinement (which would complete the model
    # and supersede the cap): the subtraction stops at the cap on every file
    summary = batch(
        folder, tmp_path / "out", identify_options={"max_modes": 1, "refine": False}, progress=False
    )
    assert {r["status"] for r in summary.rows} == {STATUS_CAPPED}
    assert not summary.ok and summary.n_capped == 2 and summary.n_failed == 0
    assert all("subtract:max_modes" in r["message"] for r in summary.rows)
    assert "2 capped (incomplete)" in summary.format()
    with open(tmp_path / "out" / SUMMARY_NAME, newline="") as fh:
        assert {row["status"] for row in csv.DictReader(fh)} == {STATUS_CAPPED}
    # a re-run finds the outputs up to date, and they stay capped
    again = batch(
        folder, tmp_path / "out", identify_options={"max_modes": 1, "refine": False}, progress=False
    )
    assert {r["status"] for r in again.rows} == {STATUS_CAPPED}
    assert all("up to date" in r["message"] for r in again.rows)


def test_cli_batch_exit_code_and_identify_last_line(folder, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(
        ["batch", str(folder), "-o", str(out), "-q", "--max-modes", "1", "--no-refine"]
    ) == (EXIT_BATCH_CAPPED)
    assert "2 capped" in capsys.readouterr().out
    assert main(["batch", str(folder), "-o", str(tmp_path / "o2"), "-q"]) == EXIT_OK
    text = capsys.readouterr().out
    assert "0 capped" in text
    assert EXIT_BATCH_CAPPED not in (EXIT_OK, EXIT_BATCH_FAILURES)
    # identify: the last line says the result is incomplete
    assert (
        main(["identify", str(folder / "a.nc"), "-q", "--max-modes", "1", "--no-refine"]) == EXIT_OK
    )
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("incomplete:") and "subtract:max_modes" in last
    main(["identify", str(folder / "a.nc"), "-q"])
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert not last.startswith("incomplete")


def test_ok_file_has_status_ok(folder, tmp_path):
    summary = batch(folder, tmp_path / "out", progress=False)
    assert {r["status"] for r in summary.rows} == {STATUS_OK}, summary.format()
    assert summary.ok
    assert names.ATTR_AMI_CAPPED  # the attribute name the status is read from
