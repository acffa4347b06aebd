"""netCDF I/O: lossless round trips, plain-xarray reading, provenance, atomic writes, lazy open."""

from __future__ import annotations

import json
import math
import re
import string

import netCDF4
import numpy as np
import pytest
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import ami_xr
from ami_xr import names, provenance
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io import netcdf
from ami_xr.io.netcdf import open_dataset, to_netcdf

from ..reference import forbid_compute

dask = pytest.importorskip("dask")

# Attributes to_netcdf/open_dataset add; the round-trip comparison removes exactly these, and
# the generated Datasets never carry them, so nothing else can hide behind the stripping.
PROVENANCE_ATTRS = (
    names.ATTR_HISTORY,
    names.ATTR_VERSION,
    provenance.ATTR_FUNCTION,
    names.ATTR_SOURCE_FILE,
)


def _strip_provenance(ds: xr.Dataset) -> xr.Dataset:
    out = ds.copy()
    out.attrs = {k: v for k, v in ds.attrs.items() if k not in PROVENANCE_ATTRS}
    return out


def _bits(values: np.ndarray) -> np.ndarray:
    """Raw bytes of a float or complex array, to compare bit for bit (NaN payloads, -0.0)."""
    values = np.ascontiguousarray(values)
    return values.reshape(-1).view(np.uint8)


def _same_attr(a, b) -> bool:
    """Strict attribute comparison: value and kind (a bool must come back a bool, ...)."""
    if isinstance(a, (bool, np.bool_)):
        return isinstance(b, (bool, np.bool_)) and bool(a) == bool(b)
    if a is None or isinstance(a, (dict, str)):
        return type(b) is type(a) and a == b
    if isinstance(a, (complex, np.complexfloating)):
        return isinstance(b, (complex, np.complexfloating)) and _bits(
            np.complex128(a)
        ).tolist() == (_bits(np.complex128(b)).tolist())
    if isinstance(a, (list, tuple, np.ndarray)):
        a_arr, b_arr = np.asarray(a), np.asarray(b)
        if a_arr.size == 0:
            return np.asarray(b).size == 0
        if a_arr.dtype.kind in "fc":
            return a_arr.shape == b_arr.shape and np.array_equal(_bits(a_arr), _bits(b_arr))
        return a_arr.shape == b_arr.shape and a_arr.tolist() == b_arr.tolist()
    if isinstance(a, (float, np.floating)):
        return isinstance(b, (float, np.floating)) and (a == b or (math.isnan(a) and math.isnan(b)))
    return a == b and not isinstance(b, (bool, np.bool_))


def assert_round_trip(original: xr.Dataset, back: xr.Dataset) -> None:
    """``back`` (read from disk) equals ``original`` exactly, dtypes and bits included."""
    assert not set(PROVENANCE_ATTRS) & set(original.attrs)
    stripped = _strip_provenance(back)
    xr.testing.assert_identical(stripped, original)
    for name, var in original.variables.items():
        got = back.variables[name]
        if var.dtype.kind in "biufc":
            assert got.dtype == var.dtype, name
        if var.dtype.kind in "fc":
            assert np.array_equal(_bits(var.values), _bits(got.values)), name
        for key, value in var.attrs.items():
            assert _same_attr(value, got.attrs[key]), (name, key, value, got.attrs[key])
    for key, value in original.attrs.items():
        assert _same_attr(value, back.attrs[key]), (key, value, back.attrs[key])


SPECIAL = np.array(
    [0.0, -0.0, np.nan, -np.nan, np.inf, -np.inf, 5e-324, np.finfo(float).max, 1 / 3]
)


def _special_complex() -> np.ndarray:
    re_, im = np.meshgrid(SPECIAL, SPECIAL)
    z = np.empty(re_.shape, complex)
    z.real, z.imag = re_, im
    # a NaN with a non-default payload must survive too
    z.reshape(-1).view(np.uint64)[0] = 0x7FF8_0000_DEAD_BEEF
    return z


# --- round trips ---------------------------------------------------------------------------------


def test_frf_dataset_round_trips(tmp_path, frf_dataset):
    path = to_netcdf(frf_dataset, tmp_path / "frf.nc")
    assert path == tmp_path / "frf.nc"
    assert_round_trip(frf_dataset, open_dataset(path))


