"""``ami-xr identify`` on a file holding FRFs and modes (issue 40 item 1): the FRFs are
identified and the file's modes carried as a reference set (frequency, damping, MAC)."""

from __future__ import annotations

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.app.cli import EXIT_ERROR, EXIT_OK, main
from ami_xr.io.reference_modes import (
    REFERENCE_MODE,
    compare_modes,
    format_reference_table,
    split_frf_and_modes,
)

from ..reference import damped_chain

POINTS = ["1+Z", "2+Z", "3+Z", "4+Z", "5+Z"]


@pytest.fixture(scope="module")
def truth_and_frf():
    truth = ami_xr.simulate.residues(damped_chain(POINTS), "2+Z")
    f = np.linspace(0.5, 70.0, 700)
    g = ami_xr.simulate.frf(truth, f)
    h = g[names.FRF].values
    rng = np.random.default_rng(4)
    noise = rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape)
    g[names.FRF].values = h + 0.003 * np.abs(h).max(axis=1, keepdims=True) * noise
    return truth, g


def test_split_and_compare(truth_and_frf):
    truth, g = truth_and_frf
    both = g.assign_coords({names.MODE: truth[names.MODE].values}).assign(
        {v: truth[v] for v in (names.EIGENVALUE, names.MODE_VECTOR)}
    )
    frf, modes = split_frf_and_modes(both, "/somewhere/test.uff")
    assert names.MODE not in frf.dims and names.EIGENVALUE not in frf
    assert modes.attrs["reference_modes_source"] == "test.uff"  # no folder
    result = ami_xr.identify(frf)
    out = compare_modes(result, modes)
    assert out["reference_mac"].dims == (names.MODE, REFERENCE_MODE)
    np.testing.assert_array_equal(out["reference_match"].values, truth[names.MODE].values)
    np.testing.assert_allclose(
        out["reference_natural_frequency"].values, truth[names.NATURAL_FREQUENCY].values
    )
    assert np.all(np.diag(out["reference_mac"].values) > 0.99)
    table = format_reference_table(out)
    assert "reference modes from test.uff" in table and table.count("\n") == 1 + 5
    # an identification result read back is split too: identify it again, compare
    frf2, modes2 = split_frf_and_modes(out)
    results = ("ami_", "refine_", "analysis_band_")
    assert not any(k.startswith(results) and not k.startswith("ami_xr_") for k in frf2.attrs)
    assert names.FRF_SYNTHESIZED not in frf2 and "reference_mac" not in frf2
    np.testing.assert_array_equal(modes2[names.EIGENVALUE].values, out[names.EIGENVALUE].values)


def test_identify_a_uff_with_frfs_and_modes(truth_and_frf, tmp_path, capsys):
    truth, g = truth_and_frf
    both = g.assign_coords({names.MODE: truth[names.MODE].values}).assign(
        {v: truth[v] for v in (names.EIGENVALUE, names.MODE_VECTOR)}
    )
    uff = ami_xr.write_uff(both, tmp_path / "test.uff")
    out = tmp_path / "out.nc"
    assert main(["identify", str(uff), "-o", str(out), "-q"]) == EXIT_OK
    said = capsys.readouterr().out
    assert "FRFs and 5 modes" in said and "reference modes from test.uff" in said
    r = ami_xr.open_dataset(out)
    # dataset 55 holds 6 significant digits
    np.testing.assert_allclose(
        r["reference_natural_frequency"].values, truth[names.NATURAL_FREQUENCY].values, rtol=1e-5
    )
    np.testing.assert_allclose(
        r[names.NATURAL_FREQUENCY].values, truth[names.NATURAL_FREQUENCY].values, rtol=3e-3
    )  # identified from FRFs with 0.3 % noise: measured at most 1.1e-3
    assert np.all(np.diag(r["reference_mac"].values) > 0.99)


def test_identify_an_identification_result_again(truth_and_frf, tmp_path, capsys):
    _, g = truth_and_frf
    first = tmp_path / "modes.nc"
    ami_xr.to_netcdf(g, tmp_path / "frf.nc")
    assert main(["identify", str(tmp_path / "frf.nc"), "-o", str(first), "-q"]) == EXIT_OK
    capsys.readouterr()
    assert main(["identify", str(first), "-o", str(tmp_path / "again.nc"), "-q"]) == EXIT_OK
    r = ami_xr.open_dataset(tmp_path / "again.nc")
    np.testing.assert_allclose(
        r[names.NATURAL_FREQUENCY].values, r["reference_natural_frequency"].values, rtol=1e-9
    )


def test_a_modes_only_file_is_still_refused(truth_and_frf, tmp_path, capsys):
    truth, _ = truth_and_frf
    path = ami_xr.to_netcdf(truth, tmp_path / "truth.nc")
    assert main(["identify", str(path)]) == EXIT_ERROR
    assert "a modes file" in capsys.readouterr().err
