"""Time windows along the last axis, their correction factors, and batched windowing.

Windows (canonical names; aliases in brackets):

* ``"boxcar"`` [``"rectangular"``, ``"rect"``, ``"none"``]: all ones.
* ``"hann"`` [``"hanning"``]: ``0.5 + 0.5 cos(fac)``, ``fac = linspace(-pi, pi, m)``.
* ``"flattop"`` [``"flat-top"``, ``"flat_top"``]: five-term cosine sum with scipy's coefficients.
* ``"exponential"``: ``exp(-k / tau)`` for samples ``k = 0 .. n-1``, set by a decay rate ``decay``
  (1/s, with the sampling rate ``fs``: ``tau = fs / decay`` samples) or by its value ``end_value``
  at the last sample (``tau = (n - 1) / -ln(end_value)``).
* ``"force"`` [``"transient"``]: 1 over the first ``width`` samples (the hammer pulse), then a
  falling half-cosine over ``taper`` samples, then 0.

The cosine windows are ``scipy.signal.get_window``'s own (not reimplemented), periodic
(``sym=False``, scipy's default ``fftbins=True``) or symmetric (``sym=True``). The exponential
and force windows are one-sided, start at sample 0 and ignore ``sym``; the exponential window equals
``scipy.signal.windows.exponential(n, center=0, tau=tau, sym=False)``.

Exponential windows and damping
-------------------------------
Multiplying a mode ``A exp(lam t)`` by ``exp(-beta t)`` gives ``A exp((lam - beta) t)`` exactly, at
every sample: the windowed record is the impulse response of a system whose every eigenvalue is
shifted by ``-beta`` and whose residues ``A`` are unchanged. An identification of the windowed data
therefore finds ``lam_meas = lam - beta``, and the true eigenvalue is ``lam = lam_meas + beta``:
the damped frequency ``Im(lam)`` is unchanged and ``-Re(lam) = -Re(lam_meas) - beta``, i.e.
``zeta wn = zeta_meas wn_meas - beta`` exactly (with ``wn = |lam|``, ``wn_meas = |lam_meas|``;
``wn`` and ``wn_meas`` differ only to second order in ``beta / wn``).
:func:`exponential_decay_rate` returns ``beta``.
"""

from __future__ import annotations

import math

import numpy as np

from ami_xr.errors import AmiXrValueError

WINDOWS = ("boxcar", "hann", "flattop", "exponential", "force")
_ALIASES = {
    "boxcar": "boxcar",
    "rectangular": "boxcar",
    "rect": "boxcar",
    "none": "boxcar",
    "hann": "hann",
    "hanning": "hann",
    "flattop": "flattop",
    "flat-top": "flattop",
    "flat_top": "flattop",
    "exponential": "exponential",
    "force": "force",
    "transient": "force",
}
# The cosine windows are scipy's (its names); ami_xr adds only what scipy lacks for impact tests
# (a force window, an exponential window set by decay rate or end value) and the batched product.
_SCIPY_NAMES = {"hann": "hann", "flattop": "flattop"}


# --- private helpers (clean input assumed; never raise) ---------------------------------------
# Plain numpy: each is one vectorised expression, which numba would only make slower to start
# (every jitted function costs compile time on a first run).


def _exponential(n: int, tau: float) -> np.ndarray:
    """``exp(-k / tau)`` for ``k = 0 .. n-1`` (``tau`` in samples)."""
    return np.exp(-np.arange(n, dtype=np.float64) / tau)


def _force(n: int, width: int, taper: int) -> np.ndarray:
    """1 on ``[0, width)``, half-cosine ``0.5 (1 + cos(pi (j + 1) / (taper + 1)))`` on the next
    ``taper`` samples ``j = 0 .. taper-1``, 0 after; truncated at ``n``."""
    out = np.zeros(n, dtype=np.float64)
    out[: min(width, n)] = 1.0
    j = np.arange(max(0, min(taper, n - width)), dtype=np.float64)
    out[width : width + j.size] = 0.5 * (1.0 + np.cos(np.pi * (j + 1.0) / (taper + 1)))
    return out


# --- public wrappers (validate, then call the kernels) ----------------------------------------


def window_name(name: str) -> str:
    """Canonical name of a window (``"hanning"`` -> ``"hann"``); raises on an unknown name."""
    if not isinstance(name, str) or name.strip().lower() not in _ALIASES:
        raise AmiXrValueError(
            f"window: expected one of {', '.join(WINDOWS)} (or an alias: "
            f"{', '.join(sorted(set(_ALIASES) - set(WINDOWS)))}), got {name!r}"
        )
    return _ALIASES[name.strip().lower()]