def test_special_complex_values_round_trip_bit_for_bit(tmp_path):
    z = _special_complex()
    with np.errstate(over="ignore"):  # float max -> inf in complex64 is fine here
        z32 = z.astype(np.complex64)
    ds = xr.Dataset(
        {"z": (("a", "b"), z), "z32": (("a", "b"), z32), "s": ((), z[0, 2])},
        coords={"zc": ("a", z[:, 3])},  # complex non-index coordinate
    )
    back = open_dataset(to_netcdf(ds, tmp_path / "z.nc"))
    assert_round_trip(ds, back)
    assert back["zc"].dtype == np.complex128 and "zc" in back.coords
    assert back["z32"].dtype == np.complex64


def test_attributes_of_all_types_round_trip(tmp_path, frf_dataset):
    attrs = {
        "text": "héllo ∂",
        "empty_text": "",
        "integer": 7,
        "int32": np.int32(-3),
        "huge_int": 2**70,
        "number": 0.1,
        "nan": float("nan"),
        "flag": True,
        "off": np.bool_(False),
        "complex": 1.5 - 2j,
        "complex_list": [1j, 2.0, complex(np.nan, -0.0)],
        "bool_list": [True, False, True],
        "floats": [1.0, np.nan, -0.0],
        "one_float": [2.5],
        "one_text": ["a"],
        "texts": ["a", "bc"],
        "empty_list": [],
        "nothing": None,
        "mapping": {"window": "hann", "n": 3, "nested": {"x": [1, 2]}},
    }
    ds = frf_dataset.assign_attrs(attrs)
    ds["frf"].attrs.update(flag=False, complex=1j, nothing=None)
    ds.coords[names.FREQUENCY].attrs["long_name"] = "frequency"
    assert_round_trip(ds, open_dataset(to_netcdf(ds, tmp_path / "a.nc")))


def test_bool_and_string_variables_round_trip(tmp_path):
    ds = xr.Dataset(
        {
            "mask": (("point",), np.array([True, False, True])),
            "name": (("point",), np.array(["tip", "", "m₃"])),
            "count": (("point",), np.array([1, -2, 3], dtype=np.int16)),
            "with_nan": (("point",), np.array([1.0, np.nan, 3.0])),
        },
        coords={names.POINT: ["a", "b", "c"], "used": ("point", [False, True, True])},
    )
    path = to_netcdf(ds, tmp_path / "b.nc")
    assert_round_trip(ds, open_dataset(path))
    with netCDF4.Dataset(path) as nc:  # on disk: int8 (netCDF has no bool)
        assert nc["mask"].dtype == np.int8


def test_time_dataset_with_records_round_trips(tmp_path):
    rng = np.random.default_rng(1)
    ds = ami_xr.make_time_dataset(
        rng.standard_normal((2, 3, 100)),
        fs=50.0,
        force=rng.standard_normal((2, 100)),
        drive_point=0,
    )
    assert_round_trip(ds, open_dataset(to_netcdf(ds, tmp_path / "t.nc")))


def test_accessor_to_netcdf(tmp_path, frf_dataset):
    path = frf_dataset.ami.to_netcdf(tmp_path / "acc.nc")
    assert_round_trip(frf_dataset, open_dataset(path))


# --- readable without ami_xr ---------------------------------------------------------------------


def test_plain_xarray_recovers_complex_values(tmp_path, frf_dataset):
    path = to_netcdf(frf_dataset, tmp_path / "frf.nc")
    raw = xr.open_dataset(path)
    frf = raw[names.FRF]
    assert frf.dims == (names.POINT, names.FREQUENCY, names.COMPLEX)
    assert frf.attrs[netcdf.ATTR_COMPLEX] == "real,imag along last dim complex"
    assert frf.attrs["units"] == "m/N"
    recovered = frf.isel(complex=0) + 1j * frf.isel(complex=1)
    # re + 1j * im is exact for finite values (its products are with 0 and 1): bit-identical
    np.testing.assert_array_equal(recovered.values, frf_dataset.frf.values)
    # the bit-exact recipe from the README
    exact = np.ascontiguousarray(frf.values).view(np.complex128)[..., 0]
    assert np.array_equal(_bits(exact), _bits(frf_dataset.frf.values))
    raw.close()


