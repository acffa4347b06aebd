"""Files a colleague can read: no machine paths, CF metadata (issue 12, item 4)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names, provenance
from ami_xr.io.netcdf import open_dataset, to_netcdf


def _no_folder_in(path, folder) -> None:
    data = path.read_bytes()
    for text in {str(folder), str(folder.resolve())}:
        assert text.encode() not in data, f"{path.name} holds the machine path {text}"


def test_written_files_hold_file_names_not_machine_paths(tmp_path, frf_dataset):
    first = to_netcdf(frf_dataset, tmp_path / "p.nc", parameters={"input": str(tmp_path / "a")})
    back = open_dataset(first)
    assert back.attrs[names.ATTR_SOURCE_FILE] == str(first)  # in memory: where it was read
    second = to_netcdf(back, tmp_path / "q.nc", function="ami_xr.app.cli.convert")
    for path in (first, second):
        _no_folder_in(path, tmp_path)
    again = open_dataset(second)
    records = provenance.history(again)
    assert records[0]["parameters"] == {"input": "a"}
    assert records[1][names.ATTR_SOURCE_FILE] == "p.nc"
    with xr.open_dataset(second, engine="netcdf4") as raw:
        assert raw.attrs[names.ATTR_SOURCE_FILE] == "p.nc"


def test_add_history_stores_the_file_name():
    out = provenance.add_history(xr.Dataset(), "f", {"n": 1}, source_file="/some/dir/run1.lvm")
    assert out.attrs[names.ATTR_SOURCE_FILE] == "run1.lvm"
    (record,) = json.loads(out.attrs[names.ATTR_HISTORY])
    assert record[names.ATTR_SOURCE_FILE] == "run1.lvm"
    assert provenance.file_name("relative/x.nc") == "x.nc"


def test_lvm_and_uff_readers_write_no_machine_path(tmp_path, frf_dataset):
    pytest.importorskip("pyuff")
    from ami_xr.io.uff import read_uff, write_uff

    uff = tmp_path / "g.uff"
    write_uff(frf_dataset, uff)
    ds = read_uff(uff)
    assert ds.attrs[names.ATTR_SOURCE_FILE] == "g.uff"
    out = to_netcdf(ds, tmp_path / "g.nc")
    _no_folder_in(out, tmp_path)
    assert np.array_equal(open_dataset(out).frf.values, ds.frf.values)


def _fixture_frfs():
    """The test fixture's three-mode FRFs with a little noise (points 1, 2, 3; drive point 1)."""
    from ..conftest import _frf_fixture_modes
    from ..reference import frf_from_residues

    lam, residue = _frf_fixture_modes()
    frequency = np.linspace(0.5, 50.0, 200)
    frf = frf_from_residues(2 * np.pi * frequency, lam, residue)
    rng = np.random.default_rng(0)
    frf = frf + 1e-4 * np.abs(frf).max() * (rng.standard_normal(frf.shape) + 0j)
    return ami_xr.make_frf_dataset(frf, frequency, points=[1, 2, 3], drive_point=1)


@pytest.fixture(scope="module")
def identified():
    """Identified modes (with refinement) of the fixture's FRFs, and the same without a drive
    point (mode vectors then unscaled)."""
    ds = _fixture_frfs()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scaled = ami_xr.identify(ds)
        unscaled = ami_xr.identify(_without_drive(ds))
    return scaled, unscaled


def _without_drive(ds):
    out = ds.copy()
    out.attrs = {k: v for k, v in ds.attrs.items() if k != names.ATTR_DRIVE_POINT}
    return out


def test_refined_residue_and_mode_vector_carry_units(identified):
    scaled, unscaled = identified
    frf_units = scaled[names.FRF].attrs[names.ATTR_UNITS]
    assert scaled[names.RESIDUE].attrs[names.ATTR_UNITS] == f"{frf_units} rad/s"
    assert scaled[names.MODE_VECTOR].attrs[names.ATTR_UNITS] == f"sqrt({frf_units})"
    assert scaled[names.RESIDUE_STD].attrs[names.ATTR_UNITS] == f"{frf_units} rad/s"
    assert scaled[names.MODE_VECTOR_STD].attrs[names.ATTR_UNITS] == f"sqrt({frf_units})"
    assert scaled[names.MAC].attrs[names.ATTR_UNITS] == "1"
    assert unscaled[names.MODE_VECTOR].attrs[names.ATTR_UNITS] == "1"  # unit largest entry


