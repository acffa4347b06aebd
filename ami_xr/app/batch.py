"""Batch processing of a whole test campaign: every measurement file in a folder tree -> modes.

:func:`batch` walks ``input_dir`` for netCDF (``.nc``), UFF (``.uff``, ``.unv``) and LabVIEW
(``.lvm``) files, runs each through the pipeline (time histories -> :func:`ami_xr.frf`;
FRFs -> :func:`ami_xr.identify`) and writes ``<output_dir>/<same relative folder>/<stem>.modes.nc``.

Guarantees
----------
* **Atomic outputs.** Each result is written with :func:`ami_xr.to_netcdf` (temporary file in the
  target folder, then a rename), so an output file is either complete or absent; a crash,
  ``kill`` or Ctrl-C never leaves a partial result (temporary folders left by a killed run are
  removed at the start of the next run). A Ctrl-C or SIGTERM (also one sent to the whole
  process group) stops the batch within about a second: queued files are not started, files in
  progress stop at their next safe point (:mod:`ami_xr.interrupt`) with their output rolled
  back, the summary is written and ``KeyboardInterrupt`` (SIGINT) or ``SystemExit(143)``
  (SIGTERM) is raised. The summary lists exactly the outputs on disk: a file whose result was
  written but not yet reported when the signal came is listed from its output.
* **Resumable, incremental.** Each output records the SHA-256 of its input file, the input's size
  and mtime, and a hash of the pipeline parameters (attributes ``batch_input_sha256``,
  ``batch_parameters_sha256``). A re-run skips a file whose output matches both (the content
  hash decides, always: a touched but unchanged input is still up to date, and an input
  changed in place with the same size and mtime is redone) and redoes it otherwise;
  ``force=True`` redoes everything (:mod:`ami_xr.app.batch_files`).
* **One bad file never stops the batch.** Its error is reported in the summary (status
  ``failed``) and the others go on.
* **An incomplete result is not a success.** A file whose identification stopped at a cap
  (attribute ``ami_capped`` non-empty: ``subtract:max_modes``, ``refine:add_modes``, ...) gets
  status ``capped`` (also when its output is up to date), is counted apart in the summary line
  and makes ``ami-xr batch`` exit with 4 when no file failed (3 when some failed).
* **Summary.** ``<output_dir>/batch_summary.csv`` (file, status, modes found, natural frequencies
  in Hz, output, seconds, message), written atomically after every run; an existing read-only
  summary is refused before any work (:class:`~ami_xr.errors.DataFileError`).
* **Outputs inside the inputs.** The batch's own outputs are left out by name (``*.modes.nc``,
  report folders), never by folder: an ``output_dir`` inside ``input_dir`` that holds
  measurements has them processed, with a one-line notice on stderr.
* **No machine path in an output file.** The summary (messages too) and the outputs name files
  relative to ``input_dir`` and ``output_dir`` (:func:`ami_xr.app.redact.relative_paths`).
"""

from __future__ import annotations

import concurrent.futures as cf
import csv
import json
import os
import signal
import sys
import time
import traceback
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ami_xr import interrupt, names, provenance
from ami_xr.app.batch_files import (
    ATTR_INPUT,
    ATTR_INPUT_MTIME,
    ATTR_INPUT_SHA,
    ATTR_INPUT_SIZE,
    ATTR_PARAMS,
    ATTR_PARAMS_SHA,
    OUTPUT_SUFFIX,
    REPORT_SUFFIX,
    STATUS_CAPPED,
    STATUS_FAILED,
    STATUS_OK,
    STATUS_UP_TO_DATE,
    SUMMARY_FIELDS,
    SUMMARY_NAME,
    check_summary,
    find_inputs,
    output_inside_input,
    output_path,
    parameters_hash,
    sha256,
)
from ami_xr.app.batch_files import modal_summary as _modal_summary
from ami_xr.app.batch_files import plan as _plan
from ami_xr.app.batch_files import reconcile as _reconcile
from ami_xr.app.batch_files import summary_row as _row
from ami_xr.app.redact import relative_paths
from ami_xr.core import flags
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.atomic import atomic_folder, atomic_open, interrupts_deferred, remove_stale
from ami_xr.io.formats import read_any
from ami_xr.io.reference_modes import compare_modes, frfs_and_modes
from ami_xr.progress import Progress, notice

