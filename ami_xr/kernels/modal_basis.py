"""Modal basis functions: the contribution of one mode with unit residue to an FRF.

Two models of the data:

* continuous time (the paper's eq. 4): ``1/(i w - lam)`` and, for the conjugate term,
  ``1/(i w - conj(lam))``;
* discrete time, for FRFs made as ``dt * DFT`` of an impulse response sampled at ``dt``: the
  exact contribution of ``A exp(lam t)`` is ``dt / (1 - exp((lam - i w) dt))`` (the rectangle rule
  plus all aliases), and likewise for the conjugate term. With the record length ``n`` known and
  ``w`` on the DFT grid, the truncation of the record multiplies it by ``1 - exp(lam n dt)``.

A mode with residue ``A = A1 + i A2`` contributes ``A * b(lam) + conj(A) * b(conj(lam))``.
"""

from __future__ import annotations

import numpy as np

from ami_xr.kernels._numba import jit


@jit
def _pole_basis(omega, lam, dt, n_samples):
    """``b(lam)`` on the angular-frequency grid ``omega`` (rad/s); ``dt <= 0`` means continuous."""
    out = np.empty(omega.shape[0], dtype=np.complex128)
    if dt > 0.0:
        scale = dt
        if n_samples > 0:
            scale = dt * (1.0 - np.exp(lam * (n_samples * dt)))
        for i in range(omega.shape[0]):
            out[i] = scale / (1.0 - np.exp((lam - 1j * omega[i]) * dt))
    else:
        for i in range(omega.shape[0]):
            out[i] = 1.0 / (1j * omega[i] - lam)
    return out


def pole_basis(
    omega: np.ndarray, lam: complex, dt: float | None = None, n_samples: int | None = None
) -> np.ndarray:
    """Contribution of ``exp(lam t)`` (unit residue) to the FRF at angular frequencies ``omega``.

    Parameters
    ----------
    omega : ndarray of float, shape (n,)
        Angular frequencies in rad/s.
    lam : complex
        Pole in rad/s.
    dt : float, optional
        Sample interval in s when the FRF is ``dt * DFT`` of a sampled impulse response;
        ``None`` for the continuous-time model.
    n_samples : int, optional
        Record length of that impulse response; includes the truncation factor
        ``1 - exp(lam n dt)``, exact when ``omega`` lies on the DFT grid ``2 pi k / (n dt)``.
    """
    omega = np.ascontiguousarray(omega, dtype=np.float64)
    if omega.ndim != 1:
        raise ValueError(
            f"omega: expected a 1-D array of angular frequencies, got shape {omega.shape}"
        )
    return _pole_basis(omega, complex(lam), float(dt) if dt else 0.0, int(n_samples or 0))


def mode_contribution(
    omega: np.ndarray,
    lam: complex,
    residue: complex,
    dt: float | None = None,
    n_samples: int | None = None,
) -> np.ndarray:
    """One mode's contribution ``A b(lam) + conj(A) b(conj(lam))`` (eq. 4 or its discrete form)."""
    return residue * pole_basis(omega, lam, dt, n_samples) + np.conj(residue) * pole_basis(
        omega, np.conj(lam), dt, n_samples
    )
