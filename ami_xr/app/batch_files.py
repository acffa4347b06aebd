"""The files of a batch (:mod:`ami_xr.app.batch`): which measurements it reads, where their
results go, whether a result is still up to date, and the summary's write check.

* **Inputs.** Every ``.nc``, ``.uff``/``.unv`` and ``.lvm`` file under the input folder, hidden
  files and folders left out. The batch's own outputs are recognised by name, never by the
  folder they are in: ``*.modes.nc`` anywhere, and ``<stem>.report/`` folders and
  ``batch_summary.csv`` in the output tree. So an output folder inside the inputs (``-o
  camp/day1`` where ``day1/`` holds measurements) never hides a measurement.
* **Staleness by content.** An output records the SHA-256 of its input (with its size and
  mtime). It is up to date when the parameters match and the input's content hash equals the
  recorded one; the hash is streamed (1 MiB at a time) and skipped only when the size differs
  (then the content differs too). Size and mtime alone never decide "up to date": a copy tool
  that keeps both can change the content.
* **Read-only summary.** An existing ``batch_summary.csv`` that is read-only is refused before
  any work, as every other read-only output is (:func:`ami_xr.io.formats.check_output`).
* **The plan.** :func:`plan` decides, before any work, each file's summary row (a name
  collision, a special file, an up-to-date output) or its job; :func:`reconcile` lists the
  outputs written but not reported when a batch stopped.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ami_xr import names
from ami_xr.app.redact import relative_paths
from ami_xr.core import flags
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.formats import INPUT_SUFFIXES, check_input, same_file

OUTPUT_SUFFIX = ".modes.nc"
REPORT_SUFFIX = ".report"
SUMMARY_NAME = "batch_summary.csv"
ATTR_INPUT = "batch_input"
ATTR_INPUT_SHA = "batch_input_sha256"
ATTR_INPUT_SIZE = "batch_input_size"
ATTR_INPUT_MTIME = "batch_input_mtime_ns"
ATTR_PARAMS_SHA = "batch_parameters_sha256"
ATTR_PARAMS = "batch_parameters"
# Bump when the meaning of the pipeline changes so old outputs are redone.
PIPELINE_VERSION = 1
_WRITE_BITS = stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH
_HASH_BLOCK = 1 << 20

STATUS_OK = "ok"
STATUS_UP_TO_DATE = "up to date"
STATUS_FAILED = "failed"
STATUS_CAPPED = "capped"  # identified, but a phase stopped at a cap: modes may be missing
SUMMARY_FIELDS = ("file", "status", "modes", "frequencies_hz", "output", "seconds", "message")


# --- discovery -----------------------------------------------------------------------------------
def _inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def find_inputs(
    input_dir: str | os.PathLike,
    *,
    exclude: Iterable[Path] = (),
    output_dir: str | os.PathLike | None = None,
) -> list[Path]:
    """Measurement files under ``input_dir`` (recursive, sorted), skipping hidden files and
    folders, ``*.modes.nc`` results, anything under the ``exclude`` folders and, inside
    ``output_dir``, the batch's report folders (``<stem>.report/``). Measurements inside
    ``output_dir`` are found like any other."""
    root = Path(input_dir)
    excluded = [Path(e).resolve() for e in exclude]
    outputs = Path(output_dir).resolve() if output_dir is not None else None
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        here = Path(dirpath)
        real = here.resolve()
        in_outputs = outputs is not None and _inside(real, outputs)
        dirnames[:] = sorted(
            d
            for d in dirnames
            if not d.startswith(".")
            and (real / d).resolve() not in excluded
            and not (in_outputs and d.endswith(REPORT_SUFFIX))
        )
        for name in sorted(filenames):
            if name.startswith(".") or name.lower().endswith(OUTPUT_SUFFIX):
                continue
            if Path(name).suffix.lower() in INPUT_SUFFIXES:
                found.append(here / name)
    return found


def output_inside_input(input_dir: Path, output_dir: Path) -> str | None:
    """``output_dir`` relative to ``input_dir`` when it lies inside it (not equal), else None."""
    inner, outer = output_dir.resolve(), input_dir.resolve()
    if inner == outer or outer not in inner.parents:
        return None
    return inner.relative_to(outer).as_posix()


#: Why ``batch DIR -o DIR`` is refused (a usage error on the command line).
BATCH_SAME_FOLDER = (
    "{path!r} is the input folder DIR; expected another folder (results would mix with the "
    "measurements), e.g. DIR/results"
)


def same_folder(a: str | os.PathLike | None, b: str | os.PathLike | None) -> bool:
    """``a`` and ``b`` name one existing folder (another spelling, a symlink or a bind mount)."""
    return a is not None and b is not None and same_file(a, b)


def output_path(input_file: Path, input_dir: Path, output_dir: Path) -> Path:
    """Where the result of ``input_file`` goes: same relative folder, ``<stem>.modes.nc``."""
    rel = input_file.relative_to(input_dir)
    return output_dir / rel.parent / (rel.stem + OUTPUT_SUFFIX)


# --- hashing and up-to-date check ----------------------------------------------------------------
def sha256(path: Path) -> str:
    """SHA-256 of the file's content, read in 1 MiB blocks (constant memory)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(_HASH_BLOCK), b""):
            h.update(chunk)
    return h.hexdigest()


