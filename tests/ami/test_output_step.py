"""The one output step of identify (:func:`ami_xr.ami.pipeline.reported`) and the array helpers
it calls give what the Dataset steps they replace give (issue 39): sorting, the resolution
check and the quality indicators; the noise model handed over as variables; the provenance
record written into a Dataset's own attributes."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names, provenance
from ami_xr.ami import common as c
from ami_xr.ami import pipeline, whitening
from ami_xr.ami.resolution import resolution_checked


@pytest.fixture(scope="module")
def unsorted():
    """An identify result before its output step (refined, not yet sorted), and its input."""
    ds, _ = ami_xr.simulate.random_system(seed=5, n_points=5, n_frequencies=512, noise=0.02)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = ami_xr.identify(ds)
    # shuffle the modes back out of order: the output step must sort them again
    perm = np.roll(np.arange(out.sizes[names.MODE]), 1)
    drop = [names.MODE_LABEL_UNSORTED, names.MPC, names.MPD, names.COMPLEXITY]
    drop.append(names.MODE_VECTOR_NORMALISED)
    shuffled = out.drop_vars(drop).isel({names.MODE: perm, names.MODE_2: perm})
    return shuffled, ds


def test_reported_equals_the_dataset_steps(unsorted):
    result, whole = unsorted
    assert result.sizes[names.MODE] >= 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        steps = pipeline.finish_modes(result.copy(), whole, refined=True)
        steps = pipeline.with_quality(resolution_checked(steps, whole))
        once = pipeline.reported(result.copy(), whole, refined=True)
    xr.testing.assert_identical(once, steps)
    assert np.all(np.diff(once[names.NATURAL_FREQUENCY].values) >= 0)
    assert once[names.MODE].values.tolist() == list(range(1, once.sizes[names.MODE] + 1))


def test_reported_hands_the_noise_model_in(unsorted):
    """The variables given replace the working frf_line_noise_std in the one build."""
    result, whole = unsorted
    work = result.assign(
        {names.FRF_LINE_NOISE_STD: (result[names.FRF].dims, np.ones(result[names.FRF].shape))}
    )
    extra = {"noise_model_level": xr.Variable((names.POINT,), np.arange(whole.sizes["point"]))}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        once = pipeline.reported(work, whole, refined=True, noise_model=extra)
    assert names.FRF_LINE_NOISE_STD not in once
    np.testing.assert_array_equal(once["noise_model_level"].values, extra["noise_model_level"])


def test_noise_model_back_equals_from_working():
    """For a fit in the quantity given, from_working is the drop plus noise_model_back."""
    ds, _ = ami_xr.simulate.random_system(seed=1, n_points=5, n_frequencies=256, noise=0.02)
    sd = np.full(ds[names.FRF].shape, 0.01)
    given = ds.assign({names.FRF_LINE_NOISE_STD: (ds[names.FRF].dims, sd)})
    white = whitening.decide(given)
    if white.k:
        pytest.skip("this record is fitted in another quantity")
    result = whitening.to_working(given, white)
    back = whitening.from_working(result, given, white)
    new = whitening.noise_model_back(result, given, white)
    assert names.FRF_LINE_NOISE_STD in new
    for name, var in new.items():
        np.testing.assert_array_equal(xr.as_variable(var, name=name).values, back[name].values)
    assert set(back.data_vars) == set(result.data_vars) | set(new)


def test_record_history_writes_into_the_attrs_given():
    ds = xr.Dataset({"x": ("t", np.arange(3))}, attrs={"a": 1})
    copied = provenance.add_history(ds, "ami_xr.something", {"n": 2})
    assert names.ATTR_HISTORY not in ds.attrs  # add_history leaves its input alone
    attrs = dict(ds.attrs)
    provenance.record_history(attrs, "ami_xr.something", {"n": 2})
    records = provenance._records(attrs[names.ATTR_HISTORY])
    assert [r["function"] for r in records] == ["ami_xr.something"]
    assert records[0]["parameters"] == {"n": 2}
    assert attrs[provenance.ATTR_FUNCTION] == copied.attrs[provenance.ATTR_FUNCTION]
    with provenance.nested_calls():  # inside a call that records itself: nothing
        inner = {}
        provenance.record_history(inner, "ami_xr.other")
        assert inner == {}


def test_finish_records_into_the_phase_output():
    out = xr.Dataset(attrs={"k": "v"})
    same = c.finish(out, "ami_xr.subtract", "subtract", {"delta": 1.0})
    assert same is out and out.attrs[names.ATTR_AMI_PHASE] == "subtract"
    assert [r["function"] for r in provenance.history(out)] == ["ami_xr.subtract"]


def test_keep_modes_equals_the_xarray_steps(unsorted):
    """The modes kept, relabelled 1..n, in one build: what ``isel`` and ``assign_coords`` give
    (on ``mode`` and ``mode_2``)."""
    result, _ = unsorted
    keep = np.ones(result.sizes[names.MODE], bool)
    keep[1] = False
    index = np.flatnonzero(keep)
    labels = np.arange(1, index.size + 1)
    steps = result.isel({names.MODE: index, names.MODE_2: index})
    steps = steps.assign_coords({names.MODE: labels, names.MODE_2: labels})
    xr.testing.assert_identical(c.keep_modes(result, keep), steps)


def test_built_without_the_private_constructor_is_the_same(monkeypatch):
    """``common.built`` uses xarray's private ``Dataset._construct_direct``; should a later
    xarray drop or change it, the public constructor gives the identical Dataset."""
    import numpy as np
    import xarray as xr

    from ami_xr.ami import common

    f = xr.Variable(("frequency",), np.linspace(1.0, 2.0, 5), {"units": "Hz"})
    variables = {
        "frequency": f,
        "point": xr.Variable(("point",), np.array(["a", "b"])),
        "frf": xr.Variable(("point", "frequency"), np.ones((2, 5), complex), {"units": "m/N"}),
        "label": (("point",), np.array([1, 2])),
    }
    attrs = {"drive_point": "a"}
    direct = common.built(variables, ["label"], attrs)

    def changed(*args):
        raise TypeError("a changed signature")

    for gone in (None, changed):
        monkeypatch.setattr(common, "_direct_constructor", lambda gone=gone: gone)
        xr.testing.assert_identical(common.built(variables, ["label"], attrs), direct)
        assert set(direct.coords) == {"frequency", "point", "label"}
