"""``ami-xr identify --workers N`` / ``--scheduler ADDRESS``: identification on dask.distributed.

With either option the FRF file (netCDF) is opened lazily, chunked along ``point``
(``--chunk-points``, whole along ``frequency``), and :func:`ami_xr.identify` runs with a
``dask.distributed`` client active: a ``LocalCluster`` of ``N`` single-threaded workers
(``--worker-memory`` each), or the existing scheduler at ``ADDRESS``. Each pass over the data
is then one graph of a task per chunk and a tree sum (:mod:`ami_xr.ami.scale`); only small sums
reach this process.

Failures end in bounded time, each as one :class:`ClusterError` naming the address:

* no scheduler answering at ``ADDRESS`` (or something else listening there) within
  ``--cluster-timeout`` seconds; a scheduler with no worker after as long;
* all workers lost during the run (none back within ``--cluster-timeout``), a worker that died
  running a task (killed, or over its memory limit: a chunk too big for ``--worker-memory`` is
  refused before the run), the connection to the scheduler lost;
* SIGINT/SIGTERM (held by :mod:`ami_xr.interrupt` while this process waits on the cluster) end
  the run within about a second, also while the local cluster starts (it starts in a thread of
  its own, the main thread looking for a held signal): the computation is abandoned, the local
  cluster closed (its worker processes killed by pid), and the signal raised as usual (exit
  130/143). Local worker processes ignore SIGINT (a Ctrl-C is the
  command's to handle) and end with this process whatever kills it (``distributed`` ties them to
  their nanny by a pipe; SIGKILL of this process closes it).

``distributed``'s own log lines go to the logger ``ami_xr.dask``, shown on stderr only with
``-v``.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ami_xr import interrupt
from ami_xr.app.options import memory_size, ranged, scheduler_address
from ami_xr.errors import AmiXrValueError

__all__ = ["ClusterError", "add_cluster_options", "cluster", "read_frfs", "LOGGER"]

DISTRIBUTED_MISSING = "--workers/--scheduler need dask.distributed: pip install 'ami_xr[dask]'"

#: The logger that receives ``distributed``'s (and tornado's) log records.
LOGGER = "ami_xr.dask"
#: Loggers of the cluster's libraries that print on their own (distributed configures them).
_FOREIGN_LOGGERS = ("distributed", "tornado", "bokeh")
#: Seconds between two looks of the watcher at signals, workers and the scheduler.
POLL_SECONDS = 0.1
#: Seconds the client and the local cluster each get to close after the run.
CLOSE_SECONDS = 1.0
#: The same after a signal or a failure (the workers are killed first: nothing to wait for).
FAST_CLOSE_SECONDS = 0.3
#: A chunk's FRF block times this must fit in a worker's memory limit (the per-chunk kernels
#: hold a few arrays of the block's size at once).
CHUNK_MEMORY_FACTOR = 4


class ClusterError(AmiXrValueError):
    """The dask cluster of ``--workers``/``--scheduler`` cannot run (or finish) the work: the
    message names the address and what happened."""


def add_cluster_options(p: argparse.ArgumentParser) -> None:
    """Add ``--workers``, ``--scheduler``, ``--chunk-points``, ``--worker-memory`` and
    ``--cluster-timeout`` to the parser ``p``."""
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
    g.add_argument(
        "--cluster-timeout",
        type=ranged(float, 0, 3600, low_open=True),
        default=10.0,
        metavar="SECONDS",
        help="how long to wait for the scheduler to answer, for a first worker, and for lost "
        "workers or a lost scheduler to come back during the run (default: %(default)s)",
    )


def _wanted(args: argparse.Namespace) -> bool:
    workers, scheduler = getattr(args, "workers", None), getattr(args, "scheduler", None)
    if workers is not None and scheduler is not None:
        raise AmiXrValueError("--workers and --scheduler: give one, not both")
    if workers is not None and workers < 1:
        raise AmiXrValueError(f"--workers: expected an integer >= 1, got {workers}")
    return workers is not None or scheduler is not None


def _timeout(args: argparse.Namespace) -> float:
    return float(getattr(args, "cluster_timeout", None) or 10.0)


def read_frfs(path: str, args: argparse.Namespace):
    """The FRF file: lazily chunked along ``point`` (whole along ``frequency``, whatever the
    file's own chunking) when a cluster is asked for (netCDF only), else read as
    ``ami-xr identify`` always does. With ``--workers``, a chunk too big for
    ``--worker-memory`` is a :class:`ClusterError` naming both options."""
    from ami_xr.io.formats import read_any

    if not _wanted(args):
        return read_any(path, want="frf")
    if Path(path).suffix.lower() != ".nc":
        raise AmiXrValueError(f"--workers/--scheduler: expected a netCDF (.nc) file, got {path!r}")
    if args.chunk_points < 1:
        raise AmiXrValueError(f"--chunk-points: expected an integer >= 1, got {args.chunk_points}")
    import ami_xr
    from ami_xr import names
    from ami_xr.io.kinds import refuse_other_kind

    ds = ami_xr.open_dataset(path, chunks={"point": int(args.chunk_points)})
    refuse_other_kind(ds, path, "frf")  # a modes file: say which command takes it
    if names.FRF in ds and names.FREQUENCY in ds[names.FRF].dims:
        # the per-FRF kernels take whole lines: one chunk along frequency
        ds = ds.chunk({names.FREQUENCY: -1})
        if getattr(args, "workers", None) is not None:
            check_chunk_memory(ds[names.FRF], int(args.chunk_points), args)
    return ds


def check_chunk_memory(frf: Any, chunk_points: int, args: argparse.Namespace) -> None:
    """Refuse (:class:`ClusterError`) a chunk whose FRF block, times
    :data:`CHUNK_MEMORY_FACTOR`, exceeds the memory limit of a local worker."""
    try:
        from distributed.worker_memory import parse_memory_limit
    except ImportError:  # the cluster itself says that distributed is missing
        return
    limit = parse_memory_limit(
        args.worker_memory, 1, total_cores=int(args.workers), logger=logging.getLogger(LOGGER)
    )
    if not limit:
        return
    rows = min(chunk_points, int(frf.shape[0])) if frf.ndim else 1
    per_point = int(frf.dtype.itemsize) * (int(frf.size) // max(int(frf.shape[0]), 1))
    need = CHUNK_MEMORY_FACTOR * rows * per_point
    if need > limit:
        fits = max(1, int(limit // (CHUNK_MEMORY_FACTOR * max(per_point, 1))))
        raise ClusterError(
            f"--chunk-points {chunk_points}: a chunk of {rows} FRFs needs about "
            f"{need / 2**20:.0f} MiB on a worker, more than --worker-memory "
            f"{args.worker_memory} ({limit / 2**20:.0f} MiB); use --chunk-points {fits} or less, "
            "or a larger --worker-memory"
        )


# --- logging ---------------------------------------------------------------------------------


class _Forward(logging.Handler):
    """Hands a record of a foreign logger to :data:`LOGGER`."""

    def emit(self, record: logging.LogRecord) -> None:
        logging.getLogger(LOGGER).handle(record)


def route_logs(verbose: bool) -> None:
    """Route the log records of ``distributed``, tornado and bokeh in this process to
    :data:`LOGGER`, printed on stderr with ``verbose`` (INFO and above), else dropped.

    For the rest of the process (a command): ``distributed`` still logs while its cluster
    closes and at interpreter exit."""
    forward = _Forward()
    names = [n for n in list(logging.root.manager.loggerDict) if n.startswith(_FOREIGN_LOGGERS)]
    for name in {*_FOREIGN_LOGGERS, *names}:
        logger = logging.getLogger(name)
        if name in _FOREIGN_LOGGERS or not logger.propagate:
            logger.handlers, logger.propagate = [forward], False
        else:
            logger.handlers = []  # its records reach a routed parent
    ours = logging.getLogger(LOGGER)
    ours.propagate = False
    if verbose:
        shown = logging.StreamHandler(sys.stderr)
        shown.setFormatter(logging.Formatter("ami-xr: %(name)s: %(levelname)s: %(message)s"))
        ours.handlers, ours.level = [shown], logging.INFO
    else:
        ours.handlers, ours.level = [logging.NullHandler()], logging.CRITICAL + 1


#: dask config key (inherited by the local workers) that says whether ``-v`` was given.
VERBOSE_KEY = "ami_xr.verbose"


def dask_setup(worker: Any) -> None:
    """Preload of the local workers (runs in each worker process): SIGINT ignored (a Ctrl-C
    reaches the whole process group; the command, not its workers, acts on it); warnings shown
    as the command shows them (:func:`worker_warning`)."""
    import warnings

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    warnings.showwarning = worker_warning


def worker_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` of a local worker: ami_xr's own warnings as one line each,
    other packages' (numpy's "overflow encountered", ...) only with ``-v``, as the command
    line shows those of its own process."""
    import warnings

    import dask

    from ami_xr.errors import AmiXrWarning

    if issubclass(category, AmiXrWarning):
        text = f"ami-xr: warning: {category.__name__}: {' '.join(str(message).split())}"
    elif dask.config.get(VERBOSE_KEY, False):
        text = warnings.formatwarning(message, category, filename, lineno, line).rstrip()
    else:
        return
    with contextlib.suppress(OSError, ValueError, AttributeError):
        print(text, file=sys.stderr, flush=True)


# --- the cluster -------------------------------------------------------------------------------


def _config(args: argparse.Namespace) -> dict[str, Any]:
    timeout = f"{_timeout(args)}s"
    return {
        "distributed.comm.timeouts.connect": timeout,
        # a task whose worker dies is not retried on the next: one death is reported
        "distributed.scheduler.allowed-failures": 0,
        VERBOSE_KEY: bool(getattr(args, "verbose", False)),  # the workers' warnings
    }


def _probe(address: str, timeout: float) -> None:
    """Raise :class:`ClusterError` unless a dask scheduler answers an identity request at
    ``address`` within ``timeout`` seconds (distributed's own client waits unbounded on a
    server that accepts and stays silent, and fails deep inside on one that is not dask)."""
    import asyncio

    from distributed.comm import connect

    async def ask() -> Any:
        comm = await connect(address, timeout=timeout)
        try:
            await comm.write({"op": "identity"})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(ask(), timeout))
    except (OSError, TimeoutError, asyncio.TimeoutError) as err:
        raise ClusterError(
            f"--scheduler {address}: no dask scheduler answered within {timeout:g} s "
            f"({type(err).__name__}); is it running, and is the address right?"
        ) from None
    except Exception as err:  # noqa: BLE001 - whatever answered, it is not a dask scheduler
        reply = err
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        what = type(reply).__name__ + (" in the handshake" if isinstance(reply, Exception) else "")
        raise ClusterError(
            f"--scheduler {address}: what answered there is not a dask scheduler ({what})"
        )


