"""Progress on stderr for long work started from the command line or :func:`ami_xr.batch.batch`.

One helper, :class:`Progress`, for both kinds of work:

* counted (``total`` given): a bar advanced by :meth:`Progress.update`, e.g. files of a batch;
* open-ended (``total=None``): one long call with no progress hook of its own (identification),
  shown as the elapsed time, refreshed from a daemon thread.

tqdm draws the bar when it is installed, a plain line otherwise. Leaving the ``with`` block,
also by Ctrl-C or an error, stops the thread (it wakes every :data:`TICK_SECONDS`) and closes the
bar, so an interrupt never waits on the indicator.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any

__all__ = ["MIN_ITEMS", "Progress", "TICK_SECONDS", "elapsed"]

#: Seconds between refreshes of an open-ended (elapsed-time) line.
TICK_SECONDS = 0.25
#: :func:`elapsed` shows its line from this many items on (small jobs finish in a blink).
MIN_ITEMS = 8


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

    def __init__(self, total: int, desc: str):
        self.total, self.n, self.desc = total, 0, desc
        self._draw()

    def _draw(self) -> None:
        done = int(self.WIDTH * self.n / self.total) if self.total else self.WIDTH
        bar = "#" * done + "." * (self.WIDTH - done)
        sys.stderr.write(f"\r{self.desc}: [{bar}] {self.n}/{self.total}")
        sys.stderr.flush()

    def update(self, n: int = 1) -> None:
        self.n += n
        self._draw()

    def close(self) -> None:
        sys.stderr.write("\n")
        sys.stderr.flush()


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

    Examples
    --------
    >>> with Progress("files", total=3, enabled=False) as bar:
    ...     for _ in range(3):
    ...         bar.update()
    """

    def __init__(self, desc: str, *, total: int | None = None, unit: str = "it", enabled=True):
        self.desc, self.total, self.unit = desc, total, unit
        self.enabled = bool(enabled) and total != 0
        self._bar: Any = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    def __enter__(self) -> Progress:
        if not self.enabled:
            return self
        tqdm = _tqdm()
        if self.total is not None:
            if tqdm is None:
                self._bar = _PlainBar(self.total, self.desc)
            else:
                self._bar = tqdm(total=self.total, desc=self.desc, unit=self.unit, file=sys.stderr)
            return self
        if tqdm is not None:
            self._bar = tqdm(
                total=None,
                desc=self.desc,
                file=sys.stderr,
                bar_format="{desc}: {elapsed}",
                leave=False,
            )
        self._thread = threading.Thread(target=self._tick, args=(time.perf_counter(),), daemon=True)
        self._thread.start()
        return self

    def _tick(self, start: float) -> None:
        while not self._stop.wait(TICK_SECONDS):
            if self._bar is not None:
                self._bar.refresh()
            else:
                sys.stderr.write(f"\r{self.desc}: {time.perf_counter() - start:.1f} s")
                sys.stderr.flush()

    def update(self, n: int = 1) -> None:
        """Advance a counted bar by ``n`` steps (nothing when disabled or open-ended)."""
        if self._bar is not None and self.total is not None:
            self._bar.update(n)

    def __exit__(self, *exc: object) -> bool:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
        if self._bar is not None:
            self._bar.close()
        elif self._thread is not None:
            sys.stderr.write("\n")
        return False


def elapsed(desc: str, n_items: int, *, enabled: bool = True) -> Progress:
    """An elapsed-time line for one long call over ``n_items`` items (e.g. FRFs).

    Shown only on a terminal (a ticking line would clutter logs and pipes) and from
    :data:`MIN_ITEMS` items on.
    """
    return Progress(desc, enabled=enabled and sys.stderr.isatty() and n_items >= MIN_ITEMS)