def test_plain_netcdf4_sees_float_pairs(tmp_path):
    z = _special_complex()
    path = to_netcdf(xr.Dataset({"z": (("a", "b"), z)}), tmp_path / "z.nc")
    with netCDF4.Dataset(path) as nc:
        nc.set_auto_mask(False)
        var = nc["z"]
        assert var.dimensions == ("a", "b", "complex")
        assert var.dtype == np.float64
        assert "_FillValue" not in var.ncattrs()
        pairs = var[:]
    assert np.array_equal(_bits(pairs[..., 0]), _bits(z.real.copy()))
    assert np.array_equal(_bits(pairs[..., 1]), _bits(z.imag.copy()))


def test_encoded_attributes_are_documented_on_disk(tmp_path, frf_dataset):
    ds = frf_dataset.assign_attrs(flag=True, pole=1 + 2j, meta={"a": 1})
    raw = xr.open_dataset(to_netcdf(ds, tmp_path / "a.nc"))
    tags = json.loads(raw.attrs[netcdf.ATTR_ENCODED_ATTRS])
    assert tags == {"flag": "bool", "pole": "complex", "meta": "json"}
    # an attribute written and read: no arithmetic
    np.testing.assert_array_equal(raw.attrs["pole"], [1.0, 2.0])
    assert json.loads(raw.attrs["meta"]) == {"a": 1}
    raw.close()


# --- what cannot be stored is refused before any file is written ---------------------------------


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (
            lambda ds: ds.assign_attrs(grid=np.ones((2, 2))),
            r"attribute 'grid' of the Dataset: a 2-D",
        ),
        (lambda ds: ds.assign_attrs(items={1, 2}), r"attribute 'items' of the Dataset: type set"),
        (lambda ds: ds.assign_attrs(bad={"x": {1, 2}}), r"attribute 'bad' .*not JSON-serialisable"),
        (lambda ds: ds.assign_attrs(nul="a\x00b"), r"attribute 'nul' .*NUL character"),
        (
            lambda ds: ds.assign_attrs({netcdf.ATTR_ENCODED_ATTRS: "{}"}),
            r"attribute 'ami_xr_encoded_attrs' of the Dataset: the name is reserved",
        ),
        (
            lambda ds: ds.assign(frf=ds.frf.assign_attrs(when=np.datetime64("2020-01-01"))),
            r"attribute 'when' of variable 'frf': type datetime64",
        ),
        (
            lambda ds: ds.assign_coords(mode=("mode", [1j, 2j])),
            r"coordinate 'mode': a complex dimension coordinate cannot be written",
        ),
        (
            lambda ds: ds.assign(extra=(("complex",), [1.0, 2.0])),
            r"ds: has a dim 'complex', reserved for the on-disk complex encoding",
        ),
    ],
)
def test_unstorable_content_raises_before_writing(tmp_path, frf_dataset, mutate, match):
    with pytest.raises(AmiXrValueError, match=match):
        to_netcdf(mutate(frf_dataset), tmp_path / "x.nc")
    assert list(tmp_path.iterdir()) == []


# --- provenance ----------------------------------------------------------------------------------


def test_provenance_is_recorded(tmp_path, frf_dataset):
    path = to_netcdf(
        frf_dataset, tmp_path / "p.nc", function="ami_xr.simulate.frf", parameters={"J": 1}
    )
    back = open_dataset(path)
    (record,) = json.loads(back.attrs[names.ATTR_HISTORY])
    assert record["function"] == "ami_xr.simulate.frf"
    assert record["parameters"] == {"J": 1}
    assert record["ami_xr_version"] == ami_xr.__version__
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", record["time_utc"])
    assert back.attrs[names.ATTR_VERSION] == ami_xr.__version__
    assert back.attrs[names.ATTR_SOURCE_FILE] == str(path)
    # writing what was read records where it came from and keeps the older record
    path2 = to_netcdf(back, tmp_path / "q.nc")
    again = open_dataset(path2)
    first, second = json.loads(again.attrs[names.ATTR_HISTORY])
    assert first == record
    assert second["function"] == "ami_xr.to_netcdf"
    assert second["source_file"] == path.name  # a file name, never a machine path
    assert again.attrs[names.ATTR_SOURCE_FILE] == str(path2)


