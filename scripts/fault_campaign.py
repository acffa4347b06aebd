"""Fault-injection campaign: nothing lost, nothing hangs, no traceback (issue 9).

Usage::

    python scripts/fault_campaign.py                       # default: 1600 faults, 2 processes
    python scripts/fault_campaign.py --quick --points 60   # issue-25 categories, a few each
    python scripts/fault_campaign.py --cases 200 --seed 3 --categories truncate flip
    python scripts/fault_campaign.py --workers 4 --keep /tmp/campaign

Categories (each case is one injected fault):

``truncate``    every supported input (netCDF FRF and time files, UFF ASCII and binary, LVM)
                cut at a random byte, fed to ``ami-xr convert/identify/frf``
``flip``        the same files with 1-8 random bytes changed
``signal``      SIGINT, SIGTERM, SIGKILL (or a double SIGINT) at a random moment of
                ``ami-xr convert big.nc -o out.nc`` (a file of tens of MB), over an existing
                destination or none
``batch``       the same signals during ``ami-xr batch``
``concurrent``  2-4 ``ami-xr convert`` processes writing one destination at the same time
``dataset``     hypothesis-generated Datasets (valid, or with one defect) through
                ``ami_xr.validate`` and ``ami_xr.identify``

Issue 25 (faults at scale; these run the console entry point ``ami_xr.app.cli.run`` with its
signal handling):

``phase``       SIGINT or SIGTERM at a random moment of ``ami-xr identify big.nc -o m.nc -q``
                on the benchmark tiled to ``--points`` points (1000; subtraction, isolation,
                global fit, refinement, write) or of ``ami-xr convert big.nc -o b.uff``: exit
                130/143 (or 0 when it had finished), no crash, no bug-class message, output
                absent or complete, nothing left over, honoured within :data:`HONOUR_S`
``compile``     the same on a small file with an empty numba cache (first-run compilation)
``special``     a FIFO, a symlink to /dev/zero, a folder as the input of every command, a FIFO
                inside a batch folder: refused with a clear message, never a hang
``fullfs``      convert/identify under an ``RLIMIT_FSIZE`` limit (a full filesystem): exit 0
                with a complete file, or exit 1 naming the full device, the old target intact
``readonly``    numba cache and HOME unwritable (read-only folders, a plain file): the run works
``streams``     stderr closed (``2>&-``), stdout closed, stdout a pipe closed after one byte:
                exit 0, output written

Issue 42 (``scripts/fault_cases_issue42.py``):

``cluster``     ``identify --scheduler`` with no scheduler, a silent server or an HTTP server
                at the address; SIGINT/SIGTERM to ``identify --workers 2`` at a random moment
                (honoured within 2 s); SIGKILL of ``identify --workers 2`` and of ``batch
                --workers 2`` (no worker may outlive it); values that overflow in the workers
                (no raw numpy warning)
``threads``     8 threads of one process opening and identifying netCDF files (no crash)

Every outcome is classified as

``clean error``     exit code 1, 2 or 130 (or, in-process, a ``ValueError`` subclass) with a
                    one-line message that names the file or argument, no traceback;
``correct result``  exit 0 and the result equals that of the intact input (truncations), is
                    complete and valid (byte flips: a flipped data byte cannot be detected), or
                    the destination is old-or-new-complete (signals, concurrent writers);
``anything else``   a traceback, exit 0 with a wrong or partial result, a hang past the
                    timeout, a crash (killed by a signal it was not sent), an invalid Dataset
                    accepted, a lost or partial file, a temporary file left after a rerun, or
                    a changed input.

CLI cases run as real processes: ``truncate``/``flip``/``dataset`` cases in a child forked from
a worker that has already imported ``ami_xr`` (so a case costs the command's work, not the
interpreter start-up; the child runs ``ami_xr.app.cli.main`` exactly as the console script does and
is killed at the timeout), ``signal``/``batch``/``concurrent`` cases as ``ami-xr`` subprocesses.
Exits 1 when any case ends as "anything else" or any file was lost or left partial.

Written against the public API (``ami_xr.app.cli.main``, ``ami_xr.open_dataset``,
``ami_xr.read_uff``, ``ami_xr.validate``, ``ami_xr.identify``, ``ami_xr.write_uff``,
``ami_xr.make_frf_dataset``, ``ami_xr.make_time_dataset``). ``tests/test_faults.py`` runs a
small seeded subset of the same generators.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from collections import Counter, defaultdict
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

CLEAN, CORRECT, OTHER = "clean error", "correct result", "anything else"
OUTCOMES = (CLEAN, CORRECT, OTHER)
ISSUE25 = ("phase", "compile", "special", "fullfs", "readonly", "streams")
ISSUE42 = ("cluster", "threads")
CATEGORIES = ("truncate", "flip", "signal", "batch", "concurrent", "dataset", *ISSUE25, *ISSUE42)
#: Share of the default case count per category (the write-interrupt cases are slow).
DEFAULT_SHARE = {
    "truncate": 0.42,
    "flip": 0.42,
    "signal": 0.03,
    "batch": 0.015,
    "concurrent": 0.015,
    "dataset": 0.10,
    "phase": 0.14,
    "compile": 0.01,
    "special": 0.03,
    "fullfs": 0.03,
    "readonly": 0.005,
    "streams": 0.005,
    "cluster": 0.01,
    "threads": 0.003,
}
#: --full: every category, weighted so that the signal cases on 1000 points, the cluster and the
#: thread cases stay a bounded share of the wall time on a 2-core machine.
FULL_SHARE = {
    "truncate": 0.40,
    "flip": 0.40,
    "signal": 0.02,
    "batch": 0.012,
    "concurrent": 0.015,
    "dataset": 0.06,
    "phase": 0.035,
    "compile": 0.003,
    "special": 0.02,
    "fullfs": 0.015,
    "readonly": 0.003,
    "streams": 0.004,
    "cluster": 0.011,
    "threads": 0.002,
}
FULL_MIN_CASES = 1500
#: --quick: a few cases of every issue-25 category (minutes, not hours).
QUICK_COUNTS = {"phase": 8, "compile": 2, "special": 8, "fullfs": 6, "readonly": 2, "streams": 3}
HONOUR_S = 2.0  # a SIGINT/SIGTERM must stop the run within this (issue 25 target)
#: The phase cases signal a run within its first this many seconds: a 1000-point UFF convert
#: takes minutes on a loaded 2-core machine (442 s), and each case would wait half of it.
SIGNAL_WINDOW_S = 90.0
#: The console script as installed: run() holds signals for the safe points.
AMI_XR_RUN = [sys.executable, "-c", "from ami_xr.app.cli import run; run()"]
BUG_CLASS = ("Traceback (most recent call last)", "unexpected", "SystemError", "Segmentation")
EXIT_CLEAN = (1, 2, 130)
EXIT_BATCH_CAPPED = 4  # batch: every file done, some result stopped at a cap (not a failure)
CASE_TIMEOUT_S = 60.0  # one forked CLI or in-process case
STOP_BOUND_S = 15.0  # a process sent SIGINT/SIGTERM must be gone within this
#: Besides a file name, an error may name one of these (a variable or coordinate of the data
#: model, or an option) to count as naming what is wrong.
NAMED_THINGS = (
    "'frf'",
    "frequency",
    "'point'",
    "'time'",
    "force",
    "response",
    "coherence",
    "drive_point",
    "band",  # identify's --band: a corrupted frequency axis can leave too few lines in it
    "--",
)
TEMP_GLOB = ".*.tmp"  # temporary folders of ami_xr's atomic writer (hidden, .tmp suffix)
#: Every forked CLI case runs the console script as installed (signals held for the safe points,
#: exit handling as a user sees it), not main() unarmed
AMI_XR = AMI_XR_RUN


class Result(NamedTuple):
    """Outcome of one injected fault."""

    category: str
    case: str
    outcome: str
    detail: str = ""
    lost: tuple[str, ...] | list[str] = ()  # files lost or left partial
    audit: tuple[str, ...] | list[str] = ()  # failure classes seen in its commands (AUDIT)


# --- input files ---------------------------------------------------------------------------------

LVM_HEADER = (
    "LabVIEW Measurement\t\nWriter_Version\t2\nReader_Version\t2\nSeparator\tTab\n"
    "Decimal_Separator\t.\nMulti_Headings\tYes\nX_Columns\tNo\nTime_Pref\tAbsolute\n"
    "***End_of_Header***\t\n\t\n"
)
LVM_SEGMENT = (
    "Channels\t2\t\t\nSamples\t{n}\t{n}\t\nY_Unit_Label\tNewtons\tm/s^2\t\n"
    "X_Dimension\tTime\tTime\t\nX0\t{x0}\t{x0}\t\nDelta_X\t{dx}\t{dx}\t\n"
    "***End_of_Header***\t\t\t\nX_Value\tForce (Trigger)\tAcceleration (Trigger)\tComment\n"
)


def write_lvm(path: Path, force: np.ndarray, response: np.ndarray, dx: float) -> Path:
    """Write records (n_record, n_time) of force and response as a LabVIEW LVM file."""
    parts = [LVM_HEADER]
    for i, (f, a) in enumerate(zip(force, response, strict=True)):
        parts.append(LVM_SEGMENT.format(n=f.size, x0=float(i), dx=dx))
        parts.extend(f"\t{fi:.6e}\t{ai:.6e}\n" for fi, ai in zip(f, a, strict=True))
        parts.append("\n")
    path.write_text("".join(parts))
    return path


def small_frf(seed: int = 0, n_points: int = 3, n_frequency: int = 256, scale: float = 1.0):
    """A small valid FRF Dataset of two modes plus noise (``ami_xr.make_frf_dataset``)."""
    import ami_xr

    rng = np.random.default_rng(seed)
    f = np.linspace(0.0, 50.0, n_frequency)
    w = 2 * np.pi * f
    fn = np.sort(rng.uniform(8.0, 40.0, 2))
    zeta = rng.uniform(0.01, 0.03, 2)
    phi = rng.uniform(0.3, 1.0, (2, n_points))
    h = np.zeros((n_points, n_frequency), complex)
    for k in range(2):
        wn = 2 * np.pi * fn[k]
        h += np.outer(phi[k] * phi[k, 0], 1.0 / (wn**2 - w**2 + 2j * zeta[k] * wn * w))
    h += 1e-3 * np.abs(h).max() * (rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape))
    return ami_xr.make_frf_dataset(scale * h, f, drive_point=0, frf_type="receptance")


def small_time(seed: int = 0, n_records: int = 3, n_time: int = 512, fs: float = 256.0):
    """Impact-like force and response records (n_record, n_point=1, n_time)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_time) / fs
    force = np.zeros((n_records, n_time))
    # an asymmetric pulse: its spectrum has no exact zero (a symmetric 4-tap one is 0 at Nyquist)
    force[:, 5:10] = np.array([0.3, 0.8, 1.0, 0.6, 0.2]) * rng.uniform(50, 100, (n_records, 1))
    kernel = np.exp(-3.0 * t) * np.sin(2 * np.pi * 20.0 * t)
    response = np.array([np.convolve(fr, kernel)[:n_time] for fr in force])
    response += 1e-3 * rng.standard_normal(response.shape)
    return force, response, fs