def test_written_files_carry_cf_metadata(tmp_path, identified):
    from ami_xr.io import cf

    path = to_netcdf(identified[0], tmp_path / "m.nc", function="ami_xr.identify")
    frf_units = identified[0][names.FRF].attrs["units"]
    with xr.open_dataset(path, engine="netcdf4") as raw:
        assert raw.attrs["Conventions"] == "CF-1.11"
        assert raw.attrs["title"].startswith("Modal parameters identified by the Algorithm")
        assert raw.attrs["source"] == f"ami_xr {ami_xr.__version__}"
        assert "Mode Isolation" in raw.attrs["references"]
        lines = raw.attrs["history"].splitlines()
        assert len(lines) == len(json.loads(raw.attrs[names.ATTR_HISTORY]))
        assert lines[-1].endswith(f"ami_xr.identify (ami_xr {ami_xr.__version__})")
        assert lines[-1][:20].endswith("Z")  # UTC
        for name, var in raw.variables.items():
            assert var.attrs.get("long_name"), f"{name} has no long_name"
            numeric = var.dtype.kind in "iuf" and var.attrs.get("dtype") != "bool"
            if name == names.RESIDUAL_COEFFICIENT:  # two units along residual_term
                assert var.attrs["units_lower"] == f"{frf_units} (rad/s)^2"
                assert var.attrs["units_upper"] == frf_units
            elif name in (names.MODE_VECTOR, names.MODE_VECTOR_STD, "ami_mode_vector"):
                assert "units" not in var.attrs and var.attrs["units_of_square"] == frf_units
            elif numeric and "flag_masks" not in var.attrs:
                assert var.attrs.get("units"), f"{name} has no units"
        # sorted integer points stay a coordinate; string labels become a CF label variable
        assert raw[names.POINT].dims == (names.POINT,)
        assert names.RESIDUAL_TERM not in raw.variables
        assert raw.residual_term_label.dims == (names.RESIDUAL_TERM,)
        mask = raw[names.QUALITY_FLAGS]  # the bit field itself, with its CF table
        assert cf.QUALITY_FLAG_MASK not in raw.variables
        meanings = mask.attrs["flag_meanings"].split()
        assert list(mask.attrs["flag_masks"]) == [1 << k for k in range(len(meanings))]
        np.testing.assert_array_equal(mask.values, identified[0][names.QUALITY_FLAGS].values)


def test_flag_mask_and_conventions_merge():
    from ami_xr.io import cf

    flags = np.array(["", f"{names.FLAG_SINGLE_FRF},{names.FLAG_LOW_DRIVE_SNR}", "unknown"])
    assert cf.flag_mask(flags).tolist() == [0, 1 | 8, 0]
    ds = xr.Dataset({"v": ("x", [1.0])}, attrs={"Conventions": "CF-1.6, ACDD-1.3"})
    out = cf.annotate(ds)
    assert out.attrs["Conventions"] == "CF-1.11 ACDD-1.3"
    assert out.v.attrs == {"long_name": "v"} and ds.v.attrs == {}  # input untouched


def test_cf_history_one_line_per_step_after_foreign_history():
    from ami_xr.io import cf

    ds = provenance.add_history(xr.Dataset(attrs={"history": "made by hand"}), "ami_xr.f")
    ds = provenance.add_history(ds, "ami_xr.g")
    assert ds.attrs["history"] == "made by hand"  # in memory: untouched
    first, second, third = cf.annotate(ds).attrs["history"].splitlines()
    assert first == "made by hand"
    assert " ami_xr.f (ami_xr " in second and " ami_xr.g (ami_xr " in third