__all__ = [
    "batch",
    "BatchSummary",
    "estimate_frf",
    "find_inputs",
    "output_path",
]


@dataclass
class BatchSummary:
    """Outcome of :func:`batch`: one row per input file, and where the summary CSV is.

    Attributes
    ----------
    rows : list of dict
        Keys ``file`` (path relative to the input folder), ``status`` ("ok", "up to date",
        "capped": identified but stopped at a cap listed in ``message``, or "failed"),
        ``modes`` (number found, "" when failed), ``frequencies_hz`` (space-separated
        natural frequencies), ``output`` (relative to the output folder), ``seconds``,
        ``message`` (error or warnings).
    csv_path : pathlib.Path
        The summary CSV.
    """

    rows: list[dict[str, Any]] = field(default_factory=list)
    csv_path: Path | None = None

    @property
    def n_failed(self) -> int:
        """Number of files that failed."""
        return sum(r["status"] == STATUS_FAILED for r in self.rows)

    @property
    def n_capped(self) -> int:
        """Number of files whose identification stopped at a cap (incomplete, not failed)."""
        return sum(r["status"] == STATUS_CAPPED for r in self.rows)

    @property
    def ok(self) -> bool:
        """True when no file failed and none stopped at a cap."""
        return self.n_failed == 0 and self.n_capped == 0

    def format(self, width: int = 60) -> str:
        """The summary as an aligned text table."""
        header = ("file", "status", "modes", "frequencies [Hz]")
        body = []
        for r in self.rows:
            freqs = r["frequencies_hz"]
            if len(freqs) > width:
                freqs = freqs[: width - 3] + "..."
            status = r["status"]
            if status == STATUS_FAILED:
                freqs = r["message"].splitlines()[0][:width] if r["message"] else ""
            body.append(tuple(map(_printable, (r["file"], status, str(r["modes"]), freqs))))
        if not body:
            return "no input files found"
        widths = [max(len(h), *(len(row[i]) for row in body)) for i, h in enumerate(header)]
        lines = [
            "  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip(),
            "  ".join("-" * w for w in widths),
        ]
        lines += [
            "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip() for row in body
        ]
        counts = {
            s: sum(r["status"] == s for r in self.rows)
            for s in (STATUS_OK, STATUS_UP_TO_DATE, STATUS_CAPPED, STATUS_FAILED)
        }
        lines.append(
            f"{len(self.rows)} file(s): {counts[STATUS_OK]} processed, "
            f"{counts[STATUS_UP_TO_DATE]} up to date, {counts[STATUS_CAPPED]} capped "
            f"(incomplete), {counts[STATUS_FAILED]} failed"
        )
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.format()


def _printable(text: Any) -> Any:
    """``text`` with the bytes of a file name that is not valid UTF-8 shown as ``\\xff``.

    ``os.walk`` hands such names over with surrogate escapes, which no UTF-8 file or terminal
    can take; other values pass unchanged.
    """
    if not isinstance(text, str):
        return text
    try:
        text.encode("utf-8")
        return text
    except UnicodeEncodeError:
        pass
    try:
        raw = text.encode("utf-8", "surrogateescape")
    except UnicodeEncodeError:  # a lone surrogate that is no escaped byte
        return text.encode("utf-8", "backslashreplace").decode("utf-8")
    return raw.decode("utf-8", "backslashreplace")


# --- one file ---------------------------------------------------------------------------------
def estimate_frf(ts, frf_options: dict[str, Any] | None = None):
    """FRFs of a time Dataset by :func:`ami_xr.dsp.frf.frf_from_options`; without an
    ``excitation`` option the one rule of ``ami-xr frf`` decides (``"auto"``:
    :func:`ami_xr.dsp.timeseries.excitation_of`), so batch and frf treat a file alike."""
    from ami_xr.dsp.frf import frf_from_options

    options = dict(frf_options or {})
    options.setdefault("excitation", "auto")
    return frf_from_options(ts, options)


BATCH_FUNCTION = "ami_xr.batch"  # the provenance record of each output