#: The intact inputs, one per supported format: FRF and time netCDF, UFF dataset 58 FRFs in
#: ASCII and binary, UFF time responses, LabVIEW LVM hammer hits.
INPUT_NAMES = ("frf.nc", "time.nc", "frf_ascii.uff", "frf_binary.uff", "time.uff", "hits.lvm")


def make_inputs(folder: Path, seed: int = 0) -> dict[str, Path]:
    """The intact input files of every supported format, written into ``folder``."""
    import ami_xr

    folder.mkdir(parents=True, exist_ok=True)
    g = small_frf(seed)
    force, response, fs = small_time(seed)
    tds = ami_xr.make_time_dataset(
        response[:, None, :], fs=fs, force=force, drive_point=0, response_quantity="displacement"
    )
    files = {name: folder / name for name in INPUT_NAMES}
    ami_xr.to_netcdf(g, files["frf.nc"])
    ami_xr.to_netcdf(tds, files["time.nc"])
    ami_xr.write_uff(g, files["frf_ascii.uff"])
    ami_xr.write_uff(g, files["frf_binary.uff"], binary=True)
    ami_xr.write_uff(tds, files["time.uff"])
    write_lvm(files["hits.lvm"], force, response, 1.0 / fs)
    return files


def commands_for(name: str) -> list[list[str]]:
    """CLI commands (``IN`` = the input, ``OUT.x`` = an output) run on an input file."""
    if name.startswith("frf"):
        out = "OUT.uff" if name.endswith(".nc") else "OUT.nc"
        return [["convert", "IN", "-o", out], ["identify", "IN", "-q", "--no-refine"]]
    if name.endswith(".nc"):
        return [["convert", "IN", "-o", "OUT.uff"], ["frf", "IN", "-o", "OUT.nc"]]
    return [["convert", "IN", "-o", "OUT.nc"], ["frf", "IN", "-o", "OUT.nc"]]


# --- running one CLI command in a forked child ---------------------------------------------------


def _child_cli(argv: list[str]) -> int:
    from ami_xr.app.cli import main

    try:
        return int(main(argv) or 0)
    except SystemExit as err:  # argparse; the console script turns these into the exit code
        return err.code if isinstance(err.code, int) else 1
    except BaseException:  # what the console script would print: a raw traceback
        traceback.print_exc()
        return 1


