"""ami_xr.validate and the make_*_dataset constructors: every bad-input case, one at a time."""

from __future__ import annotations

import re

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError, SchemaError
from ami_xr.io.datasets import make_frf_dataset, make_time_dataset
from ami_xr.io.schema import find_problems, validate

# --- helpers ----------------------------------------------------------------------------------


def _time_dataset(n_time=64, force=True, records=None):
    rng = np.random.default_rng(0)
    shape = (3, n_time) if records is None else (records, 3, n_time)
    response = rng.standard_normal(shape)
    f = None
    if force:
        f = rng.standard_normal(n_time if records is None else (records, n_time))
    return make_time_dataset(response, fs=256.0, force=f, points=["a", "b", "c"], drive_point="b")


def _with_attrs(ds, **attrs):
    out = ds.copy()
    out.attrs = {**ds.attrs, **attrs}
    return out


def _without_attr(ds, name):
    out = ds.copy()
    out.attrs = {k: v for k, v in ds.attrs.items() if k != name}
    return out


def _set_frf(ds, values):
    out = ds.copy(deep=True)
    out[names.FRF].values[...] = values
    return out


def _with_frf_index(ds, index, value):
    out = ds.copy(deep=True)
    out[names.FRF].values[index] = value
    return out


def _with_coord(ds, dim, values):
    out = ds.copy()
    return out.assign_coords({dim: (dim, np.asarray(values), ds[dim].attrs)})


def _repeat_one(values, i):
    out = values.copy()
    out[i] = out[i - 1]
    return out


# --- valid Datasets -----------------------------------------------------------------------------


def test_valid_frf_dataset_is_returned_unchanged(frf_dataset):
    assert validate(frf_dataset) is frf_dataset
    assert ami_xr.validate(frf_dataset, kind="frf") is frf_dataset
    assert frf_dataset.ami.validate() is frf_dataset


def test_valid_time_datasets():
    for ds in (_time_dataset(), _time_dataset(records=4), _time_dataset(force=False)):
        assert validate(ds) is ds
        assert validate(ds, kind="time") is ds


def test_find_problems_lists_without_raising_in_the_callers_names(frf_dataset):
    assert find_problems(frf_dataset) == ("FRF Dataset", [])
    bad = frf_dataset.drop_vars(names.FREQUENCY)
    what, problems = find_problems(bad)
    assert what == "FRF Dataset" and any("coordinate 'frequency'" in p for p in problems)
    _, renamed = find_problems(bad, arguments={names.FREQUENCY: "freqs"})
    assert any("argument 'freqs'" in p for p in renamed) and len(renamed) == len(problems)
    with pytest.raises(SchemaError):
        validate(bad)


def test_unit_impulse_time_dataset_needs_no_force():
    ds = _time_dataset(force=False)
    assert names.FORCE not in ds
    assert ds.attrs["excitation"] == "unit_impulse"


def test_extra_variables_may_hold_nan(frf_dataset):
    ds = frf_dataset.assign(coherence=frf_dataset.frf.real * np.nan)
    assert validate(ds) is ds


def test_lazy_dataset_validates_without_error(frf_dataset):
    pytest.importorskip("dask")
    lazy = frf_dataset.chunk({names.FREQUENCY: 50})
    assert validate(lazy) is lazy
    bad = _with_frf_index(frf_dataset, (0, 3), np.nan).chunk({names.FREQUENCY: 50})
    with pytest.raises(SchemaError, match="found 1 NaN"):
        validate(bad)


def test_make_frf_dataset_keeps_dask_input_lazy(frf_dataset):
    da = pytest.importorskip("dask.array")
    lazy = da.from_array(frf_dataset.frf.values, chunks=(1, 50))
    ds = make_frf_dataset(lazy, frf_dataset.frequency.values, drive_point=0)
    assert isinstance(ds.frf.data, da.Array)


def test_require_drive_point_false_accepts_missing_or_unknown(frf_dataset):
    missing = _without_attr(frf_dataset, names.ATTR_DRIVE_POINT)
    unknown = _with_attrs(frf_dataset, drive_point=99)
    assert validate(missing, require_drive_point=False) is missing
    assert validate(unknown, require_drive_point=False) is unknown


def test_check_values_false_skips_nan_scan(frf_dataset):
    bad = _with_frf_index(frf_dataset, (1, 2), np.inf)
    assert validate(bad, check_values=False) is bad


# --- one bad FRF Dataset per problem ------------------------------------------------------------

