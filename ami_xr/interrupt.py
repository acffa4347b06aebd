"""Interrupts that land where they are safe.

A signal cannot be handled inside compiled (numba) code: Python runs a handler between
bytecodes, and one that raises while numba's dispatcher is between its C and Python parts
leaves "returned a result with an exception set" errors or worse. So while :func:`armed` is in
force (the command line arms it for the whole command), a SIGINT or SIGTERM that arrives while
a frame of numba, llvmlite, the kernel modules or a thread pool is on the main thread's stack is
only *recorded*, and :func:`checkpoint` raises it at the next safe point between bounded pieces
of work; one that arrives elsewhere (reading, plotting, plain Python between kernels) is raised
at once, as Python would:

* ``KeyboardInterrupt`` for SIGINT (the command line exits 130);
* :class:`Terminated` (a ``SystemExit(143)``) for SIGTERM.

The checkpoints sit in the progress reporting the labeled layers already call between pieces
of kernel work (:func:`ami_xr.progress.detail`, the phase steps, the optimiser's iteration
counter), in numba's compile events (a first run that compiles stops between two kernels), and
in the command line between reading, computing and writing. :func:`is_armed` tells the
labeled layers to call their kernels in pieces even when no progress bar listens.

In a worker process of ``ami-xr batch`` the parent's stop request arrives through a shared
event (:func:`use_event`); the worker's checkpoints raise as for a signal.

Outside :func:`armed` (library use in a notebook) nothing changes: Python's own handlers stay.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = [
    "EXIT_INTERRUPTED",
    "EXIT_TERMINATED",
    "Terminated",
    "armed",
    "checkpoint",
    "exit_code",
    "hold",
    "is_armed",
    "pending",
    "received",
    "use_event",
]

EXIT_INTERRUPTED = 128 + signal.SIGINT  # 130, as a shell reports a Ctrl-C
EXIT_TERMINATED = 128 + signal.SIGTERM  # 143

_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Terminated(SystemExit):
    """Raised at a checkpoint after SIGTERM: ``SystemExit(143)``, so ``finally`` blocks run."""

    def __init__(self) -> None:
        super().__init__(EXIT_TERMINATED)


class _State:
    def __init__(self) -> None:
        self.armed = 0  # nesting depth of armed()
        self.pending: list[int] = []  # signals recorded and not yet raised
        self.received: list[int] = []  # every signal recorded (the exit code depends on them)
        self.event: Any = None  # a multiprocessing.Event set by a batch parent
        self.numba_hooked = False
        self.last = time.perf_counter()  # time of the last checkpoint (campaign measurements)
        self.longest = 0.0  # longest gap between two checkpoints while armed (seconds)


_STATE = _State()


# Modules whose Python frames may sit between numba's C dispatcher and compiled code, or wait
# on threads that run compiled code: a signal handled while one of them is on the stack is held
# for the next checkpoint.
_HELD_IN = ("numba", "llvmlite", "ami_xr.kernels", "threading", "concurrent.futures")


def _safe_here(frame: Any) -> bool:
    """Whether raising in ``frame`` (where the main thread was when the signal came) cannot land
    in numba's machinery: no frame of :data:`_HELD_IN` on its stack."""
    while frame is not None:
        name = frame.f_globals.get("__name__", "") or ""
        if name.startswith(_HELD_IN):
            return False
        frame = frame.f_back
    return True


def _raise(signum: int) -> None:
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated


def _record(signum: int, frame: Any) -> None:
    # Raised at once where that is safe (reading, plotting, plain Python); held for the next
    # checkpoint while numba's machinery may be on the stack (see the module doc).
    _STATE.received.append(signum)
    if _safe_here(frame):
        _raise(signum)
    _STATE.pending.append(signum)


def hold(signum: int, frame: Any) -> None:
    """A signal handler that only records (never raises): for a process idle between pieces of
    work, e.g. a batch worker waiting for its next file."""
    _STATE.pending.append(signum)
    _STATE.received.append(signum)


def is_armed() -> bool:
    """Whether signals are held for the checkpoints (the command line, a batch worker)."""
    return _STATE.armed > 0


def pending() -> int | None:
    """The first recorded signal not yet raised (or SIGTERM for a stop request), else None."""
    if _STATE.pending:
        return _STATE.pending[0]
    if _STATE.event is not None and _STATE.event.is_set():
        return signal.SIGTERM
    return None


def received() -> list[int]:
    """Every signal recorded while armed (also those already raised), in order."""
    return list(_STATE.received)


def exit_code() -> int | None:
    """130 or 143 for the first signal received while armed, None when none came."""
    first = _STATE.received[0] if _STATE.received else None
    if first is None:
        return EXIT_TERMINATED if _STATE.event is not None and _STATE.event.is_set() else None
    return EXIT_INTERRUPTED if first == signal.SIGINT else EXIT_TERMINATED


def checkpoint() -> None:
    """Raise a recorded signal here, at a safe point: ``KeyboardInterrupt`` for SIGINT,
    :class:`Terminated` for SIGTERM (or a batch parent's stop request). Cheap; nothing happens
    outside :func:`armed`, in threads other than the main one, or with nothing pending."""
    state = _STATE
    if not state.armed:
        return
    now = time.perf_counter()
    state.longest = max(state.longest, now - state.last)
    state.last = now
    if not state.numba_hooked:
        _hook_numba()
    signum = pending()
    if signum is None or threading.current_thread() is not threading.main_thread():
        return
    if state.pending:
        state.pending.pop(0)
    _raise(signum)


def longest_gap() -> float:
    """Longest time (s) between two checkpoints since :func:`armed` began (for the campaign)."""
    return _STATE.longest


def _hook_numba() -> None:
    """Listen to numba's compile events once numba is imported (never imports it): a first run
    that compiles many kernels stops between two of them. An exception raised from a listener
    goes up numba's Python compile path like a compile error (no lock or cache entry is left
    half-done: numba writes its cache files by rename)."""
    import sys

    if "numba" not in sys.modules:
        return
    _STATE.numba_hooked = True
    try:
        from numba.core import event
    except ImportError:  # pragma: no cover - an older numba without the event API
        return

    class CompileCheckpoint(event.Listener):
        def on_start(self, ev: Any) -> None:
            checkpoint()

        def on_end(self, ev: Any) -> None:
            checkpoint()

    event.register("numba:compile", CompileCheckpoint())


@contextmanager
def armed() -> Iterator[None]:
    """Hold SIGINT and SIGTERM for :func:`checkpoint` while the block runs (main thread only;
    elsewhere, and when nested, it only marks the block as armed). On leaving, the previous
    handlers are restored; signals recorded and not raised stay in :func:`received`."""
    main = threading.current_thread() is threading.main_thread()
    previous: dict[int, Any] = {}
    if main and not _STATE.armed:
        for signum in _SIGNALS:
            previous[signum] = signal.signal(signum, _record)
    _STATE.armed += 1
    _STATE.last, _STATE.longest = time.perf_counter(), 0.0
    try:
        yield
    finally:
        _STATE.armed -= 1
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def use_event(event: Any) -> None:
    """In a worker process: treat ``event`` (a ``multiprocessing.Event``) being set as a stop
    request that the checkpoints raise as :class:`Terminated`."""
    _STATE.event = event


def reset() -> None:
    """Forget recorded signals and the stop event (tests; a fresh command in the same process)."""
    _STATE.pending.clear()
    _STATE.received.clear()
    _STATE.event = None
