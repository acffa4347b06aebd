"""Interrupts that land where they are safe.

A signal cannot be handled inside compiled (numba) code: Python runs a handler between
bytecodes, and one that raises while numba's dispatcher is between its C and Python parts
leaves "returned a result with an exception set" errors or worse. So while :func:`armed` is in
force (the command line arms it for the whole command), a SIGINT or SIGTERM that arrives while
a frame of numba, llvmlite, the kernel modules or a thread pool is on the main thread's stack is
only *recorded*, and :func:`checkpoint` raises it at the next safe point between bounded pieces
of work; one that arrives elsewhere (reading, plotting, plain Python between kernels) is raised
at once, as Python would. Inside numba's Python compiler (a first run compiles a kernel for up
to 15 s with no checkpoint) no compiled code runs, so a signal is raised at once there too, like
a compile error; inside llvmlite (C calls into LLVM, callbacks from it) it is raised as soon as
numba's frame that called llvmlite runs again (see :func:`_classify`):

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
import sys
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
        self.target: Any = None  # numba frame traced to raise in once llvmlite returns


_STATE = _State()


# Modules whose Python frames may sit between numba's C dispatcher and compiled code, or wait
# on threads that run compiled code: a signal handled while one of them is on the stack is held
# for the next checkpoint (except inside numba's compiler, see _classify).
_HELD_IN = ("numba", "llvmlite", "ami_xr.kernels", "threading", "concurrent.futures")
# Never raised in, even inside the compiler: a thread pool or lock wait, the disk cache (numba
# removes its temporary file on Exception only), pickling for it.
_NEVER_IN = ("threading", "concurrent.futures", "numba.core.caching", "numba.core.serialize")
# numba's compiler lock is taken and given back in Python: never raised between the two (its
# decorator's frame, which holds the lock around a compile, is no obstacle).
_LOCK_STEPS = ("acquire", "release", "__enter__", "__exit__")
# Where the C dispatcher (or a caller compiling ahead) enters numba's Python compiler.
_COMPILE_ENTRIES = ("_compile_for_args", "compile")


def _module(frame: Any) -> str:
    return frame.f_globals.get("__name__", "") or ""


def _classify(frame: Any) -> tuple[str, Any]:
    """Where the main thread was (``frame``) when a signal came, and what may be done there.

    ``("plain", None)``: no frame of :data:`_HELD_IN`; raise at once. ``("compiler", None)``:
    inside numba's Python compiler (type inference, lowering, codegen), entered from the
    dispatcher, with no llvmlite frame: no compiled code runs (a nopython kernel cannot call
    back into Python, and numba compiles callees before it runs a caller), so an exception goes
    up numba's compile path like a compile error (numba catches ``Exception`` only; its locks are
    context managers); raise at once. ``("llvm", target)``: the same but inside llvmlite, whose
    Python binding hands LLVM objects' ownership over between two statements (raising there
    could free one twice) and runs C callbacks (where ctypes swallows an exception): raise when
    control is back in ``target``, numba's frame that called llvmlite. ``("held", None)``:
    anything else (compiled code or a thread pool may be on the stack); hold for a checkpoint.
    """
    frames = []
    while frame is not None:
        frames.append(frame)
        frame = frame.f_back
    names = [_module(f) for f in frames]
    if not any(n.startswith(_HELD_IN) for n in names):
        return "plain", None
    if any(n.startswith(_NEVER_IN) for n in names):
        return "held", None
    if any(
        n == "numba.core.compiler_lock" and f.f_code.co_name in _LOCK_STEPS
        for n, f in zip(names, frames, strict=True)
    ):
        return "held", None
    numba_like = [i for i, n in enumerate(names) if n.startswith(("numba", "llvmlite"))]
    if not numba_like:
        return "held", None  # a kernel module's Python between compiled calls
    entry = numba_like[-1]  # the outermost: nothing of numba runs outside it
    if names[entry] != "numba.core.dispatcher":
        return "held", None
    if frames[entry].f_code.co_name not in _COMPILE_ENTRIES:
        return "held", None
    in_llvm = [i for i, n in enumerate(names) if n.startswith("llvmlite")]
    if not in_llvm:
        return "compiler", None
    target = frames[in_llvm[-1] + 1]  # exists: the entry is outside every llvmlite frame
    if not names[in_llvm[-1] + 1].startswith("numba"):
        return "held", None
    return "llvm", target


def _safe_here(frame: Any) -> bool:
    """Whether a signal that came while the main thread was in ``frame`` may be raised at once:
    nothing of numba's machinery on the stack, or inside numba's Python compiler (see
    :func:`_classify`)."""
    return _classify(frame)[0] in ("plain", "compiler")


def _raise(signum: int) -> None:
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated


def _untrace() -> None:
    target, _STATE.target = _STATE.target, None
    if target is not None:
        target.f_trace = None
        if sys.gettrace() is _no_call_trace:
            sys.settrace(None)


def _no_call_trace(frame: Any, event: str, arg: Any) -> None:
    return None  # new frames are not traced: only the target frame's own f_trace runs


def _raise_back_in(frame: Any, event: str, arg: Any) -> Any:
    """The target frame's trace function: its next line (or return) after llvmlite returned."""
    _untrace()
    if _STATE.armed and _STATE.pending:
        _raise(_STATE.pending.pop(0))
    return None


def _raise_when_back_in(target: Any) -> None:
    """Raise the pending signal as soon as numba's ``target`` frame runs again (llvmlite
    returned): a line-trace on that frame only, nothing else traced. Skipped when a debugger or
    coverage already traces (the signal then waits for the next checkpoint)."""
    if _STATE.target is not None or sys.gettrace() is not None:
        return
    _STATE.target = target
    target.f_trace = _raise_back_in
    target.f_trace_lines = True
    sys.settrace(_no_call_trace)


def _record(signum: int, frame: Any) -> None:
    # Raised at once where that is safe (reading, plotting, plain Python, numba's compiler);
    # raised when llvmlite returns inside the compiler; held for the next checkpoint while
    # compiled code may be on the stack (see the module doc).
    _STATE.received.append(signum)
    kind, target = _classify(frame)
    if kind in ("plain", "compiler"):
        _raise(signum)
    _STATE.pending.append(signum)
    if kind == "llvm":
        _raise_when_back_in(target)


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
    _untrace()
    _raise(signum)


def longest_gap() -> float:
    """Longest time (s) between two checkpoints since :func:`armed` began (for the campaign)."""
    return _STATE.longest


def _hook_numba() -> None:
    """Listen to numba's compile events once numba is imported (never imports it): a first run
    that compiles many kernels stops between two of them. An exception raised from a listener
    goes up numba's Python compile path like a compile error (no lock or cache entry is left
    half-done: numba writes its cache files by rename)."""
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
        if not _STATE.armed:
            _untrace()
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