def _process_one(job: dict[str, Any]) -> dict[str, Any]:
    """Run the pipeline on one file (in a worker process); never raises for a bad file."""
    import ami_xr
    from ami_xr.ami import identify

    inp, out = Path(job["input"]), Path(job["output"])
    row = _row(job["rel"], job["out_rel"], STATUS_FAILED)
    start = time.perf_counter()
    try:
        # one record per output, the batch's, with the read and identify as its steps
        with warnings.catch_warnings(record=True) as caught, provenance.command(BATCH_FUNCTION):
            warnings.simplefilter("always")
            input_sha = sha256(inp)
            st = inp.stat()
            ds, given = frfs_and_modes(read_any(inp), job["rel"])
            if names.FRF not in ds:
                ds = estimate_frf(ds, job["frf_options"])
            result = identify(ds, **job["identify_options"])
            if given is not None:  # the file's own modes, kept as the reference set
                result = compare_modes(result, given)
            result.attrs.update(
                {
                    ATTR_INPUT: job["rel"],
                    ATTR_INPUT_SHA: input_sha,
                    ATTR_INPUT_SIZE: str(st.st_size),
                    ATTR_INPUT_MTIME: str(st.st_mtime_ns),
                    ATTR_PARAMS_SHA: job["params_sha"],
                    ATTR_PARAMS: json.dumps(job["parameters"], sort_keys=True, default=repr),
                }
            )
            out.parent.mkdir(parents=True, exist_ok=True)
            if job["report"]:
                from ami_xr.app.report import report

                # Report first: the netCDF output appearing marks the whole file as done.
                folder = out.with_name(out.name[: -len(OUTPUT_SUFFIX)] + REPORT_SUFFIX)
                with atomic_folder(folder) as tmp:  # swapped in whole: never a partial report
                    report(result, tmp)
            # a stop held since identify's last checkpoint ends the file here, before its write
            # starts: a worker whose parent died exits after PARENT_GRACE_SECONDS, and a write
            # begun at the end of that grace left its temporary folder (min-versions run)
            interrupt.checkpoint()
            ami_xr.to_netcdf(result, out, parameters=job["parameters"])  # BATCH_FUNCTION's
        row["modes"], row["frequencies_hz"] = _modal_summary(result)
        caps = flags.run_status(result.attrs).text()
        row["status"] = STATUS_CAPPED if caps else STATUS_OK
        messages = sorted(
            {
                f"{w.category.__name__}: {w.message}"
                for w in caught
                if issubclass(w.category, UserWarning)
            }
        )
        if caps:
            messages.insert(0, f"stopped at cap(s): {caps}")
        row["message"] = "; ".join(messages)
    except Exception as err:  # a bad file must not stop the batch: report it and go on
        first = str(err).strip().splitlines()
        row["message"] = f"{type(err).__name__}: {' '.join(s.strip() for s in first)}"
        if job.get("traceback"):
            row["traceback"] = traceback.format_exc()
    files = {inp: job["rel"], out: job["out_rel"]}  # no machine path in the summary
    row["message"] = relative_paths(row["message"], files, job["folders"])
    row["seconds"] = round(time.perf_counter() - start, 3)
    return row


# --- the batch ----------------------------------------------------------------------------------
def _write_summary(rows: list[dict], path: Path) -> None:
    # Held Ctrl-C: the summary of an interrupted batch is written in full (it is small).
    with interrupts_deferred(), atomic_open(path, "w") as fh:
        writer = csv.DictWriter(fh, fieldnames=SUMMARY_FIELDS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows({k: _printable(v) for k, v in row.items()} for row in rows)


def _worker_init(stop_event, parent: int | None = None, threads: int | None = None) -> None:
    """In a worker process: Ctrl-C from the terminal is the parent's to decide (ignored here);
    the parent's stop request (``stop_event``) and a SIGTERM sent to the process group are held
    and raised at the worker's next checkpoint (:mod:`ami_xr.interrupt`). A watchdog thread
    ends the worker when its parent (process id ``parent``) is gone (:func:`_watch_parent`).
    ``threads``: the compute threads this worker may use (its share of the cores)."""
    if threads is not None:
        from ami_xr.kernels.projection import THREADS_ENV

        os.environ[THREADS_ENV] = str(threads)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, interrupt.hold)
    interrupt.use_event(stop_event)
    if parent is not None:
        import threading

        threading.Thread(
            target=_watch_parent,
            args=(parent, stop_event),
            name="ami_xr-parent-watch",
            daemon=True,
        ).start()


#: Seconds between two looks of a batch worker at its parent process.
PARENT_POLL_SECONDS = 0.25
#: Seconds a worker whose parent died gets to stop at a checkpoint before it exits regardless.
PARENT_GRACE_SECONDS = 2.0


