"""UFF files as other tools write them (issue 33, items 1, 2, 3, 9 and 11).

Normal modes (dataset 55, analysis type 2) keep their frequency and damping; every DOF a dataset 55
lists is kept, zero or not; dataset 164 converts node coordinates as it converts values; lines
padded with blanks (SDynPy) are read; ordinate types 0/1 are read when the unit label says the
quantity. The files come from pyuff's writer in ``tmp_path``, and from pyuff's own test data
(``sample_data/uff55_*.uff``, MIT, see ``sample_data/README.md``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ami_xr import names
from ami_xr.errors import AmiXrWarning, DataFileError
from ami_xr.io.uff import read_uff, write_uff
from ami_xr.io.uff.modes import HYSTERETIC_DAMPING, MODAL_MASS
from ami_xr.io.uff.read import ATTR_QUANTITY_FROM_LABEL, ATTR_UNITS_ASSUMED, ATTR_UNITS_SCALED

from ..reference import REPO

pyuff = pytest.importorskip("pyuff")

SAMPLE = REPO / "sample_data"
FREQ = np.arange(1.0, 9.0)


def _write(path, sets):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pyuff's notes on optional fields
        pyuff.UFF(str(path)).write_sets(sets, mode="add")
    return path


def _normal_mode(k, freq, zeta, nodes, shapes, mass=1.0, hysteretic=0.0, n_per_node=3):
    """A dataset 55 of analysis type 2 as pyuff.prepare_55 builds it (real shapes)."""
    comps = {f"r{c + 1}": np.asarray(shapes[c], dtype=float) for c in range(n_per_node)}
    return pyuff.prepare_55(
        model_type=1,
        id1="FE normal modes",
        analysis_type=2,
        data_ch=2 if n_per_node == 3 else 3,
        spec_data_type=8,
        data_type=2,
        n_data_per_node=n_per_node,
        node_nums=list(nodes),
        load_case=1,
        mode_n=k,
        freq=float(freq),
        modal_m=float(mass),
        modal_damp_vis=float(zeta),
        modal_damp_his=float(hysteretic),
        **comps,
    )


def _frf_record(node, spec, label, denom_label="NONE", data=None, ref=1):
    return pyuff.prepare_58(
        binary=0,
        id1="peer",
        func_type=4,
        rsp_node=node,
        rsp_dir=3,
        ref_node=ref,
        ref_dir=3,
        ord_data_type=6,
        num_pts=FREQ.size,
        abscissa_spacing=1,
        abscissa_min=float(FREQ[0]),
        abscissa_inc=1.0,
        abscissa_spec_data_type=18,
        ordinate_spec_data_type=spec,
        ordinate_axis_units_lab=label,
        orddenom_spec_data_type=13,
        orddenom_axis_units_lab=denom_label,
        data=(np.arange(FREQ.size) + 1.0) * node + 0.5j if data is None else data,
        x=FREQ,
    )


def _units_164(length, force=1.0, code=5, name="mm (milli newton)"):
    return pyuff.prepare_164(
        units_code=code,
        units_description=name,
        temp_mode=1,
        length=length,
        force=force,
        temp=1.0,
        temp_offset=273.15,
        return_full_dict=True,
    )


# --- item 1: normal modes keep frequency, damping and modal mass --------------------------------
def test_normal_modes_give_frequency_damping_and_eigenvalue(tmp_path):
    freqs, zetas, masses = [12.5, 31.0, 47.25], [0.01, 0.025, 0.0], [2.0, 0.5, 1.0]
    nodes = [1, 2, 3]
    shapes = np.array([[0.5, -1.0, 0.25], [0.0, 0.75, -0.5], [1.0, 0.5, -0.125]])
    path = _write(
        tmp_path / "fe.uff",
        [
            _normal_mode(k + 1, f, z, nodes, shapes * (k + 1), mass=m)
            for k, (f, z, m) in enumerate(zip(freqs, zetas, masses, strict=True))
        ],
    )
    ds = read_uff(path)
    # %13.5e holds these values exactly
    np.testing.assert_array_equal(ds[names.NATURAL_FREQUENCY].values, freqs)
    np.testing.assert_array_equal(ds[names.DAMPING_RATIO].values, zetas)
    wn = 2 * np.pi * np.array(freqs)
    zeta = np.array(zetas)
    lam = -zeta * wn + 1j * wn * np.sqrt(1 - zeta**2)
    np.testing.assert_allclose(ds[names.EIGENVALUE].values, lam, rtol=1e-14)
    np.testing.assert_allclose(np.abs(ds[names.EIGENVALUE].values) / (2 * np.pi), freqs)
    np.testing.assert_array_equal(ds[MODAL_MASS].values, masses)
    assert HYSTERETIC_DAMPING not in ds
    assert "analysis type 2" in ds.attrs["uff_analysis_type"]
    # mode 2 writes its shape times 2
    got = ds[names.MODE_VECTOR].sel({names.POINT: ["1+X", "2+Y", "3+Z"], names.MODE: 2}).values
    np.testing.assert_array_equal(got, 2 * np.array([0.5, 0.75, -0.125]))


def test_pyuffs_normal_mode_file_keeps_its_frequencies():
    ds = read_uff(SAMPLE / "uff55_translation.uff")
    np.testing.assert_array_equal(ds[names.NATURAL_FREQUENCY].values, [10.0, 12.0, 13.0])
    np.testing.assert_array_equal(ds[names.DAMPING_RATIO].values, [0.0, 0.0, 0.0])
    np.testing.assert_allclose(
        ds[names.EIGENVALUE].values, 2j * np.pi * np.array([10.0, 12.0, 13.0]), rtol=1e-15
    )
    assert np.all(ds[names.EIGENVALUE].values.real == 0.0)


def test_a_normal_mode_export_converts_with_its_frequencies(tmp_path):
    from ami_xr.app.cli import main
    from ami_xr.io.netcdf import open_dataset

    out = tmp_path / "modes.nc"
    assert main(["convert", str(SAMPLE / "uff55_translation.uff"), "-o", str(out)]) == 0
    back = open_dataset(out)
    np.testing.assert_array_equal(back[names.NATURAL_FREQUENCY].values, [10.0, 12.0, 13.0])
    assert np.isfinite(back[names.EIGENVALUE].values).all()


def test_normal_modes_stored_with_frfs_are_merged_with_their_frequencies(tmp_path):
    frfs = [_frf_record(node, 12, "m/s^2", "N") for node in (1, 2)]
    modes = [_normal_mode(1, 3.5, 0.02, [1, 2], [[0, 0], [0, 0], [1.0, -0.5]])]
    ds = read_uff(_write(tmp_path / "both.uff", frfs + modes))
    np.testing.assert_array_equal(ds[names.NATURAL_FREQUENCY].values, [3.5])
    np.testing.assert_array_equal(ds[names.DAMPING_RATIO].values, [0.02])
    np.testing.assert_array_equal(ds[names.MODE_VECTOR].values[:, 0], [1.0, -0.5])


def test_hysteretic_damping_is_kept_and_said(tmp_path):
    path = _write(
        tmp_path / "h.uff",
        [_normal_mode(1, 20.0, 0.0, [1], [[1.0], [0.0], [0.0]], hysteretic=0.04)],
    )
    with pytest.warns(AmiXrWarning, match="hysteretic damping but no viscous"):
        ds = read_uff(path)
    np.testing.assert_array_equal(ds[HYSTERETIC_DAMPING].values, [0.04])
    assert ds[names.DAMPING_RATIO].values.tolist() == [0.0]


@pytest.mark.parametrize("zeta", [1.0, 1.5, -2.0])
def test_a_damping_ratio_without_an_oscillating_mode_is_refused(tmp_path, zeta):
    path = _write(tmp_path / "z.uff", [_normal_mode(4, 20.0, zeta, [1], [[1.0], [0.0], [0.0]])])
    with pytest.raises(DataFileError, match=r"z.uff: dataset 55 of mode 4 .*viscous damping ratio"):
        read_uff(path)


# --- item 2: every DOF the file lists ------------------------------------------------------------
def test_zero_valued_dofs_are_kept():
    ds = read_uff(SAMPLE / "uff55_translation_rotation.uff")
    assert ds.sizes[names.POINT] == 43 * 6  # 43 nodes, 6 values each; the rotations are 0
    for axis in ("RX", "RY", "RZ"):
        assert f"1+{axis}" in ds[names.POINT].values.tolist()
    rotations = [p for p in ds[names.POINT].values.tolist() if "+R" in p]
    assert np.all(ds[names.MODE_VECTOR].sel({names.POINT: rotations}).values == 0)


def test_a_node_on_a_nodal_line_keeps_its_dofs(tmp_path):
    # node 2 sits on the nodal line of both modes: every value of it is 0
    shapes = [[[1.0, 0.0, -1.0], [0.0, 0.0, 0.0], [0.5, 0.0, 0.5]]]
    path = _write(
        tmp_path / "nodal.uff",
        [_normal_mode(k, 10.0 * k, 0.01, [1, 2, 3], np.array(shapes[0]) * k) for k in (1, 2)],
    )
    ds = read_uff(path)
    expected = [f"{n}+{a}" for n in (1, 2, 3) for a in "XYZ"]
    assert ds[names.POINT].values.tolist() == expected
    assert np.all(ds[names.MODE_VECTOR].sel({names.POINT: ["2+X", "2+Y", "2+Z"]}).values == 0)


def test_own_files_keep_only_the_points_they_hold(tmp_path):
    """write_uff pads the components of a node it has no point for with 0 (ID line 1 says the
    file is its own): those are not points."""
    from ami_xr import make_frf_dataset

    ds = make_frf_dataset(
        np.ones((3, 4), complex),
        FREQ[:4],
        points=["1+Z", "2+Z", "3+Y"],
        drive_point="1+Z",
        response_quantity="displacement",
    )
    ds = ds.assign_coords({names.MODE: [1]}).assign(
        {
            names.EIGENVALUE: (names.MODE, np.array([-0.5 + 30j])),
            names.MODE_VECTOR: ((names.POINT, names.MODE), np.array([[1.0], [0.0], [0.5]])),
        }
    )
    back = read_uff(write_uff(ds, tmp_path / "own.uff", include=["modes"]))
    # "2+Z" is 0 in the only mode: it cannot be told from the padding and is left out
    assert back[names.POINT].values.tolist() == ["1+Z", "3+Y"]


def test_a_dataset_55_whose_values_per_node_disagree_with_its_data_characteristic(tmp_path):
    """Record 6 saying 1 value per node for three translations (data characteristic 2, as SDynPy
    writes it) is read with the 3 values the lines hold, and said; a characteristic of scalars
    (1 value per node) is refused."""
    path = _write(
        tmp_path / "ok.uff", [_normal_mode(1, 5.0, 0.0, [1, 2], [[1, 2], [0, 0], [3, 4]])]
    )
    text = path.read_text().splitlines()
    header = [i for i, line in enumerate(text) if line.split()[:2] == ["1", "2"]][0]
    text[header] = text[header][:-10] + f"{1:10d}"  # values per node: 1
    path.write_text("\n".join(text) + "\n")
    with pytest.warns(
        AmiXrWarning, match=r"states 1 value\(s\) per node for data characteristic 2"
    ):
        ds = read_uff(path)
    shape = ds[names.MODE_VECTOR].isel(mode=0)
    assert {k: float(shape.sel(point=k).real) for k in ("1+X", "2+X", "1+Z", "2+Z")} == {
        "1+X": 1.0,
        "2+X": 2.0,
        "1+Z": 3.0,
        "2+Z": 4.0,
    }
    fields = text[header].split()
    text[header] = "".join(f.rjust(10) for f in [fields[0], fields[1], "1", *fields[3:5], "1"])
    path.write_text("\n".join(text) + "\n")  # scalars, 1 value per node: not a mode shape
    with pytest.raises(DataFileError, match=r"holds 1 value\(s\) per node.*expected 3"):
        read_uff(path)


# --- item 3: dataset 164 converts the node coordinates too ---------------------------------------
def _nodes_15(xyz_mm):
    n = len(xyz_mm)
    return pyuff.prepare_15(
        node_nums=list(range(1, n + 1)),
        def_cs=[0] * n,
        disp_cs=[0] * n,
        color=[1] * n,
        x=[p[0] for p in xyz_mm],
        y=[p[1] for p in xyz_mm],
        z=[p[2] for p in xyz_mm],
    )


def _nodes_2411(xyz_mm):
    n = len(xyz_mm)
    return pyuff.prepare_2411(
        node_nums=np.arange(1, n + 1),
        def_cs=np.zeros(n, int),
        disp_cs=np.zeros(n, int),
        color=np.ones(n, int),
        x=np.array([p[0] for p in xyz_mm]),
        y=np.array([p[1] for p in xyz_mm]),
        z=np.array([p[2] for p in xyz_mm]),
        return_full_dict=True,
    )


XYZ_MM = [(0.0, 0.0, 0.0), (250.0, 12.5, -5.0), (500.0, 0.0, 40.0)]


@pytest.mark.parametrize("geometry", [_nodes_15, _nodes_2411], ids=["15", "2411"])
def test_coordinates_in_millimetres_become_metres(tmp_path, geometry):
    frfs = [_frf_record(node, 8, "NONE", "NONE") for node in (1, 2, 3)]
    path = _write(tmp_path / "mm.uff", [_units_164(1000.0), geometry(XYZ_MM), *frfs])
    ds = read_uff(path)
    xyz = np.array(XYZ_MM) / 1000.0
    for j, coord in enumerate(names.POINT_COORDS):
        np.testing.assert_allclose(ds[coord].values, xyz[:, j], rtol=1e-12)
        assert ds[coord].attrs[names.ATTR_UNITS] == "m"
        assert "length / 1000 (dataset 164: mm" in ds[coord].attrs[ATTR_UNITS_SCALED]
    # the FRF values were converted by the same dataset (mm -> m)
    np.testing.assert_allclose(ds[names.FRF].values[0], ((np.arange(8) + 1.0) + 0.5j) / 1000.0)
    how = ds.attrs[ATTR_UNITS_SCALED]
    assert "response length / 1000" in how and "point coordinates length / 1000" in how


def test_coordinates_of_a_modes_file_follow_dataset_164(tmp_path):
    modes = [_normal_mode(1, 5.0, 0.0, [1, 2, 3], [[1, 2, 3], [0, 0, 0], [0, 0, 0]])]
    path = _write(tmp_path / "m.uff", [_units_164(1000.0), _nodes_15(XYZ_MM), *modes])
    ds = read_uff(path)
    np.testing.assert_allclose(ds[names.POINT_X].sel({names.POINT: "2+Y"}).values, 0.25, rtol=1e-12)
    assert "point coordinates length / 1000" in ds.attrs[ATTR_UNITS_SCALED]


def test_coordinates_with_labelled_values_still_follow_dataset_164(tmp_path):
    """The FRFs say their units (kept as they are), the nodes follow the file's units."""
    frfs = [_frf_record(node, 12, "mm/s^2", "N") for node in (1, 2, 3)]
    path = _write(tmp_path / "lab.uff", [_units_164(1000.0), _nodes_15(XYZ_MM), *frfs])
    ds = read_uff(path)
    assert ds.attrs[names.ATTR_RESPONSE_UNITS] == "mm/s^2"
    np.testing.assert_allclose(ds[names.POINT_X].values, [0.0, 0.25, 0.5], rtol=1e-12)
    assert ds.attrs[ATTR_UNITS_SCALED].startswith("values converted to SI: point coordinates")


