"""How much one ``identify`` builds (issue 39, Done when): the FRF Dataset validated once, and
at most 3 Datasets built. Counted with hooks on the data model's one validator
(:func:`ami_xr.io.schema.find_problems` as the phases call it) and on ``xarray.Dataset``'s two
constructors (``__init__`` and ``_construct_direct``, which every xarray operation that returns
a new Dataset goes through; ``xarray.Dataset(...)`` counts two, one for its ``Coordinates``)
while one ``identify`` runs; a Dataset is charged to the innermost ami_xr function on the stack
(the caller of the phases' one builder, :func:`ami_xr.ami.common.built`), and the places are
those functions."""

from __future__ import annotations

import traceback
import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami import common
from ami_xr.simulate.spread import many_points


@pytest.fixture(scope="module")
def small():
    ds, _ = ami_xr.simulate.random_system(seed=2, n_points=5, n_frequencies=1024, noise=0.01)
    return ds


_PACKAGE = str(Path(ami_xr.__file__).parent)


def _builder() -> str:
    """The innermost ami_xr function on the stack (file:function)."""
    for frame in reversed(traceback.extract_stack()[:-2]):
        if frame.filename.startswith(_PACKAGE) and frame.name != "built":
            return f"{Path(frame.filename).name}:{frame.name}"
    return "?"


def _counted(monkeypatch, ds, **options) -> dict:
    """Run ``identify(ds, **options)`` once and count FRF validations and Datasets built (all,
    and the places that build them)."""
    counts: dict = {"validations": 0, "datasets": 0, "places": set()}
    validate = common.find_problems

    def counting_validate(data, kind, *args, **kwargs):
        if kind == "frf":
            counts["validations"] += 1
        return validate(data, kind, *args, **kwargs)

    init = xr.Dataset.__init__
    direct = xr.Dataset._construct_direct.__func__

    def counted(place: str) -> None:
        counts["datasets"] += 1
        counts["places"].add(place)

    def counting_init(self, *args, **kwargs):
        counted(_builder())
        init(self, *args, **kwargs)

    def counting_direct(cls, *args, **kwargs):
        counted(_builder())
        return direct(cls, *args, **kwargs)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ami_xr.identify(ds, **options)  # warm: lazy imports and caches are not counted
        monkeypatch.setattr(common, "find_problems", counting_validate)
        monkeypatch.setattr(xr.Dataset, "__init__", counting_init)
        monkeypatch.setattr(xr.Dataset, "_construct_direct", classmethod(counting_direct))
        try:
            ami_xr.identify(ds, **options)
        finally:
            monkeypatch.undo()
    return counts


def test_the_hooks_count(monkeypatch, small):
    """The hooks see the work they count: a phase called on its own validates its input."""
    counts = {"validations": 0}
    validate = common.find_problems

    def counting_validate(data, kind, *args, **kwargs):
        counts["validations"] += kind == "frf"
        return validate(data, kind, *args, **kwargs)

    monkeypatch.setattr(common, "find_problems", counting_validate)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ami_xr.subtract(small)
    assert counts["validations"] == 1


def test_one_validation_per_identify(monkeypatch, small):
    counts = _counted(monkeypatch, small)
    assert counts["validations"] == 1, counts


def test_one_validation_per_identify_on_the_compressed_path(monkeypatch):
    ds, _ = many_points(60, 256, 5, noise=0.01, seed=1)
    counts = _counted(monkeypatch, ds, compress=12)
    assert counts["validations"] == 1, counts


def test_datasets_per_identify_on_the_compressed_path(monkeypatch):
    """60 points compressed to 12 virtual FRFs (48 Datasets before): the virtual FRFs, their
    phases' two outputs (fit phases, refinement), every point's residues at their poles, the
    band's attributes on the working FRFs and the one output step."""
    ds, _ = many_points(60, 256, 5, noise=0.01, seed=1)
    counts = _counted(monkeypatch, ds, compress=12)
    assert counts["datasets"] <= 6, counts


def test_at_most_three_datasets_on_windowed_data(monkeypatch, small):
    """The exponential window's correction is made on the arrays in the output step."""
    windowed = small.assign_attrs({names.ATTR_EXP_DECAY: 0.2})
    counts = _counted(monkeypatch, windowed)
    assert counts["datasets"] <= 3, counts


