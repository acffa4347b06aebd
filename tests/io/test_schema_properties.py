"""Property-based tests (hypothesis) of the data model: :func:`ami_xr.validate`,
:func:`ami_xr.io.schema.find_problems`, the constructors :func:`ami_xr.make_frf_dataset` and
:func:`ami_xr.make_time_dataset`, and the netCDF round trip of valid Datasets.

Random valid Datasets pass; each random corruption from a catalogue (a missing variable,
coordinate or attribute, a wrong dtype, a non-increasing axis, duplicate labels, NaN, a drive
point that is not a point, unknown units) raises :class:`~ami_xr.errors.SchemaError` naming the
broken part; several independent corruptions at once are all reported.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ami_xr
from ami_xr import names, provenance
from ami_xr.errors import SchemaError
from ami_xr.io.schema import find_problems

_SETTINGS = settings(max_examples=40, deadline=None)
_LABEL_TEXT = st.text(alphabet="abcdefghij0123456789_-", min_size=1, max_size=6)

# --- random valid Datasets --------------------------------------------------------------------


@st.composite
def labels(draw, n: int) -> np.ndarray:
    """``n`` unique point labels, all int or all str."""
    if draw(st.booleans()):
        return np.array(
            draw(st.lists(st.integers(-1000, 1000), min_size=n, max_size=n, unique=True))
        )
    return np.array(draw(st.lists(_LABEL_TEXT, min_size=n, max_size=n, unique=True)))


@st.composite
def units(draw) -> dict[str, str]:
    quantity = draw(st.sampled_from(sorted(names.RESPONSE_UNITS)))
    return {
        "response_quantity": quantity,
        "response_units": draw(st.sampled_from(names.RESPONSE_UNITS[quantity])),
        "force_units": draw(st.sampled_from(names.FORCE_UNITS)),
    }


@st.composite
def frf_datasets(draw) -> xr.Dataset:
    n_point = draw(st.integers(1, 4))
    n_freq = draw(st.integers(2, 8))
    points = draw(labels(n_point))
    steps = draw(st.lists(st.floats(1e-3, 100.0), min_size=n_freq, max_size=n_freq))
    frequency = draw(st.sampled_from([0.0, 0.5, 10.0])) + np.cumsum(steps) - steps[0]
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    frf = rng.normal(size=(n_point, n_freq)) + 1j * rng.normal(size=(n_point, n_freq))
    source = draw(st.sampled_from(names.SOURCES))
    extra = {}
    if source == names.SOURCE_IMPULSE:  # lines k / (N dt) of the record's rfft grid
        dt = draw(st.floats(1e-6, 1.0))
        k0 = draw(st.sampled_from([0, 1, 3]))
        n_samples = 2 * (k0 + n_freq - 1) + draw(st.integers(0, 1))
        frequency = np.arange(k0, k0 + n_freq) / (n_samples * dt)
        extra = {names.ATTR_DT: dt, names.ATTR_NSAMPLES: n_samples}
    return ami_xr.make_frf_dataset(
        frf,
        frequency,
        points=points,
        drive_point=points[draw(st.integers(0, n_point - 1))],
        frf_source=source,
        **draw(units()),
        **extra,
    )


@st.composite
def time_datasets(draw) -> xr.Dataset:
    n_point = draw(st.integers(1, 3))
    n_time = draw(st.integers(2, 16))
    n_record = draw(st.one_of(st.none(), st.integers(1, 3)))
    points = draw(labels(n_point))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    shape = (n_point, n_time) if n_record is None else (n_record, n_point, n_time)
    response = rng.normal(size=shape)
    force = None
    if draw(st.booleans()):
        force = rng.normal(size=n_time if n_record is None else (n_record, n_time))
    return ami_xr.make_time_dataset(
        response,
        fs=draw(st.floats(1.0, 1e5)),
        force=force,
        points=points,
        drive_point=points[draw(st.integers(0, n_point - 1))],
        **draw(units()),
    )


# --- the catalogue of corruptions ---------------------------------------------------------------


@dataclass(frozen=True)
class Corruption:
    """One way to break a valid Dataset, the phrase the report must contain, and the part of
    the Dataset it touches (corruptions of one part can hide each other, so a combined test
    takes at most one per part)."""

    name: str
    part: str  # parts joined by "+" when the check of the corrupted item needs several
    named: str
    apply: Callable[[xr.Dataset, np.random.Generator], xr.Dataset]
    applies: Callable[[xr.Dataset], bool] = lambda ds: True


def _drop_attr(key):
    def apply(ds, rng):
        out = ds.copy()
        del out.attrs[key]
        return out

    return apply


def _set_attr(key, value):
    def apply(ds, rng):
        return ds.assign_attrs({key: value})

    return apply


def _set_var_attr(var, key, value):
    def apply(ds, rng):
        out = ds.copy()
        out[var].attrs[key] = value
        return out

    return apply


def _nan_in(var):
    def apply(ds, rng):
        out = ds.copy(deep=True)
        flat = out[var].values.reshape(-1)
        flat[rng.integers(flat.size)] = rng.choice([np.nan, np.inf, -np.inf])
        return out

    return apply


def _swap_two(dim):
    def apply(ds, rng):
        values = ds[dim].values.copy()
        i = int(rng.integers(values.size - 1))
        if rng.integers(2):
            values[[i, i + 1]] = values[[i + 1, i]]  # decreasing step
        else:
            values[i + 1] = values[i]  # repeated value
        return ds.assign_coords({dim: (dim, values, ds[dim].attrs)})

    return apply


def _duplicate_label(ds, rng):
    values = ds[names.POINT].values.copy()
    values[-1] = values[0]
    return ds.assign_coords({names.POINT: values})


def _drive_not_a_point(ds, rng):
    values = ds[names.POINT].values
    stranger = int(np.max(values)) + 1 if values.dtype.kind == "i" else "not_a_point"
    return ds.assign_attrs({names.ATTR_DRIVE_POINT: stranger})


def _retype(var, dtype):
    def apply(ds, rng):
        out = ds.copy()
        values = ds[var].values
        out[var] = (ds[var].dims, np.real(values).astype(dtype), ds[var].attrs)
        return out

    return apply


def _float_labels(ds, rng):
    return ds.assign_coords({names.POINT: np.arange(ds.sizes[names.POINT]) + 0.5})


def _several_points(ds):
    return ds.sizes[names.POINT] >= 2


FRF_CORRUPTIONS = (
    Corruption("drop frf", "frf", "variable 'frf'", lambda ds, rng: ds.drop_vars(names.FRF)),
    Corruption("real frf", "frf", "variable 'frf'", _retype(names.FRF, np.float64)),
    Corruption("NaN in frf", "frf", "variable 'frf'", _nan_in(names.FRF)),
    Corruption(
        "drop frequency",
        "frequency",
        "coordinate 'frequency'",
        lambda ds, rng: ds.drop_vars(names.FREQUENCY),
    ),
    Corruption(
        "non-increasing frequency", "frequency", "coordinate 'frequency'", _swap_two("frequency")
    ),
    Corruption(
        "frequency in rad/s",
        "frequency",
        "attribute 'units' of variable 'frequency'",
        _set_var_attr(names.FREQUENCY, names.ATTR_UNITS, "rad/s"),
    ),
    Corruption(
        "drop point", "point", "coordinate 'point'", lambda ds, rng: ds.drop_vars(names.POINT)
    ),
    Corruption("float labels", "point", "coordinate 'point'", _float_labels),
    Corruption(
        "duplicate labels", "point", "coordinate 'point'", _duplicate_label, _several_points
    ),
    Corruption("drive point not a point", "point", "attribute 'drive_point'", _drive_not_a_point),
    Corruption(
        "drop drive_point",
        "point",
        "attribute 'drive_point'",
        _drop_attr(names.ATTR_DRIVE_POINT),
    ),
    Corruption(
        "drop response_quantity",
        "quantity",
        "attribute 'response_quantity'",
        _drop_attr(names.ATTR_QUANTITY),
    ),
    Corruption(
        "drop frf_type", "frf_type", "attribute 'frf_type'", _drop_attr(names.ATTR_FRF_TYPE)
    ),
    Corruption(
        "unknown response units",
        "units",
        "attribute 'response_units'",
        _set_attr(names.ATTR_RESPONSE_UNITS, "furlong"),
    ),
    Corruption(
        "unknown force units",
        "units",
        "attribute 'force_units'",
        _set_attr(names.ATTR_FORCE_UNITS, "kgf"),
    ),
    Corruption(
        "drop force_units", "units", "attribute 'force_units'", _drop_attr(names.ATTR_FORCE_UNITS)
    ),
    Corruption(
        "wrong frf units",
        "frf+units",
        "attribute 'units' of variable 'frf'",
        _set_var_attr(names.FRF, names.ATTR_UNITS, "m/s/kgf"),
    ),
    Corruption(
        "unknown frf_source",
        "source",
        "attribute 'frf_source'",
        _set_attr(names.ATTR_SOURCE, "guess"),
    ),
    Corruption(
        "impulse source without dt",
        "source",
        "attribute 'sample_interval'",
        lambda ds, rng: ds.assign_attrs(
            {names.ATTR_SOURCE: names.SOURCE_IMPULSE, names.ATTR_DT: -1.0}
        ),
    ),
)

TIME_CORRUPTIONS = (
    Corruption(
        "drop response",
        "response",
        "variable 'response'",
        lambda ds, rng: ds.drop_vars(names.RESPONSE),
    ),
    Corruption("NaN in response", "response", "variable 'response'", _nan_in(names.RESPONSE)),
    Corruption(
        "int response", "response", "variable 'response'", _retype(names.RESPONSE, np.int64)
    ),
    Corruption(
        "drop force",
        "force",
        "variable 'force'",
        lambda ds, rng: ds.drop_vars(names.FORCE),
        lambda ds: names.FORCE in ds,
    ),
    Corruption(
        "NaN in force",
        "force",
        "variable 'force'",
        _nan_in(names.FORCE),
        lambda ds: names.FORCE in ds,
    ),
    Corruption(
        "drop excitation",
        "force",
        "variable 'force'",
        _drop_attr(names.ATTR_EXCITATION),
        lambda ds: names.FORCE not in ds,
    ),
    Corruption("non-increasing time", "time", "coordinate 'time'", _swap_two(names.TIME)),
    Corruption(
        "time in ms",
        "time",
        "attribute 'units' of variable 'time'",
        _set_var_attr(names.TIME, names.ATTR_UNITS, "ms"),
    ),
    Corruption(
        "duplicate labels", "point", "coordinate 'point'", _duplicate_label, _several_points
    ),
    Corruption("drive point not a point", "point", "attribute 'drive_point'", _drive_not_a_point),
    Corruption(
        "unknown response units",
        "units",
        "attribute 'response_units'",
        _set_attr(names.ATTR_RESPONSE_UNITS, "furlong"),
    ),
    Corruption(
        "wrong response variable units",
        "response+units",
        "attribute 'units' of variable 'response'",
        _set_var_attr(names.RESPONSE, names.ATTR_UNITS, "parsec"),
    ),
    Corruption(
        "drop response_quantity",
        "quantity",
        "attribute 'response_quantity'",
        _drop_attr(names.ATTR_QUANTITY),
    ),
)

KIND_CORRUPTIONS = {
    "frf": (frf_datasets, FRF_CORRUPTIONS),
    "time": (time_datasets, TIME_CORRUPTIONS),
}


def _named_in(problems: list[str], phrase: str) -> bool:
    return any(p.startswith(phrase + ":") for p in problems)


# --- properties ---------------------------------------------------------------------------------


@_SETTINGS
@given(data=st.data(), kind=st.sampled_from(sorted(KIND_CORRUPTIONS)))
def test_random_valid_datasets_pass(data, kind):
    ds = data.draw(KIND_CORRUPTIONS[kind][0]())
    assert ami_xr.validate(ds) is ds
    assert ami_xr.validate(ds, kind) is ds
    assert find_problems(ds, kind) == (f"{'FRF' if kind == 'frf' else 'Time'} Dataset", [])


@_SETTINGS
@given(
    data=st.data(), kind=st.sampled_from(sorted(KIND_CORRUPTIONS)), seed=st.integers(0, 2**32 - 1)
)
def test_each_single_corruption_is_reported_by_name(data, kind, seed):
    make, catalogue = KIND_CORRUPTIONS[kind]
    ds = data.draw(make())
    corruption = data.draw(st.sampled_from([c for c in catalogue if c.applies(ds)]))
    bad = corruption.apply(ds, np.random.default_rng(seed))
    with pytest.raises(SchemaError) as info:
        ami_xr.validate(bad, kind)
    assert isinstance(info.value, ValueError)
    # the problem is the first word of one entry, and the message lists every entry
    assert _named_in(info.value.problems, corruption.named), (corruption.name, info.value.problems)
    assert corruption.named in str(info.value)
    assert all(p in str(info.value) for p in info.value.problems)


@_SETTINGS
@given(
    data=st.data(), kind=st.sampled_from(sorted(KIND_CORRUPTIONS)), seed=st.integers(0, 2**32 - 1)
)
def test_several_corruptions_are_all_reported(data, kind, seed):
    make, catalogue = KIND_CORRUPTIONS[kind]
    ds = data.draw(make())
    usable = [c for c in catalogue if c.applies(ds)]
    order = data.draw(st.permutations(usable))
    n_wanted = data.draw(st.integers(2, 4))
    chosen, taken = [], set()
    for corruption in order:  # independent corruptions: no part in common
        parts = set(corruption.part.split("+"))
        if len(chosen) < n_wanted and not parts & taken:
            chosen.append(corruption)
            taken |= parts
    rng = np.random.default_rng(seed)
    bad = ds
    for corruption in chosen:
        bad = corruption.apply(bad, rng)
    with pytest.raises(SchemaError) as info:
        ami_xr.validate(bad, kind)
    for corruption in chosen:
        assert _named_in(info.value.problems, corruption.named), (
            corruption.name,
            [c.name for c in chosen],
            info.value.problems,
        )


@_SETTINGS
@given(data=st.data())
def test_constructor_errors_name_the_argument(data):
    n_point = data.draw(st.integers(2, 4))
    n_freq = data.draw(st.integers(2, 6))
    points = np.arange(n_point)
    frequency = np.linspace(0.0, 10.0, n_freq)
    frf = np.ones((n_point, n_freq), complex)
    kwargs = {"points": points, "drive_point": 0, "response_units": "m"}
    kwargs["response_quantity"] = "displacement"  # stated: units are checked against it
    broken = data.draw(
        st.lists(
            st.sampled_from(["points", "drive_point", "response_units", "frequency", "frf"]),
            min_size=1,
            max_size=5,
            unique=True,
        )
    )
    if "points" in broken:
        kwargs["points"] = np.r_[points[:-1], points[0]]  # a duplicate label
    if "drive_point" in broken:
        kwargs["drive_point"] = n_point + 7
    if "response_units" in broken:
        kwargs["response_units"] = "m/s"  # units of velocity for a displacement
    if "frequency" in broken:
        frequency = frequency[::-1].copy()
    if "frf" in broken:
        frf[data.draw(st.integers(0, n_point - 1)), data.draw(st.integers(0, n_freq - 1))] = np.nan
    if "points" in broken and "drive_point" not in broken:
        kwargs["drive_point"] = int(kwargs["points"][0])
    with pytest.raises(SchemaError) as info:
        ami_xr.make_frf_dataset(frf, frequency, **kwargs)
    for argument in broken:
        assert _named_in(info.value.problems, f"argument {argument!r}"), (
            argument,
            info.value.problems,
        )


PROVENANCE_ATTRS = (
    names.ATTR_HISTORY,
    names.ATTR_VERSION,
    provenance.ATTR_FUNCTION,
    names.ATTR_SOURCE_FILE,
)


def _without_provenance(ds: xr.Dataset) -> xr.Dataset:
    out = ds.copy()
    out.attrs = {k: v for k, v in ds.attrs.items() if k not in PROVENANCE_ATTRS}
    return out


@settings(
    max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data(), kind=st.sampled_from(sorted(KIND_CORRUPTIONS)))
def test_netcdf_round_trip_of_valid_datasets_is_identical(tmp_path, data, kind):
    ds = data.draw(KIND_CORRUPTIONS[kind][0]())
    path = ami_xr.to_netcdf(ds, tmp_path / "valid.nc")
    back = ami_xr.open_dataset(path)
    # exact: complex values are stored as float pairs and attributes are tagged, so nothing is
    # rounded; only the provenance attributes the write/read add may differ
    xr.testing.assert_identical(_without_provenance(back), _without_provenance(ds))
    assert ami_xr.validate(back, kind) is back
