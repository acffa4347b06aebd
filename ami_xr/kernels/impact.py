"""Impact-test hit checks on plain arrays: clipping runs and force pulses.

* :func:`extreme_run` - longest run of consecutive samples equal to the channel's maximum or
  minimum. An analogue-to-digital converter driven past its range returns its limit code for
  every sample of the overload, so a run of several identical extreme samples marks clipping
  (a genuine peak of a smooth signal is one sample, two at most by quantization). An extreme
  close to the median, such as the zero floor of a clean pulse, is ignored.
* :func:`force_pulses` - the pulses of a hammer force: runs of samples with ``|f| > threshold``,
  runs separated by fewer than ``min_gap`` quiet samples merged into one pulse. A second pulse
  is a double impact (the hammer bounced).
"""

from __future__ import annotations

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit


@jit
def _extreme_run(x, center, out):
    """out[b] = longest run of samples of x[b] equal to max(x[b]) or min(x[b]).

    Only an extreme at least half as far from ``center[b]`` (the median) as the farther one
    counts, so the flat quiet part of a noise-free pulse (its minimum, 0) is not clipping.
    """
    for b in range(x.shape[0]):
        n = x.shape[1]
        hi = x[b, 0]
        lo = x[b, 0]
        for k in range(n):
            if x[b, k] > hi:
                hi = x[b, k]
            if x[b, k] < lo:
                lo = x[b, k]
        dhi = hi - center[b]
        dlo = center[b] - lo
        far = max(dhi, dlo)
        use_hi = dhi > 0.0 and dhi >= 0.5 * far
        use_lo = dlo > 0.0 and dlo >= 0.5 * far
        best = 0
        run_hi = 0
        run_lo = 0
        for k in range(n):
            run_hi = run_hi + 1 if (use_hi and x[b, k] == hi) else 0
            run_lo = run_lo + 1 if (use_lo and x[b, k] == lo) else 0
            if run_hi > best:
                best = run_hi
            if run_lo > best:
                best = run_lo
        out[b] = best
    return out


@jit
def _force_pulses(f, threshold, min_gap, out):
    """Pulses of |f[b]| > threshold[b]; out[b] = (count, first start, first end, second start).

    Ends are inclusive; -1 where there is no such pulse.
    """
    for b in range(f.shape[0]):
        count = 0
        start0 = -1
        end0 = -1
        start1 = -1
        last = -(min_gap + 1)
        for k in range(f.shape[1]):
            if abs(f[b, k]) > threshold[b]:
                if k - last > min_gap:  # quiet for more than min_gap samples: a new pulse
                    count += 1
                    if count == 2:
                        start1 = k
                    elif count == 1:
                        start0 = k
                if count == 1:
                    end0 = k
                last = k
        out[b, 0] = count
        out[b, 1] = start0
        out[b, 2] = end0
        out[b, 3] = start1
    return out


def extreme_run(x: np.ndarray) -> np.ndarray:
    """Longest run of samples equal to the maximum or minimum, per row of ``x`` (batch, time)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] < 1:
        raise AmiXrValueError(f"x: expected shape (batch, time) with time >= 1, got {x.shape}")
    return _extreme_run(x, np.median(x, axis=1), np.empty(x.shape[0], np.int64))


def force_pulses(f: np.ndarray, threshold: np.ndarray, min_gap: int = 3) -> np.ndarray:
    """Pulses of ``|f| > threshold`` per row of ``f`` (batch, time).

    Returns
    -------
    ndarray of int64, shape (batch, 4)
        Number of pulses, first sample and last sample of the first pulse, first sample of the
        second pulse (-1 where absent).
    """
    f = np.ascontiguousarray(f, dtype=np.float64)
    thr = np.ascontiguousarray(np.broadcast_to(threshold, f.shape[:1]), dtype=np.float64)
    if f.ndim != 2:
        raise AmiXrValueError(f"f: expected shape (batch, time), got {f.shape}")
    if int(min_gap) < 0:
        raise AmiXrValueError(f"min_gap: expected an integer >= 0, got {min_gap!r}")
    return _force_pulses(f, thr, int(min_gap), np.empty((f.shape[0], 4), np.int64))
