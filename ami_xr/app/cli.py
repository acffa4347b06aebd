"""The ``ami-xr`` command line: a thin shell over the public functions.

Each subcommand parses its options (:mod:`ami_xr.app.parser`), calls one public function
(:mod:`ami_xr.app.commands`; heavy imports happen inside the subcommand, so ``ami-xr --help`` is
fast and compiles nothing), and maps errors to exit codes. This module is the entry point: one
rule holds for every subcommand (:func:`main`), and the process-wide handling is :func:`run`'s:

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
* Exit codes (defined once, in :mod:`ami_xr.app.terminal`, and read from here): 0 success
  (:data:`EXIT_OK`); 1 an error (:data:`EXIT_ERROR`); 2 a usage error (argparse,
  :data:`EXIT_USAGE`); 3 ``batch`` finished but some files failed (:data:`EXIT_BATCH_FAILURES`);
  4 ``batch`` finished, none failed, but some identifications stopped at a cap (status
  ``capped``, :data:`EXIT_BATCH_CAPPED`); 130 interrupted by Ctrl-C (:data:`EXIT_INTERRUPTED`,
  one line ``ami-xr <command>: interrupted``); 143 terminated by SIGTERM (:data:`EXIT_TERMINATED`,
  one line ``ami-xr: terminated``; a write in progress is rolled back first).

Option defaults are read from the signatures of the functions they feed, only when a help text
shows them (:mod:`ami_xr.app.options`, which also declares the options shared by several
subcommands); options left at their default are not passed on, so the library applies its own.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import os
import re
import signal
import sys
import traceback
import warnings
from collections.abc import Sequence
from pathlib import Path

from ami_xr.app.options import check_paths
from ami_xr.app.parser import build_parser
from ami_xr.app.terminal import (  # noqa: F401 - the exit codes are read from here too
    EXIT_BATCH_CAPPED,
    EXIT_BATCH_FAILURES,
    EXIT_ERROR,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_TERMINATED,
    EXIT_USAGE,
    silence_stdout,
)
from ami_xr.errors import AmiXrError, AmiXrWarning

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
        silence_stdout()
    netcdf = sys.modules.get("ami_xr.io.netcdf")
    if netcdf is not None and netcdf.write_failed():
        # HDF5 (netCDF4 1.6.5) crashed in its exit handler after a failed write: the output is
        # rolled back and everything is said, so leave without the library's exit handlers
        with contextlib.suppress(OSError, ValueError):
            sys.stderr.flush()
        os._exit(code)
    # the interpreter's last garbage collection walks every object of a large run: 1.8-2.3 s
    # of a 1000-point identify's exit on a loaded machine, after a Ctrl-C was honoured; frozen
    # objects are left to the process's end (atexit handlers and module teardown still run)
    gc.freeze()
    sys.exit(code)


def _say_err(text: str) -> None:
    try:
        print(text, file=sys.stderr, flush=True)
    except (OSError, ValueError):  # stderr gone: the exit code says it
        pass


if __name__ == "__main__":  # pragma: no cover
    run()