def run_forked(
    func: Callable[..., int], args: tuple, cwd: Path, timeout: float = CASE_TIMEOUT_S
) -> tuple[int | None, str, str, float]:
    """Run ``func(*args)`` in a forked child in ``cwd``; (exit code or None on hang, out, err, s).

    The child gets default signal handling and its own stdout/stderr files; it is killed with
    its process group when it runs past ``timeout``.
    """
    out_path, err_path = cwd / ".stdout", cwd / ".stderr"
    start = time.monotonic()
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # child
        code = 1
        try:
            os.setpgid(0, 0)
            os.chdir(cwd)
            signal.signal(signal.SIGINT, signal.default_int_handler)
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            fd_out = os.open(out_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            fd_err = os.open(err_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            os.dup2(fd_out, 1)
            os.dup2(fd_err, 2)
            # the parent's sys.stdout may not write to fd 1 (pytest's capture replaces it)
            sys.stdout = open(1, "w", closefd=False)  # noqa: SIM115
            sys.stderr = open(2, "w", closefd=False)  # noqa: SIM115
            code = func(*args)
        except BaseException:
            traceback.print_exc()
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code)
    code: int | None = None
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            code = os.waitstatus_to_exitcode(status)
            break
        if time.monotonic() - start > timeout:
            try:
                os.killpg(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            os.waitpid(pid, 0)
            break
        time.sleep(0.005)
    elapsed = time.monotonic() - start
    read = lambda p: p.read_text(errors="replace") if p.exists() else ""  # noqa: E731
    out, err = read(out_path), read(err_path)
    for p in (out_path, err_path):
        p.unlink(missing_ok=True)
    _SEEN.append((code, err))
    return code, out, err, elapsed


# --- checks shared by the categories -------------------------------------------------------------


def digest(path: Path) -> str | None:
    """SHA-256 of a file, or None when it does not exist."""
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None


def leftovers(folder: Path) -> list[str]:
    """Temporary files/folders of the atomic writer anywhere under ``folder``."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob(TEMP_GLOB))


def read_result(path: Path):
    """An output file as a Dataset (netCDF or UFF), loaded; raises if unreadable."""
    import ami_xr

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if path.suffix == ".nc":
            with ami_xr.open_dataset(path) as ds:
                return ds.load()
        return ami_xr.read_uff(path)


def same_data(a, b) -> bool:
    """Same variables, coordinates and values (attributes such as provenance ignored)."""
    try:
        return bool(a.equals(b))
    except Exception:  # noqa: BLE001 - different structures compare unequal
        return False


def clean_error(code: int | None, err: str, names: list[str]) -> tuple[bool, str]:
    """Whether (exit code, stderr) is a clean error; else why not.

    Clean: exit 1, 2 or 130, no traceback, one error line (warning lines aside) that names
    one of ``names`` (the files) or of :data:`NAMED_THINGS`, and is not the CLI's
    "unexpected ... (run with -v ...)" fallback.
    """
    if code not in EXIT_CLEAN:
        return False, f"exit code {code}"
    if "Traceback (most recent call last)" in err:
        return False, "traceback on stderr: " + err.strip().splitlines()[-1][:200]
    lines = [ln for ln in err.strip().splitlines() if ln.strip() and ": warning: " not in ln]
    if code == 2:  # argparse usage error: usage lines plus one error line
        return (bool(lines) and "error:" in lines[-1]), "usage error without an error line"
    if code == 130:
        return True, ""
    if len(lines) != 1:
        return False, f"{len(lines)} error lines: " + " | ".join(lines)[:300]
    if "run with -v" in lines[0]:  # the CLI's fallback for an exception nobody anticipated
        return False, f"unexpected exception: {lines[0][:300]}"
    if not any(n in lines[0] for n in (*names, *NAMED_THINGS)):
        return False, f"error names no file or argument ({names}): {lines[0][:200]}"
    return True, ""


# --- categories truncate and flip ----------------------------------------------------------------

REFERENCE: dict[tuple[str, int], tuple[int, str, Any]] = {}  # per worker: intact-input results


def _prepare_case(work: Path, src: Path, argv: list[str]) -> tuple[Path, list[str], Path | None]:
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="case"))
    target = case_dir / src.name
    shutil.copyfile(src, target)
    out = None
    real = []
    for a in argv:
        if a == "IN":
            real.append(src.name)
        elif a.startswith("OUT"):
            out = case_dir / ("result" + Path(a).suffix)
            real.append(out.name)
        else:
            real.append(a)
    return case_dir, real, out


def _reference(work: Path, src: Path, k: int) -> tuple[int, str, Any]:
    key = (str(src), k)
    if key not in REFERENCE:
        case_dir, argv, out = _prepare_case(work, src, commands_for(src.name)[k])
        code, stdout, _, _ = run_forked(_child_cli, (argv,), case_dir)
        data = read_result(out) if out is not None and out.exists() else None
        REFERENCE[key] = (code, stdout, data)
        shutil.rmtree(case_dir)
    return REFERENCE[key]


def undetectable_cut(data: bytes, cut: int, suffix: str) -> bool:
    """Whether ``data[:cut]`` is itself a well-formed file, so no reader can see the cut.

    UFF has no dataset count: a cut between two datasets (the kept part ends with a closing
    ``-1`` line, the rest starts with the next opening one) leaves a valid file of fewer
    datasets. LVM has no checksum: a cut at the end of a segment, or inside the last value of
    a segment's last row (``4.123e-01`` -> ``4.12``), leaves a valid file. Anything else is
    detectable (a dataset without its ``-1``, a segment short of its ``Samples``).
    """
    kept, rest = data[:cut], data[cut:]
    if suffix == ".uff":
        return kept.rstrip().endswith(b"-1") and rest.lstrip().startswith(b"-1")
    line_start = kept.rfind(b"\n") + 1
    line_end = data.find(b"\n", cut)
    line_end = len(data) if line_end < 0 else line_end
    full, partial = data[line_start:line_end], kept[line_start:]
    after = data[line_end:].strip()
    at_segment_end = not after or after.startswith(b"Channels")
    if not partial.strip():  # cut at a line start: fine only after a segment's last row
        return not full.strip() or (at_segment_end and not full.strip(b"\t "))
    same_fields = partial.count(b"\t") == full.count(b"\t") and partial.split(b"\t")[-1]
    return at_segment_end and bool(same_fields) and partial[-1:].isdigit()


def corrupt(data: bytes, kind: str, rng: random.Random) -> tuple[bytes, str]:
    """Truncate ``data`` at a random byte, or change 1-8 random bytes; (new data, what)."""
    if kind == "truncate":
        cut = rng.randrange(0, len(data))
        return data[:cut], f"cut at byte {cut} of {len(data)}"
    buf = bytearray(data)
    where = sorted(rng.randrange(len(buf)) for _ in range(rng.randint(1, 8)))
    for i in where:
        buf[i] = (buf[i] + rng.randrange(1, 256)) % 256
    return bytes(buf), f"bytes changed at {where}"


def file_fault_case(
    kind: str, src: Path, k: int, seed: int, work: Path, timeout: float = CASE_TIMEOUT_S
) -> Result:
    """One truncation or byte-flip case: fault ``src``, run command ``k`` on it, classify.

    A command still running after ``timeout`` seconds is killed and counts as a hang.
    """
    rng = random.Random(seed)
    ref_code, ref_out, ref_data = _reference(work, src, k)
    case_dir, argv, out = _prepare_case(work, src, commands_for(src.name)[k])
    target = case_dir / src.name
    original = src.read_bytes()
    bad, what = corrupt(original, kind, rng)
    undetectable = kind == "truncate" and undetectable_cut(original, len(bad), src.suffix)
    what += " (a well-formed shorter file)" if undetectable else ""
    target.write_bytes(bad)
    before = digest(target)
    code, stdout, err, elapsed = run_forked(_child_cli, (argv,), case_dir, timeout)
    label = f"ami-xr {' '.join(argv)} ({src.name} {what}, seed {seed})"
    lost = []
    try:
        if code is None:
            return Result(kind, label, OTHER, f"hang: no exit within {timeout:.0f} s")
        if digest(target) != before:
            lost.append(f"{label}: input changed")
        left = leftovers(case_dir)
        if left:
            lost.append(f"{label}: temporary files left: {left}")
        if code != 0:
            ok, why = clean_error(code, err, [src.name] + ([out.name] if out else []))
            if out is not None and out.exists():
                lost.append(f"{label}: output written although exit {code}")
            return Result(kind, label, CLEAN if ok and not lost else OTHER, why, lost)
        if "Traceback (most recent call last)" in err:
            return Result(kind, label, OTHER, "exit 0 with a traceback on stderr", lost)
        if out is None:  # identify: a flipped value may change the modes legitimately
            good = kind == "flip" or undetectable or (ref_code == 0 and stdout == ref_out)
            why = "" if good else "exit 0 but printed table differs from the intact file's"
        else:
            try:
                data = read_result(out)
            except Exception as exc:  # noqa: BLE001 - any unreadable output is partial
                lost.append(f"{label}: output unreadable: {type(exc).__name__}: {exc}")
                return Result(kind, label, OTHER, "exit 0 with an unreadable output", lost)
            if kind == "truncate" and not undetectable:
                good = ref_data is not None and same_data(data, ref_data)
                why = "" if good else "exit 0 with a result that differs from the intact file's"
            elif kind == "truncate":  # a valid file of fewer records: must be read whole
                good = ref_data is not None and set(data.sizes) == set(ref_data.sizes)
                why = "" if good else f"exit 0 with sizes {dict(data.sizes)}"
            else:  # a changed data byte is undetectable; the output must still be complete
                good = ref_data is not None and dict(data.sizes) == dict(ref_data.sizes)
                why = "" if good else f"exit 0 with sizes {dict(data.sizes)}"
        return Result(kind, label, CORRECT if good and not lost else OTHER, why, lost)
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


# --- category dataset (hypothesis) ---------------------------------------------------------------

#: Defects that make a Dataset invalid: validate and identify must raise a ValueError subclass.
DEFECTS = (
    "nan_frf",
    "inf_frf",
    "real_frf",
    "decreasing_frequency",
    "duplicate_frequency",
    "negative_frequency",
    "duplicate_points",
    "drop_frf",
    "drop_frequency_coord",
    "rename_point_dim",
    "empty_points",
    "one_frequency",
    "frequency_times_2pi",
    "extra_dim",
)


def dataset_strategy():
    """Hypothesis strategy of (n_points, n_frequency, seed, scale exponent, defect or None)."""
    from hypothesis import strategies as st

    return st.tuples(
        st.integers(1, 4),
        st.integers(16, 160),
        st.integers(0, 2**16),
        st.sampled_from([0, 0, 0, -12, 12, -300, 300]),
        st.one_of(st.none(), st.sampled_from(DEFECTS)),
    )


def build_dataset(n_points: int, n_frequency: int, seed: int, exponent: int, defect: str | None):
    """A small FRF Dataset, with ``defect`` applied (None: valid)."""
    import xarray as xr

    ds = small_frf(seed, n_points, n_frequency, scale=10.0**exponent)
    if defect is None:
        return ds
    frf = ds["frf"]
    if defect == "nan_frf":
        return ds.assign(frf=frf.where(frf.frequency != frf.frequency[n_frequency // 2]))
    if defect == "inf_frf":
        return ds.assign(frf=frf.where(frf.frequency != frf.frequency[1], np.inf + 0j))
    if defect == "real_frf":
        return ds.assign(frf=np.abs(frf))
    if defect == "decreasing_frequency":
        return ds.assign_coords(frequency=ds.frequency.values[::-1].copy())
    if defect == "duplicate_frequency":
        f = ds.frequency.values.copy()
        f[3] = f[2]
        return ds.assign_coords(frequency=f)
    if defect == "negative_frequency":
        return ds.assign_coords(frequency=ds.frequency.values - 10.0)
    if defect == "duplicate_points":
        if n_points < 2:
            return build_dataset(2, n_frequency, seed, exponent, defect)
        p = ds.point.values.copy()
        p[1] = p[0]
        return ds.assign_coords(point=p)
    if defect == "drop_frf":
        return ds.drop_vars("frf")
    if defect == "drop_frequency_coord":
        return ds.drop_vars("frequency")
    if defect == "rename_point_dim":
        return ds.rename({"point": "channel"})
    if defect == "empty_points":
        return ds.isel(point=slice(0, 0))
    if defect == "one_frequency":
        return ds.isel(frequency=slice(0, 1))
    if defect == "frequency_times_2pi":
        # frequency in rad/s labelled Hz: disagrees with sample_interval/record_samples if the
        # Dataset records them; else the lines are merely spaced differently (still valid)
        return ds.assign_coords(frequency=ds.frequency.values * 2 * np.pi)
    if defect == "extra_dim":
        return ds.assign(frf=xr.concat([frf, frf], dim="repeat"))
    raise ValueError(f"unknown defect {defect!r}")


#: Defects that need not be rejected (a Dataset may be valid after them).
MAY_PASS = {"frequency_times_2pi"}
#: Defects the data model allows (validate passes) but identify must reject.
IDENTIFY_REJECTS = {"one_frequency"}


def check_dataset(params: tuple) -> tuple[str, str]:
    """Run validate and identify on one generated Dataset; (outcome, detail)."""
    import ami_xr

    defect = params[-1]
    try:
        ds = build_dataset(*params)
    except Exception as exc:  # noqa: BLE001 - a generator bug, reported, not hidden
        return OTHER, f"building the Dataset failed: {type(exc).__name__}: {exc}"
    for step in ("validate", "identify"):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ami_xr.errors.AmiXrWarning)
                warnings.simplefilter("ignore", RuntimeWarning)
                if step == "validate":
                    ami_xr.validate(ds)
                else:
                    res = ami_xr.identify(ds, refine=False)
                    if not isinstance(res, type(ds)):
                        return OTHER, f"identify returned {type(res).__name__}"
        except ami_xr.AmiXrValueError as exc:
            msg = str(exc)
            if "\n" in msg.strip() and step == "identify":
                return OTHER, f"{step}: multi-line message: {msg[:200]}"
            if defect is None and step == "validate":
                return OTHER, f"validate rejected a valid Dataset: {msg[:200]}"
            return CLEAN, f"{step}: {type(exc).__name__}"
        except Exception as exc:  # noqa: BLE001 - exactly what the campaign looks for
            return OTHER, f"{step}: {type(exc).__name__}: {str(exc)[:200]}"
        if step == "validate" and defect is not None and defect not in MAY_PASS | IDENTIFY_REJECTS:
            return OTHER, "validate accepted an invalid Dataset"
    if defect is not None and defect not in MAY_PASS:
        return OTHER, "identify accepted an invalid Dataset"
    return CORRECT, ""


def _child_dataset(params: tuple, result_file: str) -> int:
    outcome, detail = check_dataset(params)
    Path(result_file).write_text(json.dumps([outcome, detail]))
    return 0


def draw_datasets(n: int, seed: int) -> list[tuple]:
    """``n`` parameter tuples drawn by hypothesis from :func:`dataset_strategy` with ``seed``."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import seed as hseed

    drawn: list[tuple] = []

    @hseed(seed)
    @settings(
        max_examples=n,
        database=None,
        deadline=None,
        suppress_health_check=list(HealthCheck),
        phases=["generate"],
    )
    @given(dataset_strategy())
    def collect(params):
        drawn.append(params)

    collect()
    return drawn[:n]


def dataset_case(params: tuple, work: Path) -> Result:
    """One generated Dataset, checked in a forked child (so a hang is caught)."""
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="ds"))
    result_file = case_dir / "result.json"
    try:
        code, _, err, _ = run_forked(_child_dataset, (params, str(result_file)), case_dir)
        _SEEN[-1] = (code, "")  # library use, not a command: its stderr is not a message
        n_points, n_frequency, seed, exponent, defect = params
        label = (
            f"validate/identify of n_points={n_points} n_frequency={n_frequency} seed={seed} "
            f"scale=1e{exponent} defect={defect}"
        )
        if code is None:
            return Result("dataset", label, OTHER, f"hang: no result within {CASE_TIMEOUT_S} s")
        if code != 0 or not result_file.exists():
            return Result("dataset", label, OTHER, f"crash: exit {code}: {err.strip()[-200:]}")
        outcome, detail = json.loads(result_file.read_text())
        return Result("dataset", label, outcome, detail)
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