FRF_CASES = {
    "no frf or response": (
        lambda ds: ds.drop_vars(names.FRF),
        r"variable 'frf' or variable 'response': missing",
    ),
    "wrong dims": (
        lambda ds: ds.transpose(names.FREQUENCY, names.POINT),
        r"variable 'frf': expected dims \('point', 'frequency'\), got \('frequency', 'point'\)",
    ),
    "reference dim": (  # multi-reference data: the drive points are the references
        lambda ds: ds.expand_dims({names.REFERENCE: [1]}),
        r"attribute 'drive_point': not used with a 'reference' dim",
    ),
    "on-disk complex dim": (
        lambda ds: ds.assign(
            frf=xr.concat([ds.frf.real, ds.frf.imag], names.COMPLEX).transpose(..., names.COMPLEX)
        ),
        r"variable 'frf': has the on-disk dim 'complex'.*ami_xr.open_dataset",
    ),
    "real frf": (
        lambda ds: ds.assign(frf=ds.frf.real),
        r"variable 'frf': expected complex values \(complex128\), got dtype float64",
    ),
    "nan": (
        lambda ds: _with_frf_index(ds, (1, 7), complex(np.nan, 0)),
        r"variable 'frf': expected finite values, found 1 NaN or inf value\(s\) at 1 "
        r"point\(s\) \(point: count\) \S+: 1",
    ),
    "inf": (
        lambda ds: _with_frf_index(ds, (2, 0), complex(0, np.inf)),
        r"variable 'frf': expected finite values, found 1 NaN or inf value\(s\) at 1 point",
    ),
    "empty": (
        lambda ds: ds.isel({names.FREQUENCY: slice(0, 0)}),
        r"variable 'frf': empty \(expected at least one value, got shape \(3, 0\)\)",
    ),
    "missing frequency coord": (
        lambda ds: ds.drop_vars(names.FREQUENCY),
        r"coordinate 'frequency': missing \(expected 1-D values in Hz",
    ),
    "duplicate frequencies": (
        lambda ds: _with_coord(ds, names.FREQUENCY, _repeat_one(ds.frequency.values, 100)),
        r"coordinate 'frequency': expected strictly increasing values, found duplicate frequency",
    ),
    "decreasing frequencies": (
        lambda ds: _with_coord(ds, names.FREQUENCY, ds.frequency.values[::-1]),
        r"coordinate 'frequency': expected strictly increasing values, not increasing at 199",
    ),
    "negative frequencies": (
        lambda ds: _with_coord(ds, names.FREQUENCY, ds.frequency.values - 10.0),
        r"coordinate 'frequency': expected non-negative frequencies, got \d+ negative",
    ),
    "nan frequency": (
        lambda ds: _with_coord(ds, names.FREQUENCY, np.r_[np.nan, ds.frequency.values[1:]]),
        r"coordinate 'frequency': expected finite values",
    ),
    "frequency units": (
        lambda ds: ds.assign_coords(frequency=ds.frequency.assign_attrs(units="rad/s")),
        r"attribute 'units' of variable 'frequency': expected 'Hz', got 'rad/s'",
    ),
    "missing point coord": (
        lambda ds: ds.drop_vars(names.POINT),
        r"coordinate 'point': missing \(expected unique int or str labels",
    ),
    "duplicate points": (
        lambda ds: _with_coord(ds, names.POINT, [1, 2, 1]),
        r"coordinate 'point': expected unique labels, duplicates \[1\]",
    ),
    "float points": (
        lambda ds: _with_coord(ds, names.POINT, [1.0, 2.0, 3.0]),
        r"coordinate 'point': expected int or str labels, got dtype float64",
    ),
    "missing drive point": (
        lambda ds: _without_attr(ds, names.ATTR_DRIVE_POINT),
        r"attribute 'drive_point': missing .*require_drive_point=False",
    ),
    "drive point not a point": (
        lambda ds: _with_attrs(ds, drive_point=7),
        r"attribute 'drive_point': 7 is not among the point labels \[1, 2, 3\]",
    ),
    "drive point of wrong type": (
        lambda ds: _with_attrs(ds, drive_point="1"),
        r"attribute 'drive_point': expected a point label of type int, got '1' \(str\)",
    ),
    "unknown quantity": (
        lambda ds: _with_attrs(ds, response_quantity="strain"),
        r"attribute 'response_quantity': expected one of \('displacement', 'velocity', "
        r"'acceleration'\), got 'strain'",
    ),
    "missing quantity": (
        lambda ds: _without_attr(ds, names.ATTR_QUANTITY),
        r"attribute 'response_quantity': expected one of .*, missing",
    ),
    "frf_type inconsistent": (
        lambda ds: _with_attrs(ds, frf_type="mobility"),
        r"attribute 'frf_type': expected 'receptance' \(response_quantity is 'displacement'\), "
        r"got 'mobility'",
    ),
    "response units for quantity": (
        lambda ds: _with_attrs(ds, response_units="m/s"),
        r"attribute 'response_units': expected one of \('m', 'mm', 'um', 'in'\) for "
        r"displacement, got 'm/s'",
    ),
    "unknown force units": (
        lambda ds: _with_attrs(ds, force_units="kgf"),
        r"attribute 'force_units': expected one of \('N', 'kN', 'lbf'\), got 'kgf'",
    ),
    "frf units": (
        lambda ds: ds.assign(frf=ds.frf.assign_attrs(units="mm/N")),
        r"attribute 'units' of variable 'frf': expected 'm/N' \(response_units/force_units\), "
        r"got 'mm/N'",
    ),
    "unknown source": (
        lambda ds: _with_attrs(ds, frf_source="guessed"),
        r"attribute 'frf_source': expected one of \('impulse_response', .*\), got 'guessed'",
    ),
    "impulse without sample_interval": (
        lambda ds: _with_attrs(ds, frf_source="impulse_response", record_samples=4096),
        r"attribute 'sample_interval': expected a positive sample interval in s because "
        r"frf_source is 'impulse_response', missing",
    ),
    "impulse with negative sample_interval": (
        lambda ds: _with_attrs(
            ds, frf_source="impulse_response", sample_interval=-0.01, record_samples=4096
        ),
        r"attribute 'sample_interval': expected a positive sample interval .* got -0.01",
    ),
    "impulse without record_samples": (
        lambda ds: _with_attrs(ds, frf_source="impulse_response", sample_interval=0.01),
        r"attribute 'record_samples': expected a positive integer record length",
    ),
    "negative window decay": (
        lambda ds: _with_attrs(ds, exponential_window_decay=-1.0),
        r"attribute 'exponential_window_decay': expected a finite decay rate >= 0",
    ),
}


