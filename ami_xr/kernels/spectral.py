"""Spectral kernels: Welch segments, auto- and cross-spectrum accumulation, FRF estimators.

The estimation of FRFs from time histories runs in three jitted steps with an FFT between them::

    prepare_segments  x (channel, time) -> windowed, detrended segments (channel, segment, nperseg)
    (scipy.fft.rfft in the caller)      -> spectra (channel, segment, frequency)
    accumulate_spectra (linear, exp.)   -> Gff (ref, ref, f), Gfy (ref, point, f), Gyy (point, f)
    frf_from_spectra                    -> H (ref, point, f) and coherence (point, f)

Conventions (scipy.signal's): the cross-spectrum of ``x`` and ``y`` is ``conj(X) Y`` so
``Gfy[i, p] = E[conj(F_i) Y_p]``; for one force ``H1 = Gfy / Gff``, ``H2 = Gyy / conj(Gfy)``,
``Hv`` the total-least-squares estimate, and the ordinary coherence
``|Gfy|^2 / (Gff Gyy)``. With several forces ``Gfy = Gff H`` is solved per frequency (MIMO H1) and
the coherence is the multiple coherence ``Re(Gfy^H H) / Gyy``.

Kernels take batch dims first and the core dim (time or frequency) last. Private ``_name`` kernels
assume clean input and never raise; the public wrappers check shapes and values first.
"""

from __future__ import annotations

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit

DETRENDS = ("none", "constant", "linear")
ESTIMATORS = ("H1", "H2", "Hv")
_DETREND_CODE = {"none": 0, "constant": 1, "linear": 2}
_ESTIMATOR_CODE = {"H1": 1, "H2": 2, "Hv": 3}


# --- private kernels (clean input assumed; never raise) ---------------------------------------


@jit
def _prepare_segments(x, starts, window, detrend, out):
    """Copy, detrend and window segments of ``x`` into ``out``.

    x (channel, time) float64; starts (segment,) int64; window (channel, nperseg);
    detrend 0 none, 1 constant (segment mean), 2 linear (least-squares line);
    out (channel, segment, nperseg) float64, overwritten.
    """
    n_ch = x.shape[0]
    nseg = starts.shape[0]
    m = out.shape[2]
    # linear detrend: the centred index t - tm sums to 0, so slope = sum((t-tm) x) / sum((t-tm)^2)
    tm = 0.5 * (m - 1)
    stt = 0.0
    for k in range(m):
        stt += (k - tm) * (k - tm)
    for c in range(n_ch):
        for s in range(nseg):
            a = starts[s]
            mean = 0.0
            slope = 0.0
            if detrend >= 1:
                acc = 0.0
                for k in range(m):
                    acc += x[c, a + k]
                mean = acc / m
            if detrend == 2 and stt > 0.0:
                acc = 0.0
                for k in range(m):
                    acc += (k - tm) * x[c, a + k]
                slope = acc / stt
            for k in range(m):
                out[c, s, k] = (x[c, a + k] - mean - slope * (k - tm)) * window[c, k]
    return out


