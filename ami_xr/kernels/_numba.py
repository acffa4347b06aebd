"""The one place for numba policy.

* Lazy compilation: no eager signatures, so ``import ami_xr`` and ``ami-xr --help`` compile nothing.
* ``cache=True`` so a compiled kernel is reused by the next process (set ``AMI_XR_NUMBA_CACHE=0``
  to switch the on-disk cache off, e.g. on a read-only install).
* ``fastmath`` stays off: results must match the numpy references to rounding.
* ``NUMBA_DISABLE_JIT=1`` (numba's own switch) runs every kernel as plain Python for debugging
  and coverage.
"""

from __future__ import annotations

import os

import numba

CACHE = os.environ.get("AMI_XR_NUMBA_CACHE", "1").strip().lower() not in ("0", "false", "no", "off")


def jit(func=None, *, parallel: bool = False, **options):
    """``numba.njit`` with the project's policy (lazy, cached, no fastmath)."""
    options.setdefault("cache", CACHE)
    options.setdefault("fastmath", False)
    options.setdefault("nogil", True)

    def decorate(f):
        return numba.njit(parallel=parallel, **options)(f)

    return decorate if func is None else decorate(func)


def guvectorize(signatures, layout: str, **options):
    """``numba.guvectorize`` with the project's policy (cached, no fastmath).

    Note that gufuncs need explicit signatures; they are compiled on first call only when
    ``signatures`` is empty (dynamic gufunc), which is what we use to keep imports cheap.
    """
    options.setdefault("cache", CACHE)
    options.setdefault("fastmath", False)
    options.setdefault("nopython", True)
    if signatures:
        return numba.guvectorize(signatures, layout, **options)
    return numba.guvectorize(layout, **options)


prange = numba.prange