def test_add_history_values_and_unreadable_history():
    ds = xr.Dataset(attrs={names.ATTR_HISTORY: "not json"})
    assert provenance.history(ds) == []
    out = provenance.add_history(
        ds, "f", {"z": 1 + 2j, "a": np.arange(2), "n": np.float32(0.5), "o": object}
    )
    assert ds.attrs == {names.ATTR_HISTORY: "not json"}  # input untouched
    (record,) = provenance.history(out)
    assert record["parameters"] == {"z": [1.0, 2.0], "a": [0, 1], "n": 0.5, "o": repr(object)}
    assert out.attrs[provenance.ATTR_FUNCTION] == "f"
    assert names.ATTR_SOURCE_FILE not in out.attrs


def test_to_netcdf_does_not_mutate_input(tmp_path, frf_dataset):
    before = frf_dataset.copy(deep=True)
    to_netcdf(frf_dataset, tmp_path / "x.nc")
    # input untouched: no arithmetic
    xr.testing.assert_identical(frf_dataset, before)


# --- atomic writes -------------------------------------------------------------------------------


def _write_old(tmp_path, frf_dataset):
    path = to_netcdf(frf_dataset, tmp_path / "data.nc")
    return path, path.read_bytes()


def test_failed_write_leaves_old_file_and_no_temp_file(tmp_path, frf_dataset, monkeypatch):
    path, old = _write_old(tmp_path, frf_dataset)
    real_to_netcdf = xr.Dataset.to_netcdf

    def half_write_then_fail(self, target, *args, **kwargs):
        real_to_netcdf(self, target, *args, **kwargs)  # a complete temp file ...
        with open(target, "r+b") as f:  # ... damaged, as by a crash mid-write
            f.truncate(100)
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", half_write_then_fail)
    with pytest.raises(RuntimeError, match="disk on fire"):
        to_netcdf(frf_dataset * 2, path)
    assert path.read_bytes() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.nc"]


def test_error_while_computing_lazy_data_leaves_old_file(tmp_path, frf_dataset):
    path, old = _write_old(tmp_path, frf_dataset)

    def fail_on_last_block(block, block_info=None):
        if block_info[0]["chunk-location"][-1] == 3:
            raise ZeroDivisionError("block 3 cannot be computed")
        return block

    lazy = frf_dataset.chunk({names.FREQUENCY: 50})
    lazy["frf"] = lazy.frf.copy(
        data=lazy.frf.data.map_blocks(fail_on_last_block, dtype=np.complex128)
    )
    for _ in range(5):  # worker threads may still run after the error: repeat to catch races
        with pytest.raises(ZeroDivisionError, match="block 3"):
            to_netcdf(lazy, path)
        assert path.read_bytes() == old
        assert sorted(p.name for p in tmp_path.iterdir()) == ["data.nc"]


def test_write_into_missing_folder_or_onto_folder(tmp_path, frf_dataset):
    with pytest.raises(DataFileError, match=r"folder .*nowhere does not exist"):
        to_netcdf(frf_dataset, tmp_path / "nowhere" / "x.nc")
    with pytest.raises(DataFileError, match=r"is a folder"):
        to_netcdf(frf_dataset, tmp_path)


def test_overwrite_the_file_a_lazy_dataset_was_opened_from(tmp_path):
    rng = np.random.default_rng(2)
    ds = ami_xr.make_time_dataset(rng.standard_normal((3, 4000)), fs=1000.0, drive_point=0)
    ds["z"] = ds.response * (1 - 2j)
    path = to_netcdf(ds, tmp_path / "rec.nc")
    lazy = open_dataset(path, chunks={names.TIME: 512})
    assert isinstance(lazy["z"].data, dask.array.Array)
    doubled = lazy * 2  # still lazy: reads the file while the new one is written
    to_netcdf(doubled, path)
    back = open_dataset(path)
    # doubling is exact in binary floating point and the file stores float64: bit-identical
    np.testing.assert_array_equal(back.response.values, 2 * ds.response.values)
    np.testing.assert_array_equal(back.z.values, 2 * ds.z.values)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.nc"]
    # also the plain case: write a lazily opened Dataset unchanged onto itself
    lazy = open_dataset(path, lazy=True)
    to_netcdf(lazy, path)
    xr.testing.assert_identical(_strip_provenance(open_dataset(path)), _strip_provenance(back))