def test_the_dataset_hook_counts(monkeypatch, small):
    """The constructor hooks see what they count: an assign builds one Dataset in its caller."""
    counts = _counted(monkeypatch, small)
    assert counts["datasets"] >= len(counts["places"]) > 0
    assert "pipeline.py:identify_single" in counts["places"] or any(
        p.startswith("pipeline.py") for p in counts["places"]
    )


def test_datasets_built_in_at_most_three_places(monkeypatch, small):
    counts = _counted(monkeypatch, small)
    assert len(counts["places"]) <= 3, (len(counts["places"]), counts["datasets"])


@pytest.mark.parametrize("options", [{}, {"refine": False}, {"method": "paper"}])
def test_at_most_three_datasets_per_identify(monkeypatch, small, options):
    """Each output built once, from the phases' Variables (5 points x 1024 lines: 3 Datasets;
    22 before, from assign chains): no assign, copy or isel of a Dataset between them."""
    counts = _counted(monkeypatch, small, **options)
    assert counts["datasets"] <= 3, counts


def test_datasets_built_in_the_three_places_of_today(monkeypatch, small):
    """Where identify builds its Datasets (5 points x 1024 lines: 3 Datasets in 3 places; 130
    in 23 places before issue 39): the fit phases' labeled output (``pipeline._labeled``), the
    refinement's (``refine._with_results``) and the one output step (``pipeline.reported``).
    The band is no copy of the input (its record goes into the output's attributes); the
    sort, the resolution check, the quality indicators, the noise model and the provenance
    record build no Dataset of their own, nor does the refinement beyond its one output."""
    counts = _counted(monkeypatch, small)
    assert counts["places"] <= {
        "pipeline.py:_labeled",
        "refine.py:_with_results",
        "pipeline.py:reported",
    }, counts["places"]


def test_identify_leaves_its_input_as_it_was(small):
    """No copy for the band: the caller's Dataset keeps its attributes (no band, no noise
    model written into them) and a second identify of it gives the same result."""
    before = dict(small.attrs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        first = ami_xr.identify(small)
        assert small.attrs == before
        second = ami_xr.identify(small)
    assert small.attrs == before
    assert "analysis_band_fmin" in first.attrs
    np.testing.assert_array_equal(first["eigenvalue"].values, second["eigenvalue"].values)


def test_the_fit_phases_pass_arrays_inside_identify(monkeypatch, small):
    """subtract -> isolate -> global fit hand each other arrays inside ``identify``: no Dataset
    is built in their modules or in the derived outputs' (``derive.py``); the outputs of all
    three are labeled in one place, at their end (``pipeline._labeled``)."""
    counts = _counted(monkeypatch, small)
    phases = ("subtract.py", "isolate.py", "global_fit.py", "derive.py")
    assert not {p for p in counts["places"] if p.split(":")[0] in phases}, counts["places"]
    assert "pipeline.py:_labeled" in counts["places"]


@pytest.mark.parametrize("method", ["simo", "per_frf"])
def test_the_public_phases_are_the_same_calls(small, method):
    """The public phases, chained on their own, give identify's phase outputs exactly (they
    are checked labeled wrappers over the calls identify makes on its arrays)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = ami_xr.identify(small, method=method, refine=False)
        chain = ami_xr.global_fit(ami_xr.isolate(ami_xr.subtract(small), method=method))
    assert out.sizes["mode"] == chain.sizes["mode"] > 0
    order = out["mode_label_unsorted"].values - 1  # identify reports the modes by frequency
    for name in common.SUBTRACT_VARS + common.ISOLATE_VARS + common.GLOBAL_VARS:
        if name not in chain:
            continue
        mine = chain[name]
        if "mode" in mine.dims:
            mine = mine.isel(mode=order)
        if "mode_2" in mine.dims:
            mine = mine.isel(mode_2=order)
        assert mine.dims == out[name].dims, name
        if name == "quality_flags":  # identify adds its own (under_resolved, ...)
            assert not np.any(mine.values & ~out[name].values), name
            continue
        np.testing.assert_array_equal(mine.values, out[name].values, err_msg=name)
