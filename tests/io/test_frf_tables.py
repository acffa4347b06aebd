"""Issue 29, "CSV and MATLAB input": FRF tables as text (.csv/.txt/.dat) and MATLAB (.mat) files.

The shipped sample FRFs are exported in each accepted layout and read back (values equal to the
precision of the format); ``ami-xr identify`` on the exports finds the modes it finds on the
netCDF file; bad files give one clear error naming the file and the column or variable, and
nothing is written.
"""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest
import scipy.io

import ami_xr
from ami_xr import names
from ami_xr.app.cli import EXIT_ERROR, EXIT_OK, main
from ami_xr.dsp.quantity import ATTR_QUANTITY_ASSUMED
from ami_xr.errors import AmiXrValueError, AssumptionWarning, DataFileError
from ami_xr.io.formats import read_any
from ami_xr.io.frf_tables.text import ATTR_COLUMNS_ASSUMED
from ami_xr.io.kinds import ModesFileError

from ..reference import REPO, SUBPROCESS_ENV

SAMPLE = REPO / "sample_data" / "benchmark_frf.nc"


@pytest.fixture(scope="module")
def sample():
    return ami_xr.open_dataset(SAMPLE).load()


def _quiet(read, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AssumptionWarning)
        return read(*args, **kwargs)


# --- writers of the accepted layouts (what a lab's export looks like) ------------------------
def write_csv(
    path,
    ds,
    *,
    layout="reim",
    sep=",",
    header=True,
    meta=True,
    labels=None,
    freq_name="freq [Hz]",
    unit=" [m/N]",
):
    """The FRFs of ``ds`` as a text table; numbers with repr (exact float64)."""
    labels = list(ds[names.POINT].values) if labels is None else labels
    frf = ds[names.FRF].values
    columns, titles = [ds[names.FREQUENCY].values], [freq_name]
    for label, h in zip(labels, frf, strict=True):
        if layout == "reim":
            columns += [h.real, h.imag]
            titles += [f"{label}_re{unit}", f"{label}_im{unit}"]
        else:
            columns += [np.abs(h), np.degrees(np.angle(h))]
            titles += [f"{label} mag", f"{label} phase"]
    lines = []
    if meta:
        lines += [f"# drive_point: {ds.attrs[names.ATTR_DRIVE_POINT]}", "# exported for a test"]
    if header:
        lines.append(sep.join(titles))
    lines += [sep.join(repr(float(v)) for v in row) for row in np.array(columns).T]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_mat(path, ds, *, lines_by_points=True, struct=None, **extra):
    variables = {
        "freq": ds[names.FREQUENCY].values,
        "H": ds[names.FRF].values.T if lines_by_points else ds[names.FRF].values,
        "points": np.array(list(ds[names.POINT].values), dtype=object),
        "drive_point": str(ds.attrs[names.ATTR_DRIVE_POINT]),
        "frf_units": "m/N",
        **extra,
    }
    scipy.io.savemat(path, {struct: variables} if struct else variables)
    return path


def write_v73(path, variables):
    """A MATLAB v7.3 file as MATLAB lays it out: HDF5 after a 512-byte header, arrays
    transposed, complex as (real, imag), text as UTF-16 codes, cells as references."""
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w", userblock_size=512) as f:
        refs = f.create_group("#refs#")

        def put(where, name, value):
            if isinstance(value, str):
                codes = np.array([[ord(c)] for c in value], dtype=np.uint16)
                d = where.create_dataset(name, data=codes)
                d.attrs["MATLAB_class"] = np.bytes_("char")
            elif isinstance(value, list):
                targets = []
                for k, item in enumerate(value):
                    put(refs, f"{name}_{k}", item)
                    targets.append(refs[f"{name}_{k}"].ref)
                d = where.create_dataset(name, data=np.array([targets]).T, dtype=h5py.ref_dtype)
                d.attrs["MATLAB_class"] = np.bytes_("cell")
            else:
                arr = np.atleast_2d(np.asarray(value)).T
                if np.iscomplexobj(arr):
                    pair = np.dtype([("real", "<f8"), ("imag", "<f8")])
                    packed = np.empty(arr.shape, dtype=pair)
                    packed["real"], packed["imag"] = arr.real, arr.imag
                    arr = packed
                d = where.create_dataset(name, data=arr)
                d.attrs["MATLAB_class"] = np.bytes_("double")

        for name, value in variables.items():
            put(f, name, value)
    with open(path, "r+b") as f:
        f.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116))
    return path