def test_si_files_are_not_scaled(tmp_path):
    frfs = [_frf_record(node, 8, "m", "N") for node in (1, 2, 3)]
    path = _write(
        tmp_path / "si.uff", [_units_164(1.0, code=1, name="SI"), _nodes_15(XYZ_MM), *frfs]
    )
    ds = read_uff(path)
    np.testing.assert_array_equal(ds[names.POINT_X].values, [0.0, 250.0, 500.0])
    assert ATTR_UNITS_SCALED not in ds.attrs and ATTR_UNITS_SCALED not in ds[names.POINT_X].attrs


# --- item 9: lines padded with blanks (SDynPy) ---------------------------------------------------
def _pad_lines(path, out):
    """Every line padded with blanks to 80 columns, as SDynPy's writer pads them."""
    lines = path.read_text().splitlines()
    out.write_text("".join(line.ljust(80) + "\n" for line in lines))
    return out


def test_blank_padded_lines_are_read(tmp_path):
    # 8 complex values in double precision: 4 lines of 4E20.12; 7 leave a half line
    frfs = [_frf_record(node, 12, "m/s^2", "N", data=np.arange(7.0) * node + 1j) for node in (1, 2)]
    for r in frfs:
        r["num_pts"] = 7
        r["x"] = FREQ[:7]
    modes = [_normal_mode(1, 3.5, 0.02, [1, 2], [[0, 0], [0, 0], [1.0, -0.5]])]
    plain = _write(tmp_path / "plain.uff", frfs + modes)
    padded = _pad_lines(plain, tmp_path / "padded.uff")
    with pytest.raises(Exception, match="Error"):
        pyuff.UFF(str(padded)).read_sets()  # pyuff alone fails on the padding
    got, expected = read_uff(padded), read_uff(plain)
    np.testing.assert_array_equal(got[names.FRF].values, expected[names.FRF].values)
    np.testing.assert_array_equal(got[names.MODE_VECTOR].values, expected[names.MODE_VECTOR].values)
    np.testing.assert_array_equal(got[names.NATURAL_FREQUENCY].values, [3.5])
    padded_modes = read_uff(padded, kind="modes")
    assert padded_modes.sizes[names.POINT] == 6