def test_cf_metadata_is_an_on_disk_encoding(tmp_path, identified):
    """open_dataset removes exactly what to_netcdf added: read back == written, and nothing
    accumulates over read/write cycles."""
    from ami_xr.io import cf

    ds = identified[0].copy()
    ds.attrs["history"] = "made by hand"
    ds[names.FREQUENCY].attrs["long_name"] = "my frequency"
    first = open_dataset(to_netcdf(ds, tmp_path / "a.nc"))
    second = open_dataset(to_netcdf(first, tmp_path / "b.nc"))
    for back in (first, second):
        assert cf.QUALITY_FLAG_MASK not in back and cf.ATTR_CF_ADDED not in back.attrs
        assert back.attrs["history"] == "made by hand" and "Conventions" not in back.attrs
        assert not {"title", "source", "references"} & set(back.attrs)
        assert back[names.FREQUENCY].attrs["long_name"] == "my frequency"
        assert "long_name" not in back[names.POINT].attrs
        for name, var in ds.variables.items():
            assert back.variables[name].attrs == var.attrs, name
    with xr.open_dataset(tmp_path / "b.nc", engine="netcdf4") as raw:
        assert raw.attrs["history"].splitlines()[0] == "made by hand"
        assert len(raw.attrs["history"].splitlines()) == 1 + len(provenance.history(second))


def test_complex_layout_reads_with_netcdf4_auto_complex(tmp_path, frf_dataset):
    netCDF4 = pytest.importorskip("netCDF4")
    if tuple(int(p) for p in netCDF4.__version__.split(".")[:2]) < (1, 7):
        pytest.skip("auto_complex needs netCDF4 >= 1.7")
    path = to_netcdf(frf_dataset, tmp_path / "c.nc")
    with netCDF4.Dataset(path, auto_complex=True) as nc:
        values = nc[names.FRF][:]
    assert values.dtype == np.complex128
    np.testing.assert_array_equal(values, frf_dataset[names.FRF].values)
    with xr.open_dataset(path, engine="netcdf4", auto_complex=True) as raw:
        np.testing.assert_array_equal(raw[names.FRF].values, frf_dataset[names.FRF].values)


def test_mode_vector_units_on_disk_are_the_units_of_the_square(tmp_path):
    """UDUNITS has integer powers only ("m0.5" is read as 0.25): sqrt(X) units are stored as
    units_of_square = X on disk and come back as units = sqrt(X)."""
    from ami_xr.io import cf

    ds = xr.Dataset(
        {
            names.MODE_VECTOR: ((names.POINT, names.MODE), np.ones((2, 1)), {"units": "sqrt(m/N)"}),
            "kept": ("x", [1.0], {"units": "sqrt(m/N)", cf.ATTR_UNITS_OF_SQUARE: "own"}),
        },
        coords={names.POINT: ["a", "b"], names.MODE: [1]},
    )
    encoded = cf.annotate(ds)
    attrs = encoded[names.MODE_VECTOR].attrs
    assert "units" not in attrs and attrs[cf.ATTR_UNITS_OF_SQUARE] == "m/N"
    assert encoded["kept"].attrs["units"] == "sqrt(m/N)"  # the user's own attribute wins
    assert ds[names.MODE_VECTOR].attrs == {"units": "sqrt(m/N)"}  # input untouched
    back = open_dataset(to_netcdf(ds, tmp_path / "u.nc"))
    xr.testing.assert_identical(back.drop_attrs(deep=False), ds)
    assert back[names.MODE_VECTOR].attrs == {"units": "sqrt(m/N)"}


@pytest.mark.parametrize(
    "labels",
    [["b", "a", "c"], [3, 1, 2], [1, 1, 2], [True, False, True], ["only"], [1, 2, 3]],
)
def test_dim_coordinates_cf_cannot_hold_are_label_variables_on_disk(tmp_path, labels):
    """CF 1.3: a coordinate variable is numeric and strictly monotonic. Others are stored as the
    label variable <dim>_label and come back as the dim coordinate."""
    from ami_xr.io import cf

    ds = xr.Dataset(
        {"v": ((names.POINT, "r"), np.arange(2.0 * len(labels)).reshape(-1, 2))},
        coords={names.POINT: labels, "r": ["lower", "upper"]},
    )
    path = to_netcdf(ds, tmp_path / "l.nc")
    numeric = np.asarray(labels).dtype.kind in "iuf"
    cf_coordinate = bool(numeric and (len(labels) < 2 or np.all(np.diff(labels) > 0)))
    with xr.open_dataset(path, engine="netcdf4") as raw:
        assert ("point_label" in raw.variables) is not cf_coordinate
        assert (names.POINT in raw.variables) is cf_coordinate
        assert "r_label" in raw.variables and "r" not in raw.variables
        assert "r_label" in raw.v.encoding["coordinates"].split()  # CF coordinates attribute
    back = open_dataset(path)
    xr.testing.assert_identical(back.drop_attrs(deep=False), ds)
    assert set(back.indexes) == set(ds.indexes)
    assert cf.LABEL_SUFFIX == "_label"