# --- round trips -------------------------------------------------------------------------------
def test_csv_real_imaginary_round_trip_is_exact(sample, tmp_path):
    path = write_csv(tmp_path / "frf.csv", sample)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)  # everything is said: nothing assumed
        ds = ami_xr.open_frf(path)
    np.testing.assert_array_equal(ds[names.FRF].values, sample[names.FRF].values)
    np.testing.assert_array_equal(ds[names.FREQUENCY].values, sample[names.FREQUENCY].values)
    assert ds[names.POINT].values.tolist() == sample[names.POINT].values.tolist()
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "tip"
    assert ds.attrs[names.ATTR_QUANTITY] == "displacement"
    assert ds[names.FRF].attrs["units"] == "m/N"
    assert ds.attrs[names.ATTR_SOURCE] == names.SOURCE_MEASURED
    assert ds.attrs[names.ATTR_SOURCE_FILE] == "frf.csv"
    ami_xr.validate(ds)


def test_magnitude_phase_in_degrees_with_integer_labels(sample, tmp_path):
    path = write_csv(
        tmp_path / "frf.csv",
        sample,
        layout="magphase",
        labels=[1, 2, 3, 4],
        meta=False,
        freq_name="frequency_hz",
    )
    assert path.read_text().splitlines()[0].startswith("frequency_hz,1 mag,1 phase,2 mag")
    with pytest.warns(AssumptionWarning, match=r"frf\.csv: no response quantity.*m/N assumed"):
        ds = ami_xr.open_frf(path, drive_point=1)
    assert ds[names.POINT].values.tolist() == [1, 2, 3, 4]
    assert ds.attrs[names.ATTR_DRIVE_POINT] == 1
    assert "m/N assumed" in ds.attrs[ATTR_QUANTITY_ASSUMED]
    # magnitude and phase in decimal text: equal to a few ulp of the magnitude
    scale = np.abs(sample[names.FRF].values).max()
    np.testing.assert_allclose(
        ds[names.FRF].values, sample[names.FRF].values, rtol=0, atol=8 * np.finfo(float).eps * scale
    )


@pytest.mark.parametrize(("suffix", "sep"), [(".txt", "\t"), (".dat", " "), (".csv", ";")])
def test_separators_and_suffixes(sample, tmp_path, suffix, sep):
    path = write_csv(tmp_path / f"frf{suffix}", sample, sep=sep, freq_name="f", unit="")
    ds = _quiet(ami_xr.open_frf, path, response_quantity="displacement")
    np.testing.assert_array_equal(ds[names.FRF].values, sample[names.FRF].values)
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "tip"


def test_quoted_names_and_comment_lines(tmp_path):
    path = tmp_path / "export.csv"
    path.write_text(
        "# Exported by a spectrum analyser\n# Response Quantity = acceleration\n"
        '"Frequency (Hz)","Point 1, Z re","Point 1, Z im"\n\n"1.0","2.5","-1"\n2,3,4\n'
        "# end of data\n"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)  # one FRF, drive point given
        ds = ami_xr.open_frf(path, drive_point="Point 1, Z")
    assert ds[names.POINT].values.tolist() == ["Point 1, Z"]
    assert ds.attrs[names.ATTR_QUANTITY] == "acceleration"
    np.testing.assert_array_equal(ds[names.FRF].values, [[2.5 - 1j, 3 + 4j]])


def test_headerless_pairs_are_read_and_the_layout_is_said(sample, tmp_path):
    path = write_csv(tmp_path / "frf.dat", sample, sep=" ", header=False, meta=False)
    with pytest.warns(AssumptionWarning) as seen:
        ds = ami_xr.open_frf(path)
    said = [str(w.message) for w in seen if issubclass(w.category, AssumptionWarning)]
    assert any("frf.dat: no header line" in s and "points 0 to 3" in s for s in said), said
    assert ds[names.POINT].values.tolist() == [0, 1, 2, 3]
    assert "real and imaginary" in ds.attrs[ATTR_COLUMNS_ASSUMED]
    np.testing.assert_array_equal(ds[names.FRF].values, sample[names.FRF].values)