@jit
def _accumulate(F, Y, Gff, Gfy, Gyy, count, n_average):
    """Add the segments' ``conj(F_i) F_j``, ``conj(F_i) Y_p`` and ``|Y_p|^2`` to the spectra,
    segment by segment in order; returns the new segment count.

    F (ref, segment, freq) and Y (point, segment, freq) complex128; Gff (ref, ref, freq),
    Gfy (ref, point, freq) complex128, Gyy (point, freq) float64, updated in place.
    ``n_average <= 0``: linear, plain sums. ``n_average >= 1``: exponential (running)
    averaging; segment number ``m`` (1-based over the whole run, ``count`` seen before this
    call) updates ``G <- G + (S_m - G) / min(m, n_average)`` -- a linear average over the first
    ``n_average`` segments, then forgetting with time constant ``n_average`` segments; the
    spectra then hold averages, not totals.
    """
    nref = F.shape[0]
    npt = Y.shape[0]
    nseg = F.shape[1]
    nf = F.shape[2]
    for s in range(nseg):
        linear = n_average <= 0
        wgt = 1.0 if linear else 1.0 / min(count + s + 1, n_average)
        for i in range(nref):
            for j in range(nref):
                for k in range(nf):
                    v = np.conj(F[i, s, k]) * F[j, s, k]
                    Gff[i, j, k] += v if linear else (v - Gff[i, j, k]) * wgt
        for p in range(npt):
            for k in range(nf):
                y = Y[p, s, k]
                a = y.real * y.real + y.imag * y.imag
                Gyy[p, k] += a if linear else (a - Gyy[p, k]) * wgt
                for i in range(nref):
                    v = np.conj(F[i, s, k]) * y
                    Gfy[i, p, k] += v if linear else (v - Gfy[i, p, k]) * wgt
    return count + nseg


@jit
def _frf_from_spectra(Gff, Gfy, Gyy, estimator, H, coh):
    """Per-frequency FRF estimate and (multiple) coherence; NaN where undefined (zero power).

    Gff (ref, ref, f), Gfy (ref, point, f) complex; Gyy (point, f) float;
    estimator 1 H1, 2 H2, 3 Hv (H2 and Hv for one force only); H (ref, point, f) complex and
    coh (point, f) float, overwritten.
    """
    nref = Gff.shape[0]
    npt = Gyy.shape[0]
    nf = Gyy.shape[1]
    nan = np.nan
    if nref == 1:
        for p in range(npt):
            for k in range(nf):
                gff = Gff[0, 0, k].real
                gfy = Gfy[0, p, k]
                gyy = Gyy[p, k]
                a2 = gfy.real * gfy.real + gfy.imag * gfy.imag
                if gff > 0.0 and gyy > 0.0:
                    coh[p, k] = a2 / (gff * gyy)
                else:
                    coh[p, k] = nan
                if estimator == 1:
                    H[0, p, k] = gfy / gff if gff > 0.0 else complex(nan, nan)
                elif estimator == 2:
                    H[0, p, k] = gyy / np.conj(gfy) if a2 > 0.0 else complex(nan, nan)
                else:
                    # Hv: principal eigenvector of [[Gff, Gfy], [Gyf, Gyy]] (equal noise weights)
                    # (d + r) / (2 conj(Gfy)) with r = sqrt(d^2 + 4 |Gfy|^2); for d < 0 the
                    # same value as 2 Gfy / (r - d), free of cancellation (Gyy << Gff is common:
                    # the two spectra carry different units)
                    if a2 > 0.0:
                        d = gyy - gff
                        r = np.sqrt(d * d + 4.0 * a2)
                        if d >= 0.0:
                            H[0, p, k] = (d + r) / (2.0 * np.conj(gfy))
                        else:
                            H[0, p, k] = 2.0 * gfy / (r - d)
                    else:
                        H[0, p, k] = complex(nan, nan)
        return
    # several forces: H1 = Gff^-1 Gfy, multiple coherence Re(Gfy^H H) / Gyy
    A = np.empty((nref, nref), dtype=np.complex128)
    B = np.empty((nref, npt), dtype=np.complex128)
    for k in range(nf):
        for i in range(nref):
            for j in range(nref):
                A[i, j] = Gff[i, j, k]
            for p in range(npt):
                B[i, p] = Gfy[i, p, k]
        # Gff is Hermitian positive semi-definite; singular means a force channel without power
        # or fully correlated forces at this frequency -> NaN, never an exception.
        ok = True
        d = np.abs(np.linalg.det(A))
        scale = 1.0
        for i in range(nref):
            scale *= abs(A[i, i].real)
        if not (d > 1e-12 * scale) or scale == 0.0:
            ok = False
        if ok:
            X = np.linalg.solve(A, B)
            for p in range(npt):
                num = 0.0
                for i in range(nref):
                    H[i, p, k] = X[i, p]
                    num += (np.conj(B[i, p]) * X[i, p]).real
                coh[p, k] = num / Gyy[p, k] if Gyy[p, k] > 0.0 else nan
        else:
            for p in range(npt):
                coh[p, k] = nan
                for i in range(nref):
                    H[i, p, k] = complex(nan, nan)


