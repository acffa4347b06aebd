"""Issue 34: messages that name what they mean — the noise-floor check after one spike, a
corrupt ``ami_xr_encoded_attrs`` attribute, a corrupt settings attribute."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami.settings import FrfAttributes, GlobalFitSettings, SubtractSettings, from_attrs
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io import netcdf
from ami_xr.kernels import isolate as ki


# --- item 2: the noise-floor message -----------------------------------------------------------
def _params():
    return ki.IsolateParams(
        delta=0.5,
        tol=1e-4,
        max_iter=10,
        pfa=1e-3,
        min_points=3,
        zeta_max=0.25,
        merge_tol=0.5,
        max_modes=4,
        reweight=True,
        se_fraction=ki.STOP_FRACTION,
        paper_sweeps=False,
    )


def _frfs(n_p=4, n_f=64):
    omega = np.linspace(1.0, 10.0, n_f)
    rng = np.random.default_rng(0)
    data = 1.0 / (1j * omega[None, :] + 0.1 - 5j) + 1e-3 * rng.standard_normal((n_p, n_f))
    return data.astype(complex), omega


@pytest.mark.parametrize(
    ("bad", "said"),
    [(0.0, "0"), (np.nan, "nan"), (np.inf, "inf"), (-1.0, "-1")],
)
def test_noise_floor_message_names_the_rows_and_the_value(bad, said):
    data, omega = _frfs()
    sigma = np.array([1e-3, bad, bad, 1e-3])
    for call in (
        lambda: ki.isolate_simo(
            data, omega, None, None, np.array([-0.1 + 5j]), 1, sigma, _params()
        ),
        lambda: ki.isolate_batch(
            data,
            omega,
            None,
            None,
            np.full((4, 1), -0.1 + 5j),
            np.ones((4, 1), complex),
            np.ones(4, int),
            sigma,
            _params(),
        ),
    ):
        with pytest.raises(AmiXrValueError, match=r"^sigma: ") as info:
            call()
        text = str(info.value)
        assert "got shape" not in text  # the old message: "expected (4,), got shape (4,)"
        assert "rows 1, 2" in text and said in text, text
        assert "noise floor" in text


def test_noise_floor_of_wrong_shape_says_shape():
    data, omega = _frfs()
    with pytest.raises(AmiXrValueError, match=r"sigma: expected one noise floor per FRF.*\(3,\)"):
        ki.isolate_simo(data, omega, None, None, np.array([-0.1 + 5j]), 1, np.ones(3), _params())


def test_one_spike_gives_a_result_or_a_message_that_says_what_is_wrong():
    _, frf, _ = ami_xr.simulate.benchmark(noise=0.0)
    spiked = frf.copy(deep=True)
    spiked[names.FRF][0, 500] = 1e308  # one line far above everything else
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            result = ami_xr.identify(spiked)
        except AmiXrValueError as err:
            text = str(err)
            assert "got shape" not in text, text
            assert "noise floor" in text and ("0" in text) and "spike" in text, text
        else:
            assert names.MODE in result.dims


# --- item 3: a corrupt ami_xr_encoded_attrs attribute ------------------------------------------
@pytest.fixture(scope="module")
def raw_file(tmp_path_factory):
    """An ami_xr file (with tagged attributes) read back with plain xarray."""
    folder = tmp_path_factory.mktemp("attrs")
    ds = xr.Dataset(
        {"x": ("n", np.arange(3.0), {"flag": True, "z": 1 + 2j, "note": "plain"})},
        attrs={"ok": True, "note": "plain"},
    )
    path = ami_xr.to_netcdf(ds, folder / "a.nc")
    with xr.open_dataset(path) as raw:
        return raw.load()


CORRUPT = {
    "invalid JSON": ("{bad", r"not valid JSON"),
    "not an object": ("[1, 2]", r"expected a JSON object"),
    "ghost key": ('{"ghost": "json"}', r"names attribute 'ghost', which .* does not have"),
    "unknown tag": ('{"note": "nope"}', r"unknown encoding tag 'nope' for attribute 'note'"),
    "tag does not fit": ('{"note": "complex"}', r"'note'.*tagged 'complex'"),
}


@pytest.mark.parametrize("case", list(CORRUPT))
@pytest.mark.parametrize("owner", ["the Dataset", "variable 'x'"])
def test_corrupt_encoded_attrs_name_the_attribute(raw_file, tmp_path, case, owner):
    value, why = CORRUPT[case]
    raw = raw_file.copy(deep=True)
    attrs = raw.attrs if owner == "the Dataset" else raw["x"].attrs
    attrs[netcdf.ATTR_ENCODED_ATTRS] = value
    with pytest.raises(DataFileError) as info:
        netcdf.decode(raw)
    text = str(info.value)
    assert netcdf.ATTR_ENCODED_ATTRS in text and owner in text, text
    assert re.search(why, text), text
    assert "JSONDecodeError" not in text and "KeyError" not in text

    path = tmp_path / "c.nc"
    raw.to_netcdf(path)
    with pytest.raises(DataFileError) as info:
        ami_xr.open_dataset(path)
    text = str(info.value)
    assert str(path) in text and netcdf.ATTR_ENCODED_ATTRS in text and owner in text, text
    assert "JSONDecodeError" not in text and "KeyError" not in text


def test_the_cli_says_it_in_one_line(raw_file, tmp_path, capsys):
    from ami_xr.app.cli import EXIT_ERROR, main

    raw = raw_file.copy(deep=True)
    raw.attrs[netcdf.ATTR_ENCODED_ATTRS] = '{"ghost": "json"}'
    path = tmp_path / "c.nc"
    raw.to_netcdf(path)
    assert main(["convert", str(path), "-o", str(tmp_path / "c.uff")]) == EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and netcdf.ATTR_ENCODED_ATTRS in err[0] and "ghost" in err[0], err
    assert "a bug" not in err[0]


# --- settings read back from attributes ---------------------------------------------------------
@pytest.mark.parametrize(
    ("cls", "attr", "value", "expected"),
    [
        (SubtractSettings, names.ATTR_AMI_MAX_MODES, "ghost", "an integer"),
        (SubtractSettings, names.ATTR_AMI_PFA, "abc", "a number"),
        (FrfAttributes, names.ATTR_EXP_DECAY, "abc", "a number"),
        (GlobalFitSettings, names.ATTR_AMI_RESIDUAL_TERMS, "maybe", "0 or 1"),
    ],
)
def test_corrupt_settings_attribute_names_it(cls, attr, value, expected):
    with pytest.raises(AmiXrValueError, match=rf"attribute '{attr}': expected {expected}"):
        from_attrs(cls, {attr: value})


def test_settings_attributes_still_read_back():
    assert from_attrs(GlobalFitSettings, {names.ATTR_AMI_BAND: "all"}).band == "all"
    assert from_attrs(GlobalFitSettings, {names.ATTR_AMI_BAND: np.float64(2.0)}).band == 2.0
    assert from_attrs(GlobalFitSettings, {names.ATTR_AMI_RESIDUAL_TERMS: np.int8(1)}).residual_terms
    assert from_attrs(SubtractSettings, {names.ATTR_AMI_MAX_MODES: np.int64(7)}).max_modes == 7