def test_overwrite_the_file_an_eager_dataset_was_opened_from(tmp_path, frf_dataset):
    path = to_netcdf(frf_dataset, tmp_path / "frf.nc")
    eager = open_dataset(path)
    to_netcdf(eager.assign(frf=eager.frf * 3), path)
    # the same single multiplication of the same values on both sides, stored losslessly: bit-
    # identical
    np.testing.assert_array_equal(open_dataset(path).frf.values, 3 * frf_dataset.frf.values)


# --- bad files -----------------------------------------------------------------------------------


def test_missing_file(tmp_path):
    missing = tmp_path / "nope.nc"
    with pytest.raises(DataFileError, match=re.escape(f"{missing}: no such file")):
        open_dataset(missing)
    with pytest.raises(DataFileError, match="not a file"):
        open_dataset(tmp_path)


def test_not_a_netcdf_file(tmp_path):
    text = tmp_path / "notes.nc"
    text.write_text("this is not netCDF\n")
    with pytest.raises(DataFileError, match=re.escape(str(text)) + ".*not netCDF"):
        open_dataset(text)
    empty = tmp_path / "empty.nc"
    empty.write_bytes(b"")
    with pytest.raises(DataFileError, match=re.escape(str(empty))):
        open_dataset(empty)


@pytest.mark.parametrize("keep", [0.5, 0.9])
@pytest.mark.parametrize("lazy", [False, True])
def test_truncated_file(tmp_path, frf_dataset, keep, lazy):
    path = to_netcdf(frf_dataset, tmp_path / "frf.nc")
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(DataFileError, match=re.escape(str(path)) + ".*truncated"):
        open_dataset(path, lazy=lazy)


@pytest.mark.parametrize("fmt", ["NETCDF4", "NETCDF4_CLASSIC", "NETCDF3_64BIT"])
def test_opens_files_not_written_by_ami_xr(tmp_path, fmt):
    ds = xr.Dataset({"y": (("t",), np.arange(4.0))}, coords={"t": np.arange(4)}, attrs={"a": 1})
    path = tmp_path / "plain.nc"
    ds.to_netcdf(path, format=fmt, engine="netcdf4")
    back = open_dataset(path)
    # a file round trip: no arithmetic
    np.testing.assert_array_equal(back.y.values, ds.y.values)
    assert back.attrs["a"] == 1 and back.attrs[names.ATTR_SOURCE_FILE] == str(path)


def test_rewriting_a_plainly_opened_file_points_to_open_dataset(tmp_path, frf_dataset):
    raw = xr.open_dataset(to_netcdf(frf_dataset.assign_attrs(flag=True), tmp_path / "frf.nc"))
    with pytest.raises(AmiXrValueError, match=r"reserved .*ami_xr.open_dataset"):
        to_netcdf(raw, tmp_path / "again.nc")
    raw_attrs = raw.drop_dims(names.COMPLEX)
    with pytest.raises(AmiXrValueError, match=r"reserved .*use ami_xr.open_dataset"):
        to_netcdf(raw_attrs, tmp_path / "again.nc")
    raw.close()


def test_wrongly_flagged_complex_variable_is_a_data_file_error(tmp_path):
    path = tmp_path / "odd.nc"
    xr.Dataset({"z": (("a",), [1.0, 2.0, 3.0], {netcdf.ATTR_COMPLEX: "x"})}).to_netcdf(path)
    with pytest.raises(DataFileError, match=r"variable 'z' is flagged 'ami_xr_complex'"):
        open_dataset(path)


# --- lazy opening --------------------------------------------------------------------------------