# --- public wrappers (validate, then call the kernels) ----------------------------------------


def detrend_code(detrend) -> int:
    """Code of a detrend name: "none" (or False/None) 0, "constant" 1, "linear" 2."""
    if detrend is False or detrend is None:
        return 0
    if not isinstance(detrend, str) or detrend.lower() not in _DETREND_CODE:
        raise AmiXrValueError(
            f"detrend: expected one of {', '.join(map(repr, DETRENDS))} or False, got {detrend!r}"
        )
    return _DETREND_CODE[detrend.lower()]


def estimator_code(estimator) -> int:
    """Code of an estimator name (``"H1"``, ``"H2"``, ``"Hv"``; case-insensitive)."""
    table = {k.lower(): v for k, v in _ESTIMATOR_CODE.items()}
    if not isinstance(estimator, str) or estimator.lower() not in table:
        raise AmiXrValueError(
            f"estimator: expected one of {', '.join(map(repr, ESTIMATORS))}, got {estimator!r}"
        )
    return table[estimator.lower()]


def prepare_segments(
    x: np.ndarray, starts: np.ndarray, window: np.ndarray, detrend="constant"
) -> np.ndarray:
    """Detrended, windowed segments ``x[c, s:s+nperseg]`` for every channel and start.

    Parameters
    ----------
    x : ndarray, shape (channel, time)
        Real samples.
    starts : ndarray of int, shape (segment,)
        First sample of each segment.
    window : ndarray, shape (nperseg,) or (channel, nperseg)
        Window per channel (a 1-D window is used for every channel).
    detrend : {"constant", "linear", "none"} or False
        Removed from each segment before windowing (scipy's order).

    Returns
    -------
    ndarray of float64, shape (channel, segment, nperseg)
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 2:
        raise AmiXrValueError(f"x: expected shape (channel, time), got {x.shape}")
    w = np.asarray(window, dtype=np.float64)
    if w.ndim == 1:
        w = np.broadcast_to(w, (x.shape[0], w.shape[0]))
    w = np.ascontiguousarray(w)
    if w.ndim != 2 or w.shape[0] != x.shape[0] or w.shape[1] < 1:
        raise AmiXrValueError(
            f"window: expected shape (nperseg,) or ({x.shape[0]}, nperseg), got {w.shape}"
        )
    starts = np.ascontiguousarray(starts, dtype=np.int64)
    m = w.shape[1]
    if starts.ndim != 1 or (starts.size and (starts.min() < 0 or starts.max() + m > x.shape[1])):
        raise AmiXrValueError(
            f"starts: every segment of {m} samples must lie inside the {x.shape[1]} samples"
        )
    out = np.empty((x.shape[0], starts.shape[0], m), dtype=np.float64)
    return _prepare_segments(x, starts, w, detrend_code(detrend), out)


def _spectra_shapes(F, Y):
    F = np.ascontiguousarray(F, dtype=np.complex128)
    Y = np.ascontiguousarray(Y, dtype=np.complex128)
    if F.ndim != 3 or Y.ndim != 3 or F.shape[1:] != Y.shape[1:]:
        raise AmiXrValueError(
            f"F, Y: expected shapes (ref, segment, freq) and (point, segment, freq) with the same "
            f"segments and frequencies, got {F.shape} and {Y.shape}"
        )
    return F, Y


def accumulate_spectra(
    F: np.ndarray,
    Y: np.ndarray,
    sums: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    *,
    average: str = "linear",
    count: int = 0,
    n_average: int = 8,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Accumulate auto- and cross-spectra of segment spectra ``F`` (forces) and ``Y`` (responses).

    Parameters
    ----------
    F, Y : ndarray of complex, shapes (ref, segment, freq) and (point, segment, freq)
    sums : (Gff, Gfy, Gyy), optional
        Running sums (linear) or averages (exponential) to update in place; new zeros if omitted.
    average : {"linear", "exponential"}
        Linear: plain sums (divide by the segment count at the end). Exponential: running
        averages with time constant ``n_average`` segments (see ``_accumulate``).
    count : int
        Segments already accumulated in ``sums``.

    Returns
    -------
    Gff (ref, ref, freq), Gfy (ref, point, freq), Gyy (point, freq), new count
    """
    F, Y = _spectra_shapes(F, Y)
    nref, npt, nf = F.shape[0], Y.shape[0], F.shape[2]
    if sums is None:
        sums = (
            np.zeros((nref, nref, nf), np.complex128),
            np.zeros((nref, npt, nf), np.complex128),
            np.zeros((npt, nf), np.float64),
        )
    Gff, Gfy, Gyy = sums
    if Gff.shape != (nref, nref, nf) or Gfy.shape != (nref, npt, nf) or Gyy.shape != (npt, nf):
        raise AmiXrValueError("sums: shapes do not match F and Y")
    if average == "linear":
        new = _accumulate(F, Y, Gff, Gfy, Gyy, int(count), 0)
        return Gff, Gfy, Gyy, int(new)
    if average == "exponential":
        if int(n_average) < 1:
            raise AmiXrValueError(f"n_average: expected an integer >= 1, got {n_average!r}")
        new = _accumulate(F, Y, Gff, Gfy, Gyy, int(count), int(n_average))
        return Gff, Gfy, Gyy, int(new)
    raise AmiXrValueError(f"average: expected 'linear' or 'exponential', got {average!r}")


