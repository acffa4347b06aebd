"""Atomic file writes: every file ami_xr writes goes through here.

A target is either complete or untouched. The data goes to a file inside a private temporary
folder next to the target (``.<name>.<random>.tmp/<name>``, same file system, so the final
:func:`os.replace` is one rename), is flushed to disk, then replaces the target; the folder is
removed. On any error — ``KeyboardInterrupt`` included — the temporary folder is removed and an
existing target is left as it was.

The new file gets the mode of any freshly created file (``0o666`` less the umask), never the
``0o600`` of :func:`tempfile.mkstemp`.

Why a folder rather than a temporary file: after a failed dask-backed netCDF write a straggling
worker thread may reopen the file by name (xarray reopens in append mode, which creates it);
once the folder is gone such a reopen fails instead of leaving a stray file. It also gives
writers that refuse to overwrite (pyuff) a path that does not exist yet.

Two entry points::

    with atomic_path(target) as tmp:        # a writer that takes a file name
        ds.to_netcdf(tmp)

    with atomic_open(target, "w") as fh:    # a writer that takes an open file
        fh.write(text)

Leftovers of a hard crash (``kill -9``, power loss) are folders matching :data:`TEMP_GLOB`;
:func:`remove_stale` deletes them.
"""

from __future__ import annotations

import os
import shutil
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from ami_xr.errors import AmiXrValueError, DataFileError

__all__ = ["atomic_path", "atomic_open", "remove_stale", "TEMP_GLOB"]

TEMP_SUFFIX = ".tmp"
# Glob pattern of the temporary folders (hidden, ``.tmp`` suffix) for :func:`remove_stale`.
TEMP_GLOB = f".*{TEMP_SUFFIX}"


def _checked_target(path: str | os.PathLike) -> Path:
    """Absolute target path; raise :class:`DataFileError` before anything is created."""
    path = Path(path).absolute()
    if not path.parent.is_dir():
        raise DataFileError(f"{path}: folder {path.parent} does not exist")
    if path.is_dir():
        raise DataFileError(f"{path}: is a folder, expected a file path")
    return path


def _remove_tree(folder: Path) -> None:
    """Remove the temporary folder, retrying while a straggling writer re-creates its file."""
    for _ in range(50):
        try:
            shutil.rmtree(folder)
        except FileNotFoundError:
            return
        except OSError:
            time.sleep(0.01)
        if not folder.exists():
            return


def _fsync_file(path: Path) -> None:
    with open(path, "rb+") as f:
        os.fsync(f.fileno())


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary file path; on a clean exit it replaces ``path`` in one rename.

    Parameters
    ----------
    path : str or path-like
        Target file; its folder must exist. Overwritten if it exists.

    Yields
    ------
    pathlib.Path
        A path that does not exist yet, with the same name as the target, inside a fresh hidden
        folder next to it. The body must create the file there (and close it).

    Raises
    ------
    DataFileError
        The folder of ``path`` is missing, ``path`` is a folder, or an ``OSError`` occurred while
        writing or renaming (the message names ``path``). Every other exception of the body
        propagates unchanged. In all cases the temporary folder is gone and an existing target
        is untouched.
    """
    path = _checked_target(path)
    tmp_dir = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}{TEMP_SUFFIX}")
    tmp = tmp_dir / path.name
    try:
        tmp_dir.mkdir()
        yield tmp
        _fsync_file(tmp)
        os.replace(tmp, path)
        tmp_dir.rmdir()
    except OSError as err:
        _remove_tree(tmp_dir)
        raise DataFileError(f"{path}: cannot write: {type(err).__name__}: {err}") from err
    except BaseException:
        _remove_tree(tmp_dir)
        raise


@contextmanager
def atomic_open(
    path: str | os.PathLike,
    mode: str = "w",
    *,
    encoding: str | None = "utf-8",
    newline: str | None = "",
) -> Iterator[IO[Any]]:
    """Open a temporary file for writing; on a clean exit it replaces ``path`` in one rename.

    Parameters
    ----------
    path : str or path-like
        Target file; its folder must exist. Overwritten if it exists.
    mode : {"w", "wb"}
        Text or binary.
    encoding, newline : str or None
        As for :func:`open` in text mode (ignored in binary mode). The default ``newline=""``
        writes line endings as given, which :mod:`csv` needs.

    Yields
    ------
    file object
        Closed before the rename.

    Raises
    ------
    AmiXrValueError
        ``mode`` is not ``"w"`` or ``"wb"``.
    DataFileError
        As for :func:`atomic_path`.
    """
    if mode not in ("w", "wb"):
        raise AmiXrValueError(f"mode: expected 'w' or 'wb', got {mode!r}")
    text = {} if "b" in mode else {"encoding": encoding, "newline": newline}
    with atomic_path(path) as tmp, open(tmp, mode, **text) as fh:
        yield fh


def remove_stale(folder: str | os.PathLike) -> list[Path]:
    """Remove temporary folders a hard crash left in ``folder`` (recursively); return them.

    Only hidden entries named like :func:`atomic_path`'s (``.<name>.<12 hex>.tmp``) are removed.
    Do not call this while another process may be writing into ``folder``.
    """
    removed = []
    for entry in sorted(Path(folder).rglob(TEMP_GLOB)):
        stem = entry.name[: -len(TEMP_SUFFIX)]
        token = stem.rsplit(".", 1)[-1]
        if len(token) == 12 and all(c in "0123456789abcdef" for c in token):
            if entry.is_dir():
                _remove_tree(entry)
            else:
                entry.unlink(missing_ok=True)
            removed.append(entry)
    return removed