def test_a_taken_label_name_and_float_axes_keep_the_coordinate():
    from ami_xr.io import cf

    ds = xr.Dataset(coords={names.POINT: ["a", "b"], "point_label": ("x", [1, 2])})
    out = cf.annotate(ds)
    assert out[names.POINT].values.tolist() == ["a", "b"]  # point_label taken: left alone
    axis = xr.Dataset(coords={names.TIME: [0.0, 1.0, np.nan]})  # a float axis is data
    assert cf.ELAPSED_TIME in cf.annotate(axis).indexes  # renamed (no date), not a label


# --- history lists only the calls the user made (issue 23) -------------------------------------


def _functions(ds) -> list[str]:
    return [r["function"] for r in provenance.history(ds)]


def test_history_of_cli_frf_on_an_lvm_file_lists_only_the_users_calls(tmp_path):
    """``ami-xr frf hits.lvm``: one record, the command's, with the read and the impact FRF as
    its steps; no ``ami_xr.frf`` (never called) and nothing else."""
    from ami_xr.app.cli import main

    from .test_lvm import _write
    from .test_lvm_assumptions import hit_rows

    lvm = _write(tmp_path / "hits.lvm", [hit_rows(p) for p in (100.0, 110.0, 95.0)])
    out = tmp_path / "h.nc"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the drive point the reader assumes
        assert (
            main(["frf", str(lvm), "-o", str(out), "--drive-point", "Acceleration (Trigger)"]) == 0
        )
    records = provenance.history(open_dataset(out))
    assert [r["function"] for r in records] == ["ami-xr frf"]
    steps = records[0]["steps"]
    assert [s["function"] for s in steps] == ["ami_xr.read_lvm", "ami_xr.impact_frf"]
    assert steps[0]["source_file"] == "hits.lvm" and steps[1]["parameters"]["n_records_used"] == 3
    assert records[-1]["parameters"]["excitation"] == "impact"
    assert "step_of" not in json.dumps(records)  # every step was gathered
    with xr.open_dataset(out, engine="netcdf4") as raw:
        assert raw.attrs["history"].splitlines()[-1].split()[1:3] == ["ami-xr", "frf"]


def test_identify_records_itself_not_its_phases(identified, tmp_path):
    """identify runs subtract, isolate, global_fit and refine; only identify is recorded; through
    the CLI the command is, with identify (and the write) as its steps."""
    from ami_xr.app.cli import main

    src = _functions(identified[0])
    assert src[-1] == "ami_xr.identify"
    assert not {"ami_xr.subtract", "ami_xr.isolate", "ami_xr.global_fit", "ami_xr.refine"} & set(
        src
    )
    frfs = to_netcdf(_fixture_frfs(), tmp_path / "g.nc")
    before = _functions(open_dataset(frfs))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["identify", str(frfs), "-o", str(tmp_path / "m.nc"), "-q"]) == 0
    after = _functions(open_dataset(tmp_path / "m.nc"))
    assert after == [*before, "ami-xr identify"]
    last = provenance.history(open_dataset(tmp_path / "m.nc"))[-1]
    assert [s["function"] for s in last["steps"]] == ["ami_xr.identify"]
    assert last["parameters"]["input"] == "g.nc"


def test_simulated_identify_history_and_direct_phase_calls():
    """On the simulator: identify adds one record; the phases called by the user record each."""
    g, _ = ami_xr.simulate.random_system(n_points=5, seed=1, noise=0.0)
    before = _functions(g)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        modes = ami_xr.identify(g, refine=False)
        sub = ami_xr.subtract(g, 0.05)
    assert _functions(modes) == [*before, "ami_xr.identify"]
    assert _functions(sub) == [*before, "ami_xr.subtract"]