# --- categories signal, batch and concurrent (real ami-xr processes) -----------------------------


def big_file(folder: Path, megabytes: float = 24.0, seed: int = 0) -> Path:
    """A netCDF FRF file of about ``megabytes`` MB (complex128 values, 16 bytes each)."""
    import ami_xr

    n_points = 24
    n_freq = int(megabytes * 2**20 / 16 / n_points)
    rng = np.random.default_rng(seed)
    h = rng.standard_normal((n_points, n_freq)) + 1j * rng.standard_normal((n_points, n_freq))
    path = folder / "big.nc"
    ami_xr.to_netcdf(
        ami_xr.make_frf_dataset(h, np.linspace(0, 1000, n_freq), frf_type="receptance"), path
    )
    return path


def _spawn(argv: list[str], cwd: Path) -> subprocess.Popen:
    return subprocess.Popen(
        AMI_XR + argv,
        cwd=cwd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )


def _finish(proc: subprocess.Popen, bound: float) -> tuple[int | None, str]:
    """Wait up to ``bound`` s for ``proc``: ``(exit code, stderr)``; a hang (None) is killed
    with its process group."""
    try:
        _, err = proc.communicate(timeout=bound)
        code: int | None = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        _, err = proc.communicate()
        code = None
    text = err.decode(errors="replace") if err else ""
    _SEEN.append((code, text))
    return code, text


def _stop(proc: subprocess.Popen, sig_name: str, bound: float) -> tuple[int | None, str, float]:
    """Send the signal(s); wait up to ``bound`` s; (exit code or None if hung, stderr, s)."""
    start = time.monotonic()
    if proc.poll() is None:
        if sig_name == "SIGINTx2":
            proc.send_signal(signal.SIGINT)
            time.sleep(0.2)
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        else:
            proc.send_signal(getattr(signal, sig_name))
    code, err = _finish(proc, bound)
    return code, err, time.monotonic() - start


def _interrupt_problems(code: int | None, err: str, sig_name: str, waited: float) -> list[str]:
    sent = {getattr(signal, sig_name.replace("x2", ""))}
    problems = []
    if code is None:
        problems.append(f"hang: still running {waited:.0f} s after {sig_name}")
    elif "Traceback (most recent call last)" in err:
        problems.append("traceback: " + err.strip().splitlines()[-1][:200])
    elif code < 0 and -code not in sent:  # dying of the signal sent is the Unix convention
        problems.append(f"crashed with signal {-code}")
    return problems


SIGNALS = ("SIGINT", "SIGTERM", "SIGKILL", "SIGINTx2")  # SIGINTx2: Ctrl-C twice, 0.2 s apart


def signal_case(
    seed: int, work: Path, big: Path, full_s: float, sig_name: str | None = None
) -> Result:
    """Signal ``ami-xr convert big.nc -o out.nc`` at a random moment; check the destination.

    ``full_s`` is the time of an uninterrupted run; ``sig_name`` (one of :data:`SIGNALS`)
    defaults to a random one.
    """
    rng = random.Random(seed)
    sig_name = sig_name or rng.choice(SIGNALS)
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="sig"))
    src = case_dir / big.name
    shutil.copyfile(big, src)
    dest = case_dir / "out.nc"
    existed = rng.random() < 0.5
    if existed:
        dest.write_bytes(b"old destination content")
    old, before = digest(dest), digest(src)
    delay = rng.uniform(0.3, 1.15) * full_s
    label = f"ami-xr convert big.nc -o out.nc, {sig_name} at {delay:.2f} s (seed {seed})"
    label += ", out.nc existed" if existed else ""
    try:
        proc = _spawn(["convert", src.name, "-o", dest.name], case_dir)
        time.sleep(delay)
        code, err, waited = _stop(proc, sig_name, STOP_BOUND_S)
        problems = _interrupt_problems(code, err, sig_name, waited)
        lost = []
        now = digest(dest)
        if now != old:
            try:
                if not same_data(read_result(dest), read_result(src)):
                    lost.append(f"{label}: out.nc is neither the old file nor the full result")
            except Exception as exc:  # noqa: BLE001
                what = "lost" if now is None else f"partial ({type(exc).__name__})"
                lost.append(f"{label}: out.nc {what}")
        if digest(src) != before:
            lost.append(f"{label}: input big.nc changed")
        rerun = subprocess.run(
            AMI_XR + ["convert", src.name, "-o", dest.name],
            cwd=case_dir,
            capture_output=True,
            timeout=CASE_TIMEOUT_S,
        )
        if rerun.returncode not in (0, EXIT_BATCH_CAPPED):  # 4: done, a result at a cap
            problems.append(f"rerun exit {rerun.returncode}: {rerun.stderr.decode()[-200:]}")
        left = leftovers(case_dir)
        if left:
            lost.append(f"{label}: temporary files left after a rerun: {left}")
        detail = "; ".join(problems) + (f" (exit {code}, stopped in {waited:.1f} s)")
        return Result("signal", label, OTHER if problems or lost else CORRECT, detail, lost)
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


