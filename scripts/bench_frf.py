"""Benchmark: H1 and coherence from a long shaker record streamed from netCDF.

1. A child process writes a synthetic shaker test to netCDF with :func:`ami_xr.to_netcdf` from
   a lazily built (dask) Dataset: white random force, ``--points`` responses of a lightly damped
   multi-mode system (IIR filters; each dask chunk warmed up over the preceding 2 s), a little
   output noise. Default 16 responses + 1 force, 12,000,000 samples each: 2.04e8 samples.
2. This process opens the file lazily (``ami_xr.open_dataset(path, chunks={"time": chunk})``)
   and runs ``ami_xr.frf(ds, "H1", ...)``: chunk by chunk, overlap carried across chunk borders.
   It prints the throughput (samples of all channels per second) and the peak resident memory
   (``resource.getrusage``, read right after the streaming run).
3. Speed against scipy on the same in-memory slice (``--slice`` samples per channel, measured
   in this run): ``scipy.signal.csd`` (force x all responses) + ``scipy.signal.welch`` (force,
   responses) for H1 and coherence, against ``ami_xr.frf`` on the slice as an in-memory
   Dataset; both single-threaded, both with the same window, nperseg, noverlap and detrend.
   The ratio is scipy time / ami_xr time (> 1: ami_xr faster). The H1 of both must agree.

Usage::

    python scripts/bench_frf.py                       # full size (a few minutes, ~1.6 GB file)
    python scripts/bench_frf.py --samples 2000000     # smaller
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

FS = 2048.0
WARMUP = 4096  # samples (2 s) to settle the IIR state at a chunk start: e^(-sigma t) < 1e-13


def _system(n_points: int):
    """Second-order sections of each response: three modes (40, 170, 420 Hz, 2.5 % damping)
    with point-dependent gains."""
    import scipy.signal

    rng = np.random.default_rng(0)
    sos_all = []
    for p in range(n_points):
        num = np.zeros(1)
        den = np.ones(1)
        for fn in (40.0, 170.0, 420.0):
            w = 2 * np.pi * fn
            b, a = scipy.signal.bilinear(
                [rng.uniform(0.2, 1.0) * np.cos(p + fn)], [1.0, 2 * 0.025 * w, w * w], fs=FS
            )
            num = np.polyadd(np.polymul(num, a), np.polymul(b, den))
            den = np.polymul(den, a)
        sos_all.append(scipy.signal.tf2sos(num, den))
    return np.array(sos_all)


def _force_block(i: int, n: int) -> np.ndarray:
    """Force chunk ``i`` (n samples): white noise from a per-chunk seed, so any chunk (and the
    tail of the chunk before it) can be made independently."""
    return np.random.default_rng([7, i]).standard_normal(n)


def _response_block(i: int, n: int, chunk: int, sos: np.ndarray) -> np.ndarray:
    """Responses of chunk ``i``: filter the last WARMUP samples of chunk i-1 then chunk i."""
    import scipy.signal

    f = _force_block(i, n)
    if i > 0:
        f = np.concatenate([_force_block(i - 1, chunk)[-WARMUP:], f])
    out = np.empty((sos.shape[0], f.size))
    for p in range(sos.shape[0]):
        out[p] = scipy.signal.sosfilt(sos[p], f)
    out = out[:, f.size - n :]
    out += 1e-3 * np.random.default_rng([8, i]).standard_normal(out.shape)  # output noise
    return out


def write(path: Path, n_points: int, n_time: int, chunk: int) -> None:
    """Write the synthetic shaker record lazily, one chunk in memory at a time (child process)."""
    import dask
    import dask.array as da
    import xarray as xr

    import ami_xr
    from ami_xr import names

    sos = _system(n_points)
    sizes = (chunk,) * (n_time // chunk) + ((n_time % chunk,) if n_time % chunk else ())
    force = da.map_blocks(
        lambda block_id=None: _force_block(block_id[0], sizes[block_id[0]]),
        chunks=(sizes,),
        dtype=np.float64,
        meta=np.empty(0),
    )
    response = da.map_blocks(
        lambda block_id=None: _response_block(block_id[1], sizes[block_id[1]], chunk, sos),
        chunks=((n_points,), sizes),
        dtype=np.float64,
        meta=np.empty((0, 0)),
    )
    ds = xr.Dataset(
        {
            names.RESPONSE: ((names.POINT, names.TIME), response, {names.ATTR_UNITS: "m/s^2"}),
            names.FORCE: ((names.TIME,), force, {names.ATTR_UNITS: "N"}),
        },
        coords={
            names.POINT: np.arange(n_points),
            names.TIME: (names.TIME, np.arange(n_time) / FS, {names.ATTR_UNITS: "s"}),
        },
        attrs={
            names.ATTR_DRIVE_POINT: 0,
            names.ATTR_QUANTITY: "acceleration",
            names.ATTR_RESPONSE_UNITS: "m/s^2",
            names.ATTR_FORCE_UNITS: "N",
        },
    )
    with dask.config.set(scheduler="synchronous"):  # one chunk in memory at a time
        ami_xr.to_netcdf(ds, path, function="scripts/bench_frf.py")


def _peak_rss_mb(who=resource.RUSAGE_SELF) -> float:
    return resource.getrusage(who).ru_maxrss / 1024.0  # kB on Linux


def _scipy_h1(f: np.ndarray, y: np.ndarray, **kw):
    import scipy.signal

    _, gfy = scipy.signal.csd(f, y, **kw)
    _, gff = scipy.signal.welch(f, **kw)
    _, gyy = scipy.signal.welch(y, **kw)
    return gfy / gff, np.abs(gfy) ** 2 / (gff * gyy)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=16, help="response channels (default 16)")
    ap.add_argument(
        "--samples",
        type=int,
        default=12_000_000,
        help="samples per channel (default 12e6: 17 x 12e6 = 2.04e8 in all)",
    )
    ap.add_argument("--chunk", type=int, default=2**19, help="time chunk on disk read [samples]")
    ap.add_argument("--nperseg", type=int, default=2048)
    ap.add_argument(
        "--slice",
        type=int,
        default=2**19,
        help="samples per channel of the in-memory slice for the scipy comparison",
    )
    ap.add_argument("--dir", default=None, help="folder for the netCDF file (default: temp)")
    ap.add_argument("--keep", action="store_true", help="keep the netCDF file")
    ap.add_argument("--write-only", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.write_only:
        write(Path(args.write_only), args.points, args.samples, args.chunk)
        return 0

    import ami_xr
    from ami_xr import names

    folder = Path(args.dir or tempfile.mkdtemp(prefix="ami_xr_bench_"))
    path = folder / "shaker.nc"
    n_channels = args.points + 1
    total = n_channels * args.samples
    print(
        f"record: {args.points} responses + 1 force, {args.samples:,} samples each at "
        f"{FS:g} Hz = {total:.3g} samples ({total * 8 / 2**30:.2f} GiB float64)"
    )
    t0 = time.perf_counter()
    subprocess.run(
        [
            sys.executable,
            __file__,
            "--write-only",
            str(path),
            "--points",
            str(args.points),
            "--samples",
            str(args.samples),
            "--chunk",
            str(args.chunk),
        ],
        check=True,
    )
    t_write = time.perf_counter() - t0
    print(
        f"wrote {path} ({path.stat().st_size / 2**30:.2f} GiB) in {t_write:.1f} s; "
        f"writer peak RSS {_peak_rss_mb(resource.RUSAGE_CHILDREN):.0f} MB"
    )

    kw = dict(nperseg=args.nperseg, noverlap=args.nperseg // 2, window="hann", detrend="constant")
    try:
        ds = ami_xr.open_dataset(path, chunks={names.TIME: args.chunk})
        # warm the numba cache on a tiny slice so compile time is not counted
        ami_xr.frf(ds.isel({names.TIME: slice(0, 4 * args.nperseg)}).load(), "H1", **kw)
        rss_before = _peak_rss_mb()
        t0 = time.perf_counter()
        est = ami_xr.frf(ds, "H1", **kw)
        t_stream = time.perf_counter() - t0
        rss_stream = _peak_rss_mb()
        print(
            f"streamed H1 + coherence: {t_stream:.1f} s, {total / t_stream:.3g} samples/s "
            f"({est.attrs[names.ATTR_N_AVERAGES]} segments of {args.nperseg}), "
            f"chunk {args.chunk:,} samples"
        )
        print(
            f"peak resident memory (streaming, getrusage): {rss_stream:.0f} MB "
            f"(before the run: {rss_before:.0f} MB)"
        )

        # same-slice comparison against scipy.signal, in memory
        n = min(args.slice, args.samples)
        part = ds.isel({names.TIME: slice(0, n)}).load()
        f = part[names.FORCE].values
        y = part[names.RESPONSE].values
        fs = FS
        reps = 3
        t_ours = min(_timed(lambda: ami_xr.frf(part, "H1", **kw)) for _ in range(reps))
        t_scipy = min(_timed(lambda: _scipy_h1(f, y, fs=fs, **kw)) for _ in range(reps))
        ours = ami_xr.frf(part, "H1", **kw)
        h_ref, c_ref = _scipy_h1(f, y, fs=fs, **kw)
        err_h = np.max(np.abs(ours[names.FRF].values - h_ref)) / np.max(np.abs(h_ref))
        err_c = np.max(np.abs(ours[names.COHERENCE].values - c_ref))
        slice_samples = n_channels * n
        print(
            f"in-memory slice of {n:,} samples x {n_channels} channels: ami_xr.frf "
            f"{t_ours:.3f} s ({slice_samples / t_ours:.3g} samples/s), scipy.signal csd+welch "
            f"{t_scipy:.3f} s ({slice_samples / t_scipy:.3g} samples/s); speed ratio "
            f"scipy/ami_xr = {t_scipy / t_ours:.2f}"
        )
        print(
            f"agreement with scipy on the slice: max |dH1|/max|H1| = {err_h:.1e}, "
            f"max |d coherence| = {err_c:.1e}"
        )
        print(
            "summary "
            + json.dumps(
                {
                    "samples_total": total,
                    "throughput_samples_per_s": round(total / t_stream),
                    "peak_rss_mb_streaming": round(rss_stream),
                    "peak_rss_mb_total": round(_peak_rss_mb()),
                    "speed_ratio_vs_scipy": round(t_scipy / t_ours, 2),
                }
            )
        )
    finally:
        if not args.keep:
            path.unlink(missing_ok=True)
            if args.dir is None:
                os.rmdir(folder)
    return 0


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


if __name__ == "__main__":
    sys.exit(main())
