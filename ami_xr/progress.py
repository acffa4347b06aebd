"""Progress on stderr for long work started from the command line or :func:`ami_xr.batch.batch`.

One helper, :class:`Progress`, for both kinds of work:

* counted (``total`` given): a bar advanced by :meth:`Progress.update`, e.g. files of a batch;
* open-ended (``total=None``): one long call with no progress hook of its own, shown as the
  elapsed time, refreshed from a daemon thread;
* phases of one long call (:func:`phases`, used by ``ami_xr.identify(ds, progress=True)``): a
  counted bar of the phases done, named by the running one, whose elapsed time keeps moving
  during a long phase; on the command line it appears only after :data:`DELAY_SECONDS`.
  Inside a phase the bar also counts what that phase counts (:func:`detail`): FRFs done by
  the per-FRF kernels (:func:`by_rows`), and the refinement's modes and iterations
  (:class:`Iterations`); e.g. ``identify: 1 FRFs x 25601 lines (refine: 15 modes,
  iteration 12): 75%|...| 3/4 [00:05<...]``.

Every count is also a safe point for an interrupt (:func:`ami_xr.interrupt.checkpoint`): while
the command line holds signals (:func:`ami_xr.interrupt.armed`), :func:`active` is true, so the
kernels are called in pieces and a Ctrl-C or SIGTERM is raised between two of them, never
inside numba's dispatcher.

tqdm draws the bar when it is installed, a plain line otherwise. Leaving the ``with`` block,
also by Ctrl-C or an error, stops the thread (it wakes every :data:`TICK_SECONDS`) and closes the
bar, so an interrupt never waits on the indicator.

Progress never fails the work it shows: with no usable stderr (``sys.stderr`` None, as under
``pythonw`` or some services, or closed) nothing is drawn, and a stderr that fails a write
(closed during the work, a broken pipe) ends the drawing, quietly (:func:`stderr`).
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any

from ami_xr.errors import AmiXrValueError
from ami_xr.interrupt import checkpoint, is_armed

__all__ = [
    "DELAY_SECONDS",
    "Iterations",
    "MIN_ITEMS",
    "PhaseBar",
    "Progress",
    "THREAD_NAME",
    "TICK_SECONDS",
    "active",
    "by_rows",
    "detail",
    "elapsed",
    "notice",
    "on_a_terminal",
    "phases",
    "stderr",
]


#: Name of the thread that redraws a live bar.
THREAD_NAME = "ami_xr-progress"
#: Seconds between refreshes of an open-ended (elapsed-time) line.
TICK_SECONDS = 0.25
#: :func:`elapsed` shows its line from this many items on (small jobs finish in a blink).
MIN_ITEMS = 8
#: The command line draws a phase bar only once the work has lasted this long (seconds).
DELAY_SECONDS = 2.0
#: :func:`by_rows` splits a kernel call into at most this many calls (one count each).
MAX_CALLS = 50

# Where :func:`detail` sends the running phase's counts: set by :func:`phases` while a bar (or a
# callback with a ``detail`` method) listens, None otherwise (then nothing is counted or split).
_DETAIL: ContextVar = ContextVar("ami_xr_progress_detail", default=None)


#: What a write to a stream that is gone raises: closed (ValueError), a broken pipe or an I/O
#: error (OSError), not a stream at all (AttributeError).
STREAM_ERRORS = (OSError, ValueError, AttributeError)


def stderr():
    """``sys.stderr`` when progress can be drawn on it, else None: None under ``pythonw`` or a
    service that has none, or closed (a write would raise)."""
    stream = sys.stderr
    if stream is None or not callable(getattr(stream, "write", None)):
        return None
    try:
        if stream.closed:
            return None
    except STREAM_ERRORS:
        return None
    return stream


def _write(stream, text: str) -> bool:
    """Write and flush ``text``; False (nothing raised) when the stream is gone."""
    try:
        stream.write(text)
        stream.flush()
    except STREAM_ERRORS:
        return False
    return True


def on_a_terminal() -> bool:
    """Whether stderr is a usable terminal (False when it is None or closed)."""
    stream = stderr()
    try:
        return stream is not None and bool(stream.isatty())
    except STREAM_ERRORS:
        return False


def notice(text: str) -> None:
    """``text`` as a line on stderr, or nowhere when there is none or it is closed."""
    stream = stderr()
    if stream is not None:
        _write(stream, text + "\n")


def active() -> bool:
    """Whether a progress bar listens for counts inside the running phase, or signals are held
    for the checkpoints (:func:`ami_xr.interrupt.is_armed`): either way, long kernel work is
    done in pieces with a :func:`detail` call between them."""
    return _DETAIL.get() is not None or is_armed()


def detail(text: str) -> None:
    """Show ``text`` (counts inside the running phase) on the bar; nothing when none listens.
    Also a safe point for a held interrupt (:func:`ami_xr.interrupt.checkpoint`)."""
    checkpoint()
    report = _DETAIL.get()
    if report is not None:
        report(text)


def by_rows(kernel, args: tuple, rowwise: tuple[int, ...], unit: str = "FRFs"):
    """``kernel(*args)``, a kernel that treats every row (FRF) on its own: with a bar listening,
    called on blocks of rows (at most :data:`MAX_CALLS` calls), counting the rows done, and its
    outputs (arrays with one row per input row) joined. The rows are computed by the same code
    either way, so the results are identical; without a bar it is one call, as before.

    ``rowwise``: positions in ``args`` of the arrays with one row per FRF.
    """
    n_rows = args[rowwise[0]].shape[0]
    if not active() or n_rows < 2:
        return kernel(*args)
    import numpy as np  # lazy: the command line imports this module before numpy is needed

    step = -(-n_rows // MAX_CALLS)
    parts = []
    detail(f"0/{n_rows} {unit}")
    for lo in range(0, n_rows, step):
        block = list(args)
        for i in rowwise:
            block[i] = args[i][lo : lo + step]
        parts.append(kernel(*block))
        detail(f"{min(lo + step, n_rows)}/{n_rows} {unit}")
    return tuple(np.concatenate(outs, axis=0) for outs in zip(*parts, strict=True))


class Iterations:
    """Counts iterations of an optimiser into :func:`detail`: pass as the ``trace`` list of
    :func:`ami_xr.core.varpro.levenberg_marquardt` (its ``append`` is called once per iteration).
    ``stage`` and ``modes`` name what is being fitted."""

    def __init__(self) -> None:
        self.n, self.modes, self.stage = 0, 0, ""

    def append(self, _item: object) -> None:
        self.n += 1
        self.show()

    def show(self) -> None:
        stage = f"{self.stage}, " if self.stage else ""
        detail(f"{stage}{self.modes} modes, iteration {self.n}")


def _tqdm():
    """tqdm's class, or None when tqdm is not installed (it is an optional extra)."""
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm


class _PlainBar:
    """A counted progress line on stderr for when tqdm is not installed."""

    WIDTH = 30

    def __init__(self, total: int, desc: str, delay: float = 0.0, file=None):
        self.total, self.n, self.desc = total, 0, desc
        self._start, self._delay, self._shown = time.perf_counter(), delay, False
        self._file = file  # None: the stream is gone, nothing is drawn
        self._draw()

    def _draw(self) -> None:
        seconds = time.perf_counter() - self._start
        if seconds < self._delay or self._file is None:
            return
        self._shown = True
        done = int(self.WIDTH * self.n / self.total) if self.total else self.WIDTH
        bar = "#" * done + "." * (self.WIDTH - done)
        line = f"\r{self.desc}: [{bar}] {self.n}/{self.total} {seconds:.1f} s"
        if not _write(self._file, line):
            self._file = None  # closed during the work: stop drawing

    def update(self, n: int = 1) -> None:
        self.n += n
        self._draw()

    def refresh(self) -> None:
        self._draw()

    def set_description_str(self, desc: str, refresh: bool = True) -> None:
        self.desc = desc
        if refresh:
            self._draw()

    def close(self) -> None:
        if self._shown and self._file is not None:
            _write(self._file, "\n")


class Progress:
    """Context manager showing progress on stderr while the ``with`` block runs.

    Parameters
    ----------
    desc : str
        Label in front of the bar or the elapsed time.
    total : int, optional
        Number of steps of counted work; None for one open-ended call (elapsed time).
    unit : str, default "it"
        Unit of a counted bar (tqdm only).
    enabled : bool, default True
        False shows nothing (the block still runs); so does ``total=0``.
    delay : float, default 0
        Show nothing until the block has run this many seconds.
    live : bool, default False
        A counted bar is also redrawn every :data:`TICK_SECONDS`, so its elapsed time moves
        during a long step.

    Examples
    --------
    >>> with Progress("files", total=3, enabled=False) as bar:
    ...     for _ in range(3):
    ...         bar.update()
    """

    def __init__(
        self,
        desc: str,
        *,
        total: int | None = None,
        unit: str = "it",
        enabled=True,
        delay: float = 0.0,
        live: bool = False,
    ):
        self.desc, self.total, self.unit = desc, total, unit
        self.delay, self.live = float(delay), bool(live)
        self.enabled = bool(enabled) and total != 0
        self._bar: Any = None
        self._t0 = time.perf_counter()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._file: Any = None

    def __enter__(self) -> Progress:
        self._t0 = time.perf_counter()
        # the stream of this block, taken once: no stderr (pythonw) or a closed one draws nothing
        self._file = stderr() if self.enabled else None
        if self._file is None:
            return self
        tqdm = _tqdm()
        if self.total is not None:
            if tqdm is None:
                self._bar = _PlainBar(self.total, self.desc, self.delay, file=self._file)
            else:
                self._bar = tqdm(
                    total=self.total,
                    desc=self.desc,
                    unit=self.unit,
                    file=self._file,
                    delay=self.delay,
                )
            if self.live:
                self._start_ticking()
            return self
        if tqdm is not None:
            self._bar = tqdm(
                total=None,
                desc=self.desc,
                file=self._file,
                bar_format="{desc}: {elapsed}",
                leave=False,
            )
        self._start_ticking()
        return self

    def _start_ticking(self) -> None:
        self._thread = threading.Thread(
            target=self._tick, args=(time.perf_counter(),), daemon=True, name=THREAD_NAME
        )
        self._thread.start()

    def _tick(self, start: float) -> None:
        while not self._stop.wait(TICK_SECONDS):
            if time.perf_counter() - start < self.delay:
                continue
            if self._bar is not None:
                try:
                    self._bar.refresh()
                except STREAM_ERRORS:  # tqdm's own guard missed it: stop redrawing
                    return
            elif self._file is None or not _write(
                self._file, f"\r{self.desc}: {time.perf_counter() - start:.1f} s"
            ):
                self._file = None  # closed during the work: stop drawing
                return

    def update(self, n: int = 1) -> None:
        """Advance a counted bar by ``n`` steps (nothing when disabled or open-ended)."""
        if self._bar is not None and self.total is not None:
            with contextlib.suppress(*STREAM_ERRORS):
                self._bar.update(n)

    def describe(self, text: str, refresh: bool = True) -> None:
        """Name the running step after the label: ``desc (text)``; ``refresh=False`` leaves the
        redraw to the live thread (cheap enough to call at every iteration)."""
        if self._bar is not None:
            shown = time.perf_counter() - self._t0 >= self.delay
            with contextlib.suppress(*STREAM_ERRORS):
                self._bar.set_description_str(f"{self.desc} ({text})", refresh=refresh and shown)

    def __exit__(self, *exc: object) -> bool:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
        if self._bar is not None:
            with contextlib.suppress(*STREAM_ERRORS):
                self._bar.close()
        elif self._thread is not None and self._file is not None:
            _write(self._file, "\n")
        return False