def parameters_hash(parameters: dict[str, Any]) -> str:
    text = json.dumps({"pipeline": PIPELINE_VERSION, **parameters}, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def output_attrs(path: Path) -> dict[str, Any] | None:
    """Global attributes of an existing output (None when missing or unreadable)."""
    if not path.is_file():
        return None
    try:
        import netCDF4

        from ami_xr.io.lazy_source import NETCDF_LOCK

        with NETCDF_LOCK, netCDF4.Dataset(path) as nc:  # HDF5 is not thread-safe
            return {k: nc.getncattr(k) for k in nc.ncattrs()}
    except (OSError, RuntimeError, ValueError):
        return None


def up_to_date(inp: Path, out: Path, params_sha: str) -> bool:
    """Whether ``out`` is the result of ``inp``'s present content with these parameters.

    The content hash decides; a different size skips it (a new content for sure). A matching
    size and mtime never stand in for the hash (module docstring).
    """
    attrs = output_attrs(out)
    if attrs is None or attrs.get(ATTR_PARAMS_SHA) != params_sha:
        return False
    recorded = attrs.get(ATTR_INPUT_SHA)
    if not recorded:
        return False
    if str(attrs.get(ATTR_INPUT_SIZE)) != str(inp.stat().st_size):
        return False
    return recorded == sha256(inp)


# --- the summary ---------------------------------------------------------------------------------
def check_summary(output_dir: Path) -> Path:
    """The summary's path; :class:`DataFileError` when it exists and is read-only (or a folder),
    raised before any work, so nothing is computed for a summary that cannot be written."""
    path = output_dir / SUMMARY_NAME
    label = f"output_dir {str(output_dir)!r}"
    if path.is_dir():
        raise DataFileError(f"{label}: {SUMMARY_NAME} is a folder; expected the summary file")
    if path.exists():
        mode = path.stat().st_mode
        # permission bits as well as access(2): root passes access() for a 0444 file
        if not (os.access(path, os.W_OK) and mode & _WRITE_BITS):
            raise DataFileError(
                f"{label}: {SUMMARY_NAME} exists and is read-only (mode "
                f"{stat.S_IMODE(mode):04o}); make it writable or choose another output folder"
            )
    return path


# --- the plan and the rows --------------------------------------------------------------------
def summary_row(
    rel: str, out_rel: str, status: str, message: str = "", modes="", frequencies_hz=""
):
    """One summary row (the fields of SUMMARY_FIELDS)."""
    return {
        "file": rel,
        "status": status,
        "modes": modes,
        "frequencies_hz": frequencies_hz,
        "output": out_rel,
        "seconds": 0.0,
        "message": message,
    }


def modal_summary(ds) -> tuple[int, str]:
    """The number of modes of a result and their natural frequencies (Hz, sorted, as text)."""
    if names.EIGENVALUE not in ds:
        return 0, ""
    import numpy as np

    fn = np.sort(np.abs(np.atleast_1d(ds[names.EIGENVALUE].values)) / (2 * np.pi))
    return int(fn.size), " ".join(f"{f:.4f}" for f in fn)


def modal_summary_from_file(path: Path) -> tuple[int | str, str]:
    """:func:`modal_summary` of the result file ``path`` (empty fields when it cannot be read)."""
    try:
        from ami_xr.io.netcdf import open_dataset

        return modal_summary(open_dataset(path))
    except (AmiXrValueError, OSError):
        return "", ""


def reconcile(rows: dict[str, dict], jobs: list[dict]) -> None:
    """Rows for outputs written but not reported (the parent stopped before a worker's result
    came back): the summary lists exactly the outputs on disk."""
    for job in jobs:
        if rows.get(job["rel"]):
            continue
        out = Path(job["output"])
        try:
            if not up_to_date(Path(job["input"]), out, job["params_sha"]):
                continue
        except OSError:
            continue
        count, freqs = modal_summary_from_file(out)
        caps = flags.run_status(output_attrs(out) or {}).text()
        status = STATUS_CAPPED if caps else STATUS_OK
        rows[job["rel"]] = summary_row(
            job["rel"],
            job["out_rel"],
            status,
            "written; the batch stopped before its report",
            modes=count,
            frequencies_hz=freqs,
        )


def plan(
    inputs: list[Path], input_dir: Path, output_dir: Path, shared: dict[str, Any], force: bool
) -> tuple[dict[str, dict], list[dict]]:
    """Summary rows keyed by relative input path (final for name collisions and up-to-date
    files, empty for the others) and one job per file to process (``shared`` plus its paths)."""
    rows: dict[str, dict] = {}
    jobs, claimed = [], {}
    for inp in inputs:
        out = output_path(inp, input_dir, output_dir)
        rel = inp.relative_to(input_dir).as_posix()
        out_rel = out.relative_to(output_dir).as_posix()
        if out in claimed:
            rows[rel] = summary_row(
                rel,
                out_rel,
                STATUS_FAILED,
                f"output name collides with that of {claimed[out]}; rename one of the files",
            )
            continue
        claimed[out] = rel
        try:  # a named pipe would block the batch forever: refused before anything opens it
            check_input(inp, name=rel)
        except DataFileError as err:
            why = relative_paths(str(err), {inp: rel}, shared["folders"])  # no machine path
            rows[rel] = summary_row(rel, "", STATUS_FAILED, why)
            continue
        if not force and up_to_date(inp, out, shared["params_sha"]):
            count, freqs = modal_summary_from_file(out)
            caps = flags.run_status(output_attrs(out) or {}).text()
            status, message = STATUS_UP_TO_DATE, ""
            if caps:  # an up-to-date incomplete result stays incomplete
                status, message = STATUS_CAPPED, f"up to date; stopped at cap(s): {caps}"
            rows[rel] = summary_row(
                rel, out_rel, status, message, modes=count, frequencies_hz=freqs
            )
            continue
        rows[rel] = {}
        paths = {"input": str(inp), "output": str(out), "rel": rel, "out_rel": out_rel}
        jobs.append({**paths, **shared})
    return rows, jobs
