"""Issue 24 item 9: the CLI's excitation line reads as a sentence, and the Subtraction Phase's
warnings point at the caller's line, not at ami_xr's own source."""

from __future__ import annotations

import warnings

import numpy as np

import ami_xr
from ami_xr import names
from ami_xr.app.cli import EXIT_OK, main
from ami_xr.errors import NoModesWarning


def _random_test(n=8192, fs=1000.0):
    rng = np.random.default_rng(1)
    force = rng.standard_normal(n)
    t = np.arange(200) / fs
    h = np.exp(-20 * t) * np.sin(2 * np.pi * 50 * t)
    return ami_xr.make_time_dataset(
        np.convolve(force, h)[:n], fs=fs, force=force, response_quantity="displacement"
    )


def test_frf_says_why_the_excitation_is_random(tmp_path, capsys):
    path = tmp_path / "t.nc"
    ami_xr.to_netcdf(_random_test(), path)
    assert main(["frf", str(path), "-o", str(tmp_path / "g.nc")]) == EXIT_OK
    out = capsys.readouterr().out
    (line,) = [s for s in out.splitlines() if s.startswith("excitation:")]
    assert "it is not" not in line
    assert "the force is" in line and "--excitation sets it" in line


def _noise(ds):
    rng = np.random.default_rng(0)
    shape = ds[names.FRF].shape
    return ds.assign({names.FRF: ds[names.FRF].copy(data=rng.standard_normal(shape) + 0j)})


def test_subtract_and_identify_warnings_point_at_this_file(frf_dataset):
    for function in (ami_xr.subtract, ami_xr.identify):
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            function(_noise(frf_dataset))
        ours = [w for w in said if issubclass(w.category, NoModesWarning)]
        assert ours, function
        assert all(w.filename == __file__ for w in ours), [w.filename for w in ours]