def test_single_frf_assumes_its_point_is_the_drive_point(sample, tmp_path):
    one = sample.isel({names.POINT: [2]})
    path = write_csv(tmp_path / "one.csv", one, meta=False)
    with pytest.warns(AssumptionWarning, match=r"one\.csv: drive point assumed to be 'm2'"):
        ds = ami_xr.open_frf(path)
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "m2"
    assert "single FRF" in ds.attrs[names.ATTR_DRIVE_POINT_ASSUMED]


@pytest.mark.parametrize("lines_by_points", [True, False])
def test_mat_round_trip_is_exact_in_either_orientation(sample, tmp_path, lines_by_points):
    path = write_mat(tmp_path / "frf.mat", sample, lines_by_points=lines_by_points)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)
        ds = ami_xr.open_frf(path)
    np.testing.assert_array_equal(ds[names.FRF].values, sample[names.FRF].values)
    np.testing.assert_array_equal(ds[names.FREQUENCY].values, sample[names.FREQUENCY].values)
    assert ds[names.POINT].values.tolist() == ["tip", "m1", "m2", "m3"]
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "tip"
    assert ds[names.FRF].attrs["units"] == "m/N"


def test_mat_struct_and_numeric_labels(sample, tmp_path):
    path = write_mat(
        tmp_path / "frf.mat",
        sample,
        struct="test",
        points=np.array([11.0, 12, 13, 14]),
        drive_point=11.0,
    )
    ds = ami_xr.open_frf(path)
    assert ds[names.POINT].values.tolist() == [11, 12, 13, 14]
    assert ds.attrs[names.ATTR_DRIVE_POINT] == 11
    np.testing.assert_array_equal(ds[names.FRF].values, sample[names.FRF].values)


def test_mat_v73_through_h5py(sample, tmp_path):
    labels = [str(p) for p in sample[names.POINT].values]
    path = write_v73(
        tmp_path / "frf73.mat",
        {
            "frequency": sample[names.FREQUENCY].values,
            "frf": sample[names.FRF].values.T,
            "points": labels,
            "drive_point": "tip",
            "response_quantity": "displacement",
        },
    )
    ds = ami_xr.open_frf(path)
    np.testing.assert_array_equal(ds[names.FRF].values, sample[names.FRF].values)
    assert ds[names.POINT].values.tolist() == labels
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "tip"


def test_mat_v73_without_h5py_says_what_to_do(tmp_path, monkeypatch):
    path = tmp_path / "new.mat"
    path.write_bytes(b"MATLAB 7.3 MAT-file".ljust(512) + b"\x89HDF\r\n\x1a\n" + bytes(64))
    monkeypatch.setitem(sys.modules, "h5py", None)  # as if not installed
    with pytest.raises(DataFileError, match=r"new\.mat: a MATLAB v7\.3 .*needs h5py.*'-v7'"):
        ami_xr.open_frf(path)


def test_open_frf_reads_the_other_formats_and_refuses_what_is_not_frfs(sample, tmp_path):
    ds = ami_xr.open_frf(SAMPLE, drive_point="m1")
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "m1"
    with pytest.raises(AmiXrValueError, match=r"response_quantity: only for .*text tables"):
        ami_xr.open_frf(SAMPLE, response_quantity="velocity")
    modes = ami_xr.to_netcdf(ami_xr.simulate.benchmark()[2], tmp_path / "truth.nc")
    with pytest.raises(ModesFileError, match=r"truth\.nc: a modes file"):
        ami_xr.open_frf(modes)
    lvm = tmp_path / "x.lvm"
    lvm.write_text("LabVIEW Measurement\n")
    with pytest.raises(DataFileError, match=r"time histories"):
        ami_xr.open_frf(lvm)


def test_read_any_takes_tables_and_the_drive_point(sample, tmp_path):
    path = write_csv(tmp_path / "frf.csv", sample)
    assert read_any(path, drive_point="m3").attrs[names.ATTR_DRIVE_POINT] == "m3"
    labels = ["a", "b", "c", "d"]  # one reader interface: read_any passes every option
    assert list(read_any(path, points=labels, drive_point="c")[names.POINT].values) == labels
    with pytest.raises(AmiXrValueError, match=r"points: expected 4 labels"):
        read_any(path, points=["a"])
    with pytest.raises(AmiXrValueError, match=r"force_channel: not taken by read_frf_csv"):
        read_any(path, want="frf", force_channel=0)


