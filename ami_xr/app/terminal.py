"""The ``ami-xr`` command's exit codes and its printing on stdout (shared by the parser's
subcommands and the entry point, :mod:`ami_xr.app.cli`)."""

from __future__ import annotations

import sys
from typing import Any

EXIT_OK = 0
EXIT_ERROR = 1
EXIT_USAGE = 2  # argparse exits with this itself
EXIT_BATCH_FAILURES = 3
EXIT_BATCH_CAPPED = 4  # batch: no failure, but some results incomplete (stopped at a cap)
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports a Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM


def say(*parts: Any) -> None:
    # a path that is not valid UTF-8 (surrogate-escaped by os) must not kill the output
    text = " ".join(str(p) for p in parts)
    encoding = getattr(sys.stdout, "encoding", None) or "utf-8"
    try:
        print(text.encode(encoding, "backslashreplace").decode(encoding), flush=True)
    except BrokenPipeError:  # the reader quit (`| head -1`): the work itself goes on
        silence_stdout()


def silence_stdout() -> None:
    """stdout is a broken pipe (``| head -1`` has quit): what is left to print goes nowhere,
    also at interpreter exit (where Python would report the pipe again)."""
    import os

    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
        os.close(null)
    except (OSError, ValueError, AttributeError):
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - lives with the process