def frf_from_spectra(
    Gff: np.ndarray, Gfy: np.ndarray, Gyy: np.ndarray, estimator: str = "H1"
) -> tuple[np.ndarray, np.ndarray]:
    """FRF estimate and (multiple) coherence per frequency from averaged spectra.

    Parameters
    ----------
    Gff : ndarray of complex, shape (ref, ref, freq)
    Gfy : ndarray of complex, shape (ref, point, freq)
    Gyy : ndarray of float, shape (point, freq)
    estimator : {"H1", "H2", "Hv"}
        H2 and Hv need a single force (ref == 1).

    Returns
    -------
    H : ndarray of complex, shape (ref, point, freq)
    coherence : ndarray of float, shape (point, freq); NaN where a power is zero.
    """
    code = estimator_code(estimator)
    Gff = np.ascontiguousarray(Gff, dtype=np.complex128)
    Gfy = np.ascontiguousarray(Gfy, dtype=np.complex128)
    Gyy = np.ascontiguousarray(np.real(Gyy), dtype=np.float64)
    if (
        Gff.ndim != 3
        or Gfy.ndim != 3
        or Gyy.ndim != 2
        or Gff.shape[0] != Gff.shape[1]
        or Gfy.shape[0] != Gff.shape[0]
        or Gfy.shape[1:] != Gyy.shape
        or Gff.shape[2] != Gyy.shape[1]
    ):
        raise AmiXrValueError(
            f"Gff, Gfy, Gyy: expected shapes (ref, ref, f), (ref, point, f), (point, f), got "
            f"{Gff.shape}, {Gfy.shape}, {Gyy.shape}"
        )
    if code != 1 and Gff.shape[0] != 1:
        raise AmiXrValueError(
            f"estimator: {estimator!r} needs a single force channel, got {Gff.shape[0]}; use 'H1'"
        )
    H = np.empty(Gfy.shape, np.complex128)
    coh = np.empty(Gyy.shape, np.float64)
    _frf_from_spectra(Gff, Gfy, Gyy, code, H, coh)
    return H, coh