def _connect(args: argparse.Namespace) -> tuple[Any, Any, str]:
    """(client, local cluster or None, the address named in messages)."""
    from distributed import Client, LocalCluster

    timeout = _timeout(args)
    if args.scheduler is not None:
        address = str(args.scheduler)
        _probe(address, timeout)
        try:
            client = Client(address, timeout=timeout, set_as_default=True)
        except (OSError, TimeoutError) as err:
            raise ClusterError(
                f"--scheduler {address}: the dask scheduler did not take this client within "
                f"{timeout:g} s ({type(err).__name__})"
            ) from None
        try:
            client.wait_for_workers(1, timeout=timeout)
        except (TimeoutError, OSError):
            _close(client, None)
            raise ClusterError(
                f"--scheduler {address}: the scheduler has no workers (none joined within "
                f"{timeout:g} s); start some with 'dask worker {address}'"
            ) from None
        return client, None, address
    local = None
    # a worker killed mid-task leaves a semaphore that multiprocessing's resource tracker (a
    # process of its own, started with this environment) reports on stderr at exit: the tool
    # reports the lost worker itself, in one line
    quiet = "ignore::UserWarning:multiprocessing.resource_tracker"
    if quiet not in os.environ.get("PYTHONWARNINGS", ""):
        os.environ["PYTHONWARNINGS"] = ",".join(
            x for x in (os.environ.get("PYTHONWARNINGS", ""), quiet) if x
        )
    try:
        local = LocalCluster(
            n_workers=int(args.workers),
            threads_per_worker=1,
            memory_limit=args.worker_memory,
            processes=True,
            dashboard_address=None,
            silence_logs=False if getattr(args, "verbose", False) else logging.CRITICAL + 1,
            preload=[__name__],  # dask_setup: workers leave Ctrl-C to the command
        )
    except BaseException as err:
        if local is not None:  # a signal raised as the constructor returned
            _close(None, local, fast=True)
        if not isinstance(err, Exception):
            raise
        interrupt.checkpoint()  # a signal held while the cluster started: raised here
        raise ClusterError(
            f"--workers {int(args.workers)}: the local dask cluster did not start "
            f"({type(err).__name__}: {' '.join(str(err).split())[:200]})"
        ) from None
    interrupt.checkpoint()
    try:
        client = Client(local, timeout=timeout, set_as_default=True)
    except BaseException:
        _close(None, local, fast=True)
        raise
    return client, local, f"the local cluster of {int(args.workers)} worker(s)"


