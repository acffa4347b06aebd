"""Every file ami-xr writes passes the IOOS compliance checker, CF-1.11, criteria normal (issue 23).

Skipped when the checker (``pip install "ami_xr[cf]"``) is not installed. The hammer workflow of
the README needs ``../shared/data/impact_hammer.lvm`` and skips without it; the other tests use
the simulator and the test fixtures, so they always run where the checker is installed.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.io.cf import compliance_report
from ami_xr.io.netcdf import open_dataset, to_netcdf

pytest.importorskip("compliance_checker")

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
HAMMER_LVM = DATA / "impact_hammer.lvm"


def assert_cf_compliant(path: Path) -> None:
    """The checker's ``cf:1.11`` at ``--criteria=normal``: no issue and no checker exception."""
    passed, text = compliance_report(path)
    assert passed, f"{path.name}:\n{text}"


@pytest.fixture(scope="module")
def modes(frf_dataset_module):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ami_xr.identify(frf_dataset_module)


@pytest.fixture(scope="module")
def frf_dataset_module():
    from ..conftest import _frf_fixture_modes
    from ..reference import frf_from_residues

    lam, residue = _frf_fixture_modes()
    frequency = np.linspace(0.5, 50.0, 200)
    frf = frf_from_residues(2 * np.pi * frequency, lam, residue)
    rng = np.random.default_rng(0)
    frf = frf + 1e-4 * np.abs(frf).max() * (rng.standard_normal(frf.shape) + 0j)
    return ami_xr.make_frf_dataset(frf, frequency, points=["a", "b", "c"], drive_point="a")


def test_frf_and_modes_files_pass(tmp_path, frf_dataset_module, modes):
    assert_cf_compliant(to_netcdf(frf_dataset_module, tmp_path / "frf.nc"))
    path = to_netcdf(modes, tmp_path / "modes.nc", function="ami_xr.identify")
    assert_cf_compliant(path)
    # a written file read back and written again stays compliant (nothing piles up)
    assert_cf_compliant(to_netcdf(open_dataset(path), tmp_path / "again.nc"))


def test_simulator_outputs_pass(tmp_path):
    """What ``ami-xr simulate`` writes: FRFs and the exact modes."""
    _, g, truth = ami_xr.simulate.benchmark(noise=0.0, n_samples=256)
    for name, ds in {"g": g, "truth": truth}.items():
        assert_cf_compliant(to_netcdf(ds, tmp_path / f"{name}.nc"))


def test_time_history_files_pass(tmp_path):
    """What ``ami-xr simulate --time-output`` and ``ami-xr convert x.lvm -o t.nc`` write: the
    time axis has no date, so it is ``elapsed_time`` on disk (no invented epoch)."""
    from ami_xr.app.cli import main

    from .test_lvm import _write
    from .test_lvm_assumptions import hit_rows

    g, ts = tmp_path / "g.nc", tmp_path / "ts.nc"
    assert (
        main(
            [
                "simulate",
                "beam-absorbers",
                "-o",
                str(g),
                "--time-output",
                str(ts),
                "--samples",
                "256",
            ]
        )
        == 0
    )
    assert_cf_compliant(ts)
    lvm = _write(tmp_path / "hits.lvm", [hit_rows(p) for p in (100.0, 110.0)])
    converted = tmp_path / "t.nc"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the drive point the reader assumes
        assert main(["convert", str(lvm), "-o", str(converted)]) == 0
    assert_cf_compliant(converted)
    assert names.TIME in open_dataset(converted).dims


def test_uff_converted_back_passes(tmp_path, modes):
    pytest.importorskip("pyuff")
    from ami_xr.io.uff import read_uff, write_uff

    write_uff(modes, tmp_path / "m.uff")
    assert_cf_compliant(to_netcdf(read_uff(tmp_path / "m.uff"), tmp_path / "back.nc"))


def test_batch_output_passes(tmp_path, frf_dataset_module):
    inp, out = tmp_path / "in", tmp_path / "out"
    inp.mkdir()
    to_netcdf(frf_dataset_module, inp / "a.nc")
    summary = ami_xr.batch(inp, out, progress=False)
    assert summary.ok, summary.rows
    assert_cf_compliant(out / "a.modes.nc")


@pytest.mark.slow
@pytest.mark.skipif(not HAMMER_LVM.is_file(), reason="../shared/data/impact_hammer.lvm absent")
def test_readme_hammer_workflow_files_pass(tmp_path):
    """The README's hammer test: frf, identify, convert to UFF and back."""
    from ami_xr.app.cli import main

    h, m = tmp_path / "h.nc", tmp_path / "m.nc"
    assert main(["frf", str(HAMMER_LVM), "-o", str(h)]) == 0
    assert main(["identify", str(h), "-o", str(m)]) == 0
    for path in (h, m):
        assert_cf_compliant(path)
    pytest.importorskip("pyuff")
    uff, back = tmp_path / "m.uff", tmp_path / "back.nc"
    assert main(["convert", str(m), "-o", str(uff)]) == 0
    assert main(["convert", str(uff), "-o", str(back)]) == 0
    assert_cf_compliant(back)
    assert names.EIGENVALUE in open_dataset(back)


def test_the_check_fails_on_a_unit_udunits_cannot_read(tmp_path):
    import xarray as xr

    ds = xr.Dataset(
        {"v": (("x", "y"), [[1.0, 2.0]], {"units": "furlong per hit"})},
        coords={"x": [1], "y": [1, 2]},
    )
    with pytest.raises(AssertionError, match="not recognized by UDUNITS"):
        assert_cf_compliant(to_netcdf(ds, tmp_path / "bad.nc"))