def test_nested_calls_and_public_call_record_only_the_outermost():
    @provenance.public_call
    def inner(ds):
        return provenance.add_history(ds, "inner")

    @provenance.public_call
    def outer(ds):
        ds = inner(ds)
        with provenance.nested_calls():
            ds = provenance.add_history(ds, "undecorated")
        return provenance.add_history(ds, "outer")

    ds = xr.Dataset(attrs={"keep": 1})
    assert _functions(inner(ds)) == ["inner"]
    assert _functions(outer(ds)) == ["outer"]
    with provenance.nested_calls():
        assert not provenance.recording()
        quiet = outer(ds)
    assert quiet.attrs == ds.attrs and quiet is not ds
    assert provenance.recording()


# --- time histories: an epoch-less time axis is elapsed_time on disk (issue 23) -----------------


def test_elapsed_time_axis_on_disk_and_back(tmp_path):
    from ami_xr.io import cf

    ts, _, _ = ami_xr.simulate.benchmark(noise=0.0, n_samples=64)
    path = to_netcdf(ts, tmp_path / "ts.nc")
    with xr.open_dataset(path, engine="netcdf4") as raw:
        assert names.TIME not in raw.dims and names.TIME not in raw.variables
        axis = raw[cf.ELAPSED_TIME]
        assert raw[names.RESPONSE].dims[-1] == cf.ELAPSED_TIME
        assert axis.attrs["units"] == "s" and "standard_name" not in axis.attrs
        assert axis.attrs["long_name"] == "time since the start of the record"
        assert cf.on_disk_name(raw.attrs[cf.ATTR_CF_ADDED], names.TIME) == cf.ELAPSED_TIME
    back = open_dataset(path)
    xr.testing.assert_identical(back.drop_attrs(deep=False), ts.drop_attrs(deep=False))
    lazy = open_dataset(path, chunks={names.TIME: 16})  # chunks by the in-memory name
    assert lazy[names.RESPONSE].chunks[-1][0] == 16
    assert isinstance(lazy.xindexes[names.TIME], xr.indexes.RangeIndex)
    np.testing.assert_allclose(lazy[names.TIME].values, ts[names.TIME].values, rtol=1e-12)
    assert cf.on_disk_name(None, names.TIME) == names.TIME  # files of other tools


def test_dated_time_and_a_taken_name_keep_time_on_disk(tmp_path):
    from ami_xr.io import cf

    t = np.datetime64("2019-03-11T08:42:44", "ns") + np.arange(4) * np.timedelta64(1, "ms")
    dated = xr.Dataset({"v": ((names.TIME,), np.arange(4.0))}, coords={names.TIME: t})
    since = xr.Dataset(
        {"v": ((names.TIME,), np.arange(4.0))},
        coords={names.TIME: (names.TIME, np.arange(4.0), {"units": "s since 2019-03-11"})},
    )
    taken = xr.Dataset(
        {"v": ((names.TIME,), np.arange(4.0)), cf.ELAPSED_TIME: ((), 1.0)},
        coords={names.TIME: np.arange(4.0)},
    )
    for i, ds in enumerate((dated, since, taken)):
        assert names.TIME in cf.annotate(ds).dims
        back = open_dataset(to_netcdf(ds, tmp_path / f"{i}.nc"), lazy=False)
        assert names.TIME in back.dims
        np.testing.assert_array_equal(back["v"].values, ds["v"].values)


def test_command_gathers_the_records_made_inside_as_its_steps():
    ds = provenance.add_history(xr.Dataset(), "ami_xr.earlier")  # before the command: kept
    with provenance.command("ami-xr thing"):
        assert provenance.running_command() == "ami-xr thing"
        ds = provenance.add_history(ds, "ami_xr.read", source_file="/lab/run1.lvm")
        ds = provenance.add_history(ds, "ami_xr.estimate", {"n": 2})
        ds = provenance.add_history(ds, "ami-xr thing", {"input": "run1.lvm"})
    assert provenance.running_command() is None
    records = provenance.history(ds)
    assert [r["function"] for r in records] == ["ami_xr.earlier", "ami-xr thing"]
    assert records[1]["steps"] == [
        {"function": "ami_xr.read", "parameters": {}, "source_file": "run1.lvm"},
        {"function": "ami_xr.estimate", "parameters": {"n": 2}},
    ]
    assert "steps" not in records[0]
    # outside a command nothing is gathered and nothing is marked
    plain = provenance.add_history(provenance.add_history(xr.Dataset(), "a"), "b")
    assert provenance.history(plain)[1].keys() == provenance.history(plain)[0].keys()