def batch_case(
    seed: int, work: Path, inputs: dict[str, Path], full_s: float, sig_name: str | None = None
) -> Result:
    """Signal ``ami-xr batch`` at a random moment; every output complete or absent."""
    import ami_xr

    rng = random.Random(seed)
    sig_name = sig_name or rng.choice(SIGNALS)
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="batch"))
    src_dir, out_dir = case_dir / "in", case_dir / "out"
    src_dir.mkdir()
    for i in range(4):
        ami_xr.to_netcdf(small_frf(seed + i), src_dir / f"f{i}.nc")
    shutil.copyfile(inputs["hits.lvm"], src_dir / "hits.lvm")
    before = {p.name: digest(p) for p in src_dir.iterdir()}
    delay = rng.uniform(0.2, 1.0) * full_s
    label = f"ami-xr batch in -o out, {sig_name} at {delay:.2f} s (seed {seed})"
    argv = ["batch", "in", "-o", "out", "-q", "--no-refine"]
    try:
        proc = _spawn(argv, case_dir)
        time.sleep(delay)
        # one Ctrl-C finishes the file in progress: allow the time of a whole batch on top
        code, err, waited = _stop(proc, sig_name, STOP_BOUND_S + full_s)
        problems = _interrupt_problems(code, err, sig_name, waited)
        lost = []
        for p in out_dir.rglob("*.modes.nc") if out_dir.exists() else []:
            try:
                read_result(p)
            except Exception as exc:  # noqa: BLE001
                lost.append(f"{label}: {p.name} partial ({type(exc).__name__})")
        rerun = subprocess.run(
            AMI_XR + argv, cwd=case_dir, capture_output=True, timeout=4 * CASE_TIMEOUT_S
        )
        if rerun.returncode not in (0, EXIT_BATCH_CAPPED):  # 4: done, a result at a cap
            problems.append(f"rerun exit {rerun.returncode}: {rerun.stderr.decode()[-200:]}")
        missing = [f"f{i}" for i in range(4) if not (out_dir / f"f{i}.modes.nc").exists()]
        if missing:
            lost.append(f"{label}: after a rerun no output for {missing}")
        left = leftovers(case_dir)
        if left:
            lost.append(f"{label}: temporary files left after a rerun: {left}")
        if {p.name: digest(p) for p in src_dir.iterdir()} != before:
            lost.append(f"{label}: input folder changed")
        detail = "; ".join(problems) + f" (exit {code}, stopped in {waited:.1f} s)"
        return Result("batch", label, OTHER if problems or lost else CORRECT, detail, lost)
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


def concurrent_case(seed: int, work: Path) -> Result:
    """2-4 ``ami-xr convert`` to one destination at once: it ends as exactly one full result."""
    import ami_xr

    rng = random.Random(seed)
    n = rng.randint(2, 4)
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="conc"))
    dest = case_dir / "shared.nc"
    if rng.random() < 0.5:
        dest.write_bytes(b"old")
    sources = []
    for i in range(n):
        p = case_dir / f"src{i}.nc"
        ami_xr.to_netcdf(small_frf(seed + i, n_points=8, n_frequency=4096), p)
        sources.append(p)
    label = f"{n} x ami-xr convert srcI.nc -o shared.nc at once (seed {seed})"
    try:
        procs = [_spawn(["convert", p.name, "-o", dest.name], case_dir) for p in sources]
        problems, lost = [], []
        for p in procs:
            try:
                _, err = p.communicate(timeout=CASE_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.communicate()
                problems.append("hang")
                continue
            text = err.decode(errors="replace")
            if p.returncode != 0 and not clean_error(p.returncode, text, ["shared.nc"])[0]:
                problems.append(f"exit {p.returncode}: {text.strip()[-200:]}")
        try:
            got = read_result(dest)
            if not any(same_data(got, read_result(s)) for s in sources):
                lost.append(f"{label}: shared.nc is none of the written results")
        except Exception as exc:  # noqa: BLE001
            lost.append(f"{label}: shared.nc unreadable ({type(exc).__name__})")
        left = leftovers(case_dir)
        if left:
            lost.append(f"{label}: temporary files left: {left}")
        outcome = OTHER if problems or lost else CORRECT
        return Result("concurrent", label, outcome, "; ".join(problems), lost)
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


# --- the campaign --------------------------------------------------------------------------------

_WORKER: dict[str, Any] = {}


# --- issue 25: faults at scale (the console entry point with its signal handling) ----------------
def tiled_benchmark(folder: Path, n_points: int) -> Path:
    """The shipped benchmark FRFs tiled to ``n_points`` points (1 % noise per copy)."""
    import xarray as xr

    import ami_xr

    src = Path(__file__).resolve().parents[1] / "sample_data" / "benchmark_frf.nc"
    ds = ami_xr.open_dataset(src).load()
    reps = -(-n_points // ds.sizes["point"])
    big = xr.concat([ds] * reps, dim="point").isel(point=slice(0, n_points))
    big = big.assign_coords(point=["tip"] + [f"p{i}" for i in range(1, n_points)])
    rng = np.random.default_rng(0)
    big["frf"] = big["frf"] * (1 + 0.01 * rng.standard_normal(big["frf"].shape))
    big.attrs.update(ds.attrs)
    path = folder / f"big{n_points}.nc"
    ami_xr.to_netcdf(big, path)
    return path


def _run_signalled(argv, cwd, delay, sig_name, env=None, bound=60.0):
    """Start ``ami-xr`` (run()), signal it after ``delay`` s; (code or None, stderr, seconds from
    the signal to the exit, whether it had exited before the signal)."""
    proc = subprocess.Popen(
        AMI_XR_RUN + argv,
        cwd=cwd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
        env=env,
    )
    try:
        proc.wait(timeout=delay)
        finished = True
    except subprocess.TimeoutExpired:
        finished = False
        proc.send_signal(getattr(signal, sig_name))
    sent = time.monotonic()
    code, err = _finish(proc, bound)
    return code, err, time.monotonic() - sent, finished


def _signal_verdict(code, err, waited, finished, sig_name) -> list[str]:
    expected = 128 + getattr(signal, sig_name)
    problems = []
    if code is None:
        problems.append(f"hang: still running {waited:.0f} s after {sig_name}")
    elif code < 0:
        problems.append(f"crashed with signal {-code}")
    elif code not in (expected, 0) or (code == 0 and not finished and waited > HONOUR_S):
        problems.append(f"exit {code} after {sig_name} (ignored?)")
    bug = [b for b in BUG_CLASS if b in err]
    if bug:
        problems.append(f"bug-class message {bug}: {err.strip().splitlines()[-1][:160]}")
    if code is not None and not finished and waited > HONOUR_S:
        problems.append(f"honoured after {waited:.1f} s (> {HONOUR_S} s)")
    return problems


def phase_case(seed: int, work: Path, big: Path, timings: dict, compile_: bool = False) -> Result:
    """SIGINT/SIGTERM at a random moment of identify (or convert to UFF) on the tiled set; with
    ``compile_``: identify of a small file on an empty numba cache."""
    rng = random.Random(seed)
    sig_name = rng.choice(("SIGINT", "SIGTERM"))
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="phase"))
    env = None
    try:
        if compile_:
            src = case_dir / "small.nc"
            import ami_xr

            ami_xr.to_netcdf(small_frf(seed), src)
            env = {**os.environ, "NUMBA_CACHE_DIR": str(case_dir / "empty-cache")}
            argv, out, full = ["identify", src.name, "-o", "m.nc", "-q"], "m.nc", timings["compile"]
        elif rng.random() < 0.8:
            src = big
            argv, out, full = (
                ["identify", str(big), "-o", "m.nc", "-q"],
                "m.nc",
                timings["identify"],
            )
        else:
            src = big
            argv, out, full = ["convert", str(big), "-o", "b.uff"], "b.uff", timings["convert_uff"]
        before = digest(src)
        delay = rng.uniform(0.05, 1.0) * min(full, SIGNAL_WINDOW_S)
        label = f"ami-xr {' '.join(argv[:1])} ({src.name}), {sig_name} at {delay:.2f} s"
        label += " (empty numba cache)" if compile_ else ""
        code, err, waited, finished = _run_signalled(argv, case_dir, delay, sig_name, env=env)
        problems = _signal_verdict(code, err, waited, finished, sig_name)
        lost = []
        target = case_dir / out
        if target.exists():
            try:
                if out.endswith(".nc"):
                    read_result(target)
                else:
                    import ami_xr

                    ami_xr.read_uff(target)
            except Exception as exc:  # noqa: BLE001
                lost.append(f"{label}: {out} partial ({type(exc).__name__})")
            if code not in (0, None) and not finished:
                pass  # complete output with exit 130/143: the signal came during the write
        left = leftovers(case_dir)
        if left:
            lost.append(f"{label}: temporary files left: {left}")
        if digest(src) != before:
            lost.append(f"{label}: input changed")
        detail = "; ".join(problems) + f" (exit {code}, stopped {waited:.2f} s after the signal)"
        category = "compile" if compile_ else "phase"
        return Result(category, label, OTHER if problems or lost else CORRECT, detail, lost)
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