def _worker_pids(local: Any) -> list[int]:
    """Process ids of the local cluster's worker processes (children of this process)."""
    pids = []
    for nanny in list(getattr(local, "workers", {}).values()):
        process = getattr(getattr(nanny, "process", None), "process", None)
        pid = getattr(process, "pid", None)
        if pid:
            pids.append(int(pid))
    return pids


def _kill(pids: list[int]) -> None:
    import os

    for pid in pids:  # children of this process: killed by pid, never by name
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)


def _close(client: Any, local: Any, fast: bool = False) -> None:
    """Close the client and the local cluster, each given :data:`CLOSE_SECONDS`. ``fast``
    (a signal, a failed run): the local worker processes are killed first, nothing of theirs
    being kept, and each close gets :data:`FAST_CLOSE_SECONDS`; worker processes still alive
    after the close are killed."""
    pids = _worker_pids(local) if local is not None else []
    if fast:
        _kill(pids)
    timeout = FAST_CLOSE_SECONDS if fast else CLOSE_SECONDS
    if client is not None:
        with contextlib.suppress(Exception):
            client.close(timeout=timeout)
    if local is None:
        return
    with contextlib.suppress(Exception):
        local.close(timeout=timeout)
    _kill([pid for pid in _worker_pids(local) + pids])
    # not closed again at interpreter exit (distributed would wait up to 10 s there); the
    # worker processes end with this process anyway
    local.shutdown_on_close = False