# --- bad files -----------------------------------------------------------------------------
BAD_CSV = {
    "missing column": (
        "freq,p1_re,p1_im,p2_re\n1,1,2,3\n2,1,2,3\n",
        r"bad\.csv: point 'p2': no column for the imaginary part .*'p2_im'",
    ),
    "no frequency column": (
        "hz,p1_re,p1_im\n1,1,2\n2,1,2\n",
        r"bad\.csv: no frequency column; expected one column named frequency or freq or f",
    ),
    "non-numeric cell": (
        "freq,p1_re,p1_im\n1,1,2\n2,abc,2\n",
        r"bad\.csv: line 3, column 'p1_re': 'abc' is not a number",
    ),
    "decimal comma": (
        "freq;p1_re;p1_im\n1;1,5;2\n2;1;2\n",
        r"line 2, column 'p1_re': '1,5' is not a number \(a decimal comma\?",
    ),
    "empty cell": ("freq,p1_re,p1_im\n1,1,2\n2,,2\n", r"line 3, column 'p1_re': an empty cell"),
    "not finite": ("freq,p1_re,p1_im\n1,1,nan\n2,1,2\n", r"'nan' is not a finite number"),
    "short row": ("freq,p1_re,p1_im\n1,1,2\n2,1\n", r"line 3: 2 field\(s\), expected 3"),
    "unknown column": ("freq,p1_re,p1_im,notes\n1,1,2,3\n", r"column 'notes' \(column 4\)"),
    "decreasing": (
        "freq,p1_re,p1_im\n2,1,2\n1,1,2\n",
        r"line 3, column 'freq': frequency 1 after 2; expected strictly increasing",
    ),
    "frequency unit": ("freq [rad/s],p1_re,p1_im\n1,1,2\n", r"frequencies in 'rad/s'; expected Hz"),
    "headerless even": ("1,2\n2,3\n", r"no header line and 2 column\(s\)"),
    "no rows": ("freq,p1_re,p1_im\n", r"a header and no data rows"),
    "bad unit": ("freq,p1_re [V],p1_im [V]\n1,1,2\n", r"FRF unit 'V' not understood"),
}


@pytest.mark.parametrize("case", list(BAD_CSV))
def test_bad_text_tables_name_the_file_and_the_column(tmp_path, case):
    text, message = BAD_CSV[case]
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DataFileError, match=message) as info:
        _quiet(ami_xr.open_frf, path)
    assert isinstance(info.value, ValueError)


def test_a_binary_file_is_not_read_as_text(tmp_path):
    path = tmp_path / "bad.dat"
    path.write_bytes(bytes(range(256)))
    with pytest.raises(DataFileError, match=r"bad\.dat: a binary file"):
        ami_xr.open_frf(path)


def _mat(tmp_path, variables):
    path = tmp_path / "bad.mat"
    scipy.io.savemat(path, variables)
    return path


def test_mat_struct_without_a_frequency_vector_names_the_struct(tmp_path):
    path = _mat(tmp_path, {"meas": {"H": np.ones((2, 5), complex), "fs": 100.0}})
    with pytest.raises(
        DataFileError, match=r"bad\.mat: struct 'meas' has no frequency vector.*found: H \(2, 5\)"
    ):
        ami_xr.open_frf(path)


BAD_MAT = {
    "no frf": ({"freq": np.arange(5.0)}, r"the file has no FRF matrix; expected .* frf or h"),
    "real frf": (
        {"freq": np.arange(5.0), "H": np.ones((2, 5))},
        r"variable 'H': real values; expected complex FRFs",
    ),
    "shape": (
        {"freq": np.arange(5.0), "H": np.ones((2, 4), complex)},
        r"variable 'H' has shape \(2, 4\); expected one axis of length 5",
    ),
    "labels": (
        {"freq": np.arange(5.0), "H": np.ones((2, 5), complex), "points": ["a", "b", "c"]},
        r"variable 'points': 3 label\(s\) for 2 FRFs",
    ),
    "drive point": (
        {"freq": np.arange(5.0), "H": np.ones((2, 5), complex), "drive_point": 7.0},
        r"drive_point \(from the file\): '?7'? is not one of the points \[0, 1\]",
    ),
}


