"""The one atomic writer (ami_xr.io.atomic): complete-or-untouched targets, normal file mode."""

from __future__ import annotations

import os
import stat

import pytest

from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.atomic import atomic_open, atomic_path, remove_stale

from ..reference import normal_file_mode


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.mark.parametrize("mode, data", [("w", "text\n"), ("wb", b"\x00bytes")])
def test_atomic_open_writes_with_the_normal_file_mode(tmp_path, mode, data):
    target = tmp_path / "out"
    with atomic_open(target, mode) as fh:
        fh.write(data)
    assert (target.read_text() if mode == "w" else target.read_bytes()) == data
    assert _mode(target) == normal_file_mode()
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_atomic_path_writes_with_the_normal_file_mode(tmp_path):
    target = tmp_path / "out"
    with atomic_path(target) as tmp:
        assert not tmp.exists()
        assert tmp.name == "out" and tmp.parent.parent == tmp_path
        tmp.write_bytes(b"new")
    assert target.read_bytes() == b"new"
    assert _mode(target) == normal_file_mode()
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


@pytest.mark.parametrize("error", [RuntimeError("boom"), KeyboardInterrupt()])
def test_error_mid_write_leaves_old_file_and_no_temporary(tmp_path, error):
    target = tmp_path / "out"
    target.write_bytes(b"old")
    with pytest.raises(type(error)):
        with atomic_open(target, "wb") as fh:
            fh.write(b"half")
            raise error
    with pytest.raises(type(error)):
        with atomic_path(target) as tmp:
            tmp.write_bytes(b"half")
            raise error
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_os_error_becomes_data_file_error_naming_the_target(tmp_path):
    target = tmp_path / "out"
    with pytest.raises(DataFileError, match=r"out: cannot write: FileNotFoundError"):
        with atomic_path(target):
            pass  # the body never creates the file
    assert list(tmp_path.iterdir()) == []


def test_missing_folder_folder_target_and_bad_mode(tmp_path):
    with pytest.raises(DataFileError, match=r"folder .*nowhere does not exist"):
        with atomic_open(tmp_path / "nowhere" / "x"):
            pass
    with pytest.raises(DataFileError, match="is a folder"):
        with atomic_path(tmp_path):
            pass
    with pytest.raises(AmiXrValueError, match="mode: expected 'w' or 'wb', got 'a'"):
        with atomic_open(tmp_path / "x", "a"):
            pass
    assert list(tmp_path.iterdir()) == []


def test_remove_stale_removes_only_crash_leftovers(tmp_path):
    (tmp_path / "sub").mkdir()
    stale_dir = tmp_path / "sub" / ".a.nc.0123456789ab.tmp"
    stale_dir.mkdir()
    (stale_dir / "a.nc").write_bytes(b"half")
    (tmp_path / ".b.csv.abcdef012345.tmp").write_text("half")
    kept = [tmp_path / ".user.tmp", tmp_path / "data.nc"]
    for p in kept:
        p.write_text("keep")
    removed = remove_stale(tmp_path)
    assert sorted(p.name for p in removed) == [".a.nc.0123456789ab.tmp", ".b.csv.abcdef012345.tmp"]
    assert all(p.exists() for p in kept)
    assert not stale_dir.exists()
