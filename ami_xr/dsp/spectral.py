"""Welch auto- and cross-spectra on plain arrays, streaming block by block.

One private engine, :class:`WelchAccumulator`, cuts force and response histories into windowed,
detrended segments (numba), takes their FFT (``scipy.fft.rfft``) and accumulates ``Gff``, ``Gfy``
and ``Gyy`` (numba), a batch of segments at a time so that memory stays bounded by the batch size.
Samples can arrive in blocks of any length: the samples of a segment that straddles a block
border are carried over to the next block, so feeding a record in blocks gives the same sums as
feeding it at once. :func:`csd`, :func:`welch` and :func:`coherence` are built on the engine the
way ``scipy.signal`` builds ``welch`` on ``csd``, with the same parameters and (to rounding) the
same results; the labeled :func:`ami_xr.dsp.frf.frf` uses the same engine.

Spectra are one-sided power spectral densities (``scaling="density"``): ``2 conj(X) Y /
(fs sum(w^2))`` averaged over segments, with DC and (even ``nfft``) Nyquist not doubled.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft

from ami_xr.core.checks import check_choice  # noqa: F401 (re-exported for dsp.frf)
from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import spectral as _k
from ami_xr.kernels import windows as _w

AVERAGES = ("linear", "exponential")
_BATCH_BYTES = 16 * 2**20  # segment buffer per batch (the FFT output is about as large again)


def check_segments(n_samples: int, nperseg, noverlap, nfft) -> tuple[int, int, int]:
    """Validate ``nperseg``, ``noverlap`` and ``nfft`` against a record of ``n_samples``.

    ``noverlap=None`` means ``nperseg // 2`` and ``nfft=None`` means ``nperseg`` (scipy's).
    """

    def _int(value, argument):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise AmiXrValueError(f"{argument}: expected an integer, got {value!r}")
        return int(value)

    nperseg = _int(nperseg, "nperseg")
    if nperseg < 1:
        raise AmiXrValueError(f"nperseg: expected an integer >= 1, got {nperseg}")
    if nperseg > n_samples:
        raise AmiXrValueError(
            f"nperseg: the segment of {nperseg} samples is longer than the record of "
            f"{n_samples} samples"
        )
    noverlap = nperseg // 2 if noverlap is None else _int(noverlap, "noverlap")
    if not 0 <= noverlap < nperseg:
        raise AmiXrValueError(
            f"noverlap: expected 0 <= noverlap < nperseg={nperseg}, got {noverlap}"
        )
    nfft = nperseg if nfft is None else _int(nfft, "nfft")
    if nfft < nperseg:
        raise AmiXrValueError(f"nfft: expected nfft >= nperseg={nperseg}, got {nfft}")
    return nperseg, noverlap, nfft


def resolve_window(window, nperseg: int, argument: str = "window") -> np.ndarray:
    """A window name (see :func:`ami_xr.kernels.windows.get_window`) or array -> float64 array."""
    if isinstance(window, str):
        if _w.window_name(window) in ("exponential", "force"):
            raise AmiXrValueError(
                f"{argument}: {window!r} needs parameters; pass the array from "
                "ami_xr.kernels.windows.get_window (or use ami_xr.impact_frf)"
            )
        return _w.get_window(window, nperseg)
    w = np.asarray(window)
    if (
        w.ndim != 1
        or w.shape[0] != nperseg
        or not (np.issubdtype(w.dtype, np.floating) or np.issubdtype(w.dtype, np.integer))
    ):
        raise AmiXrValueError(
            f"{argument}: expected a window name or a 1-D real array of nperseg={nperseg} "
            f"samples, got {type(window).__name__} of shape {getattr(w, 'shape', None)}"
        )
    w = np.ascontiguousarray(w, dtype=np.float64)
    if not np.all(np.isfinite(w)) or not np.any(w):
        raise AmiXrValueError(f"{argument}: contains NaN or inf, or is all zeros")
    return w


class WelchAccumulator:
    """Running Welch sums of forces and responses fed block by block.

    Parameters
    ----------
    n_force, n_response : int
        Channels of force (references) and response (points).
    fs : float
        Sampling rate in Hz (for the density scaling).
    nperseg, noverlap, nfft : int
        Segment length, overlap and FFT length (validated by :func:`check_segments`).
    force_window, response_window : ndarray, shape (nperseg,)
        Windows of the force and the response channels. The density scale uses the response
        window for every spectrum so that ratios of spectra (the FRF) see the windows only as
        what they are, multiplications of the data.
    detrend : {"constant", "linear", "none"} or False
    average : {"linear", "exponential"}
    n_average : int
        Time constant of exponential averaging in segments.
    workers : int
        Threads of ``scipy.fft``.
    """

    def __init__(
        self,
        n_force: int,
        n_response: int,
        *,
        fs: float,
        nperseg: int,
        noverlap: int,
        nfft: int,
        force_window: np.ndarray,
        response_window: np.ndarray,
        detrend="constant",
        average: str = "linear",
        n_average: int = 8,
        workers: int = 1,
    ):
        if average not in AVERAGES:
            raise AmiXrValueError(f"average: expected one of {AVERAGES}, got {average!r}")
        self.fs = float(fs)
        self.nperseg, self.noverlap, self.nfft = nperseg, noverlap, nfft
        self.step = nperseg - noverlap
        _k.detrend_code(detrend)  # checks the name before any data arrive
        self.detrend = detrend
        self.average = average
        self.n_average = int(n_average)
        self.workers = int(workers)
        self.n_force, self.n_response = int(n_force), int(n_response)
        self._wf = np.ascontiguousarray(np.broadcast_to(force_window, (n_force, nperseg)))
        self._wy = np.ascontiguousarray(np.broadcast_to(response_window, (n_response, nperseg)))
        self._scale_window = np.asarray(response_window, dtype=np.float64)
        nf = nfft // 2 + 1
        self.Gff = np.zeros((n_force, n_force, nf), np.complex128)
        self.Gfy = np.zeros((n_force, n_response, nf), np.complex128)
        self.Gyy = np.zeros((n_response, nf), np.float64)
        self.count = 0
        self._batch = max(1, _BATCH_BYTES // (8 * (n_force + n_response) * nperseg))
        self.end_record()

    @property
    def frequency(self) -> np.ndarray:
        """One-sided frequency grid in Hz (``scipy.fft.rfftfreq(nfft, 1/fs)``)."""
        return scipy.fft.rfftfreq(self.nfft, 1.0 / self.fs)

    def end_record(self) -> None:
        """Drop the carried samples: the next block starts a new record (no segment spans two)."""
        self._tail_f = np.zeros((self.n_force, 0))
        self._tail_y = np.zeros((self.n_response, 0))

    def feed(self, force: np.ndarray, response: np.ndarray) -> None:
        """Append samples ``force`` (n_force, n) and ``response`` (n_response, n) of the record."""
        f = np.asarray(force, dtype=np.float64)
        y = np.asarray(response, dtype=np.float64)
        if self._tail_f.shape[1]:
            f = np.concatenate([self._tail_f, f], axis=1)
            y = np.concatenate([self._tail_y, y], axis=1)
        f = np.ascontiguousarray(f)
        y = np.ascontiguousarray(y)
        n = f.shape[1]
        nseg = 0 if n < self.nperseg else (n - self.nperseg) // self.step + 1
        for a in range(0, nseg, self._batch):
            starts = np.arange(a, min(a + self._batch, nseg), dtype=np.int64) * self.step
            self._add(f, y, starts)
        # carry what the next segment needs; copy so the caller's block can be freed
        self._tail_f = f[:, nseg * self.step :].copy()
        self._tail_y = y[:, nseg * self.step :].copy()

    def _add(self, f: np.ndarray, y: np.ndarray, starts: np.ndarray) -> None:
        sf = _k.prepare_segments(f, starts, self._wf, self.detrend)
        sy = _k.prepare_segments(y, starts, self._wy, self.detrend)
        F = scipy.fft.rfft(sf, n=self.nfft, axis=-1, overwrite_x=True, workers=self.workers)
        del sf
        Y = scipy.fft.rfft(sy, n=self.nfft, axis=-1, overwrite_x=True, workers=self.workers)
        del sy
        *_, self.count = _k.accumulate_spectra(
            F,
            Y,
            (self.Gff, self.Gfy, self.Gyy),
            average=self.average,
            count=self.count,
            n_average=self.n_average,
        )

    def spectra(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Averaged one-sided densities ``Gff`` (ref, ref, f), ``Gfy`` (ref, point, f), ``Gyy``."""
        if self.count == 0:
            raise AmiXrValueError("nperseg: no complete segment was fed; the record is too short")
        scale = 1.0 / (self.fs * float(np.sum(self._scale_window**2)))
        if self.average == "linear":
            scale /= self.count
        side = np.full(self.nfft // 2 + 1, 2.0)
        side[0] = 1.0
        if self.nfft % 2 == 0:
            side[-1] = 1.0
        s = scale * side
        return self.Gff * s, self.Gfy * s, self.Gyy * s


def _spectral_helper(x, y, fs, window, nperseg, noverlap, nfft, detrend, average, n_average):
    """Shared by csd, welch and coherence: (f, Gxx, Gxy, Gyy) of x (n,) or (ref, n), y (.., n)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    x2 = x.reshape(-1, x.shape[-1])
    y2 = y.reshape(-1, y.shape[-1])
    if x2.shape[-1] != y2.shape[-1]:
        raise AmiXrValueError(
            f"y: expected the same number of samples as x ({x2.shape[-1]}), got {y2.shape[-1]}"
        )
    if not math.isfinite(fs) or fs <= 0:
        raise AmiXrValueError(f"fs: expected a positive sampling rate in Hz, got {fs!r}")
    for name, a in (("x", x2), ("y", y2)):
        if not np.all(np.isfinite(a)):
            raise AmiXrValueError(f"{name}: contains NaN or inf samples")
    nperseg, noverlap, nfft = check_segments(x2.shape[-1], nperseg, noverlap, nfft)
    w = resolve_window(window, nperseg)
    acc = WelchAccumulator(
        x2.shape[0],
        y2.shape[0],
        fs=fs,
        nperseg=nperseg,
        noverlap=noverlap,
        nfft=nfft,
        force_window=w,
        response_window=w,
        detrend=detrend,
        average=average,
        n_average=n_average,
    )
    acc.feed(x2, y2)
    Gxx, Gxy, Gyy = acc.spectra()
    return acc.frequency, Gxx, Gxy, Gyy


def csd(
    x,
    y,
    fs: float = 1.0,
    window="hann",
    nperseg: int = 256,
    noverlap: int | None = None,
    nfft: int | None = None,
    detrend="constant",
    average: str = "linear",
    n_average: int = 8,
) -> tuple[np.ndarray, np.ndarray]:
    """Cross power spectral density ``E[conj(X) Y]`` of 1-D ``x`` and ``y`` (n,) or (channel, n).

    Same parameters and results as ``scipy.signal.csd`` (one-sided, density, mean average);
    ``average="exponential"`` gives the running average of :class:`WelchAccumulator`.
    """
    f, _, Gxy, _ = _spectral_helper(
        x, y, fs, window, nperseg, noverlap, nfft, detrend, average, n_average
    )
    out = Gxy[0]
    return f, out[0] if np.ndim(y) == 1 else out


def welch(
    x,
    fs: float = 1.0,
    window="hann",
    nperseg: int = 256,
    noverlap: int | None = None,
    nfft: int | None = None,
    detrend="constant",
    average: str = "linear",
    n_average: int = 8,
) -> tuple[np.ndarray, np.ndarray]:
    """Power spectral density of ``x`` (n,) or (channel, n), as ``scipy.signal.welch``."""
    f, _, _, Gyy = _spectral_helper(
        np.zeros(np.shape(x)[-1]),
        x,
        fs,
        window,
        nperseg,
        noverlap,
        nfft,
        detrend,
        average,
        n_average,
    )
    return f, Gyy[0] if np.ndim(x) == 1 else Gyy


def coherence(
    x,
    y,
    fs: float = 1.0,
    window="hann",
    nperseg: int = 256,
    noverlap: int | None = None,
    nfft: int | None = None,
    detrend="constant",
    average: str = "linear",
    n_average: int = 8,
) -> tuple[np.ndarray, np.ndarray]:
    """Ordinary coherence ``|Gxy|^2 / (Gxx Gyy)`` of 1-D ``x`` and ``y`` (n,) or (channel, n)."""
    f, Gxx, Gxy, Gyy = _spectral_helper(
        x, y, fs, window, nperseg, noverlap, nfft, detrend, average, n_average
    )
    _, coh = _k.frf_from_spectra(Gxx, Gxy, Gyy, "H1")
    return f, coh[0] if np.ndim(y) == 1 else coh