def test_a_dataset_pyuff_cannot_read_is_named(tmp_path):
    frfs = [_frf_record(node, 12, "m/s^2", "N") for node in (1, 2)]
    path = _write(tmp_path / "bad.uff", frfs)
    text = path.read_text().splitlines()
    starts = [i for i, line in enumerate(text) if line.strip() == "58"]
    broken = starts[1] + 12  # the first data line of the second dataset
    text[broken] = text[broken][:10] + "x" + text[broken][11:]
    path.write_text("\n".join(text) + "\n")
    with pytest.raises(
        DataFileError,
        match=rf"bad.uff: dataset 2 of the file \(type 58, starting at line "
        rf"{starts[1]}\) cannot be read",
    ):
        read_uff(path)
    _pad_lines(path, tmp_path / "bad_padded.uff")
    with pytest.raises(DataFileError, match=r"dataset 2 of the file .*without the blanks"):
        read_uff(tmp_path / "bad_padded.uff")


# --- item 11: ordinate types 0 and 1 with unambiguous unit labels --------------------------------
@pytest.mark.parametrize("spec", [0, 1])
@pytest.mark.parametrize(
    ("label", "denom", "quantity", "units"),
    [
        ("m/s^2", "N", "acceleration", ("m/s^2", "N")),
        ("(1/N)*(m/s²)", "NONE", "acceleration", ("m/s^2", "N")),
        ("m/s/N", "NONE", "velocity", ("m/s", "N")),
        ("g", "lbf", "acceleration", ("g", "lbf")),
        ("mm", "N", "displacement", ("mm", "N")),
    ],
)
def test_ordinate_types_0_and_1_take_the_quantity_from_the_label(
    tmp_path, spec, label, denom, quantity, units
):
    path = _write(tmp_path / "o.uff", [_frf_record(n, spec, label, denom) for n in (1, 2)])
    with warnings.catch_warnings():
        warnings.simplefilter("error", AmiXrWarning)  # nothing assumed
        ds = read_uff(path)
    assert ds.attrs[names.ATTR_QUANTITY] == quantity
    assert (ds.attrs[names.ATTR_RESPONSE_UNITS], ds.attrs[names.ATTR_FORCE_UNITS]) == units
    assert f"ordinate specific data type {spec}" in ds.attrs[ATTR_QUANTITY_FROM_LABEL]
    np.testing.assert_array_equal(ds[names.FRF].values[1], (np.arange(8) + 1.0) * 2 + 0.5j)


