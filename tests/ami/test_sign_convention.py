"""Issue 24 item 6: FRFs in the other sign convention (the complex conjugate) are named as such,
not answered with "no modes identified" and a hint to raise zeta_max."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.app.cli import EXIT_ERROR, EXIT_OK, main
from ami_xr.errors import IdentificationError, NoModesWarning


def _conjugated(ds):
    return ds.assign({names.FRF: ds[names.FRF].conj()})


def test_identify_names_the_conjugate_convention(frf_dataset):
    with warnings.catch_warnings():
        warnings.simplefilter("error", NoModesWarning)  # no "raise zeta_max" hint first
        with pytest.raises(IdentificationError, match=r"complex conjugate of the e\^\{\+iwt\}"):
            ami_xr.identify(_conjugated(frf_dataset))


def test_subtract_names_it_too(frf_dataset):
    with pytest.raises(IdentificationError, match=r"ds.assign\(frf=ds.frf.conj\(\)\)"):
        ami_xr.subtract(_conjugated(frf_dataset), 0.5)


def test_noise_is_not_called_conjugate(frf_dataset):
    rng = np.random.default_rng(0)
    shape = frf_dataset[names.FRF].shape
    for _ in range(5):  # whatever subtract makes of pure noise, it is not the other convention
        noise = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NoModesWarning)
            ami_xr.subtract(
                frf_dataset.assign({names.FRF: frf_dataset[names.FRF].copy(data=noise)})
            )


def test_cli_says_so_and_conjugate_fixes_it(frf_dataset, tmp_path, capsys):
    path = tmp_path / "exported.nc"
    ami_xr.to_netcdf(_conjugated(frf_dataset), path)
    assert main(["identify", str(path), "-q"]) == EXIT_ERROR
    err = capsys.readouterr().err
    assert "complex conjugate" in err and "--conjugate" in err and "zeta_max" not in err
    assert main(["identify", str(path), "-q", "--conjugate"]) == EXIT_OK
    out = capsys.readouterr().out
    table = [line.split() for line in out.splitlines() if line[:1].isdigit()]
    assert [round(float(row[1])) for row in table] == [12, 31]