def elapsed(desc: str, n_items: int, *, enabled: bool = True) -> Progress:
    """An elapsed-time line for one long call over ``n_items`` items (e.g. FRFs).

    Shown only on a terminal (a ticking line would clutter logs and pipes) and from
    :data:`MIN_ITEMS` items on.
    """
    return Progress(desc, enabled=enabled and n_items >= MIN_ITEMS and on_a_terminal())


class PhaseBar:
    """A ``(phase, done, total)`` callback that draws the phases of one long call as a bar.

    The bar (a live :class:`Progress`, counted in phases) opens at the first call and closes
    when ``done`` reaches ``total`` or at :meth:`close`. ``delay`` (seconds) keeps short work
    silent; ``enabled=False`` draws nothing.
    """

    def __init__(self, desc: str, *, delay: float = 0.0, enabled: bool = True):
        self.desc, self.delay, self.enabled = desc, float(delay), bool(enabled)
        self._bar: Progress | None = None

    def __call__(self, phase: str, done: int, total: int) -> None:
        if not self.enabled:
            return
        if self._bar is None:
            self._bar = Progress(
                self.desc, total=total, unit="phase", delay=self.delay, live=True
            ).__enter__()
            self._n, self._drawn = 0, time.perf_counter()
        self._phase = phase
        self._bar.describe(phase)
        self._bar.update(done - self._n)
        self._n = done
        if done >= total:
            self.close()

    def detail(self, text: str) -> None:
        """Counts inside the running phase: ``desc (phase: text)``; redrawn at most every
        :data:`TICK_SECONDS` (the live thread redraws in between)."""
        if self._bar is not None:
            now = time.perf_counter()
            refresh = now - self._drawn >= TICK_SECONDS
            self._drawn = now if refresh else self._drawn
            self._bar.describe(f"{self._phase}: {text}", refresh=refresh)

    def close(self) -> None:
        """Close the bar (also when the call stopped early)."""
        if self._bar is not None:
            self._bar.__exit__(None, None, None)
            self._bar = None