def test_pyuffs_file_with_a_latin1_unit_label_reads_as_accelerance():
    ds = read_uff(SAMPLE / "non_ascii_header.uff")  # "(1/N)*(m/s²)", ordinate type 1
    assert ds.attrs[names.ATTR_QUANTITY] == "acceleration"
    assert ds[names.FRF].attrs[names.ATTR_UNITS] == "m/s^2/N"
    assert ATTR_UNITS_ASSUMED not in ds.attrs
    np.testing.assert_array_equal(
        ds[names.FRF].values[0, :2], [0.407994 + 0j, -0.0599924 - 0.055326j]
    )


def test_a_latin1_label_written_by_another_tool_is_decoded(tmp_path):
    path = _write(tmp_path / "l.uff", [_frf_record(n, 0, "(1/N)*(m/s^2)") for n in (1, 2)])
    path.write_bytes(path.read_bytes().replace(b"(m/s^2)", b"(m/s\xb2) "))  # Windows-1252 '²'
    ds = read_uff(path)
    assert (ds.attrs[names.ATTR_RESPONSE_UNITS], ds.attrs[names.ATTR_FORCE_UNITS]) == ("m/s^2", "N")


@pytest.mark.parametrize("label", ["NONE", "V", "m/s^2/V", "Pa"])
def test_ordinate_type_0_without_a_telling_label_is_refused(tmp_path, label):
    path = _write(tmp_path / "u.uff", [_frf_record(n, 0, label, "N") for n in (1, 2)])
    with pytest.raises(
        DataFileError,
        match=r"u.uff: dataset 58 record of DOF 1/3 has ordinate specific data type 0 and unit "
        r"label .* which name no response quantity; expected data type 8",
    ):
        read_uff(path)