def special_case(i: int, work: Path) -> Result:
    """A FIFO, a symlink to /dev/zero or a folder as the input of a command: a clear error."""
    kinds = ("fifo", "devzero", "folder")
    commands = ("identify", "convert", "report", "frf", "batch")
    kind, command = kinds[i % len(kinds)], commands[(i // len(kinds)) % len(commands)]
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="special"))
    try:
        import ami_xr

        if command == "batch":
            folder = case_dir / "in"
            folder.mkdir()
            ami_xr.to_netcdf(small_frf(i), folder / "good.nc")
            bad = folder / "x.nc"
            argv = ["batch", "in", "-o", "out", "-q", "--no-refine"]
        else:
            bad = case_dir / "x.nc"
            out = {"identify": "m.nc", "convert": "b.uff", "report": "rep", "frf": "g.nc"}[command]
            argv = [command, bad.name, "-o", out]
        if kind == "fifo":
            os.mkfifo(bad)
        elif kind == "devzero":
            bad.symlink_to("/dev/zero")
        else:
            bad.mkdir()
        label = f"ami-xr {command} with {kind} input"
        try:
            done = subprocess.run(
                AMI_XR_RUN + argv, cwd=case_dir, capture_output=True, text=True, timeout=120
            )
        except subprocess.TimeoutExpired:
            return Result("special", label, OTHER, "hang (no exit within 120 s)")
        problems = [b for b in BUG_CLASS if b in done.stderr]
        if command == "batch" and kind != "folder":
            rows = (case_dir / "out" / "batch_summary.csv").read_text().splitlines()
            ok = done.returncode == 3 and any(r.startswith("good.nc,ok") for r in rows)
            ok = ok and any(r.startswith("x.nc,failed") for r in rows)
            outcome = CLEAN if ok and not problems else OTHER
        elif command == "batch":  # a folder named x.nc inside the batch folder: not a file
            outcome = CLEAN if done.returncode in (0, 3) and not problems else OTHER
        else:
            named = {"fifo": "named pipe", "devzero": "character device", "folder": "folder"}
            ok = done.returncode == 1 and named[kind] in done.stderr
            outcome = CLEAN if ok and not problems else OTHER
        return Result("special", label, outcome, f"exit {done.returncode}: {done.stderr[-200:]}")
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


FSIZE_CHILD = """
import resource, sys
limit = int(sys.argv.pop(1))
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
from ami_xr.app.cli import run
run()
"""


def fullfs_case(seed: int, work: Path) -> Result:
    """convert/identify writing under a random file-size limit: complete, or a named full disk."""
    import ami_xr

    rng = random.Random(seed)
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="fullfs"))
    try:
        src = case_dir / "g.nc"
        ami_xr.to_netcdf(small_frf(seed, n_points=3, n_frequency=512), src)
        out = rng.choice(("b.nc", "b.uff", "m.nc"))
        argv = (
            ["identify", src.name, "-o", out, "-q", "--no-refine"]
            if out == "m.nc"
            else ["convert", src.name, "-o", out]
        )
        limit = rng.choice((1_000, 8_000, 30_000, 80_000, 400_000))
        target = case_dir / out
        old = rng.random() < 0.5
        if old:
            target.write_text("old\n")
        label = f"ami-xr {argv[0]} -o {out} with files limited to {limit} bytes"
        done = subprocess.run(
            [sys.executable, "-c", FSIZE_CHILD, str(limit), *argv],
            cwd=case_dir,
            capture_output=True,
            text=True,
            timeout=300,
        )
        problems = [b for b in BUG_CLASS if b in done.stderr]
        lost = []
        if done.returncode == 0:
            outcome = CORRECT
            try:
                read_result(target) if out.endswith(".nc") else ami_xr.read_uff(target)
            except Exception as exc:  # noqa: BLE001
                lost.append(f"{label}: exit 0 but {out} unreadable ({type(exc).__name__})")
        elif done.returncode == 1 and "no space left on the device" in done.stderr:
            outcome = CLEAN
            if old and target.read_text() != "old\n":
                lost.append(f"{label}: old {out} changed")
            if not old and target.exists():
                lost.append(f"{label}: partial {out} left")
        else:
            outcome = OTHER
            problems.append(f"exit {done.returncode}: {done.stderr.strip()[-200:]}")
        left = leftovers(case_dir)
        if left:
            lost.append(f"{label}: temporary files left: {left}")
        outcome = OTHER if problems else outcome
        return Result("fullfs", label, outcome, "; ".join(problems), lost)
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


def environment_case(category: str, i: int, work: Path) -> Result:
    """``readonly``: numba cache / HOME unwritable; ``streams``: closed or broken stdout/stderr.
    The run must succeed and write its output."""
    import ami_xr

    case_dir = Path(tempfile.mkdtemp(dir=work, prefix=category))
    try:
        src = case_dir / "g.nc"
        ami_xr.to_netcdf(small_frf(i), src)
        argv = ["identify", src.name, "-o", "m.nc", "-q", "--no-refine"]
        env = dict(os.environ)
        cmd = [*AMI_XR_RUN, *argv]
        shell = None
        if category == "readonly":
            plain = case_dir / "cache-file"
            plain.write_text("x")
            variant = ("cache is a file", "cache under a file + HOME under a file")[i % 2]
            env["NUMBA_CACHE_DIR"] = str(plain if i % 2 == 0 else plain / "sub")
            if i % 2:
                env["HOME"] = str(plain / "home")
        else:
            variant = ("2>&-", ">&-", "| head -c 1")[i % 3]
            quoted = " ".join(f"'{a}'" for a in cmd)
            shell = (
                f"{quoted} {variant} >/dev/null"
                if variant == "| head -c 1"
                else (
                    f"{quoted} >/dev/null {variant}" if variant == "2>&-" else f"{quoted} {variant}"
                )
            )
            if variant == "| head -c 1":
                shell = f"set -o pipefail; {quoted} | head -c 1 >/dev/null"
        label = f"identify with {variant}"
        if shell:
            done = subprocess.run(
                ["bash", "-c", shell],
                cwd=case_dir,
                capture_output=True,
                text=True,
                env=env,
                timeout=600,
            )
        else:
            done = subprocess.run(
                cmd, cwd=case_dir, capture_output=True, text=True, env=env, timeout=600
            )
        ok = done.returncode == 0 and (case_dir / "m.nc").exists()
        bug = [b for b in BUG_CLASS if b in done.stderr]
        outcome = CORRECT if ok and not bug else OTHER
        return Result(category, label, outcome, f"exit {done.returncode}: {done.stderr[-200:]}")
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