def _start(args: argparse.Namespace) -> tuple[Any, Any, str]:
    """:func:`_connect` in a thread of its own, the main thread looking for a held signal every
    :data:`POLL_SECONDS`: the cluster's start-up (seconds of worker processes starting, on a
    loaded machine ten or more) waits in ``distributed``'s event loop, where a signal is only
    held; stopped there, the worker processes started so far are killed and the half-built
    cluster is left to the ending process (not closed again at exit)."""
    import multiprocessing

    box: dict[str, Any] = {}
    abandoned = threading.Event()
    before = {p.pid for p in multiprocessing.active_children()}  # not ours to kill

    def start() -> None:
        try:
            box["value"] = _connect(args)
        except BaseException as err:  # noqa: BLE001 - handed to the main thread
            box["error"] = err
        if abandoned.is_set() and "value" in box:  # finished after the main thread gave up
            client, local, _ = box["value"]
            _close(client, local, fast=True)

    thread = threading.Thread(target=start, name="ami_xr-cluster-start", daemon=True)
    thread.start()
    try:
        while thread.is_alive():
            thread.join(POLL_SECONDS)
            interrupt.checkpoint()  # a signal held while the cluster starts: raised here
        interrupt.checkpoint()
    except BaseException:
        abandoned.set()
        _abandon(before)
        raise
    if "error" in box:
        raise box["error"]
    return box["value"]


def _abandon(before: set[int]) -> None:
    """Kill the worker processes started since ``before`` (their pids) and keep
    ``distributed`` from closing its clusters again at exit (it would wait up to 10 s for a
    half-built one)."""
    import multiprocessing

    with contextlib.suppress(Exception):
        from distributed.deploy.spec import SpecCluster

        for instance in list(SpecCluster._instances):
            instance.shutdown_on_close = False
    _kill([p.pid for p in multiprocessing.active_children() if p.pid and p.pid not in before])