@pytest.mark.parametrize("case", list(FRF_CASES))
def test_bad_frf_dataset(frf_dataset, case):
    mutate, match = FRF_CASES[case]
    bad = mutate(frf_dataset)
    with pytest.raises(SchemaError, match=match) as info:
        validate(bad)
    assert isinstance(info.value, ValueError)
    # the problem is reported exactly once and the error lists it
    assert sum(bool(re.search(match, p)) for p in info.value.problems) == 1


def test_valid_impulse_response_source(frf_dataset):
    # the lines must be a band of the rfft grid k / (record_samples * sample_interval)
    grid = _with_coord(frf_dataset, names.FREQUENCY, np.arange(1, 201) / (4096 * 0.01))
    ds = _with_attrs(grid, frf_source="impulse_response", sample_interval=0.01, record_samples=4096)
    assert validate(ds) is ds


def test_kind_frf_on_time_dataset_reports_missing_frf():
    with pytest.raises(SchemaError, match=r"variable 'frf': missing \(expected complex FRF"):
        validate(_time_dataset(), kind="frf")


def test_every_problem_is_reported_at_once(frf_dataset):
    bad = frf_dataset.assign(frf=frf_dataset.frf.real)
    bad = _with_coord(bad, names.POINT, [1, 1, 2])
    bad = _with_attrs(bad, drive_point=5, response_quantity="strain", frf_source="guessed")
    bad = _without_attr(bad, names.ATTR_FORCE_UNITS)
    with pytest.raises(SchemaError) as info:
        validate(bad)
    problems = info.value.problems
    expected = [
        "variable 'frf': expected complex",
        "coordinate 'point': expected unique labels",
        "attribute 'drive_point': 5 is not among",
        "attribute 'response_quantity': expected one of",
        "attribute 'force_units': expected one of",
        "attribute 'frf_source': expected one of",
    ]
    for text in expected:
        assert any(text in p for p in problems), (text, problems)
    message = str(info.value)
    assert f"({len(problems)} problem(s))" in message
    assert all(p in message for p in problems)


def test_not_a_dataset_and_bad_kind(frf_dataset):
    with pytest.raises(AmiXrValueError, match=r"ds: expected an xarray.Dataset .*to_dataset"):
        validate(frf_dataset.frf)
    with pytest.raises(AmiXrValueError, match=r"kind: expected None or one of \('frf', 'time'\)"):
        validate(frf_dataset, kind="modes")


# --- one bad time Dataset per problem -----------------------------------------------------------

