"""Reading force/response blocks for the Welch estimator, and the dead-channel check.

:func:`time_blocks` splits a record into the blocks it is read in (the dask chunks, or
``chunk_samples``); :func:`feed_all` feeds every block of every record to a
:class:`~ami_xr.dsp.spectral.WelchAccumulator`, reading a lazy Dataset's next block in a
background thread; :func:`check_live_channels` refuses a channel that is constant throughout.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.dsp.spectral import WelchAccumulator
from ami_xr.dsp.timeseries import is_lazy
from ami_xr.errors import AmiXrValueError

__all__ = [
    "channel_labels",
    "channel_range",
    "check_live_channels",
    "feed_all",
    "load_block",
    "time_blocks",
]


def time_blocks(n: int, da: xr.DataArray, chunk_samples: int | None) -> list[tuple[int, int]]:
    """Time blocks: the dask chunks of ``da`` (or ``chunk_samples``), else the whole record."""
    if chunk_samples is not None:
        size = int(chunk_samples)
    elif is_lazy(da):
        edges = np.cumsum((0,) + tuple(da.chunks[da.get_axis_num(names.TIME)]))
        return list(zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True))
    else:
        size = n
    return [(a, min(a + size, n)) for a in range(0, n, size)]


def load_block(da: xr.DataArray, r: int, a: int, b: int, argument: str) -> np.ndarray:
    block = np.asarray(da.isel({names.RECORD: r, names.TIME: slice(a, b)}).values, np.float64)
    if is_lazy(da) and not np.all(np.isfinite(block)):
        raise AmiXrValueError(
            f"{argument}: contains NaN or inf samples (record {r}, samples {a}..{b - 1})"
        )
    return block


def channel_labels(da: xr.DataArray, dim: str) -> list:
    """Labels along ``dim`` as plain Python values (for messages), else the positions."""
    return da[dim].values.tolist() if dim in da.coords else list(range(da.sizes[dim]))


def check_live_channels(f_range, y_range, f_da: xr.DataArray, y_da: xr.DataArray) -> None:
    """Raise when a force or response channel is constant (all zeros included) over every used
    sample: a dead sensor or an unplugged cable. Its spectra are zero, so its FRF would be NaN
    (0/0) or zero without any error. ``f_range``/``y_range`` are ``(min, max)`` pairs of arrays
    per channel, ``(reference,)`` and ``(point,)``.

    A dead response channel among good ones is an error too, not dropped with a warning: a
    dropped point would silently change the point set that mode shapes, geometry and the UFF
    writer expect; the message names the points and how to leave them out.
    """
    dead_f = np.flatnonzero(np.asarray(f_range[1]) == np.asarray(f_range[0]))
    if dead_f.size:
        refs = channel_labels(f_da, names.REFERENCE)
        which = "" if len(refs) == 1 else f" {[refs[i] for i in dead_f]} (along reference)"
        raise AmiXrValueError(
            f"force: the force channel{which} is zero/constant (dead sensor or unplugged?); "
            f"value {float(np.asarray(f_range[0])[dead_f[0]]):.6g} in every sample"
        )
    dead_y = np.flatnonzero(np.asarray(y_range[1]) == np.asarray(y_range[0]))
    if dead_y.size:
        points = [channel_labels(y_da, names.POINT)[i] for i in dead_y]
        raise AmiXrValueError(
            f"response: the response channel(s) at point(s) {points} are zero/constant (dead "
            f"sensor or unplugged?); leave them out with ds.drop_sel(point={points!r})"
        )


def channel_range(block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) per channel of a (channel, time) block."""
    return block.min(axis=-1), block.max(axis=-1)


def _merge_range(old, new):
    return new if old is None else (np.minimum(old[0], new[0]), np.maximum(old[1], new[1]))


def feed_all(acc: WelchAccumulator, f_da, y_da, records, blocks) -> None:
    """Feed every block of every used record. A lazy Dataset's next block is read in a
    background thread while this one is processed (reads and the nogil kernels overlap); at
    most two blocks are in memory. A lazy Dataset's channels are checked for being dead here,
    on the blocks as they are read (a separate pass would read the file twice)."""
    jobs = [(int(r), a, b) for r in records for a, b in blocks]
    lazy = is_lazy(f_da) or is_lazy(y_da)
    ranges: list = [None, None]

    def load(job):
        r, a, b = job
        f, y = load_block(f_da, r, a, b, "force"), load_block(y_da, r, a, b, "response")
        if lazy:  # data in memory were checked in dsp.estimator.setup
            ranges[0] = _merge_range(ranges[0], channel_range(f))
            ranges[1] = _merge_range(ranges[1], channel_range(y))
        return f, y

    def run(next_block):
        for i, (_, a, _) in enumerate(jobs):
            if a == 0 and i > 0:
                acc.end_record()  # segments never span two records
            acc.feed(*next_block(i))

    if not lazy or len(jobs) < 2:
        run(lambda i: load(jobs[i]))
    else:
        with ThreadPoolExecutor(max_workers=1) as pool:
            pending = {0: pool.submit(load, jobs[0])}

            def next_block(i):
                data = pending.pop(i).result()
                if i + 1 < len(jobs):
                    pending[i + 1] = pool.submit(load, jobs[i + 1])
                return data

            try:
                run(next_block)
            finally:
                for fut in pending.values():
                    fut.cancel()
    if lazy:
        check_live_channels(ranges[0], ranges[1], f_da, y_da)