@pytest.mark.parametrize("case", list(BAD_MAT))
def test_bad_mat_files_name_the_variable(tmp_path, case):
    variables, message = BAD_MAT[case]
    with pytest.raises(DataFileError, match=rf"bad\.mat: .*{message}"):
        _quiet(ami_xr.open_frf, _mat(tmp_path, variables))


def test_not_a_mat_file(tmp_path):
    path = tmp_path / "bad.mat"
    path.write_text("freq,H\n")
    with pytest.raises(DataFileError, match=r"bad\.mat: not a MATLAB file"):
        ami_xr.open_frf(path)


# --- the command line --------------------------------------------------------------------
@pytest.fixture(scope="module")
def nc_modes(sample):
    return _quiet(ami_xr.identify, sample)


def _modes(path):
    ds = ami_xr.open_dataset(path)
    return ds[names.NATURAL_FREQUENCY].values, ds[names.DAMPING_RATIO].values


def test_identify_csv_and_mat_find_the_modes_of_the_netcdf_file(sample, nc_modes, tmp_path, capsys):
    csv = write_csv(tmp_path / "frf.csv", sample)
    mat = write_mat(tmp_path / "frf.mat", sample)
    assert main(["identify", str(csv), "-o", str(tmp_path / "csv_modes.nc")]) == EXIT_OK
    assert main(["identify", str(mat), "-o", str(tmp_path / "mat_modes.nc")]) == EXIT_OK
    out = capsys.readouterr().out
    assert out.count("wrote modes to") == 2 and "10.34" in out
    fn_csv, zeta_csv = _modes(tmp_path / "csv_modes.nc")
    fn_mat, zeta_mat = _modes(tmp_path / "mat_modes.nc")
    np.testing.assert_array_equal(fn_csv, fn_mat)  # the same FRFs, bit for bit
    np.testing.assert_array_equal(zeta_csv, zeta_mat)
    # the sample file also says its FRFs come from a sampled impulse response (the tables
    # cannot): the same modes, within 0.01 % in frequency and 0.0005 in damping ratio
    fn_nc = nc_modes[names.NATURAL_FREQUENCY].values
    zeta_nc = nc_modes[names.DAMPING_RATIO].values
    assert fn_csv.size == fn_nc.size == 4
    np.testing.assert_allclose(fn_csv, fn_nc, rtol=1e-4)
    np.testing.assert_allclose(zeta_csv, zeta_nc, atol=5e-4)


def test_convert_csv_to_netcdf(sample, tmp_path, capsys):
    csv = write_csv(tmp_path / "frf.csv", sample)
    out = tmp_path / "frf.nc"
    assert main(["convert", str(csv), "-o", str(out)]) == EXIT_OK
    back = ami_xr.open_dataset(out)
    np.testing.assert_array_equal(back[names.FRF].values, sample[names.FRF].values)
    assert back.attrs[names.ATTR_DRIVE_POINT] == "tip"


@pytest.mark.parametrize("command", ["identify", "convert"])
def test_bad_files_on_the_command_line_are_one_line_and_write_nothing(tmp_path, capsys, command):
    csv = tmp_path / "bad.csv"
    csv.write_text(BAD_CSV["missing column"][0])
    mat = _mat(tmp_path, {"meas": {"H": np.ones((2, 5), complex)}})
    for path, what in ((csv, "'p2_im'"), (mat, "struct 'meas' has no frequency vector")):
        out = tmp_path / f"{path.stem}_{path.suffix[1:]}.nc"
        assert main([command, str(path), "-o", str(out)]) == EXIT_ERROR
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"ami-xr {command}: error: {path}"), err
        assert what in err[0]
        assert not out.exists()


def test_bad_file_exit_code_of_the_installed_command(tmp_path):
    csv = tmp_path / "bad.csv"
    csv.write_text(BAD_CSV["non-numeric cell"][0])
    proc = subprocess.run(
        [sys.executable, "-m", "ami_xr.app.cli", "identify", str(csv)],
        capture_output=True,
        text=True,
        timeout=300,
        env=SUBPROCESS_ENV,
    )
    assert proc.returncode == EXIT_ERROR  # input errors are exit 1 (2 is argparse's usage error)
    assert "line 3, column 'p1_re': 'abc' is not a number" in proc.stderr
    assert "Traceback" not in proc.stderr