TIME_CASES = {
    "missing response": (
        lambda ds: ds.drop_vars(names.RESPONSE),
        r"variable 'response': missing \(expected float responses",
        "time",
    ),
    "complex response": (
        lambda ds: ds.assign(response=ds.response * (1 + 1j)),
        r"variable 'response': expected real float values \(float64\), got dtype complex128",
        None,
    ),
    "response wrong dims": (
        lambda ds: ds.transpose(names.TIME, names.POINT),
        r"variable 'response': expected dims \('point', 'time'\) or \('record', 'point', 'time'\)",
        None,
    ),
    "response reference dim": (
        lambda ds: ds.assign(response=ds.response.expand_dims({names.REFERENCE: 2})),
        r"variable 'response': has a leading 'reference' dim: multi-reference",
        None,
    ),
    "force reference dim last": (  # several force channels go on a reference dim before time
        lambda ds: ds.assign(force=ds.force.expand_dims({names.REFERENCE: 2}, axis=-1)),
        r"variable 'force': expected dims .*\('reference', 'time'\)",
        None,
    ),
    "force wrong dims": (
        lambda ds: ds.assign(force=ds.force.expand_dims({names.POINT: ds.point})),
        r"variable 'force': expected dims \('time',\) or \('record', 'time'\)",
        None,
    ),
    "missing force": (
        lambda ds: ds.drop_vars(names.FORCE),
        r"variable 'force': missing .*excitation='unit_impulse'",
        None,
    ),
    "nan response": (
        lambda ds: ds.assign(response=ds.response.where(ds.time != ds.time[5])),
        r"variable 'response': expected finite values, found 3 NaN",
        None,
    ),
    "inf force": (
        lambda ds: ds.assign(force=ds.force.where(ds.time != ds.time[0], np.inf)),
        r"variable 'force': expected finite values, found 0 NaN and 1 inf",
        None,
    ),
    "empty": (
        lambda ds: ds.isel({names.TIME: slice(0, 0)}),
        r"variable 'response': empty",
        None,
    ),
    "uneven time steps": (
        lambda ds: _with_coord(
            ds, names.TIME, ds.time.values * (1 + 1e-3 * (ds.time.values > 0.1))
        ),
        r"coordinate 'time': expected uniform steps, step \d+ is",
        None,
    ),
    "time not increasing": (
        lambda ds: _with_coord(ds, names.TIME, ds.time.values[::-1]),
        r"coordinate 'time': expected strictly increasing values, not increasing",
        None,
    ),
    "time units": (
        lambda ds: ds.assign_coords(time=ds.time.assign_attrs(units="ms")),
        r"attribute 'units' of variable 'time': expected 's', got 'ms'",
        None,
    ),
    "response units attr": (
        lambda ds: ds.assign(response=ds.response.assign_attrs(units="mm")),
        r"attribute 'units' of variable 'response': expected 'm' \(the Dataset's response_units\)",
        None,
    ),
    "drive point not a point": (
        lambda ds: _with_attrs(ds, drive_point="z"),
        r"attribute 'drive_point': 'z' is not among the point labels \['a', 'b', 'c'\]",
        None,
    ),
    "duplicate str points": (
        lambda ds: _with_coord(ds, names.POINT, ["a", "b", "a"]),
        r"coordinate 'point': expected unique labels, duplicates \['a'\]",
        None,
    ),
    "unknown response units": (
        lambda ds: _with_attrs(ds, response_quantity="acceleration"),
        r"attribute 'response_units': expected one of \('m/s\^2', 'mm/s\^2', 'g', 'in/s\^2'\) "
        r"for acceleration, got 'm'",
        None,
    ),
}


@pytest.mark.parametrize("case", list(TIME_CASES))
def test_bad_time_dataset(case):
    mutate, match, kind = TIME_CASES[case]
    bad = mutate(_time_dataset())
    with pytest.raises(SchemaError, match=match) as info:
        validate(bad, kind=kind)
    assert sum(bool(re.search(match, p)) for p in info.value.problems) == 1


def test_time_steps_with_float_rounding_are_uniform():
    n = 2**16
    ds = make_time_dataset(np.zeros((1, n)), np.arange(n) * (60.0 / n), drive_point=0)
    assert validate(ds) is ds


# --- constructors: errors name the argument ------------------------------------------------------


def test_make_frf_dataset_defaults():
    ds = make_frf_dataset(np.ones(5, complex), np.arange(5.0))
    assert ds.frf.dims == (names.POINT, names.FREQUENCY)
    assert ds.point.values.tolist() == [0]
    assert names.ATTR_DRIVE_POINT not in ds.attrs
    assert ds.attrs[names.ATTR_FRF_TYPE] == "receptance"
    assert ds.frf.attrs[names.ATTR_UNITS] == "m/N"
    assert ds.frequency.attrs[names.ATTR_UNITS] == "Hz"
    validate(ds, require_drive_point=False)


