"""The ``ami-xr`` command line: a thin shell over the public functions.

Each subcommand parses its options, calls one public function (heavy imports happen inside the
subcommand, so ``ami-xr --help`` is fast and compiles nothing), and maps errors to exit codes.
One rule holds for every subcommand (:func:`main`):

* Outputs are checked before any work (:func:`ami_xr.app.options.check_paths`, table
  :data:`ami_xr.app.options.PATHS`): an output that is one of the inputs (also through a symlink
  or a hard link) or another output of the same run, whose suffix is not that of the format
  written (``.nc`` for netCDF; ``.nc``, ``.uff`` or ``.unv`` where the suffix chooses), that
  exists and is read-only (mode 0444: refused, never replaced), a file where a folder goes, or a
  missing or read-only folder is refused. An existing writable output is replaced, atomically.
* Warnings of ami_xr (e.g. no modes found, iteration cap reached) print as one line each;
  other packages' warnings only with ``-v``.
* Every error is one line ``ami-xr <command>: error: ...`` on stderr, never a bare traceback
  (``-v`` shows it). An expected error (bad input file, bad option value, failed
  identification: :class:`~ami_xr.errors.AmiXrError`, ValueError, OSError) says what is wrong;
  anything else is a bug, named with its type and "run with -v for the traceback".
* Exit codes (defined once, here): 0 success (:data:`EXIT_OK`); 1 an error
  (:data:`EXIT_ERROR`); 2 a usage error (argparse, :data:`EXIT_USAGE`); 3 ``batch`` finished but
  some files failed (:data:`EXIT_BATCH_FAILURES`); 4 ``batch`` finished, none failed, but some
  identifications stopped at a cap (status ``capped``, :data:`EXIT_BATCH_CAPPED`); 130
  interrupted by Ctrl-C (:data:`EXIT_INTERRUPTED`, one line ``ami-xr <command>:
  interrupted``); 143 terminated by SIGTERM (:data:`EXIT_TERMINATED`, one line
  ``ami-xr: terminated``; a write in progress is rolled back first).

Option defaults are read from the signatures of the functions they feed, only when a help text
shows them (:mod:`ami_xr.app.options`, which also declares the options shared by several
subcommands); options left at their default are not passed on, so the library applies its own.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import re
import signal
import sys
import traceback
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ami_xr.app.cluster import add_cluster_options
from ami_xr.app.options import (
    BENCHMARK,
    RANDOM_SYSTEM,
    Default,
    HelpFormatter,
    add_frf_options,
    add_identify_options,
    add_report_options,
    add_stability_option,
    check_paths,
    frf_options,
    identify_options,
    ranged,
    stability_table,
    value,
)
from ami_xr.errors import AmiXrError, AmiXrValueError, AmiXrWarning
from ami_xr.progress import DELAY_SECONDS

EXIT_OK = 0
EXIT_ERROR = 1
EXIT_USAGE = 2  # argparse exits with this itself
EXIT_BATCH_FAILURES = 3
EXIT_BATCH_CAPPED = 4  # batch: no failure, but some results incomplete (stopped at a cap)
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports a Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM

#: Errors a user can cause (bad file, bad value, missing optional package): their message is
#: the whole story. Anything else escaping a command is a bug and says how to see its traceback;
#: a bare ValueError too (ami_xr's own bad-input errors are AmiXrError subclasses; a ValueError
#: from inside xarray or numpy means a check is missing, e.g. issue 24 item 5).
EXPECTED_ERRORS = (AmiXrError, OSError, ImportError)
VERBOSE_HINT = "run with -v for the traceback"


# --- helpers -------------------------------------------------------------------------------------
def _one_line(err: BaseException) -> str:
    # SchemaError lists its problems as "  - ..." bullets: join them into one line.
    lines = [re.sub(r"^\s*-\s+", "", s).strip() for s in str(err).strip().splitlines() if s.strip()]
    text = "; ".join(lines) if lines else type(err).__name__
    if not isinstance(err, AmiXrError):
        text = f"{type(err).__name__}: {text}"
    return text


def _say(*parts: Any) -> None:
    # a path that is not valid UTF-8 (surrogate-escaped by os) must not kill the output
    text = " ".join(str(p) for p in parts)
    encoding = getattr(sys.stdout, "encoding", None) or "utf-8"
    try:
        print(text.encode(encoding, "backslashreplace").decode(encoding), flush=True)
    except BrokenPipeError:  # the reader quit (`| head -1`): the work itself goes on
        _silence_stdout()


class _CompileNotice(logging.Handler):
    """Prints the kernels' once-per-process first-compilation notice (logger
    ``names.COMPILE_LOGGER``, INFO) on the stderr of the moment."""

    def emit(self, record: logging.LogRecord) -> None:
        print(record.getMessage(), file=sys.stderr, flush=True)


def _show_compile_notice() -> None:
    from ami_xr.names import COMPILE_LOGGER

    logger = logging.getLogger(COMPILE_LOGGER)
    if not any(isinstance(h, _CompileNotice) for h in logger.handlers):
        logger.addHandler(_CompileNotice(logging.INFO))
        logger.setLevel(logging.INFO)
        logger.propagate = False


def _add_output(
    p: argparse.ArgumentParser, what: str, required: bool = True, default: Any = None
) -> None:
    if required:  # no default to show: argparse refuses the command without it
        default = argparse.SUPPRESS
    p.add_argument("-o", "--output", required=required, default=default, metavar="PATH", help=what)


def _wrote_frfs(g, path) -> str:
    from ami_xr import names

    size = g.sizes
    return f"wrote FRFs ({size[names.POINT]} points x {size[names.FREQUENCY]} lines) to {path}"


# --- subcommands ---------------------------------------------------------------------------------
def _cmd_demo(args: argparse.Namespace) -> int:
    from ami_xr.app.demo import demo

    demo(
        value(args.output),
        simulate=args.simulate,
        noise=value(args.noise),
        seed=value(args.seed),
        report=not args.no_report,
        identify_options=identify_options(args),
    )
    return EXIT_OK


def _cmd_simulate(args: argparse.Namespace) -> int:
    import ami_xr

    if args.time_output and args.system != "beam-absorbers":
        raise AmiXrValueError("--time-output: only the beam-absorbers system has impulse responses")
    common = {"noise": value(args.noise), "seed": value(args.seed)}
    if args.system == "beam-absorbers":
        kwargs = {**common, "duration": value(args.duration), "n_samples": value(args.samples)}
        ts, g, truth = ami_xr.simulate.benchmark(**kwargs)
    else:
        kwargs = {
            "n_points": value(args.points),
            "topology": value(args.topology),
            **common,
            "closely_spaced": args.closely_spaced,
            "weak_mode": args.weak_mode,
            "max_frequency_hz": value(args.max_frequency),
        }
        ts, (g, truth) = None, ami_xr.simulate.random_system(**kwargs)
    params = {"system": args.system, **kwargs}
    # each write's record is the running command's (main), with the simulator's call as a step
    ami_xr.to_netcdf(g, args.output, parameters=params)
    _say(_wrote_frfs(g, args.output))
    for data, path, what in (
        (ts, args.time_output, "impulse responses"),
        (truth, args.truth_output, "exact modal parameters"),
    ):
        if path:
            ami_xr.to_netcdf(data, path, parameters=params)
            _say(f"wrote {what} to {path}")
    return EXIT_OK


def _force_channel(text: str | None) -> int | str | None:
    """``--force-channel``: a column index when it is a number, else a column title."""
    return int(text) if text is not None and text.strip().isdigit() else text


def _cmd_frf(args: argparse.Namespace) -> int:
    import ami_xr
    from ami_xr import names
    from ami_xr.dsp.frf import frf_from_options
    from ami_xr.dsp.timeseries import excitation_of
    from ami_xr.io.formats import read_any

    reader = {
        "force_channel": _force_channel(args.force_channel),
        "points": [p.strip() for p in args.points.split(",")] if args.points else None,
        "drive_point": args.drive_point,
    }
    ts = read_any(args.input, want="time", **reader)
    options = frf_options(args)
    if "excitation" not in options:  # auto: the rule ami_xr.frf_from_options applies too
        options["excitation"] = excitation_of(ts)
        impact = options["excitation"] == "impact"
        why = "the force is a short pulse" if impact else "the force is not a short pulse"
        _say(f"excitation: {options['excitation']} ({why}; --excitation sets it)")
    g = frf_from_options(ts, options)
    if names.HIT_REJECTED in g:  # impact test: say which hits were left out and why
        rejected = g[names.HIT_REJECTED].values.astype(bool)
        reason = names.HIT_REJECT_REASON
        reasons = g[reason].values if reason in g else [""] * rejected.size
        _say(f"hits: {rejected.size}, used {int((~rejected).sum())}")
        for i in range(rejected.size):
            if rejected[i]:
                _say(f"  hit {i} rejected: {reasons[i]}")
    given = {k: v for k, v in reader.items() if v is not None}
    # the write's record is the running command's (main), the read and the FRF its steps
    ami_xr.to_netcdf(g, args.output, parameters={**given, **options})
    _say(_wrote_frfs(g, args.output))
    return EXIT_OK


def _frf_first(path: str) -> str:
    stem = Path(path).stem
    return (
        f"input {path!r} holds time histories, identify needs FRFs: run "
        f"'ami-xr frf {path} -o {stem}_frf.nc' first, then 'ami-xr identify {stem}_frf.nc'"
    )


def _cmd_identify(args: argparse.Namespace) -> int:
    import ami_xr
    from ami_xr import names
    from ami_xr.app.cluster import cluster, read_frfs
    from ami_xr.io.formats import LVM_SUFFIX, read_any, write_any
    from ami_xr.progress import on_a_terminal, on_terminal
    from ami_xr.tables import format_modal_table

    if Path(args.input).suffix.lower() == LVM_SUFFIX:  # always time histories: say so unread
        raise AmiXrValueError(_frf_first(args.input))
    from ami_xr.io.kinds import ModesFileError
    from ami_xr.io.reference_modes import compare_modes, format_reference_table
    from ami_xr.io.reference_modes import split_frf_and_modes as split

    given = None  # modes stored with the FRFs: identify the FRFs, compare with those modes
    try:
        ds = read_frfs(args.input, args)  # lazy, chunked along point with --workers/--scheduler
    except ModesFileError as refused:
        both = read_any(args.input)
        if names.FRF not in both:  # modes only: nothing to identify
            raise refused from None
        ds, given = split(both, args.input)
        n = given.sizes[names.MODE]
        _say(f"{args.input}: FRFs and {n} modes; the FRFs are identified, the modes compared")
    if names.FRF not in ds and names.TIME in ds.dims:
        raise AmiXrValueError(_frf_first(args.input))
    if args.conjugate:  # the other sign convention (ami_xr.dsp.convention)
        ds = ds.assign({names.FRF: ds[names.FRF].conj()})
    options = identify_options(args)
    # a phase bar on a terminal once the work takes more than a couple of seconds
    with cluster(args):
        result = ami_xr.identify(ds, progress=on_terminal(not args.quiet), **options)
    _say(format_modal_table(result))
    if given is not None:
        result = compare_modes(result, given)
        _say(format_reference_table(result))
    if args.stability:  # the variants take their own pfa and band; the other options stay
        others = {k: v for k, v in options.items() if k != "pfa"}
        show = not args.quiet and on_a_terminal()  # False, not an error, when stderr is closed
        result = ami_xr.stability(ds, result, progress=show, **others)
        _say(stability_table(result))
    if args.output:  # one record, the running command's (main), with identify as its step
        write_any(result, args.output, parameters={"input": args.input, **options})
        _say(f"wrote modes to {args.output}")
    caps = str(result.attrs.get(names.ATTR_AMI_CAPPED, "") or "")
    if caps:  # the last line says the result is incomplete (batch: status "capped")
        _say(f"incomplete: stopped at cap(s) {caps}; modes may be missing (see the warnings)")
    return EXIT_OK


def _cmd_report(args: argparse.Namespace) -> int:
    from ami_xr.app.report import report
    from ami_xr.io.atomic import atomic_folder
    from ami_xr.io.formats import read_any

    ds = read_any(args.input)
    # written into a temporary folder and swapped in whole: never a partial or mixed report
    with atomic_folder(args.output) as tmp:
        index = report(
            ds,
            tmp,
            title=args.title,
            figures=args.figures,
            frequency_range=args.frequency_range,
            reference=args.reference,
        )
    _say(f"wrote report to {Path(args.output) / Path(index).name}")
    return EXIT_OK


def _cmd_convert(args: argparse.Namespace) -> int:
    from ami_xr.io.formats import read_any, write_any

    src = Path(args.input)
    ds = read_any(src)
    out = write_any(
        ds,
        args.output,
        binary=args.binary,
        parameters={"input": str(src)},  # the running command's record (main)
    )
    _say(f"converted {src} -> {out}")
    return EXIT_OK


def _cmd_combine(args: argparse.Namespace) -> int:
    import ami_xr
    from ami_xr import names
    from ami_xr.io.formats import check_input, check_output

    for path in args.input:
        check_input(path)
    check_output(args.output, "netcdf", inputs=args.input, name="-o", writer="ami-xr combine")
    g = ami_xr.combine_runs(args.input, drive_point=args.drive_point, layout=args.layout)
    ami_xr.to_netcdf(g, args.output, parameters={"inputs": args.input, "layout": args.layout})
    _say(f"{g.attrs['combine_layout']}; drive point {g.attrs.get(names.ATTR_DRIVE_POINT)!r}")
    _say(_wrote_frfs(g, args.output) + f" from {len(args.input)} runs")
    return EXIT_OK


def _cmd_batch(args: argparse.Namespace) -> int:
    from ami_xr.app.batch import batch

    summary = batch(
        args.input,
        args.output,
        workers=value(args.workers),
        identify_options=identify_options(args),
        frf_options=frf_options(args),
        report=args.report,
        force=args.force,
        progress=not args.quiet,
        keep_tracebacks=args.verbose,
    )
    _say(summary.format())
    _say(f"summary: {summary.csv_path}")
    if args.verbose:
        for row in summary.rows:
            if row.get("traceback"):
                print(f"--- {row['file']}\n{row['traceback']}", file=sys.stderr)
    if summary.n_failed:
        return EXIT_BATCH_FAILURES
    return EXIT_BATCH_CAPPED if summary.n_capped else EXIT_OK


# --- parser --------------------------------------------------------------------------------------
def _add_demo(add) -> None:
    p = add(
        "demo",
        "identify the paper's benchmark and compare with the paper",
        "Load the shipped benchmark FRFs (sample_data/, or simulate them when absent), run "
        "the identification, print the modal table next to the paper's AMI values and the "
        "simulator's exact values, and write modes.nc and a report/ folder.",
    )
    _add_output(
        p, "output folder", required=False, default=Default("ami_xr.app.demo:demo", "output_dir")
    )
    p.add_argument(
        "--simulate",
        action="store_true",
        help="simulate the benchmark even when sample data are present",
    )
    _add_noise_seed(
        p,
        "noise level alpha of eq. 15 (fraction of each signal's peak) when simulating",
        "noise seed when simulating",
    )
    p.add_argument("--no-report", action="store_true", help="skip the report (no matplotlib)")
    add_identify_options(p)
    p.set_defaults(func=_cmd_demo)


def _add_noise_seed(p, noise_help: str, seed_help: str) -> None:
    """``--noise`` and ``--seed`` of the simulated benchmark (defaults from ``benchmark``)."""
    p.add_argument(
        "--noise", type=ranged(float, 0.0), default=Default(BENCHMARK, "noise"), help=noise_help
    )
    p.add_argument(
        "--seed",
        type=ranged(int, 0, 2**32 - 1),
        default=Default(BENCHMARK, "seed"),
        help=seed_help,
    )


def _add_simulate(add) -> None:
    p = add(
        "simulate",
        "simulate a test system and write its FRFs",
        "Simulate a system with exactly known modes and write its FRFs (displacement "
        "receptance, m/N) as netCDF. beam-absorbers: the paper's benchmark (cantilever beam "
        "with three absorbers, unit impulse at the tip, FRFs = dt * FFT of the noisy impulse "
        "responses). random: a random lumped-mass chain or grid (analytic FRFs, noise on "
        "their real and imaginary parts).",
    )
    p.add_argument("system", choices=("beam-absorbers", "random"), help="which system")
    _add_output(p, "FRF netCDF file to write")
    _add_noise_seed(
        p,
        "noise level alpha of eq. 15 (fraction of each signal's peak; 0 = noise-free)",
        "seed of the noise (and of the random system) (reproducible)",
    )
    p.add_argument(
        "--truth-output",
        default=None,
        metavar="PATH",
        help="also write the exact modal parameters to this netCDF file (default: not written)",
    )
    g = p.add_argument_group("beam-absorbers options")
    g.add_argument(
        "--duration",
        type=ranged(float, 0.0, low_open=True),
        default=Default(BENCHMARK, "duration"),
        help="record length [s]",
    )
    g.add_argument(
        "--samples",
        type=ranged(int, 2),
        default=Default(BENCHMARK, "n_samples"),
        help="samples per record",
    )
    g.add_argument(
        "--time-output",
        default=None,
        metavar="PATH",
        help="also write the impulse responses [m per N s] to this netCDF file (default: not "
        "written)",
    )
    g = p.add_argument_group("random options")
    g.add_argument(
        "--points",
        type=ranged(int, 5, 50),
        default=Default(RANDOM_SYSTEM, "n_points"),
        help="measured points (5-50)",
    )
    g.add_argument(
        "--topology",
        default=Default(RANDOM_SYSTEM, "topology"),
        choices=("chain", "grid"),
        help="masses in a grounded line, or on a grid clamped along one row",
    )
    g.add_argument(
        "--closely-spaced",
        action="store_true",
        help="add an absorber that makes two closely spaced modes",
    )
    g.add_argument("--weak-mode", action="store_true", help="add a weakly excited mode")
    g.add_argument(
        "--max-frequency",
        type=ranged(float, 0.0, low_open=True),
        default=Default(RANDOM_SYSTEM, "max_frequency_hz"),
        help="top of the frequency grid [Hz]; the highest mode is at 0.8 x this",
    )
    p.set_defaults(func=_cmd_simulate)


def _add_file_commands(add) -> None:
    """frf, identify, report and convert: one input file each."""
    p = add(
        "frf",
        "estimate FRFs from force and response time histories",
        "Read a time Dataset (netCDF, UFF dataset 58 time responses, LabVIEW .lvm, or MATLAB "
        ".mat channels with a sampling rate: see ami_xr.io.time_mat) and "
        "estimate FRFs with coherence (ami_xr.frf).",
    )
    p.add_argument("input", help="time-history file (.nc, .uff, .lvm, .mat)")
    _add_output(p, "FRF netCDF file to write")
    g = p.add_argument_group("channels (what the file does not say)")
    g.add_argument(
        "--force-channel",
        metavar="INDEX_OR_TITLE",
        help=".lvm, .mat: the force channel, by column index (0 = first) or title (default: "
        "the channel with a force unit (N, kN, lbf) or 'force' in its title)",
    )
    g.add_argument(
        "--points",
        metavar="LABELS",
        help=".lvm, .mat: comma-separated labels of the response channels, in file order "
        "(default: their column titles)",
    )
    g.add_argument(
        "--drive-point",
        metavar="LABEL",
        help="label of the response point where the force acts (default: the file's; for .lvm "
        "the single response channel, reported as an assumption and recorded as "
        "drive_point_assumed)",
    )
    add_frf_options(p)
    p.set_defaults(func=_cmd_frf)

    p = add(
        "identify",
        "identify modes from FRFs (subtraction, isolation, global fit)",
        "Run the Algorithm of Mode Isolation on an FRF file and print the modal table "
        "(mode, natural frequency in Hz and rad/s, damping ratio in %, FRFs that detected "
        "the mode, quality flags).",
    )
    p.add_argument("input", help="FRF file (.nc, .uff/.unv, or an FRF table: .csv/.txt/.dat, .mat)")
    _add_output(
        p,
        "result file to write (.nc: FRFs + modal results; .uff: FRFs as dataset "
        "58 and mode shapes as dataset 55) (default: none, only print the table)",
        required=False,
    )
    add_stability_option(p)
    p.add_argument(
        "--conjugate",
        action="store_true",
        help="use the complex conjugate of the FRFs read (data exported with the e^{-iwt} sign "
        "convention; ami_xr's is e^{+iwt}, see ami_xr.dsp.convention)",
    )
    p.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="no progress bar (otherwise drawn on stderr, on a terminal, once identification "
        f"has run {DELAY_SECONDS:g} s: phases done, and inside the running phase the FRFs "
        "done or the refinement's modes and iterations)",
    )
    add_identify_options(p)
    add_cluster_options(p)
    p.set_defaults(func=_cmd_identify)

    p = add(
        "report",
        "draw the figures and write an HTML report",
        "Write Bode, Nyquist, subtraction, mode-vector and MAC plots (PNG), the modal table "
        "(CSV) and an index.html showing them, from an identification result.",
    )
    p.add_argument("input", help="result file of 'ami-xr identify' (.nc)")
    _add_output(p, "report folder (created)")
    p.add_argument("--title", default=None, help="page title (default: from the source file)")
    p.add_argument(
        "--reference",
        metavar="LABEL",
        default=None,
        help="multi-reference result: draw the FRFs of this reference only (default: every "
        "reference, FRF figures once per reference; both show the participation per reference, "
        "drive-point consistency and the MAC within close pairs)",
    )
    add_report_options(p)
    p.set_defaults(func=_cmd_report)

    p = add(
        "convert",
        "convert between UFF and netCDF",
        "Convert a file by its suffixes: .uff/.unv (dataset 58 FRFs or time histories, 55 "
        "mode shapes), .lvm or an FRF table (.csv/.txt/.dat, .mat) -> .nc, and .nc -> .uff "
        "(FRFs as 58, modes as 55, time histories as 58).",
    )
    p.add_argument("input", help="input file (.uff, .unv, .lvm, .csv, .txt, .dat, .mat or .nc)")
    _add_output(p, "output file (.nc, .uff or .unv)")
    p.add_argument(
        "--binary",
        action="store_true",
        help="write UFF dataset 58 in binary (exact float64) instead of ASCII",
    )
    p.set_defaults(func=_cmd_convert)


def _add_combine(add) -> None:
    p = add(
        "combine",
        "one FRF set from the runs of a roving test",
        "Combine FRF files measured in runs (ami_xr.combine_runs): a roving response (the runs "
        "share the excitation, each measured other points) or a roving hammer (the runs share "
        "one response point; by reciprocity the hammer positions become the points). Points are "
        "concatenated; each run's force autospectrum, coherence and noise are kept, the run of "
        "each point is recorded (point_run), and the frequency lines, units and drive point are "
        "checked to agree (an error names the run that differs).",
    )
    p.add_argument("input", nargs="+", help="FRF files of the runs (.nc, .uff/.unv, tables)")
    _add_output(p, "FRF netCDF file to write")
    p.add_argument(
        "--drive-point",
        metavar="LABEL",
        type=_label,
        default=None,
        help="roving response: where the shaker acts, for runs that do not state it; roving "
        "hammer: the response point (default: what the runs state)",
    )
    p.add_argument(
        "--layout",
        choices=("auto", "roving_response", "roving_hammer"),
        default="auto",
        help="auto: a roving hammer when every run has the same one response point and its own "
        "drive point, else a roving response",
    )
    p.set_defaults(func=_cmd_combine)


def _label(text: str) -> int | str:
    """A point label: an integer when the text is one, else the text."""
    return int(text) if text.strip().lstrip("-").isdigit() else text


def _add_batch(add) -> None:
    p = add(
        "batch",
        "identify every measurement file in a folder tree",
        "Process every .nc, .uff/.unv and .lvm file under DIR (time histories -> FRFs -> "
        "modes), writing OUTDIR/<same folders>/<stem>.modes.nc atomically. Files whose "
        "output is up to date (same input content and options) are skipped, so an "
        "interrupted run resumes. A bad file is reported and skipped. Prints and writes "
        "OUTDIR/batch_summary.csv; exits with 3 when any file failed, 4 when none failed but some "
        "stopped at a cap (status capped).",
    )
    p.add_argument(
        "input", metavar="DIR", help="folder of measurement files (searched recursively)"
    )
    _add_output(p, "output folder (mirrors DIR)")
    p.add_argument(
        "--workers",
        type=ranged(int, 1, 1024),
        default=Default("ami_xr.app.batch:batch", "workers"),
        help="files processed in parallel (processes)",
    )
    p.add_argument(
        "--report", action="store_true", help="also write <stem>.report/ folders (needs matplotlib)"
    )
    p.add_argument("--force", action="store_true", help="redo files whose outputs are up to date")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="no progress bar (files done, on stderr)"
    )
    add_identify_options(p)
    add_frf_options(p)
    p.set_defaults(func=_cmd_batch)


def build_parser() -> argparse.ArgumentParser:
    """The ``ami-xr`` argument parser (every option shows its default and units in --help)."""
    from ami_xr import __version__

    parser = argparse.ArgumentParser(
        prog="ami-xr",
        formatter_class=HelpFormatter,
        description="Experimental modal analysis with the Algorithm of Mode Isolation "
        "(Ginsberg & Allen) on labeled xarray data.\n\n"
        "Start with:  ami-xr demo",
        epilog="Exit codes: 0 ok, 1 error (one line on stderr; -v shows the traceback), "
        "2 usage error, 3 batch with failed files, 4 batch with capped (incomplete) results, "
        "130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"ami_xr {__version__}")
    parser.add_argument(
        "-v", "--verbose", action="store_true", default=False, help="show tracebacks of errors"
    )
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        default=argparse.SUPPRESS,
        help="show tracebacks of errors",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def add(name: str, help_text: str, description: str) -> argparse.ArgumentParser:
        p = sub.add_parser(
            name,
            help=help_text,
            description=description,
            formatter_class=HelpFormatter,
            parents=[common],
        )
        p.set_defaults(subcommand_parser=p)
        return p

    for add_command in (_add_demo, _add_simulate, _add_file_commands, _add_combine, _add_batch):
        add_command(add)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ami-xr``; returns the exit code (see the module docstring)."""
    parser = build_parser()
    args = parser.parse_args(argv)

    def show_warning(message, category, filename, lineno, file=None, line=None):
        # ami_xr's own warnings (no modes, no convergence) as one line each; warnings from
        # other packages (numpy internals) only with -v, with their source location.
        if issubclass(category, AmiXrWarning):
            text = " ".join(str(message).split())
            print(f"ami-xr {args.command}: warning: {category.__name__}: {text}", file=sys.stderr)
        elif args.verbose:
            print(
                warnings.formatwarning(message, category, filename, lineno, line).rstrip(),
                file=sys.stderr,
            )

    prefix = f"ami-xr {args.command}"
    _show_compile_notice()  # a first run that compiles says so, once
    try:
        with warnings.catch_warnings():
            warnings.showwarning = show_warning
            check_paths(args)
            from ami_xr import provenance  # here, not at the top: --help imports no numpy

            # what the command calls are steps of its record in the files it writes
            with provenance.command(prefix):
                return int(args.func(args) or EXIT_OK)
    except KeyboardInterrupt:
        print(f"{prefix}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as err:  # the one place that turns any error into one line and exit 1
        if args.verbose:
            traceback.print_exc()
        text = _one_line(err)
        if not isinstance(err, EXPECTED_ERRORS):
            text = f"unexpected {text} - a bug, please report it" + (
                "" if args.verbose else f" ({VERBOSE_HINT})"
            )
        print(f"{prefix}: error: {text}", file=sys.stderr)
        return EXIT_ERROR


def _unraisable(hook):
    """A ``sys.unraisablehook`` that stays silent for the SystemExit/KeyboardInterrupt a signal
    raised inside a ``__del__`` or callback (Python cannot propagate those: no traceback for the
    user; :func:`run` still reports the termination)."""

    def quiet(unraisable):
        if not isinstance(unraisable.exc_value, (SystemExit, KeyboardInterrupt)):
            hook(unraisable)

    return quiet


def _usable_streams() -> None:
    """A closed stderr or stdout (``2>&-``: ``sys.stderr`` is None) writes to the null device,
    so a good run is never turned into a failure by where its messages go."""
    import os

    for name in ("stdout", "stderr"):
        if getattr(sys, name) is None:
            setattr(sys, name, open(os.devnull, "w"))  # noqa: SIM115 - lives with the process


def _silence_stdout() -> None:
    """stdout is a broken pipe (``| head -1`` has quit): what is left to print goes nowhere,
    also at interpreter exit (where Python would report the pipe again)."""
    import os

    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
        os.close(null)
    except (OSError, ValueError, AttributeError):
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - lives with the process


def _matplotlib_config_dir() -> None:
    """With a read-only HOME matplotlib complains that its config folder is not writable and
    makes a temporary one itself: make it quietly (removed at exit) unless the user chose one."""
    import os

    if os.environ.get("MPLCONFIGDIR"):
        return
    home = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config")
    folder = home / "matplotlib"
    probe = folder if folder.exists() else home if home.exists() else Path.home()
    if os.access(probe, os.W_OK | os.X_OK):
        return
    import atexit
    import shutil
    import tempfile

    try:
        tmp = tempfile.mkdtemp(prefix="ami_xr-matplotlib-")
    except OSError:
        return
    os.environ["MPLCONFIGDIR"] = tmp
    atexit.register(shutil.rmtree, tmp, True)


def run() -> None:
    """Console-script entry point: :func:`main` with the process-wide signal handling.

    SIGINT and SIGTERM are held for the safe points of :mod:`ami_xr.interrupt` (never raised
    inside numba's dispatcher): Ctrl-C exits 130 (``KeyboardInterrupt``), SIGTERM 143
    (``SystemExit(143)``, so ``finally`` blocks roll back a write in progress), each with one
    line; a signal that came too late to stop the work (the output is complete) still sets the
    exit code. Once :func:`main` has returned, both are ignored (a signal during interpreter
    shutdown would turn the outcome into a silent kill). Closed or broken standard streams and
    a read-only HOME (matplotlib's config folder) never fail a good run. Kept out of
    :func:`main`, which tests and scripts call in-process.
    """
    from ami_xr import interrupt

    _usable_streams()
    _matplotlib_config_dir()
    if hasattr(signal, "SIGXFSZ"):  # past a file-size limit a write fails (named as a full
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # disk) instead of killing the process
    sys.unraisablehook = _unraisable(sys.unraisablehook)
    with interrupt.armed():
        try:
            code = main()
        except SystemExit as stop:
            if stop.code != EXIT_TERMINATED:
                raise
            code = EXIT_TERMINATED
        # The work is done (or stopped): a signal now could only turn the outcome into a silent
        # kill during interpreter shutdown.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    # leaving armed() restored Python's own handlers: a late Ctrl-C would kill the process
    # silently while it exits (seen as -SIGINT with nothing said); keep both ignored
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    late = interrupt.exit_code()
    if late == EXIT_TERMINATED and code in (EXIT_OK, EXIT_TERMINATED):
        _say_err("ami-xr: terminated")
        code = EXIT_TERMINATED
    elif late == EXIT_INTERRUPTED and code == EXIT_OK:
        # the output was complete before the Ctrl-C could stop anything
        _say_err("ami-xr: interrupted")
        code = EXIT_INTERRUPTED
    try:
        sys.stdout.flush()
    except (BrokenPipeError, OSError, ValueError):
        _silence_stdout()
    netcdf = sys.modules.get("ami_xr.io.netcdf")
    if netcdf is not None and netcdf.write_failed():
        # HDF5 (netCDF4 1.6.5) crashed in its exit handler after a failed write: the output is
        # rolled back and everything is said, so leave without the library's exit handlers
        with contextlib.suppress(OSError, ValueError):
            sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def _say_err(text: str) -> None:
    try:
        print(text, file=sys.stderr, flush=True)
    except (OSError, ValueError):  # stderr gone: the exit code says it
        pass


if __name__ == "__main__":  # pragma: no cover
    run()
