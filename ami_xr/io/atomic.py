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

Interrupts. SIGINT and SIGTERM never leave a partial target and never hang:

* in the main thread, a SIGTERM whose action is the default (kill at once) raises
  ``SystemExit(143)`` while a write is in progress, so the temporary folder is removed as for
  Ctrl-C (``KeyboardInterrupt``);
* :func:`interrupts_deferred` holds SIGINT/SIGTERM while code runs that must not be
  interrupted half-way (netCDF/HDF5 calls under xarray's file locks: an exception raised there
  can leave a lock held, and the next ``close`` waits on it forever) and delivers them to the
  handlers in place as soon as the block ends (or earlier, at a safe point, see
  :meth:`DeferredSignals.deliver`).

Leftovers of a hard crash (``kill -9``, power loss) are folders matching :data:`TEMP_GLOB`.
Each writer holds an advisory lock (``flock``) on its temporary folder, so a leftover is one
nobody holds: :func:`atomic_path` removes those of its own target before it writes, and
:func:`remove_stale` those of a whole folder tree; folders of live writers (another process
writing the same target) are left alone.
"""

from __future__ import annotations

import contextlib
import errno
import glob
import os
import shutil
import signal
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from ami_xr.errors import AmiXrValueError, DataFileError

try:  # POSIX advisory locks tell a live writer's temporary folder from a crash leftover
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

__all__ = [
    "atomic_path",
    "atomic_open",
    "remove_stale",
    "interrupts_deferred",
    "DeferredSignals",
    "TEMP_GLOB",
    "EXIT_TERMINATED",
]

#: Exit status of a process stopped by SIGTERM during a write (128 + 15, as a shell reports it).
EXIT_TERMINATED = 128 + signal.SIGTERM
# Signals that stop a command and are held by :func:`interrupts_deferred`.
_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)

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


# --- signals -------------------------------------------------------------------------------------
def _in_main_thread() -> bool:
    # Python runs signal handlers (and may only install them) in the main thread.
    return threading.current_thread() is threading.main_thread()


def _deliver(signum: int, handler: Any) -> None:
    """Run what ``handler`` (a value of :func:`signal.getsignal`) would have done for ``signum``."""
    if callable(handler):
        handler(signum, None)
    elif handler != signal.SIG_IGN:  # SIG_DFL, or a handler not installed from Python
        signal.raise_signal(signum)


class DeferredSignals:
    """The SIGINT/SIGTERM held by :func:`interrupts_deferred` (in the order received)."""

    def __init__(self) -> None:
        self.received: list[int] = []
        self._previous: dict[int, Any] = {}

    def _record(self, signum: int, frame: Any) -> None:
        self.received.append(signum)

    def deliver(self) -> None:
        """Hand the held signals to the handlers that were in place, now.

        Call it only at a point where an exception is safe (no file lock held); the handlers
        may raise (``KeyboardInterrupt``), or not (a batch's first Ctrl-C only asks to stop
        after the current file). Does nothing outside the main thread.
        """
        if not _in_main_thread():
            return
        while self.received:
            signum = self.received.pop(0)
            _deliver(signum, self._previous.get(signum, signal.SIG_DFL))


@contextmanager
def interrupts_deferred() -> Iterator[DeferredSignals]:
    """Hold SIGINT and SIGTERM while the block runs; deliver them when it ends.

    In the main thread the handlers are replaced by one that only records the signal; on exit
    (normal or by an exception) the previous handlers are restored and each recorded signal is
    passed to its previous handler, so Ctrl-C raises ``KeyboardInterrupt`` right after the
    block. Elsewhere (signals only reach the main thread) it does nothing.

    Yields
    ------
    DeferredSignals
        Its :meth:`~DeferredSignals.deliver` hands the held signals over earlier, at a safe
        point of a long block.
    """
    deferred = DeferredSignals()
    if not _in_main_thread():
        yield deferred
        return
    try:
        for signum in _STOP_SIGNALS:
            deferred._previous[signum] = signal.signal(signum, deferred._record)
        yield deferred
    finally:
        for signum, handler in deferred._previous.items():
            signal.signal(signum, handler)
        deferred.deliver()


def _raise_exit(signum: int, frame: Any) -> None:
    raise SystemExit(128 + signum)


@contextmanager
def _sigterm_as_exit() -> Iterator[None]:
    """While a write runs in the main thread: a SIGTERM that would kill the process at once
    raises ``SystemExit(143)`` instead, so the temporary folder is removed first."""
    if not _in_main_thread() or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_exit)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


# --- full disk -----------------------------------------------------------------------------------
#: errno values that mean "no room": no space, quota exceeded, file-size limit (RLIMIT_FSIZE).
NO_SPACE_ERRNOS = tuple(
    getattr(errno, name) for name in ("ENOSPC", "EDQUOT", "EFBIG") if hasattr(errno, name)
)
#: Bytes a probe writes to tell a full disk from another write error.
PROBE_BYTES = 1 << 20


def no_space(folder: Path, err: BaseException | None = None) -> bool:
    """Whether a failed write in ``folder`` ran out of room: the error (or one it was raised
    from) says so, or the folder takes no :data:`PROBE_BYTES` more now."""
    seen = err
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno in NO_SPACE_ERRNOS:
            return True
        seen = seen.__cause__ or seen.__context__
    try:
        st = os.statvfs(folder)
        if st.f_bavail * st.f_frsize < PROBE_BYTES:
            return True
    except (OSError, AttributeError):
        pass
    probe = Path(folder) / f".space-probe.{uuid.uuid4().hex[:8]}{TEMP_SUFFIX}"
    try:
        with open(probe, "wb") as fh:
            fh.write(bytes(PROBE_BYTES))
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as probe_err:
        return probe_err.errno in NO_SPACE_ERRNOS
    finally:
        with contextlib.suppress(OSError):
            probe.unlink()
    return False


def _full_message(path: Path, err: BaseException) -> str:
    return (
        f"no space left on the device writing {path} ({type(err).__name__}: {err}); "
        "nothing was written there (the previous file, if any, is unchanged)"
    )


# --- temporary folders: lock, create, remove leftovers -------------------------------------------
def _lock(entry: Path, *, wait: bool) -> int | None:
    """An open descriptor of ``entry`` holding an exclusive ``flock``; None when another
    process holds it (``wait=False``), ``entry`` is gone, or there is no ``fcntl``."""
    if fcntl is None:  # pragma: no cover - Windows
        return None
    try:
        fd = os.open(entry, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX if wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def _new_temp_dir(path: Path) -> tuple[Path, int | None]:
    """Create and lock a fresh temporary folder for ``path``; return it and the lock."""
    for _ in range(10):
        tmp_dir = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}{TEMP_SUFFIX}")
        tmp_dir.mkdir()
        if fcntl is None:  # pragma: no cover - Windows
            return tmp_dir, None
        fd = _lock(tmp_dir, wait=True)
        # A cleaner may have taken the unlocked folder between mkdir and flock: try another.
        if fd is not None and tmp_dir.exists() and os.path.samestat(os.fstat(fd), tmp_dir.stat()):
            return tmp_dir, fd
        if fd is not None:
            os.close(fd)
    raise OSError(f"cannot create a temporary folder next to {path}")


def _is_temp_name(name: str) -> bool:
    """Whether ``name`` is that of a temporary folder (``.<name>.<12 hex>.tmp``)."""
    if not (name.startswith(".") and name.endswith(TEMP_SUFFIX)):
        return False
    token = name[: -len(TEMP_SUFFIX)].rsplit(".", 1)[-1]
    return len(token) == 12 and all(c in "0123456789abcdef" for c in token)


def _remove_abandoned(entry: Path, *, unlocked_ok: bool) -> bool:
    """Remove a leftover temporary folder (or file) no live writer holds; True if removed.

    Without ``flock`` (Windows) it is removed only when ``unlocked_ok``.
    """
    fd = _lock(entry, wait=False)
    if fd is None and not (fcntl is None and unlocked_ok):
        return False
    try:
        if entry.is_dir():
            _remove_tree(entry)
        else:
            entry.unlink(missing_ok=True)
    finally:
        if fd is not None:
            os.close(fd)
    return True


def _remove_stale_of(path: Path) -> None:
    """Remove the leftovers of earlier, killed writes of ``path`` (not those of live ones)."""
    pattern = glob.escape(f".{path.name}.") + "*" + TEMP_SUFFIX
    for entry in path.parent.glob(pattern):
        if _is_temp_name(entry.name) and entry.name[: -len(TEMP_SUFFIX) - 13] == f".{path.name}":
            _remove_abandoned(entry, unlocked_ok=False)


def _open_temp_dir(path: Path):
    """Clear the leftovers of killed writes of ``path`` and open a fresh temporary folder next
    to it: ``(folder, lock)``; a failure is a DataFileError naming ``path`` (a full disk as
    such)."""
    try:
        _remove_stale_of(path)
        return _new_temp_dir(path)
    except OSError as err:
        if no_space(path.parent, err):
            raise DataFileError(_full_message(path, err)) from err
        raise DataFileError(f"{path}: cannot write: {type(err).__name__}: {err}") from err


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
    with _sigterm_as_exit():
        tmp_dir, lock = _open_temp_dir(path)
        tmp = tmp_dir / path.name
        try:
            yield tmp
            _fsync_file(tmp)
            os.replace(tmp, path)
            tmp_dir.rmdir()
        except OSError as err:
            with interrupts_deferred():  # a second Ctrl-C must not stop the cleanup half-way
                full = no_space(tmp_dir, err)
                _remove_tree(tmp_dir)
            if full:
                raise DataFileError(_full_message(path, err)) from err
            raise DataFileError(f"{path}: cannot write: {type(err).__name__}: {err}") from err
        except Exception as err:
            # netCDF ("NetCDF: HDF error") and pyuff ("Error writing data-set") hide the cause:
            # a full disk is named as such.
            with interrupts_deferred():
                full = no_space(tmp_dir, err)
                _remove_tree(tmp_dir)
            if full:
                raise DataFileError(_full_message(path, err)) from err
            raise
        except BaseException:
            with interrupts_deferred():
                _remove_tree(tmp_dir)
            raise
        finally:
            if lock is not None:
                os.close(lock)


@contextmanager
def atomic_folder(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a fresh empty folder; on a clean exit it replaces the folder ``path`` whole.

    For outputs made of several files (a report): the body writes into the yielded folder (a
    hidden temporary folder next to ``path``); then, with signals held, an existing ``path`` is
    moved aside and the new folder renamed into place, so ``path`` is the old folder or the
    complete new one, never a mix. On an error or an interrupt the temporary folder is removed
    and ``path`` is untouched; a full disk is named as such.

    Raises
    ------
    DataFileError
        ``path`` exists and is not a folder, or an ``OSError`` occurred while writing or
        renaming (the message names ``path``).
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise DataFileError(f"{path}: exists and is not a folder")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp_dir, lock = _open_temp_dir(path)
    new = tmp_dir / path.name
    try:
        new.mkdir()
        yield new
        with interrupts_deferred():  # the two renames are not split by a Ctrl-C
            if path.exists():
                os.rename(path, tmp_dir / f"{path.name}.old")
            os.rename(new, path)
            _remove_tree(tmp_dir)
    except BaseException as err:
        with interrupts_deferred():
            full = isinstance(err, Exception) and no_space(tmp_dir, err)
            _remove_tree(tmp_dir)
        if full:
            raise DataFileError(_full_message(path, err)) from err
        if isinstance(err, OSError):
            raise DataFileError(f"{path}: cannot write: {type(err).__name__}: {err}") from err
        raise
    finally:
        if lock is not None:
            os.close(lock)


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

    Only hidden entries named like :func:`atomic_path`'s (``.<name>.<12 hex>.tmp``), files or
    folders, are removed, and only those no live writer holds (each writer keeps an ``flock``
    on its folder; without ``fcntl``, on Windows, do not call this while another process may
    be writing into ``folder``).
    """
    removed = []
    for entry in sorted(Path(folder).rglob(TEMP_GLOB)):
        if not entry.exists():  # inside a leftover removed just before
            continue
        if _is_temp_name(entry.name) and _remove_abandoned(entry, unlocked_ok=True):
            removed.append(entry)
    return removed