def time_issue25(work: Path, big: Path) -> dict[str, float]:
    """Wall time of an uninterrupted identify and UFF convert of the tiled set, and of a first
    run on an empty numba cache (where to aim the signals)."""
    import ami_xr

    timings = {}
    d = Path(tempfile.mkdtemp(dir=work))
    for key, argv in (
        ("identify", ["identify", str(big), "-o", str(d / "m.nc"), "-q"]),
        ("convert_uff", ["convert", str(big), "-o", str(d / "b.uff")]),
    ):
        start = time.monotonic()
        try:  # a run longer than the window is cut there: the signals land within it anyway
            subprocess.run(AMI_XR_RUN + argv, capture_output=True, timeout=SIGNAL_WINDOW_S)
        except subprocess.TimeoutExpired:
            pass
        timings[key] = time.monotonic() - start
    ami_xr.to_netcdf(small_frf(0), d / "s.nc")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(d / "cache")}
    start = time.monotonic()
    subprocess.run(AMI_XR_RUN + ["identify", str(d / "s.nc"), "-q"], capture_output=True, env=env)
    timings["compile"] = time.monotonic() - start
    shutil.rmtree(d)
    return timings


def _init_worker(work: str, inputs: dict[str, str]) -> None:
    """Import what the children need once, so each forked case skips the start-up."""
    import xarray  # noqa: F401

    import ami_xr.app.cli  # noqa: F401
    import ami_xr.io.formats  # noqa: F401
    import ami_xr.io.lvm  # noqa: F401
    import ami_xr.io.netcdf  # noqa: F401
    import ami_xr.io.uff  # noqa: F401

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the campaign's own Ctrl-C stops the parent
    _WORKER["work"] = Path(work)
    _WORKER["inputs"] = {k: Path(v) for k, v in inputs.items()}
    warm_up(_WORKER["work"], _WORKER["inputs"])


def warm_up(work: Path, inputs: dict[str, Path]) -> None:
    """Load the numba kernels of identify and frf once, so forked cases need not (seconds each).

    Small data only: numba's parallel kernels, whose thread pool must not be forked, stay idle.
    """
    for name in ("frf.nc", "hits.lvm"):
        for k in range(len(commands_for(name))):
            _reference(work, inputs[name], k)
    import ami_xr

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ami_xr.identify(small_frf(0), refine=False)
        ami_xr.frf(ami_xr.read_lvm(inputs["hits.lvm"]))


#: (exit code, stderr) of each command a case ran in this process (read by :func:`run_case`).
_SEEN: list[tuple[int | None, str]] = []
#: Failure classes counted over every command of the campaign (``--full`` wants 0 of each).
AUDIT = (
    "crashes", "hangs", "bug-class messages", "raw tracebacks", "foreign log lines",
    "leaked paths",
)
#: Exit codes of a crash (killed by a signal nobody sent: SIGSEGV, SIGBUS, SIGABRT, SIGILL,
#: SIGFPE), as ``waitstatus_to_exitcode`` and a shell report them.
CRASH_SIGNALS = (signal.SIGSEGV, signal.SIGBUS, signal.SIGABRT, signal.SIGILL, signal.SIGFPE)
#: stderr lines of other libraries' loggers (``distributed``, tornado, asyncio) and raw warnings.
FOREIGN = (" - distributed.", " - tornado.", "distributed.", "asyncio", "Warning: ", "warnings.warn")


def _leak_roots() -> tuple[str, ...]:
    """Paths of this machine a message must never show (the user never gave them): the
    installed packages, the interpreter, the source tree, the home folder."""
    import ami_xr

    roots = {sys.prefix, sys.base_prefix, str(Path(ami_xr.__file__).resolve().parents[1])}
    roots.add(str(Path.home()))
    return tuple(sorted(r for r in roots if r and r != "/"))


def audit(seen: list[tuple[int | None, str]], detail: str = "") -> list[str]:
    """The :data:`AUDIT` classes found in the commands ``seen`` (exit code, stderr) of a case."""
    found = set()
    roots = _leak_roots()
    if "hang" in detail:
        found.add("hangs")
    for code, err in seen:
        if code is None:
            found.add("hangs")
        elif code in [-s for s in CRASH_SIGNALS] + [128 + s for s in CRASH_SIGNALS]:
            found.add("crashes")
        if "Traceback (most recent call last)" in err:
            found.add("raw tracebacks")
        if any(b in err for b in ("unexpected", "SystemError", "Segmentation", "a bug")):
            found.add("bug-class messages")
        lines = [ln for ln in err.splitlines() if ln.strip()]
        if any(not ln.startswith("ami-xr") and any(f in ln for f in FOREIGN) for ln in lines):
            found.add("foreign log lines")
        if any(r in err for r in roots):
            found.add("leaked paths")
    return sorted(found)


def run_case(spec: tuple) -> Result:
    """Run one case spec (category, ...) in a pool worker; its commands audited."""
    _SEEN.clear()
    harness = _issue42().H.SEEN
    harness.clear()
    result = _run_case(spec)
    return result._replace(audit=tuple(audit(_SEEN + harness, result.detail)))


def _run_case(spec: tuple) -> Result:
    category, *rest = spec
    work, inputs = _WORKER["work"], _WORKER["inputs"]
    try:
        if category in ("truncate", "flip"):
            name, k, seed = rest
            return file_fault_case(category, inputs[name], k, seed, work)
        if category == "dataset":
            return dataset_case(tuple(rest[0]), work)
        if category == "signal":
            seed, full_s = rest
            return signal_case(seed, work, inputs["big.nc"], full_s)
        if category == "batch":
            seed, full_s = rest
            return batch_case(seed, work, inputs, full_s)
        if category == "concurrent":
            return concurrent_case(rest[0], work)
        if category in ("phase", "compile"):
            seed, timings = rest
            return phase_case(seed, work, inputs["tiled"], timings, category == "compile")
        if category == "special":
            return special_case(rest[0], work)
        if category == "fullfs":
            return fullfs_case(rest[0], work)
        if category in ("readonly", "streams"):
            return environment_case(category, rest[0], work)
        if category == "cluster":
            return Result(*_issue42().cluster_case(rest[0], rest[1], work, inputs["frf.nc"]))
        if category == "threads":
            return Result(*_issue42().threads_case(rest[0], work, inputs["frf.nc"]))
    except Exception as exc:  # noqa: BLE001 - a harness failure is reported as such
        return Result(category, repr(spec), OTHER, f"harness error: {type(exc).__name__}: {exc}")
    raise ValueError(f"unknown category {category!r}")