def _check_n(n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise AmiXrValueError(f"n: expected a window length that is an integer >= 1, got {n!r}")
    return int(n)


def checked_positive(value, argument: str, what: str = "number") -> float:
    """``value`` as a finite float > 0, or :class:`AmiXrValueError` naming ``argument``.

    Argument check shared by the signal-processing kernel wrappers (``windows``, ``fft``).
    """
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise AmiXrValueError(f"{argument}: expected a positive {what}, got {value!r}") from None
    if not math.isfinite(out) or out <= 0.0:
        raise AmiXrValueError(f"{argument}: expected a finite {what} > 0, got {value!r}")
    return out


def checked_samples(value, argument: str, minimum: int) -> int:
    """``value`` as an integer sample count >= ``minimum``, or :class:`AmiXrValueError` naming
    ``argument`` (booleans are refused). Shared by the ``windows`` and ``fft`` wrappers."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise AmiXrValueError(
            f"{argument}: expected an integer number of samples >= {minimum}, got {value!r}"
        )
    return int(value)


def exponential_decay_rate(
    n: int, *, fs: float, decay: float | None = None, end_value: float | None = None
) -> float:
    """Decay rate ``beta`` (1/s) that an exponential window adds to every mode.

    The window ``exp(-beta t)`` turns a mode ``A exp(lam t)`` into ``A exp((lam - beta) t)``
    exactly, so identified eigenvalues must be corrected by ``lam = lam_meas + beta`` (``Im``
    unchanged, ``-Re(lam) = -Re(lam_meas) - beta``, i.e. ``zeta wn = zeta_meas wn_meas - beta``).

    Parameters
    ----------
    n : int
        Window length in samples.
    fs : float
        Sampling rate in Hz.
    decay : float, optional
        Decay rate in 1/s; returned unchanged (after validation).
    end_value : float, optional
        Window value at the last sample, in (0, 1): ``beta = -ln(end_value) fs / (n - 1)``.
        Exactly one of ``decay`` and ``end_value`` must be given.

    Returns
    -------
    float
        ``beta`` in 1/s.
    """
    n = _check_n(n)
    fs = checked_positive(fs, "fs")
    if (decay is None) == (end_value is None):
        raise AmiXrValueError(
            "decay, end_value: the exponential window needs exactly one of decay (1/s) or "
            f"end_value (its value at the last sample), got decay={decay!r}, "
            f"end_value={end_value!r}"
        )
    if decay is not None:
        return checked_positive(decay, "decay")
    end = _end_value(end_value, n)
    return -math.log(end) * fs / (n - 1)


def _end_value(end_value, n: int) -> float:
    try:
        end = float(end_value)
    except (TypeError, ValueError):
        raise AmiXrValueError(
            f"end_value: expected a number in (0, 1), got {end_value!r}"
        ) from None
    if not (0.0 < end < 1.0):
        raise AmiXrValueError(f"end_value: expected a number in (0, 1), got {end_value!r}")
    if n < 2:
        raise AmiXrValueError(f"end_value: needs a window of n >= 2 samples, got n={n}")
    return end


def get_window(
    name: str,
    n: int,
    *,
    fs: float | None = None,
    decay: float | None = None,
    end_value: float | None = None,
    width: int | None = None,
    taper: int | None = None,
    sym: bool = False,
) -> np.ndarray:
    """A window of ``n`` samples.

    Parameters
    ----------
    name : str
        ``"boxcar"``, ``"hann"``, ``"flattop"``, ``"exponential"`` or ``"force"`` (or an alias,
        see the module docstring).
    n : int
        Number of samples, >= 1 (``n == 1`` gives ``[1.0]`` for the cosine windows, as scipy).
    fs : float, optional
        Sampling rate in Hz; required by ``"exponential"`` with ``decay``.
    decay : float, optional
        ``"exponential"`` only: decay rate in 1/s, ``w[k] = exp(-decay k / fs)``.
    end_value : float, optional
        ``"exponential"`` only: value at the last sample, in (0, 1) (instead of ``decay``).
    width : int, optional
        ``"force"`` only (required): samples of the pulse where the window is 1,
        ``1 <= width <= n``.
    taper : int, optional
        ``"force"`` only: samples of the falling half-cosine after the pulse, >= 0; default
        ``max(1, width // 10)``. A taper running past the record end is cut there.
    sym : bool, default False
        Cosine windows only: ``False`` is the periodic window for spectral analysis (scipy's
        ``fftbins=True``), ``True`` the symmetric one. One-sided windows ignore it.

    Returns
    -------
    ndarray of float64, shape (n,)
    """
    canonical = window_name(name)
    n = _check_n(n)
    _reject_unused(canonical, decay=decay, end_value=end_value, width=width, taper=taper)
    if canonical == "exponential":
        if decay is not None and end_value is None:
            if fs is None:
                raise AmiXrValueError("fs: the exponential window set by decay (1/s) needs fs (Hz)")
            tau = checked_positive(fs, "fs") / exponential_decay_rate(n, fs=fs, decay=decay)
        elif end_value is not None and decay is None:
            end = _end_value(end_value, n)
            tau = (n - 1) / -math.log(end)
        else:
            exponential_decay_rate(n, fs=1.0, decay=decay, end_value=end_value)  # raises
        return _exponential(n, tau)
    if canonical == "force":
        if width is None:
            raise AmiXrValueError("width: the force window needs width (samples of the pulse)")
        width = checked_samples(width, "width", 1)
        if width > n:
            raise AmiXrValueError(f"width: must not exceed the window length n={n}, got {width}")
        taper = max(1, width // 10) if taper is None else checked_samples(taper, "taper", 0)
        return _force(n, width, taper)
    if n == 1 or canonical == "boxcar":
        return np.ones(n, dtype=np.float64)
    from scipy.signal import get_window as scipy_window  # lazy: scipy.signal is slow to import

    w = scipy_window(_SCIPY_NAMES[canonical], n, fftbins=not sym)
    return np.ascontiguousarray(w, dtype=np.float64)


def _reject_unused(canonical: str, **params) -> None:
    users = {"decay": "exponential", "end_value": "exponential", "width": "force", "taper": "force"}
    for argument, value in params.items():
        if value is not None and users[argument] != canonical:
            raise AmiXrValueError(
                f"{argument}: only used by the {users[argument]} window, not by {canonical!r}"
            )


def checked_window_array(w, argument: str = "w") -> np.ndarray:
    """``w`` as a contiguous float64 1-D finite real array, or :class:`AmiXrValueError` naming
    ``argument``. Shared by the ``windows`` and ``fft`` wrappers."""
    w = np.asarray(w)
    if w.ndim != 1 or w.shape[0] < 1 or not np.issubdtype(w.dtype, np.number) or np.iscomplexobj(w):
        raise AmiXrValueError(
            f"{argument}: expected a non-empty 1-D real array, got shape {w.shape} dtype {w.dtype}"
        )
    w = np.ascontiguousarray(w, dtype=np.float64)
    if not np.all(np.isfinite(w)):
        raise AmiXrValueError(f"{argument}: contains NaN or inf")
    return w


def amplitude_correction(w: np.ndarray) -> float:
    """Amplitude correction ``n / sum(w)``: restores the amplitude of a sinusoid on a bin.

    2 for the periodic Hann window, 1 for boxcar.
    """
    w = checked_window_array(w)
    s = float(np.sum(w))
    if s <= 0.0:
        raise AmiXrValueError(f"w: the window sum must be > 0, got {s}")
    return w.shape[0] / s


def energy_correction(w: np.ndarray) -> float:
    """Energy (RMS) correction ``sqrt(n / sum(w**2))``: restores broadband power.

    ``sqrt(8/3)`` for the periodic Hann window (any n >= 3), 1 for boxcar.
    """
    w = checked_window_array(w)
    s2 = float(np.sum(w * w))
    if s2 <= 0.0:
        raise AmiXrValueError("w: the window must not be all zeros")
    return math.sqrt(w.shape[0] / s2)


def apply_window(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``x * w`` along the last axis, into a new array (``x`` is never modified).

    Parameters
    ----------
    x : ndarray, shape (..., n)
        Real or complex samples; real input is computed in float64, complex in complex128.
    w : ndarray, shape (n,)
        The window.

    Returns
    -------
    ndarray, shape of ``x``
    """
    x = np.asarray(x)
    w = checked_window_array(w)
    if x.ndim < 1 or x.shape[-1] != w.shape[0]:
        raise AmiXrValueError(
            f"x: expected a last axis of {w.shape[0]} samples to match the window, "
            f"got shape {x.shape}"
        )
    if not np.issubdtype(x.dtype, np.number):
        raise AmiXrValueError(f"x: expected numeric samples, got dtype {x.dtype}")
    dtype = np.complex128 if np.iscomplexobj(x) else np.float64
    return np.asarray(x, dtype=dtype) * w
