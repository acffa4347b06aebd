"""Identification of 1e3, 1e4 (and 1e5 with --full) FRFs x 4096 lines on a dask LocalCluster.

    python scripts/bench_scale.py                 # 1e3 and 1e4 points, 1 and 2 workers
    python scripts/bench_scale.py --full          # also 1e5 points (about 6.5 GB on disk)
    python scripts/bench_scale.py --points 1000 2000 --workers 2   # chosen sizes
    python scripts/bench_scale.py --points 1000 --lines 1024 4096 --workers 2  # lines exponent

Each set (:func:`ami_xr.simulate.spread.many_points`: 12 modes, 2 % noise; larger sets repeat
the first 1000 points' FRFs scaled per point by a seeded factor in [0.5, 2], built and written
block by block so that writing never holds more than 1000 FRFs) is written to a netCDF file in
``--dir``, opened lazily (``--chunk`` FRFs per chunk) and identified by :func:`ami_xr.identify`
with a ``dask.distributed`` client on a ``LocalCluster`` (single-threaded workers, ``--memory``
each). Printed per run: wall time, peak worker memory (the largest RSS any worker reported,
sampled every 0.2 s), client memory growth (RSS after minus before) and the client's peak
growth (largest RSS during the run minus before, sampled likewise), modes found; at the end the
growth exponents of time against points and against lines (least-squares slopes of log t on
log P and on log L) per worker count.
Written against ami_xr's public API.
"""

from __future__ import annotations

import argparse
import os
import threading
import time
import warnings
from pathlib import Path

import numpy as np

import ami_xr
from ami_xr.simulate.spread import many_points

LINES = 4096


def _rss_mb() -> float:
    import psutil

    return psutil.Process(os.getpid()).memory_info().rss / 2**20


def write_set(n_points: int, path: Path, chunk: int, lines: int = LINES) -> None:
    """The simulated set of ``n_points`` FRFs x ``lines`` lines, written block by block (a
    lazy FRF of 1000-FRF blocks: memory of one block, whatever ``n_points``)."""
    if path.exists():
        return
    base, _ = many_points(min(n_points, 1000), lines, 12, noise=0.02, seed=0)
    if n_points > 1000:
        import dask
        import dask.array as da

        first = base["frf"].values

        def block(k: int) -> np.ndarray:
            return first * np.random.default_rng(1 + k).uniform(0.5, 2.0, (first.shape[0], 1))

        reps = -(-n_points // 1000)
        frf = da.concatenate(
            [
                da.from_delayed(dask.delayed(block)(k), shape=first.shape, dtype=first.dtype)
                for k in range(reps)
            ]
        )[:n_points].rechunk({0: chunk})
        attrs = base["frf"].attrs
        base = base.drop_vars("frf").isel(point=np.arange(n_points) % 1000)
        base = base.assign_coords(point=np.arange(n_points))
        base["frf"] = (("point", "frequency"), frf, attrs)
    ami_xr.to_netcdf(base, path)


def run(
    path: Path, workers: int, memory: str, chunk: int
) -> tuple[float, float, float, float, int]:
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            memory_limit=memory,
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):
        peak = [0.0]
        stop = threading.Event()

        def sample():
            while not stop.is_set():
                try:
                    info = client.run(lambda: __import__("psutil").Process().memory_info().rss)
                    peak[0] = max(peak[0], max(info.values()) / 2**20)
                except Exception:  # noqa: BLE001 - a missed sample is not a result
                    pass
                stop.wait(0.2)

        ds = ami_xr.open_dataset(path, chunks={"point": chunk})
        before = _rss_mb()
        client_peak = [before]

        def sample_client():
            while not stop.is_set():
                client_peak[0] = max(client_peak[0], _rss_mb())
                stop.wait(0.2)

        threading.Thread(target=sample_client, daemon=True).start()
        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = ami_xr.identify(ds)
        seconds = time.perf_counter() - t0
        stop.set()
        sampler.join()
        growth = _rss_mb() - before
    return seconds, peak[0], growth, client_peak[0] - before, int(out.sizes.get("mode", 0))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="also 1e5 points")
    parser.add_argument("--points", type=int, nargs="+", default=None)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--memory", default="2GB", help="memory limit per worker")
    parser.add_argument("--chunk", type=int, default=1000, help="FRFs per chunk")
    parser.add_argument("--dir", default="bench_scale_data", help="where the sets are written")
    parser.add_argument("--lines", type=int, nargs="+", default=[LINES], help="lines per FRF")
    args = parser.parse_args(argv)
    sizes = args.points or ([1000, 10_000, 100_000] if args.full else [1000, 10_000])
    folder = Path(args.dir)
    folder.mkdir(parents=True, exist_ok=True)
    print(
        f"bench_scale: {sizes} FRFs x {args.lines} lines, 12 modes; workers {args.workers}, "
        f"{args.memory} each; cpu_count {os.cpu_count()}"
    )
    print(
        f"{'points':>8}{'lines':>7}{'workers':>8}{'wall s':>9}{'peak worker MB':>16}"
        f"{'client +MB':>12}{'client peak +MB':>17}{'modes':>7}",
        flush=True,
    )
    rows: list[tuple[int, int, int, float]] = []
    for n in sizes:
        for lines in args.lines:
            path = folder / (f"spread_{n}.nc" if lines == LINES else f"spread_{n}_{lines}.nc")
            write_set(n, path, args.chunk, lines)
            for w in args.workers:
                seconds, peak, growth, client, modes = run(path, w, args.memory, args.chunk)
                rows.append((n, lines, w, seconds))
                print(
                    f"{n:>8}{lines:>7}{w:>8}{seconds:>9.2f}{peak:>16.0f}{growth:>12.1f}"
                    f"{client:>17.0f}{modes:>7}",
                    flush=True,
                )
    for w in args.workers:
        for label, axis, fixed in (("points", 0, 1), ("lines", 1, 0)):
            # slope at the largest value of the other size (the one that grew least)
            mine = [r for r in rows if r[2] == w]
            if not mine:
                continue
            other = max(r[fixed] for r in mine)
            pts = [(r[axis], r[3]) for r in mine if r[fixed] == other]
            if len({p for p, _ in pts}) > 1:
                x, t = np.log([p for p, _ in pts]), np.log([t for _, t in pts])
                print(
                    f"growth exponent of time against {label}, {w} worker(s): "
                    f"{np.polyfit(x, t, 1)[0]:.2f}"
                )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
