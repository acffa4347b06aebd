"""FFT-to-FRF conversion of sampled records, batched over leading dims (time last).

* Impulse response (the paper's processing): ``FRF = dt * rfft(w * y)`` on the one-sided grid
  ``f_k = k / (n dt)``, ``k = 0 .. n // 2``. For ``y_k = 2 Re(A exp(lam k dt))`` this equals
  :func:`ami_xr.kernels.modal_basis.mode_contribution` ``(2 pi f, lam, A, dt, n)`` exactly.
* Measured force: ``FRF = rfft(w * y) / rfft(w_f * f)`` (one hit, the H1 estimate of a single
  average); ``dt`` cancels. A force that is a discrete unit impulse ``f = [1/dt, 0, ...]`` gives
  back the impulse-response formula.

The FFT is ``scipy.fft.rfft``; the per-sample work around it (window times ``dt``, the spectral
division) is one numpy expression each (no jitted code: nothing here is worth a compilation).
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels.windows import checked_positive, checked_samples, checked_window_array


def rfft_frequencies(n: int, dt: float) -> np.ndarray:
    """One-sided FFT frequencies ``k / (n dt)`` in Hz, ``k = 0 .. n // 2`` (as ``rfftfreq``)."""
    n = checked_samples(n, "n", 1)
    dt = _check_dt(dt)
    return np.arange(n // 2 + 1, dtype=np.float64) / (n * dt)


def _check_dt(dt) -> float:
    return checked_positive(dt, "dt", "sample interval in s")


def _check_record(x, argument: str) -> np.ndarray:
    x = np.asarray(x)
    if x.ndim < 1 or x.shape[-1] < 1:
        raise AmiXrValueError(
            f"{argument}: expected samples along the last axis, got shape {x.shape}"
        )
    if not np.issubdtype(x.dtype, np.number) or np.iscomplexobj(x):
        raise AmiXrValueError(f"{argument}: expected real samples, got dtype {x.dtype}")
    return np.ascontiguousarray(x, dtype=np.float64)


def _window_for(window, n: int, argument: str) -> np.ndarray:
    if window is None:
        return np.ones(n, dtype=np.float64)
    w = checked_window_array(window, argument)
    if w.shape[0] != n:
        raise AmiXrValueError(
            f"{argument}: expected {n} samples to match the record, got {w.shape[0]}"
        )
    return w


def _windowed_rfft(x: np.ndarray, w: np.ndarray, scale: float) -> np.ndarray:
    return scipy.fft.rfft(x * (scale * w), axis=-1)


def impulse_to_frf(y: np.ndarray, dt: float, *, window: np.ndarray | None = None) -> np.ndarray:
    """FRF of sampled impulse responses: ``dt * rfft(window * y)`` along the last axis.

    Parameters
    ----------
    y : ndarray of float, shape (..., n)
        Impulse responses sampled at ``t_k = k dt`` (to a unit impulse at ``t = 0``).
    dt : float
        Sample interval in s.
    window : ndarray of float, shape (n,), optional
        Applied to every record before the FFT (e.g. from
        :func:`ami_xr.kernels.windows.get_window`); default none.

    Returns
    -------
    ndarray of complex128, shape (..., n // 2 + 1)
        On the grid :func:`rfft_frequencies` ``(n, dt)``.
    """
    y = _check_record(y, "y")
    dt = _check_dt(dt)
    w = _window_for(window, y.shape[-1], "window")
    return _windowed_rfft(y, w, dt)


def frf_from_force(
    y: np.ndarray,
    f: np.ndarray,
    *,
    window: np.ndarray | None = None,
    force_window: np.ndarray | None = None,
) -> np.ndarray:
    """FRF of a response to a measured force: ``rfft(window * y) / rfft(force_window * f)``.

    Parameters
    ----------
    y : ndarray of float, shape (..., n)
        Responses.
    f : ndarray of float, shape (..., n)
        Force record(s), broadcastable to ``y`` (e.g. shape ``(n,)`` for one force shared by
        every response).
    window, force_window : ndarray of float, shape (n,), optional
        Windows of the responses and of the force; default none.

    Returns
    -------
    ndarray of complex128, shape (..., n // 2 + 1)

    Raises
    ------
    AmiXrValueError
        When the force spectrum is exactly zero at some frequency (division impossible). On
        dask-backed data this surfaces when the block is computed.
    """
    y = _check_record(y, "y")
    f = _check_record(f, "f")
    n = y.shape[-1]
    if f.shape[-1] != n:
        raise AmiXrValueError(f"f: expected {n} samples to match y, got shape {f.shape}")
    try:
        shape = np.broadcast_shapes(y.shape[:-1], f.shape[:-1])
    except ValueError:
        shape = None
    if shape != y.shape[:-1]:
        raise AmiXrValueError(f"f: shape {f.shape} does not broadcast to the responses' {y.shape}")
    w = _window_for(window, n, "window")
    wf = _window_for(force_window, n, "force_window")
    num = _windowed_rfft(y, w, 1.0)
    den = _windowed_rfft(f, wf, 1.0)
    if np.any(den == 0):
        raise AmiXrValueError(
            f"f: the force spectrum is zero at {int(np.count_nonzero(den == 0))} frequency bin(s); "
            "the FRF cannot be formed there"
        )
    return num / den