class _Watch(threading.Thread):
    """Watches, while the work runs, for a held signal, for the workers all gone and for the
    scheduler gone; on any of them it records why and closes the client, which ends the
    computation the main thread waits on."""

    def __init__(self, client: Any, address: str, timeout: float) -> None:
        super().__init__(name="ami_xr-cluster-watch", daemon=True)
        self.client, self.address, self.timeout = client, address, timeout
        self.reason: str | None = None
        self.signalled = False
        self.stop = threading.Event()

    def run(self) -> None:
        no_workers = lost = None
        while not self.stop.wait(POLL_SECONDS):
            now = time.monotonic()
            if interrupt.pending() is not None:
                self.signalled = True
                self._abort()
                return
            status = str(getattr(self.client, "status", "running"))
            lost = (lost or now) if status not in ("running", "newly-created") else None
            if lost is not None and now - lost > self.timeout:
                self.reason = self._lost_scheduler()
                self._abort()
                return
            workers = self._n_workers()
            if workers is not None:
                no_workers = (no_workers or now) if not workers else None
            if no_workers is not None and now - no_workers > self.timeout:
                self.reason = (
                    f"{self.address}: all dask workers were lost during the run and none came "
                    f"back within {self.timeout:g} s (killed, or over their memory limit?)"
                )
                self._abort()
                return

    def _n_workers(self) -> int | None:
        """The scheduler's worker count as the client last heard it (its own periodic identity
        request, every 2 s): no request from here, which would block this thread, and the
        signals it watches for, while a scheduler does not answer. None when not known."""
        identity = getattr(self.client, "_scheduler_identity", None)
        try:
            count = identity.get("n_workers") if identity else None
        except Exception:  # noqa: BLE001 - a client closing under us: the status tells
            return None
        return int(count) if isinstance(count, int) else None

    def _lost_scheduler(self) -> str:
        return (
            f"{self.address}: lost the connection to the dask scheduler during the run "
            f"(not back within {self.timeout:g} s)"
        )

    def _abort(self) -> None:
        # the local workers are killed by the close that follows in the main thread (killed
        # here, their nannies would start new ones first)
        with contextlib.suppress(Exception):
            self.client.close(timeout=FAST_CLOSE_SECONDS)


def _is_cancelled(err: BaseException) -> bool:
    """A computation ended by a closed client or lost scheduler (CancelledError and its kin)."""
    import asyncio
    import concurrent.futures

    names = {c.__name__ for c in type(err).__mro__}
    return isinstance(err, (asyncio.CancelledError, concurrent.futures.CancelledError)) or bool(
        names & {"FutureCancelledError", "CommClosedError", "CancelledError"}
    )


def _explain(err: BaseException, watch: _Watch, client: Any, address: str, args) -> str | None:
    """The one-line reason of a failed run on the cluster, None when ``err`` is not the
    cluster's doing."""
    if watch.reason is not None:
        return watch.reason
    kind = {c.__name__ for c in type(err).__mro__}
    if "KilledWorker" in kind:
        memory = (
            f" (each worker may use --worker-memory {args.worker_memory}: a smaller "
            "--chunk-points or more memory may help)"
            if getattr(args, "workers", None) is not None
            else ""
        )
        return (
            f"{address}: a dask worker died while running a task: killed or out of memory{memory}"
        )
    status = str(getattr(client, "status", "running"))
    if _is_cancelled(err) or status not in ("running", "newly-created"):
        if _is_cancelled(err) or "CommClosedError" in kind or isinstance(err, OSError):
            return watch._lost_scheduler()
    return None


@contextlib.contextmanager
def cluster(args: argparse.Namespace) -> Iterator[object | None]:
    """A dask.distributed client for ``--workers``/``--scheduler`` (closed on exit, in bounded
    time), or None when neither is given.

    Raises
    ------
    ClusterError
        No scheduler (or not a dask one) at the address, no workers, workers or scheduler lost
        during the run, a worker dead of a task (see the module docstring).
    KeyboardInterrupt, ami_xr.interrupt.Terminated
        A SIGINT/SIGTERM held while the work ran on the cluster.
    """
    if not _wanted(args):
        yield None
        return
    try:
        import dask
        import distributed  # noqa: F401
    except ImportError:
        raise AmiXrValueError(DISTRIBUTED_MISSING) from None
    route_logs(bool(getattr(args, "verbose", False)))
    # the identification's modules (numba among them) imported before the cluster runs: a
    # signal is held while numba is imported, and the run should not wait on that
    import ami_xr.ami  # noqa: F401

    with dask.config.set(_config(args)):
        client, local, address = _start(args)
        watch = _Watch(client, address, _timeout(args))
        watch.start()
        failed = False
        try:
            yield client
        except (KeyboardInterrupt, SystemExit):
            failed = True
            raise
        except BaseException as err:
            failed = True
            if watch.signalled or interrupt.pending() is not None:
                interrupt.checkpoint()  # raises the held signal (main thread, armed)
            reason = _explain(err, watch, client, address, args)
            if reason is None:
                raise
            raise ClusterError(reason) from None
        finally:
            watch.stop.set()
            _close(client, local, fast=failed or watch.signalled)
