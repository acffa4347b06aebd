"""A tiny sort for the kernels: the order of the first few values of an array (numpy + numba)."""

from __future__ import annotations

import numpy as np

from ami_xr.kernels._numba import jit


@jit
def argsort_first(a, n):
    """``np.argsort(a[:n])`` for the few modes of a group, NaN last: an insertion sort (numba's
    own argsort sorts fewer than 15 values so; same order for distinct values), which spares a
    first run numba's quicksort compilation."""
    order = np.arange(n)
    for i in range(1, n):
        k = order[i]
        v = a[k]
        j = i
        while j > 0:
            u = a[order[j - 1]]
            if not (v < u or (np.isnan(u) and not np.isnan(v))):
                break
            order[j] = order[j - 1]
            j -= 1
        order[j] = k
    return order
