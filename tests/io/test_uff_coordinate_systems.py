"""UFF coordinate systems (issue 40): nodes defined in the Cartesian systems of datasets 2420 and
18 are moved to global coordinates; cylindrical, spherical or undefined systems, and points whose
displacements are in a rotated system, are refused naming the dataset, the node and the system.
Files written by pyuff's own writer."""

from __future__ import annotations

import numpy as np
import pytest

from ami_xr import names
from ami_xr.errors import DataFileError
from ami_xr.io.uff import read_uff

from .pyuff_records import frf_record, write_sets

pyuff = pytest.importorskip("pyuff")

FREQ = np.arange(1.0, 9.0)
LOCAL = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.5, 0.5, 3.0]])  # nodes 1, 2, 3
ORIGIN = np.array([10.0, -2.0, 0.5])
# local axes in global coordinates: local X = global Y, local Y = -global X, local Z = global Z
AXES = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
GLOBAL = ORIGIN + LOCAL @ AXES


def _frf(node):
    return frf_record((np.arange(FREQ.size) + 1.0) * node + 0.5j, FREQ, rsp_node=node)


def _nodes(def_cs, disp_cs=(0, 0, 0)):
    return pyuff.prepare_2411(
        node_nums=[1, 2, 3],
        def_cs=list(def_cs),
        disp_cs=list(disp_cs),
        color=[1, 1, 1],
        x=LOCAL[:, 0],
        y=LOCAL[:, 1],
        z=LOCAL[:, 2],
        return_full_dict=True,
    )


def _cs_2420(kind=0, axes=AXES):
    matrix = np.vstack([axes, ORIGIN])
    return pyuff.prepare_2420(
        Part_UID=1,
        Part_Name="part",
        CS_sys_labels=[1],
        CS_types=[kind],
        CS_colors=[8],
        CS_names=["local"],
        CS_matrices=[matrix],
        return_full_dict=True,
    )


def _cs_18():
    return pyuff.prepare_18(
        cs_num=[1],
        cs_type=[0],
        ref_cs_num=[0],
        color=[8],
        method=[1],
        cs_name=["local"],
        ref_o=[ORIGIN],
        x_point=[ORIGIN + AXES[0]],
        xz_point=[ORIGIN + AXES[0] + AXES[2]],
        return_full_dict=True,
    )


def _xyz(ds):
    return np.column_stack([ds[c].values for c in names.POINT_COORDS])


@pytest.mark.parametrize("system", [_cs_2420, _cs_18], ids=["2420", "18"])
def test_nodes_in_a_cartesian_system_are_moved_to_global_coordinates(tmp_path, system):
    path = write_sets(tmp_path / "cs.uff", [system(), _nodes([1, 1, 1]), *map(_frf, (1, 2, 3))])
    ds = read_uff(path)
    assert list(ds[names.POINT].values) == ["1+Z", "2+Z", "3+Z"]
    np.testing.assert_allclose(_xyz(ds), GLOBAL, rtol=0, atol=1e-6)


def test_the_global_system_needs_no_dataset(tmp_path):
    path = write_sets(tmp_path / "g.uff", [_nodes([0, 0, 0]), *map(_frf, (1, 2, 3))])
    np.testing.assert_allclose(_xyz(read_uff(path)), LOCAL, rtol=0, atol=1e-12)


def test_an_undefined_or_cylindrical_system_is_refused_naming_the_node(tmp_path):
    path = write_sets(tmp_path / "u.uff", [_nodes([0, 7, 0]), *map(_frf, (1, 2, 3))])
    with pytest.raises(
        DataFileError,
        match=r"u\.uff: dataset 2411: node 2 is defined in coordinate system 7 which no "
        r"dataset 2420 or 18 defines",
    ):
        read_uff(path)
    path = write_sets(tmp_path / "c.uff", [_cs_2420(kind=1), _nodes([1, 1, 1]), _frf(1)])
    with pytest.raises(DataFileError, match=r"node 1 is defined in coordinate system 1 \(cyl"):
        read_uff(path)


def test_displacements_in_a_rotated_system_are_refused(tmp_path):
    path = write_sets(tmp_path / "d.uff", [_cs_2420(), _nodes([0, 0, 0], [0, 1, 0]), _frf(2)])
    with pytest.raises(
        DataFileError,
        match=r"dataset 2411: node 2 has its displacements in coordinate system 1, a rotated "
        r"one: the direction of point '2\+Z' is not the global one",
    ):
        read_uff(path)
    identity = write_sets(
        tmp_path / "i.uff", [_cs_2420(axes=np.eye(3)), _nodes([1, 1, 1], [1, 1, 1]), _frf(2)]
    )
    np.testing.assert_allclose(_xyz(read_uff(identity))[0], ORIGIN + LOCAL[1], atol=1e-12)
