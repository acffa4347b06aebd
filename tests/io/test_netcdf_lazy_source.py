"""Issue 34: a lazily opened file that changes or vanishes before the computation is an error
naming the file, never a result; ``close()`` releases the file."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import DataFileError
from ami_xr.io.netcdf import open_dataset, to_netcdf

CHUNKS = {names.FREQUENCY: 128}


def _frf(seed: int = 1):
    g, _ = ami_xr.simulate.random_system(
        n_points=5, n_modes=5, noise=0.01, seed=seed, n_frequencies=512
    )
    return g


@pytest.fixture
def stored(tmp_path) -> Path:
    return to_netcdf(_frf(), tmp_path / "g.nc")


def _open_handles(path: Path) -> list[str]:
    """The open file descriptors of this process that point at ``path`` (Linux)."""
    found = []
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if target.startswith(str(path.resolve())):  # "... (deleted)" after an unlink
            found.append(target)
    return found


def test_an_unchanged_file_computes_as_the_eager_open(stored):
    lazy = open_dataset(stored, chunks=CHUNKS)
    assert lazy[names.FRF].data.chunks[-1] == (128,) * 4
    xr.testing.assert_identical(lazy.compute(), open_dataset(stored))
    lazy.close()


def _truncate(path: Path) -> None:
    with open(path, "r+b") as fh:
        fh.truncate(path.stat().st_size // 2)


def _replace(path: Path) -> None:
    to_netcdf(_frf(seed=5), path)  # atomic: a new file under the same name


@pytest.mark.parametrize(
    ("change", "said"),
    [(_truncate, "changed"), (Path.unlink, "removed or renamed"), (_replace, "changed")],
    ids=["truncated", "removed", "replaced"],
)
def test_a_changed_or_vanished_source_is_an_error_naming_the_file(stored, change, said):
    lazy = open_dataset(stored, chunks=CHUNKS)
    change(stored)
    with pytest.raises(DataFileError, match=said) as info:
        lazy[names.FRF].values  # noqa: B018 - the computation is the test
    assert str(stored.resolve()) in str(info.value) and "lazily" in str(info.value)
    assert isinstance(info.value, ValueError)
    lazy.close()


def test_identify_on_a_truncated_lazy_file_raises(stored):
    lazy = open_dataset(stored, chunks=CHUNKS)
    _truncate(stored)
    with pytest.raises(DataFileError, match=r"g\.nc.*changed"):
        ami_xr.identify(lazy)
    lazy.close()


def test_an_appended_byte_with_the_same_mtime_is_a_change(stored):
    lazy = open_dataset(stored, chunks=CHUNKS)
    st = stored.stat()
    with open(stored, "ab") as fh:
        fh.write(b"\0")
    os.utime(stored, ns=(st.st_atime_ns, st.st_mtime_ns))
    with pytest.raises(DataFileError, match="changed"):
        lazy.compute()
    lazy.close()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc/self/fd")
def test_close_releases_the_file(stored):
    lazy = open_dataset(stored, chunks=CHUNKS)
    assert _open_handles(stored)  # a lazy open keeps the file open ...
    lazy.close()
    assert _open_handles(stored) == []  # ... until close()
    with open_dataset(stored, chunks=CHUNKS) as again:  # also as a context manager
        np.testing.assert_array_equal(again[names.FRF].values, _frf()[names.FRF].values)
    assert _open_handles(stored) == []