def test_a_frf_label_and_a_denominator_that_disagree_are_refused(tmp_path):
    path = _write(tmp_path / "d.uff", [_frf_record(n, 0, "m/s^2/N", "lbf") for n in (1, 2)])
    with pytest.raises(DataFileError, match="per N but the denominator label is 'lbf'"):
        read_uff(path)


def test_type_12_with_a_whole_frf_label_is_read_without_assumption(tmp_path):
    path = _write(tmp_path / "a.uff", [_frf_record(n, 12, "(m/s^2)/N") for n in (1, 2)])
    with warnings.catch_warnings():
        warnings.simplefilter("error", AmiXrWarning)
        ds = read_uff(path)
    assert ds[names.FRF].attrs[names.ATTR_UNITS] == "m/s^2/N"
    assert ATTR_UNITS_ASSUMED not in ds.attrs and ATTR_QUANTITY_FROM_LABEL not in ds.attrs


def test_time_records_of_type_0_split_into_response_and_force(tmp_path):
    def record(node, label, data):
        return pyuff.prepare_58(
            binary=0,
            id1="t",
            func_type=1,
            rsp_node=node,
            rsp_dir=3,
            ref_node=1,
            ref_dir=3,
            ord_data_type=4,
            num_pts=data.size,
            abscissa_spacing=1,
            abscissa_min=0.0,
            abscissa_inc=0.125,
            abscissa_spec_data_type=17,
            ordinate_spec_data_type=0,
            ordinate_axis_units_lab=label,
            orddenom_spec_data_type=0,
            data=data,
            x=np.arange(data.size) * 0.125,
        )

    # values %20.12e holds exactly
    response, force = np.arange(16.0) * 0.25 - 1.0, np.exp2(-np.arange(16.0))
    path = _write(tmp_path / "t.uff", [record(2, "m/s^2", response), record(1, "N", force)])
    ds = read_uff(path)
    assert ds.attrs[names.ATTR_QUANTITY] == "acceleration"
    np.testing.assert_array_equal(ds[names.FORCE].values, force)
    np.testing.assert_array_equal(ds[names.RESPONSE].sel({names.POINT: "2+Z"}).values, response)
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "1+Z"