def test_make_frf_dataset_extra_attrs_and_quantity():
    ds = make_frf_dataset(
        np.ones((2, 3), complex),
        [0.0, 1.0, 2.0],
        points=["x", "y"],
        drive_point="y",
        response_quantity="acceleration",
        response_units="g",
        force_units="lbf",
        frf_source="impulse_response",
        sample_interval=0.25,  # lines k / (4 * 0.25 s) = 0, 1, 2 Hz
        record_samples=4,
        title="bench",
    )
    assert ds.attrs["frf_type"] == "accelerance"
    assert ds.frf.attrs["units"] == "g/lbf"
    assert ds.attrs["title"] == "bench"


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"frf": np.ones((2, 3))}, r"argument 'frf': expected complex values"),
        ({"points": [4, 4]}, r"argument 'points': expected unique labels"),
        ({"drive_point": 9}, r"argument 'drive_point': 9 is not among the point labels"),
        ({"response_quantity": "strain"}, r"argument 'response_quantity': expected one of"),
        ({"response_units": "furlong"}, r"argument 'response_units': expected one of"),
        ({"force_units": "kp"}, r"argument 'force_units': expected one of"),
        ({"frf_source": "x"}, r"argument 'frf_source': expected one of"),
        ({"frequency": [0.0, 2.0, 1.0]}, r"argument 'frequency': expected strictly increasing"),
        ({"frf_source": "impulse_response"}, r"attribute 'sample_interval': expected a positive"),
    ],
)
def test_make_frf_dataset_errors_name_the_argument(kwargs, match):
    args = {"frf": np.ones((2, 3), complex), "frequency": [0.0, 1.0, 2.0], "drive_point": 0}
    args.update(kwargs)
    with pytest.raises(SchemaError, match=match) as info:
        make_frf_dataset(**args)
    assert "make_frf_dataset arguments" in str(info.value)


def test_make_frf_dataset_shape_errors():
    with pytest.raises(AmiXrValueError, match=r"frequency: expected 3 values \(frf.shape\[-1\]\)"):
        make_frf_dataset(np.ones((2, 3), complex), [0.0, 1.0])
    with pytest.raises(AmiXrValueError, match=r"points: expected 2 labels"):
        make_frf_dataset(np.ones((2, 3), complex), [0.0, 1.0, 2.0], points=[1, 2, 3])
    with pytest.raises(AmiXrValueError, match=r"frf: expected shape .*n_reference"):
        make_frf_dataset(np.ones((1, 2, 2, 3), complex), [0.0, 1.0, 2.0])


def test_make_time_dataset_shapes_and_time_axis():
    ds = make_time_dataset(np.zeros((2, 3, 8)), fs=4.0, force=np.ones((2, 8)), drive_point=1)
    assert ds.response.dims == (names.RECORD, names.POINT, names.TIME)
    assert ds.force.dims == (names.RECORD, names.TIME)
    np.testing.assert_array_equal(ds.time.values, np.arange(8) / 4.0)
    assert ds.time.attrs["units"] == "s"
    assert ds.force.attrs["units"] == "N"
    one = make_time_dataset(np.zeros(8), np.arange(8) * 0.5)
    assert one.response.dims == (names.POINT, names.TIME)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"fs": 10.0, "time": np.arange(8.0)}, AmiXrValueError, r"time, fs: give exactly one"),
        ({}, AmiXrValueError, r"time, fs: give exactly one"),
        ({"fs": -1.0}, AmiXrValueError, r"fs: expected a positive sampling rate"),
        ({"time": np.arange(7.0)}, AmiXrValueError, r"time: expected 8 values"),
        ({"fs": 1.0, "force": np.ones(5)}, AmiXrValueError, r"force: expected shape \(8,\)"),
        (
            {"time": np.r_[0.0, 1, 2, 3, 4, 5, 6, 8]},
            SchemaError,
            r"argument 'time': expected uniform steps",
        ),
        (
            {"fs": 1.0, "force": np.r_[np.nan, np.ones(7)]},
            SchemaError,
            r"argument 'force': .*1 NaN",
        ),
        ({"fs": 1.0, "points": ["p", "p"]}, SchemaError, r"argument 'points': expected unique"),
    ],
)
def test_make_time_dataset_errors_name_the_argument(kwargs, error, match):
    with pytest.raises(error, match=match):
        make_time_dataset(np.zeros((2, 8)), **kwargs)