def on_terminal(enabled: bool = True, desc: str = "") -> PhaseBar | bool:
    """The ``progress`` argument for work started from the command line: a :class:`PhaseBar`
    that appears after :data:`DELAY_SECONDS` when stderr is a terminal, else False."""
    if not (enabled and on_a_terminal()):
        return False
    return PhaseBar(desc, delay=DELAY_SECONDS)


class _Phases:
    """Reports the start of each named phase of one call: ``report(phase, done, total)`` with
    ``done`` the phases finished before it; ``("done", total, total)`` at the end."""

    def __init__(self, report, names: list[str]):
        self.report, self.names, self.done = report, list(names), 0

    def __call__(self, phase: str) -> None:
        checkpoint()  # between two phases: a safe point for a held interrupt
        if self.report is not None:
            self.done = self.names.index(phase)
            self.report(phase, self.done, len(self.names))

    def finish(self) -> None:
        if self.report is not None:
            self.report("done", len(self.names), len(self.names))


@contextmanager
def phases(progress, desc: str, names: list[str]):
    """Context for a call with the given phases; yields ``step(phase)`` to call as each starts.

    ``progress``: False or None (nothing), True (a :class:`PhaseBar` labelled ``desc`` on
    stderr, tqdm when installed), or a callable ``(phase, done, total)``. A callback with a
    ``close`` method (a :class:`PhaseBar`) is closed on leaving, also on an error (a
    :class:`PhaseBar` without a label takes ``desc``); the final
    ``("done", total, total)`` comes only when the call completes. A callback with a
    ``detail(text)`` method (a :class:`PhaseBar`) also gets the counts inside each phase
    (:func:`detail`); only then are the per-FRF kernels split (:func:`by_rows`).
    """
    if progress is True:
        progress = PhaseBar(desc)
    elif isinstance(progress, PhaseBar) and not progress.desc:
        progress.desc = desc  # e.g. on_terminal(): the call knows what it works on
    elif progress is False or progress is None:
        progress = None
    elif not callable(progress):
        raise AmiXrValueError(
            f"progress: expected True, False or a callable (phase, done, total), got {progress!r}"
        )
    step = _Phases(progress, names)
    token = _DETAIL.set(getattr(progress, "detail", None))
    try:
        yield step
        step.finish()
    finally:
        _DETAIL.reset(token)
        close = getattr(progress, "close", None)
        if close is not None:
            close()