@pytest.fixture
def long_record(tmp_path):
    rng = np.random.default_rng(3)
    ds = ami_xr.make_time_dataset(
        rng.standard_normal((2, 2**14)), fs=2**10, force=rng.standard_normal(2**14), drive_point=1
    )
    ds["spectrum"] = ds.response * (1 + 1j)
    return ds, to_netcdf(ds, tmp_path / "long.nc")


def test_chunks_open_lazily_without_reading(long_record):
    ds, path = long_record
    with dask.config.set(scheduler=forbid_compute):
        lazy = open_dataset(path, chunks={names.TIME: 2**12})
        for name in (names.RESPONSE, names.FORCE, "spectrum"):
            assert isinstance(lazy[name].data, dask.array.Array), name
        assert lazy["spectrum"].dtype == np.complex128
        assert lazy["spectrum"].data.chunks[-1] == (2**12,) * 4
    # the uniform time axis comes back as an O(1)-memory RangeIndex; as a pandas index it is
    # the stored one, bit for bit
    assert isinstance(lazy.xindexes[names.TIME], xr.indexes.RangeIndex)
    assert_round_trip(ds, lazy.compute().drop_indexes(names.TIME).set_xindex(names.TIME))


def test_lazy_rule(long_record, monkeypatch):
    _, path = long_record
    assert isinstance(open_dataset(path).response.data, np.ndarray)  # small file: eager
    assert isinstance(open_dataset(path, lazy=True).response.data, dask.array.Array)
    monkeypatch.setattr(netcdf, "LAZY_THRESHOLD_BYTES", 1000)
    assert isinstance(open_dataset(path).response.data, dask.array.Array)  # large file: lazy
    assert isinstance(open_dataset(path, lazy=False).response.data, np.ndarray)
    with pytest.raises(AmiXrValueError, match=r"chunks: given .* but lazy=False"):
        open_dataset(path, chunks={names.TIME: 10}, lazy=False)


def test_lazy_write_stays_lazy_until_written(tmp_path, long_record):
    ds, path = long_record
    lazy = open_dataset(path, chunks={names.TIME: 2**12})
    encoded = netcdf.encode(lazy)
    assert isinstance(encoded["spectrum"].data, dask.array.Array)
    assert encoded["spectrum"].dims == (names.POINT, names.TIME, names.COMPLEX)
    out = to_netcdf(lazy, tmp_path / "copy.nc")
    assert_round_trip(ds, _strip_provenance(open_dataset(out)))


# --- property test: random Datasets survive the round trip ---------------------------------------

_NAME = st.text(string.ascii_lowercase, min_size=1, max_size=6).map(lambda s: "x" + s)
_TEXT = st.text(
    st.characters(blacklist_characters="\x00", blacklist_categories=("Cs",)), max_size=8
)
_FLOAT = st.floats(allow_nan=True, allow_infinity=True)
_INT64 = st.integers(-(2**63), 2**63 - 1)
_COMPLEX = st.complex_numbers(allow_nan=True, allow_infinity=True)

_ATTR_VALUE = st.one_of(
    _TEXT,
    _INT64,
    _FLOAT,
    st.booleans(),
    _COMPLEX,
    st.none(),
    st.lists(_FLOAT, max_size=4),
    st.lists(st.integers(-1000, 1000), max_size=4),
    st.lists(_TEXT, min_size=1, max_size=3),
    st.lists(st.booleans(), min_size=1, max_size=3),
    st.lists(_COMPLEX, min_size=1, max_size=3),
    st.dictionaries(_NAME, st.one_of(_TEXT, st.integers(-5, 5)), max_size=3),
)
_ATTRS = st.dictionaries(_NAME, _ATTR_VALUE, max_size=5)


def _complex_array(shape):
    return hnp.arrays(np.float64, shape + (2,), elements=_FLOAT).map(
        lambda pairs: np.ascontiguousarray(pairs).view(np.complex128)[..., 0]
    )


