"""The phases never change the Dataset they are given, also one made by ``isel`` (which shares
its attributes with its source): an analysis band written into a sub-selection's attributes
leaked into the whole Dataset, and a later ``identify`` of it kept that band."""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names


def _snapshot(ds):
    return copy.deepcopy(dict(ds.attrs)), {
        k: copy.deepcopy(dict(ds[k].attrs)) for k in ds.variables
    }


@pytest.fixture(scope="module")
def frf():
    g, _ = ami_xr.simulate.random_system(n_points=5, seed=2, noise=0.01, n_frequencies=800)
    return g


@pytest.mark.parametrize("phase", ["identify", "subtract"])
def test_a_sub_selection_leaves_its_source_and_itself_unchanged(frf, phase):
    whole = frf.copy()
    before_whole = _snapshot(whole)
    part = whole.isel({names.FREQUENCY: slice(10, 500)})
    before_part = _snapshot(part)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # a band narrower than the data: the phase works on a sub-selection of its own
        getattr(ami_xr, phase)(part, fmax=0.8 * float(part[names.FREQUENCY][-1]))
    assert _snapshot(part) == before_part
    assert _snapshot(whole) == before_whole


def test_identify_of_the_whole_after_a_part_is_the_same_as_alone(frf):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        alone = ami_xr.identify(frf, refine=False)
        part = frf.isel({names.FREQUENCY: slice(10, 300)})
        ami_xr.identify(part, refine=False, fmax=0.8 * float(part[names.FREQUENCY][-1]))
        again = ami_xr.identify(frf, refine=False)
    assert again.attrs[names.ATTR_BAND_FMAX] == alone.attrs[names.ATTR_BAND_FMAX]
    np.testing.assert_allclose(
        again[names.NATURAL_FREQUENCY].values, alone[names.NATURAL_FREQUENCY].values
    )