def _issue42():
    """``scripts/fault_cases_issue42.py`` (the ``cluster`` and ``threads`` cases), loaded from
    beside this file however this file was loaded."""
    import importlib.util

    module = sys.modules.get("fault_cases_issue42")
    if module is None:
        path = Path(__file__).resolve().with_name("fault_cases_issue42.py")
        spec = importlib.util.spec_from_file_location("fault_cases_issue42", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules["fault_cases_issue42"] = module
        spec.loader.exec_module(module)
    return module


def plan(counts: dict[str, int], seed: int, inputs: dict[str, Path], timings: dict) -> list:
    """Case specs per category, reproducible from ``seed``."""
    rng = random.Random(seed)
    names = [n for n in inputs if n not in ("big.nc", "tiled")]
    specs: list[tuple] = []
    for kind in ("truncate", "flip"):
        for i in range(counts.get(kind, 0)):
            name = names[i % len(names)]
            k = (i // len(names)) % len(commands_for(name))
            specs.append((kind, name, k, rng.randrange(2**31)))
    if counts.get("dataset"):
        specs += [("dataset", p) for p in draw_datasets(counts["dataset"], seed)]
    for _ in range(counts.get("signal", 0)):
        specs.append(("signal", rng.randrange(2**31), timings["convert"]))
    for _ in range(counts.get("batch", 0)):
        specs.append(("batch", rng.randrange(2**31), timings["batch"]))
    for _ in range(counts.get("concurrent", 0)):
        specs.append(("concurrent", rng.randrange(2**31)))
    for kind in ("phase", "compile"):
        for _ in range(counts.get(kind, 0)):
            specs.append((kind, rng.randrange(2**31), timings))
    for kind in ("special", "readonly", "streams"):
        specs += [(kind, i) for i in range(counts.get(kind, 0))]
    for _ in range(counts.get("fullfs", 0)):
        specs.append(("fullfs", rng.randrange(2**31)))
    specs += [("cluster", i, rng.randrange(2**31)) for i in range(counts.get("cluster", 0))]
    specs += [("threads", i) for i in range(counts.get("threads", 0))]
    # slow cases first so the pool ends on short ones
    order = {"signal": 0, "batch": 0, "phase": 0, "compile": 0, "cluster": 0, "concurrent": 1}
    return sorted(specs, key=lambda s: order.get(s[0], 2))


def time_commands(work: Path, big: Path, inputs: dict[str, Path]) -> dict[str, float]:
    """Wall time of an uninterrupted big convert and a small batch (where to aim the signals)."""
    import ami_xr

    timings = {}
    d = Path(tempfile.mkdtemp(dir=work))
    start = time.monotonic()
    subprocess.run(
        AMI_XR + ["convert", str(big), "-o", str(d / "o.nc")], check=True, capture_output=True
    )
    timings["convert"] = time.monotonic() - start
    (d / "in").mkdir()
    for i in range(4):
        ami_xr.to_netcdf(small_frf(i), d / "in" / f"f{i}.nc")
    shutil.copyfile(inputs["hits.lvm"], d / "in" / "hits.lvm")
    start = time.monotonic()
    subprocess.run(
        AMI_XR + ["batch", "in", "-o", "out", "-q", "--no-refine"], cwd=d, capture_output=True
    )
    timings["batch"] = time.monotonic() - start
    shutil.rmtree(d)
    return timings


def run_campaign(
    counts: dict[str, int],
    seed: int,
    workers: int,
    work: Path,
    progress: bool = True,
    n_points: int = 1000,
    log: Path | None = None,
    minutes: float | None = None,
) -> list[Result]:
    """Make the inputs, run every case in a process pool, return the results."""
    inputs = make_inputs(work / "inputs", seed)
    timings = {}
    if counts.get("signal") or counts.get("batch"):
        inputs["big.nc"] = big_file(work / "inputs", seed=seed)
        timings = time_commands(work, inputs["big.nc"], inputs)
    if counts.get("phase") or counts.get("compile"):
        inputs["tiled"] = tiled_benchmark(work / "inputs", n_points)
        timings.update(time_issue25(work, inputs["tiled"]))
        print(
            f"  uninterrupted runs on {n_points} points: "
            + ", ".join(f"{k} {v:.1f} s" for k, v in timings.items()),
            file=sys.stderr,
            flush=True,
        )
    specs = plan(counts, seed, inputs, timings)
    if minutes is not None:  # cut short: every category in proportion, whenever it stops
        random.Random(seed).shuffle(specs)
    init_args = (str(work), {k: str(v) for k, v in inputs.items()})
    with ProcessPoolExecutor(workers, initializer=_init_worker, initargs=init_args) as pool:
        results = _run_specs(pool, specs, workers, minutes, log, progress)
    return results


def _run_specs(pool, specs: list, workers: int, minutes, log, progress) -> list[Result]:
    """The cases of ``specs`` on ``pool``, at most ``2 * workers`` in flight; none started
    after ``minutes`` (None: all); each result appended to ``log`` as a JSON line."""
    from concurrent.futures import FIRST_COMPLETED, wait

    start = time.monotonic()
    results: list[Result] = []
    todo, running = list(reversed(specs)), set()
    while todo or running:
        in_time = minutes is None or time.monotonic() - start < 60 * minutes
        while todo and in_time and len(running) < 2 * workers:
            running.add(pool.submit(run_case, todo.pop()))
        if not running:
            break
        done, running = wait(running, return_when=FIRST_COMPLETED)
        for future in done:
            res = future.result()
            results.append(res)
            if log is not None:  # one JSON line per case: a cut-short run can be summarised
                with open(log, "a") as fh:
                    fh.write(json.dumps(res._asdict()) + "\n")
            if progress and len(results) % 50 == 0:
                rate = len(results) / max(time.monotonic() - start, 1e-9) * 60
                print(
                    f"  {len(results)}/{len(specs)} cases ({rate:.1f}/min)",
                    file=sys.stderr,
                    flush=True,
                )
    if len(results) < len(specs):
        rate = len(results) / max(time.monotonic() - start, 1e-9) * 60
        print(
            f"  stopped after {minutes:g} min: {len(results)} of {len(specs)} cases "
            f"({rate:.1f}/min; all {len(specs)} would take about {len(specs) / rate:.0f} min)",
            file=sys.stderr,
            flush=True,
        )
    return results


def summarize(results: list[Result]) -> tuple[str, bool]:
    """The printed table and whether the campaign passed."""
    per = defaultdict(Counter)
    for r in results:
        per[r.category][r.outcome] += 1
    lines = [f"{'category':<12}{'cases':>7}{CLEAN:>14}{CORRECT:>16}{OTHER:>15}"]
    for cat in CATEGORIES:
        if cat in per:
            c = per[cat]
            total = sum(c.values())
            lines.append(f"{cat:<12}{total:>7}{c[CLEAN]:>14}{c[CORRECT]:>16}{c[OTHER]:>15}")
    total = Counter()
    for c in per.values():
        total.update(c)
    lines.append(
        f"{'total':<12}{sum(total.values()):>7}{total[CLEAN]:>14}"
        f"{total[CORRECT]:>16}{total[OTHER]:>15}"
    )
    lost = [item for r in results for item in r.lost]
    counts = Counter(c for r in results for c in r.audit)
    lines.append("failure classes (cases): " + ", ".join(f"{c} {counts[c]}" for c in AUDIT))
    lines.append(f"files lost or left partial: {len(lost)}")
    lines += [f"  {item}" for item in lost]
    others = [r for r in results if r.outcome == OTHER or r.audit]
    if others:
        lines.append("anything else:")
        lines += [
            f"  [{r.category}] {r.case}: {r.detail}" + (f" [{', '.join(r.audit)}]" if r.audit else "")
            for r in others
        ]
    return "\n".join(lines), not others and not lost


def default_counts(n: int, categories: list[str], shares: dict | None = None) -> dict[str, int]:
    """Split ``n`` cases over ``categories`` by ``shares`` (:data:`DEFAULT_SHARE`)."""
    share = {c: (shares or DEFAULT_SHARE)[c] for c in categories}
    total = sum(share.values())
    return {c: max(1, round(n * s / total)) for c, s in share.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", type=int, default=1600, help="injected faults in all")
    parser.add_argument("--seed", type=int, default=0, help="seed of every random choice")
    parser.add_argument("--categories", nargs="+", choices=CATEGORIES, default=list(CATEGORIES))
    parser.add_argument("--workers", type=int, default=2, help="processes")
    parser.add_argument("--keep", type=Path, help="work folder to keep (default: a temp one)")
    parser.add_argument(
        "--points", type=int, default=1000, help="points of the tiled benchmark (phase cases)"
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"only the issue-25 categories, a few cases each ({QUICK_COUNTS}) on --points",
    )
    parser.add_argument(
        "--full",
        action="store_true",
        help=f"the release campaign: every category, at least {FULL_MIN_CASES} faults, the "
        "signal cases on --points points; fails on any case in a failure class",
    )
    parser.add_argument("--log", type=Path, help="append each result as a JSON line to this file")
    parser.add_argument(
        "--minutes",
        type=float,
        help="start no case after this many minutes of cases (the plan shuffled, so that a "
        "cut-short run samples every category); prints the rate and the projected full time",
    )
    parser.add_argument(
        "--summarize", type=Path, metavar="LOG", help="print the table of a --log file and exit"
    )
    args = parser.parse_args(argv)
    if args.summarize:
        rows = [json.loads(x) for x in args.summarize.read_text().splitlines() if x.strip()]
        table, ok = summarize([Result(**r) for r in rows])
        print(table)
        print(f"{len(rows)} cases (from {args.summarize.name})")
        return 0 if ok else 1
    counts = default_counts(args.cases, args.categories)
    if args.full:
        n = max(args.cases, FULL_MIN_CASES)
        counts = default_counts(n, list(CATEGORIES), FULL_SHARE)
        print(
            f"--full: {sum(counts.values())} faults on {args.points} points: "
            + ", ".join(f"{k} {v}" for k, v in counts.items()),
            file=sys.stderr,
            flush=True,
        )
    if args.quick:
        counts = {k: v for k, v in QUICK_COUNTS.items() if k in args.categories}
    start = time.monotonic()
    if args.keep:
        args.keep.mkdir(parents=True, exist_ok=True)
        results = run_campaign(
            counts, args.seed, args.workers, args.keep, n_points=args.points, log=args.log,
            minutes=args.minutes,
        )
    else:
        with tempfile.TemporaryDirectory(prefix="fault_campaign") as tmp:
            results = run_campaign(
                counts, args.seed, args.workers, Path(tmp), n_points=args.points, log=args.log,
                minutes=args.minutes,
            )
    table, ok = summarize(results)
    print(table)
    print(f"{len(results)} cases in {time.monotonic() - start:.0f} s, seed {args.seed}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
