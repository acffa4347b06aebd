"""``ami-xr identify --workers N`` / ``--scheduler ADDRESS``: identification on dask.distributed.

With either option the FRF file (netCDF) is opened lazily, chunked along ``point``
(``--chunk-points``), and :func:`ami_xr.identify` runs with a ``dask.distributed`` client active:
a ``LocalCluster`` of ``N`` single-threaded workers (``--worker-memory`` each), or the existing
scheduler at ``ADDRESS``. Each pass over the data is then one graph of a task per chunk and a tree
sum (:mod:`ami_xr.ami.scale`); only small sums reach this process.
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from pathlib import Path

from ami_xr.app.options import memory_size, ranged, scheduler_address
from ami_xr.errors import AmiXrValueError

__all__ = ["add_cluster_options", "cluster", "read_frfs"]

DISTRIBUTED_MISSING = "--workers/--scheduler need dask.distributed: pip install 'ami_xr[dask]'"


def add_cluster_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("scale-out (dask.distributed)")
    one = g.add_mutually_exclusive_group()  # both: a usage error (exit 2) naming the two
    one.add_argument(
        "--workers",
        type=ranged(int, 1, 1024),
        metavar="N",
        help="run on a local dask.distributed cluster of N single-threaded workers "
        "(default: none, in this process)",
    )
    one.add_argument(
        "--scheduler",
        type=scheduler_address,
        metavar="ADDRESS",
        help="run on the existing dask.distributed scheduler at ADDRESS (e.g. tcp://host:8786) "
        "(default: none)",
    )
    g.add_argument(
        "--chunk-points",
        type=ranged(int, 1),
        default=1000,
        metavar="P",
        help="FRFs per chunk when running on a cluster (default: %(default)s)",
    )
    g.add_argument(
        "--worker-memory",
        type=memory_size,
        default="2GB",
        metavar="SIZE",
        help="memory limit of each local worker (--workers): a size (2GB, 512MiB, bytes), a "
        "fraction of this machine's memory, or auto (default: %(default)s)",
    )


def _wanted(args: argparse.Namespace) -> bool:
    workers, scheduler = getattr(args, "workers", None), getattr(args, "scheduler", None)
    if workers is not None and scheduler is not None:
        raise AmiXrValueError("--workers and --scheduler: give one, not both")
    if workers is not None and workers < 1:
        raise AmiXrValueError(f"--workers: expected an integer >= 1, got {workers}")
    return workers is not None or scheduler is not None


def read_frfs(path: str, args: argparse.Namespace):
    """The FRF file: lazily chunked along ``point`` when a cluster is asked for (netCDF only),
    else read as ``ami-xr identify`` always does."""
    from ami_xr.io.formats import read_any

    if not _wanted(args):
        return read_any(path, want="frf")
    if Path(path).suffix.lower() != ".nc":
        raise AmiXrValueError(f"--workers/--scheduler: expected a netCDF (.nc) file, got {path!r}")
    if args.chunk_points < 1:
        raise AmiXrValueError(f"--chunk-points: expected an integer >= 1, got {args.chunk_points}")
    import ami_xr
    from ami_xr.io.kinds import refuse_other_kind

    ds = ami_xr.open_dataset(path, chunks={"point": int(args.chunk_points)})
    refuse_other_kind(ds, path, "frf")  # a modes file: say which command takes it
    return ds


@contextlib.contextmanager
def cluster(args: argparse.Namespace) -> Iterator[object | None]:
    """A dask.distributed client for ``--workers``/``--scheduler`` (closed on exit), or None."""
    if not _wanted(args):
        yield None
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise AmiXrValueError(DISTRIBUTED_MISSING) from None
    if args.scheduler is not None:
        with Client(args.scheduler) as client:
            yield client
        return
    with (
        LocalCluster(
            n_workers=int(args.workers),
            threads_per_worker=1,
            memory_limit=args.worker_memory,
            processes=True,
            dashboard_address=None,
        ) as local,
        Client(local) as client,
    ):
        yield client