@st.composite
def random_datasets(draw):
    n_point = draw(st.integers(1, 4))
    n_freq = draw(st.integers(1, 6))
    if draw(st.booleans()):
        points = np.array(draw(st.lists(_INT64, min_size=n_point, max_size=n_point, unique=True)))
    else:
        points = np.array(draw(st.lists(_TEXT, min_size=n_point, max_size=n_point, unique=True)))
    frequency = np.sort(
        np.array(
            draw(
                st.lists(
                    st.floats(0, 1e6, allow_nan=False),
                    min_size=n_freq,
                    max_size=n_freq,
                    unique=True,
                )
            )
        )
    )
    shape = (n_point, n_freq)
    data_vars = {
        names.FRF: ((names.POINT, names.FREQUENCY), draw(_complex_array(shape)), draw(_ATTRS)),
        "real_part": (
            (names.POINT, names.FREQUENCY),
            draw(hnp.arrays(np.float64, shape, elements=_FLOAT)),
            draw(_ATTRS),
        ),
        "counts": ((names.POINT,), draw(hnp.arrays(np.int32, (n_point,))), draw(_ATTRS)),
        "mask": ((names.FREQUENCY,), draw(hnp.arrays(np.bool_, (n_freq,))), draw(_ATTRS)),
        "label": (
            (names.POINT,),
            np.array(draw(st.lists(_TEXT, min_size=n_point, max_size=n_point))),
        ),
        "scalar": ((), draw(_COMPLEX)),
    }
    if draw(st.booleans()):
        single = draw(hnp.arrays(np.float32, (n_freq, 2), elements=st.floats(width=32)))
        data_vars["single"] = (
            (names.FREQUENCY,),
            np.ascontiguousarray(single).view(np.complex64)[:, 0],
        )
    coords = {
        names.POINT: points,
        names.FREQUENCY: (names.FREQUENCY, frequency, {names.ATTR_UNITS: "Hz"}),
        "pole": ((names.POINT,), draw(_complex_array((n_point,)))),
    }
    return xr.Dataset(data_vars, coords=coords, attrs=draw(_ATTRS))


@settings(
    max_examples=50,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(ds=random_datasets())
def test_random_datasets_round_trip(tmp_path, ds):
    path = to_netcdf(ds, tmp_path / "random.nc")
    assert_round_trip(ds, open_dataset(path))
    assert_round_trip(ds, open_dataset(path, chunks={names.FREQUENCY: 2}).compute())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["random.nc"]


def test_failing_lazy_write_never_leaves_workers_writing_to_a_closed_file(tmp_path, frf_dataset):
    # dask's threaded scheduler re-raises the first failing chunk while other threads still write;
    # closing the file under them broke HDF5's state (the next open failed with "Not a valid ID")
    # or crashed the process on netCDF4 1.6.5 within ~50 tries. to_netcdf drains its pool first.
    path, old = _write_old(tmp_path, frf_dataset)

    def fail_on_block_3(block, block_info=None):
        if block_info[0]["chunk-location"][-1] == 3:
            raise ZeroDivisionError("block 3 cannot be computed")
        return block

    lazy = frf_dataset.chunk({names.FREQUENCY: 25})
    lazy["frf"] = lazy.frf.copy(data=lazy.frf.data.map_blocks(fail_on_block_3, dtype=np.complex128))
    for _ in range(100):
        with pytest.raises(ZeroDivisionError, match="block 3"):
            to_netcdf(lazy, path)
    assert path.read_bytes() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.nc"]
    # the library is still sound: a normal write and read work
    to_netcdf(frf_dataset, tmp_path / "after.nc")
    xr.testing.assert_identical(
        ami_xr.open_dataset(tmp_path / "after.nc")[names.FRF], frf_dataset[names.FRF]
    )


def test_corrupt_attribute_is_a_data_file_error_naming_the_file(tmp_path, frf_dataset, monkeypatch):
    # A flipped byte in an attribute makes netCDF4's ncattrs raise AttributeError ("NetCDF:
    # Can't open HDF5 attribute", found by scripts/fault_campaign.py): it must name the file.
    path = to_netcdf(frf_dataset, tmp_path / "frf.nc")

    def corrupt(*args, **kwargs):
        raise AttributeError("NetCDF: Can't open HDF5 attribute")

    monkeypatch.setattr(xr, "open_dataset", corrupt)
    with pytest.raises(DataFileError, match=r"frf\.nc: cannot read it as a netCDF file"):
        open_dataset(path)