def _watch_parent(parent: int, stop_event=None) -> None:
    """Stop this worker once process ``parent`` is no longer its parent (killed, also by
    SIGKILL, which it cannot catch): the file in progress stops at its next checkpoint with its
    output rolled back, as for SIGTERM; after :data:`PARENT_GRACE_SECONDS` the worker exits
    regardless (a worker idle between files, or in a long kernel). ``stop_event`` (the batch's
    stop request) is set too, so that the stop holds at every later checkpoint: a held signal
    is raised once, and the worker then took the next queued file and was cut off inside its
    write, leaving the temporary folder."""
    while os.getppid() == parent:
        time.sleep(PARENT_POLL_SECONDS)
    if stop_event is not None:
        stop_event.set()
    interrupt.hold(signal.SIGTERM, None)
    time.sleep(PARENT_GRACE_SECONDS)
    os._exit(interrupt.EXIT_TERMINATED)


def _process_in_worker(job: dict[str, Any]) -> dict[str, Any] | None:
    """:func:`_process_one` in a worker; None when a stop request ended it (output rolled back)."""
    try:
        with interrupt.armed():
            interrupt.checkpoint()  # stopped while queued in the worker: do not start
            return _process_one(job)
    except (KeyboardInterrupt, SystemExit):
        return None


