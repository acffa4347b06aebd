"""Issue 24 item 2: quantity, units and FRF-type defaults never mislabel data silently."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.dsp.quantity import ATTR_QUANTITY_ASSUMED, FRF_TYPE_SYNONYMS, frf_type_of
from ami_xr.errors import AmiXrValueError, AssumptionWarning

F = np.linspace(1.0, 100.0, 20)
H = np.ones((2, F.size), complex)


def test_no_quantity_warns_at_the_callers_line_and_records_the_assumption():
    with pytest.warns(AssumptionWarning, match="displacement") as caught:
        ds = ami_xr.make_frf_dataset(H, F)
    assert caught[0].filename == __file__  # the user's line, not ami_xr's source
    assert ds.attrs[names.ATTR_QUANTITY] == "displacement"
    assert ds.attrs[names.ATTR_FRF_TYPE] == "receptance"
    assert "response_quantity" in ds.attrs[ATTR_QUANTITY_ASSUMED]
    with pytest.warns(AssumptionWarning, match="make_time_dataset"):
        ts = ami_xr.make_time_dataset(np.ones((1, 64)), fs=64.0, force=np.ones(64))
    assert ATTR_QUANTITY_ASSUMED in ts.attrs


@pytest.mark.parametrize(
    ("kwargs", "quantity", "units"),
    [
        ({"response_quantity": "velocity"}, "velocity", "m/s"),
        ({"response_quantity": "acceleration"}, "acceleration", "m/s^2"),
        ({"response_quantity": "acceleration", "response_units": "g"}, "acceleration", "g"),
        ({"response_units": "mm/s"}, "velocity", "mm/s"),
        ({"response_quantity": "displacement"}, "displacement", "m"),
    ],
)
def test_units_default_from_the_quantity_without_a_warning(kwargs, quantity, units):
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)
        ds = ami_xr.make_frf_dataset(H, F, **kwargs)
    assert ds.attrs[names.ATTR_QUANTITY] == quantity
    assert ds.attrs[names.ATTR_RESPONSE_UNITS] == units
    assert ds.frf.attrs["units"] == f"{units}/N"
    assert ATTR_QUANTITY_ASSUMED not in ds.attrs


@pytest.mark.parametrize(
    ("frf_type", "canonical", "quantity"),
    [
        ("mobility", "mobility", "velocity"),
        ("Admittance", "mobility", "velocity"),
        ("accelerance", "accelerance", "acceleration"),
        ("inertance", "accelerance", "acceleration"),
        ("receptance", "receptance", "displacement"),
        ("compliance", "receptance", "displacement"),
        ("dynamic flexibility", "receptance", "displacement"),
        ("dynamic_flexibility", "receptance", "displacement"),
    ],
)
def test_frf_type_synonyms(frf_type, canonical, quantity):
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)
        ds = ami_xr.make_frf_dataset(H, F, frf_type=frf_type)
    assert ds.attrs[names.ATTR_FRF_TYPE] == canonical
    assert ds.attrs[names.ATTR_QUANTITY] == quantity
    assert ds.attrs[names.ATTR_RESPONSE_UNITS] == names.SI_RESPONSE_UNITS[quantity]
    # consistent with the quantity when both are given
    ds2 = ami_xr.make_frf_dataset(H, F, frf_type=frf_type, response_quantity=quantity)
    assert ds2.attrs[names.ATTR_FRF_TYPE] == canonical
    assert frf_type_of(frf_type) == canonical
    assert set(FRF_TYPE_SYNONYMS.values()) == set(names.FRF_TYPE_TO_QUANTITY)


def test_inconsistent_or_unknown_frf_type_is_an_error_naming_the_argument():
    with pytest.raises(AmiXrValueError, match="frf_type, response_quantity: a 'mobility'"):
        ami_xr.make_frf_dataset(H, F, frf_type="mobility", response_quantity="displacement")
    with pytest.raises(AmiXrValueError, match="frf_type: expected one of"):
        ami_xr.make_frf_dataset(H, F, frf_type="transmissibility")
    with pytest.raises(AmiXrValueError, match="argument .response_quantity.: expected one of"):
        ami_xr.make_frf_dataset(H, F, response_quantity="speed")
