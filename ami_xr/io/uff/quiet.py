"""pyuff's own ``print()`` output kept off the tool's standard output.

pyuff prints while it reads some datasets (its dataset-2467 reader prints every group it parses)
and, in a few corner cases, while it writes. That text is debugging output of pyuff, not a result
of this tool: left alone it lands in the middle of ``ami-xr batch``'s summary table or of a
script's output. Every call into pyuff that reads or writes a file runs inside :func:`quiet`.

:func:`quiet` replaces ``sys.stdout`` for the duration of the call by a proxy that drops what the
calling thread writes and passes what any other thread writes on to the original stream, so a
second thread printing at the same time loses nothing. One lock serialises the calls, so two
threads inside pyuff at once cannot restore ``sys.stdout`` in the wrong order.
"""

from __future__ import annotations

import contextlib
import io
import sys
import threading
from collections.abc import Iterator
from typing import Any

__all__ = ["quiet"]

_LOCK = threading.RLock()


class _ThreadFilter:
    """``sys.stdout`` while pyuff runs: the owner thread's text goes to ``sink``, others' to
    ``target``."""

    def __init__(self, target: Any, owner: int, sink: io.StringIO):
        self._target, self._owner, self._sink = target, owner, sink

    def write(self, text: str) -> int:
        if threading.get_ident() == self._owner:
            return self._sink.write(text)
        if self._target is None:  # pythonw, or stdout closed by the embedding program
            return len(text)
        return self._target.write(text)

    def flush(self) -> None:
        if self._target is not None and threading.get_ident() != self._owner:
            self._target.flush()

    def __getattr__(self, name: str) -> Any:  # encoding, isatty, fileno, ... of the real stream
        return getattr(self._target, name)


@contextlib.contextmanager
def quiet() -> Iterator[io.StringIO]:
    """Run the body with what this thread prints captured (yielded as a StringIO, for tests and
    for callers that want to look at it) instead of written to ``sys.stdout``."""
    sink = io.StringIO()
    with _LOCK:
        proxy = _ThreadFilter(sys.stdout, threading.get_ident(), sink)
        with contextlib.redirect_stdout(proxy):
            yield sink
