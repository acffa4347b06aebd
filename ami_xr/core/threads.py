"""One BLAS thread while identification runs (plain Python, no xarray).

The refinement's products are small (tens of columns): a multithreaded BLAS gains nothing on
them and loses 5-30 times when another process competes for the cores (a second identification,
``ami-xr batch --workers 2``, a dask worker with several threads). :func:`single_blas_thread`
limits every BLAS library loaded (numpy's and scipy's) to one thread for the duration of a call,
with ``threadpoolctl`` (the optional extra ``ami_xr[threads]``, in ``ami_xr[all]``; without it
nothing is limited). Each thread sets its own limit and restores it when its outermost call
leaves; where a BLAS library keeps one process-wide count, a thread leaving first restores it
for the others (slower, never wrong).
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

_LOCK = threading.Lock()
_CONTROLLER: list = []  # the cached ThreadpoolController (False without threadpoolctl)
# per thread: nested calls in one thread share the outer limit (OpenBLAS 0.3.31 ignores a limit
# set from a thread other than the main one: there the call is a no-op, never wrong)
_LOCAL = threading.local()


def _controller():
    """The cached controller of the loaded BLAS libraries (False without threadpoolctl)."""
    with _LOCK:
        if not _CONTROLLER:
            import scipy.linalg  # noqa: F401  (load scipy's BLAS too, so that it is limited)

            try:
                from threadpoolctl import ThreadpoolController
            except ImportError:
                _CONTROLLER.append(False)
            else:
                _CONTROLLER.append(ThreadpoolController())
        return _CONTROLLER[0]


@contextmanager
def single_blas_thread() -> Iterator[None]:
    """Run the body with every BLAS library limited to one thread in this thread (the
    setting is restored when the outermost call in the thread leaves)."""
    depth = getattr(_LOCAL, "depth", 0)
    controller = _controller() if depth == 0 else None
    limit = controller.limit(limits=1, user_api="blas") if controller else None
    _LOCAL.depth = depth + 1
    try:
        yield
    finally:
        _LOCAL.depth = depth
        if limit is not None:
            limit.restore_original_limits()