def _run_jobs(jobs: list[dict], workers: int) -> Iterator[dict]:
    """Rows of the files processed; a signal (held by :func:`ami_xr.interrupt.armed`) stops the
    queued files at once and the running ones at their next checkpoint, then is raised."""
    if workers == 1 or len(jobs) <= 1:
        for job in jobs:
            interrupt.checkpoint()
            yield _process_one(job)
        interrupt.checkpoint()
        return
    import multiprocessing

    from ami_xr.kernels.projection import compute_threads  # numba: only when workers run

    stop_event = multiprocessing.get_context().Event()
    pool = cf.ProcessPoolExecutor(
        max_workers=min(workers, len(jobs)),
        initializer=_worker_init,
        # each worker its share of the cores (no more compute threads than the batch's cores)
        initargs=(stop_event, os.getpid(), max(1, compute_threads() // min(workers, len(jobs)))),
    )
    futures = {pool.submit(_process_in_worker, job): job for job in jobs}
    try:
        waiting = set(futures)
        while waiting:
            # wake often: a signal held while this thread waits is acted on within POLL_SECONDS
            done, waiting = cf.wait(waiting, timeout=POLL_SECONDS, return_when=cf.FIRST_COMPLETED)
            if interrupt.pending() is not None and not stop_event.is_set():
                stop_event.set()  # running files stop at their next checkpoint
                notice(
                    "\nami-xr batch: stopping: files in progress are rolled back, queued ones "
                    "not started"
                )
                for fut in waiting:
                    fut.cancel()  # queued files are not started
            for fut in done:
                if fut.cancelled():
                    continue
                try:
                    row = fut.result()
                except cf.process.BrokenProcessPool as err:
                    # A worker died (e.g. killed for memory): report the files it did not finish.
                    job = futures[fut]
                    row = _row(job["rel"], job["out_rel"], STATUS_FAILED, f"worker died: {err}")
                if row is not None:
                    yield row
        interrupt.checkpoint()
    finally:
        # A signal or an error: workers stop at their next checkpoint, queued files are dropped;
        # finished outputs are complete, the others absent (to_netcdf removes its temporary file).
        stop_event.set()
        pool.shutdown(wait=True, cancel_futures=True)


#: Seconds between two looks of the batch parent at a held signal while workers run.
POLL_SECONDS = 0.2


def batch(
    input_dir: str | os.PathLike,
    output_dir: str | os.PathLike,
    *,
    workers: int = 1,
    identify_options: dict[str, Any] | None = None,
    frf_options: dict[str, Any] | None = None,
    report: bool = False,
    force: bool = False,
    progress: bool = True,
    keep_tracebacks: bool = False,
) -> BatchSummary:
    """Identify the modes of every measurement file in a folder tree.

    Parameters
    ----------
    input_dir : str or path-like
        Folder searched recursively for ``.nc`` (FRF or time Datasets), ``.uff``/``.unv``
        (dataset 58) and ``.lvm`` files. Hidden files and folders and ``*.modes.nc`` files are
        skipped, and so are the report folders inside ``output_dir``: an ``output_dir`` inside
        ``input_dir`` is named in a notice on stderr, and the measurements in it are processed.
    output_dir : str or path-like
        Results go to ``<output_dir>/<relative folder>/<stem>.modes.nc`` (created as needed),
        the summary to ``<output_dir>/batch_summary.csv``.
    workers : int, default 1
        Number of files processed in parallel (separate processes).
    identify_options : dict, optional
        Keyword arguments of :func:`ami_xr.identify` (e.g. ``{"method": "paper"}``).
    frf_options : dict, optional
        Keyword arguments of :func:`ami_xr.frf`, used for time-history files.
    report : bool, default False
        Also write a report folder ``<stem>.report/`` (needs matplotlib) next to each result.
    force : bool, default False
        Redo files whose outputs are up to date.
    progress : bool, default True
        Show a progress bar on stderr (tqdm when installed).
    keep_tracebacks : bool, default False
        Keep the full traceback of failed files in the rows (key ``traceback``).

    Returns
    -------
    BatchSummary
        One row per file; ``summary.ok`` is False when any file failed or stopped at a cap.

    Raises
    ------
    DataFileError
        ``input_dir`` is not a folder, ``output_dir`` is a file, or
        ``<output_dir>/batch_summary.csv`` exists and is read-only (refused before any work).
    AmiXrValueError
        ``workers`` is not a positive integer, or an options argument is not a dict.
    """
    input_dir, output_dir = Path(input_dir), Path(output_dir)
    if not input_dir.is_dir():
        raise DataFileError(f"input_dir: {str(input_dir)!r} is not a folder")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise AmiXrValueError(f"workers: expected a positive integer, got {workers!r}")
    for argument, value in (("identify_options", identify_options), ("frf_options", frf_options)):
        if value is not None and not isinstance(value, dict):
            raise AmiXrValueError(
                f"{argument}: expected a dict of keyword arguments, got {type(value).__name__}"
            )
    if output_dir.exists() and not output_dir.is_dir():
        raise DataFileError(f"output_dir: {str(output_dir)!r} exists and is not a folder")
    summary = BatchSummary(csv_path=check_summary(output_dir))  # a read-only one: before work
    rows, jobs, inputs, planned = {}, [], [], False
    try:  # a Ctrl-C from here on (also while planning) still leaves the summary
        output_dir.mkdir(parents=True, exist_ok=True)
        remove_stale(output_dir)
        opts = {"identify": identify_options or {}, "frf": frf_options or {}}
        parameters = {**opts, "report": bool(report)}
        params_sha = parameters_hash(parameters)
        inputs = find_inputs(input_dir, output_dir=output_dir)  # outputs by name, not by folder
        inner = output_inside_input(input_dir, output_dir)
        if inner is not None:
            notice(
                f"ami-xr batch: the output folder {inner} is inside the input folder: its "
                f"results (*{OUTPUT_SUFFIX}, *{REPORT_SUFFIX}/, {SUMMARY_NAME}) are not read as "
                "inputs, the measurements in it are processed"
            )
        shared = {
            "folders": [str(input_dir), str(output_dir)],  # messages name files relative to them
            "identify_options": identify_options or {},
            "frf_options": frf_options or {},
            "parameters": parameters,
            **{"params_sha": params_sha, "report": report, "traceback": keep_tracebacks},
        }
        rows, jobs = _plan(inputs, input_dir, output_dir, shared, force)
        planned = True
        with (
            interrupt.armed(),
            Progress("ami-xr batch", total=len(jobs), unit="file", enabled=progress) as bar,
        ):
            for row in _run_jobs(jobs, workers):
                rows[row["file"]] = row
                bar.update(1)
    finally:
        # Also on Ctrl-C, and a second one waits for it: the summary lists what is done
        # (unfinished files have empty rows). An error before the plan leaves no summary.
        stopped = isinstance(sys.exc_info()[1], (KeyboardInterrupt, SystemExit))
        if output_dir.is_dir() and (planned or stopped):
            with interrupts_deferred():
                _reconcile(rows, jobs)
                summary.rows = [
                    rows[inp.relative_to(input_dir).as_posix()]
                    for inp in inputs
                    if rows.get(inp.relative_to(input_dir).as_posix())
                ]
                _write_summary(summary.rows, summary.csv_path)
    return summary
