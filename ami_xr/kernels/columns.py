"""The refinement's model columns in one pass: the columns of
:func:`~ami_xr.kernels.modal_basis.model_columns` and of its derivative, real-stacked
(``[Re; Im]``, rows: lines) and multiplied by the line weights, as the variable projection
(:mod:`ami_xr.core.varpro`) uses them at every trial step; its problem record makes the line
variable and the residual-term columns once per problem. Checked wrappers:
:func:`stacked_columns`, :func:`stacked_residual_columns`.
"""

from __future__ import annotations

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.modal_basis import RESIDUAL_TERMS, residual_columns


@jit
def _cdiv(ar, ai, br, bi):
    """``(ar + i ai) / (br + i bi)`` by numpy's own rule (Smith's, the reciprocal of the scale
    multiplied), so that the kernel below gives numpy's values."""
    if abs(br) >= abs(bi):
        if br == 0.0 and bi == 0.0:
            return ar / abs(br), ai / abs(br)
        rat = bi / br
        scl = 1.0 / (br + bi * rat)
        return (ar + ai * rat) * scl, (ai - ar * rat) * scl
    rat = br / bi
    scl = 1.0 / (bi + br * rat)
    return (ar * rat + ai) * scl, (ai * rat - ar) * scl


@jit
def _pole_terms(xr, xi, pk, sk, dsk, dt):
    """``b`` and ``db/dlam`` of one pole at one line, ``(b.re, b.im, db.re, db.im)``: the
    arithmetic of :func:`.modal_basis._basis_on_lines`, operation by operation, in real numbers."""
    if dt > 0.0:
        er = pk.real * xr - pk.imag * xi  # e = p x
        ei = pk.real * xi + pk.imag * xr
        nr, ni = 1.0 - er, -ei  # den = 1 - e
        br, bi = _cdiv(dt * sk.real, dt * sk.imag, nr, ni)
        # dt (ds den + (s dt) e) / (den den)
        tr = (dsk.real * nr - dsk.imag * ni) + ((sk.real * dt) * er - (sk.imag * dt) * ei)
        ti = (dsk.real * ni + dsk.imag * nr) + ((sk.real * dt) * ei + (sk.imag * dt) * er)
        dr, di = _cdiv(dt * tr, dt * ti, nr * nr - ni * ni, nr * ni + ni * nr)
        return br, bi, dr, di
    nr, ni = xr - pk.real, xi - pk.imag  # den = x - lam
    br, bi = _cdiv(1.0, 0.0, nr, ni)
    dr, di = _cdiv(1.0, 0.0, nr * nr - ni * ni, nr * ni + ni * nr)
    return br, bi, dr, di


@jit
def _stacked_kernel(x, p, s, ds, dt, w, a, v):
    """The loop of :func:`stacked_columns`: poles ``p`` (2K,) (``exp(lam dt)``, or ``lam`` for
    ``dt <= 0``; the K poles, then their conjugates), truncation factors ``s`` and their
    derivatives ``ds`` (2K,), line variable ``x`` (L,), weights ``w`` (L,), into the first
    ``2K`` columns of ``a`` and all of ``v``."""
    n_line = x.shape[0]
    n_mode = p.shape[0] // 2
    for i in range(n_line):
        xr, xi, wi = x[i].real, x[i].imag, w[i]
        for k in range(n_mode):
            br0, bi0, dr0, di0 = _pole_terms(xr, xi, p[k], s[k], ds[k], dt)
            c = k + n_mode
            br1, bi1, dr1, di1 = _pole_terms(xr, xi, p[c], s[c], ds[c], dt)
            # columns b + b~ and i (b - b~) (Re i z = -Im z, Im i z = Re z), stacked, weighted
            a[i, 2 * k] = (br0 + br1) * wi
            a[n_line + i, 2 * k] = (bi0 + bi1) * wi
            a[i, 2 * k + 1] = -(bi0 - bi1) * wi
            a[n_line + i, 2 * k + 1] = (br0 - br1) * wi
            v[i, 2 * k] = (dr0 + dr1) * wi
            v[n_line + i, 2 * k] = (di0 + di1) * wi
            v[i, 2 * k + 1] = -(di0 - di1) * wi
            v[n_line + i, 2 * k + 1] = (dr0 - dr1) * wi


def stacked_columns(
    x: np.ndarray, lam: np.ndarray, dt: float, n_samples: int, weight: np.ndarray, fixed
) -> tuple[np.ndarray, np.ndarray]:
    """The columns of :func:`.modal_basis.model_columns`, real-stacked (``[Re; Im]``, rows:
    lines) and multiplied by ``weight`` (L,) line by line, in one pass: the refinement's
    projection evaluates them at every trial step.

    ``x`` (L,): :func:`.modal_basis.line_variable` of the lines (``dt``: 0.0 for the continuous
    model);
    ``fixed`` (2L, 2R): the residual-term columns, stacked and weighted alike
    (:func:`stacked_residual_columns`). Returns ``a`` (2L, 2K + 2R) and ``v`` (2L, 2K),
    C-contiguous: the values of stacking ``model_columns``' ``phi`` and ``dphi``.
    """
    lam = np.ascontiguousarray(np.atleast_1d(lam), dtype=np.complex128)
    x = np.ascontiguousarray(x, dtype=np.complex128)
    if lam.ndim != 1:
        raise AmiXrValueError(f"lam: expected a 1-D array of poles, got shape {lam.shape}")
    if x.ndim != 1 or np.shape(weight) != x.shape:
        raise AmiXrValueError(
            f"x, weight: expected two 1-D arrays of one length, got {x.shape}, {np.shape(weight)}"
        )
    if fixed.ndim != 2 or fixed.shape[0] != 2 * x.shape[0]:
        raise AmiXrValueError(f"fixed: expected shape ({2 * x.shape[0]}, 2R), got {fixed.shape}")
    both = np.concatenate([lam, np.conj(lam)])
    n_mode, n_line = lam.shape[0], x.shape[0]
    s = np.ones(both.shape, dtype=np.complex128)
    ds = np.zeros(both.shape, dtype=np.complex128)
    p = both
    if dt > 0.0:
        with np.errstate(over="ignore", invalid="ignore"):
            if n_samples > 0:
                e_n = np.exp(both * (n_samples * dt))
                s, ds = 1.0 - e_n, -(n_samples * dt) * e_n
            p = np.exp(both * dt)
    a = np.empty((2 * n_line, 2 * n_mode + fixed.shape[1]))
    v = np.empty((2 * n_line, 2 * n_mode))
    w = np.ascontiguousarray(weight, dtype=np.float64)
    _stacked_kernel(x, p, s, ds, float(dt), w, a, v)
    a[:, 2 * n_mode :] = fixed
    return a, v


def stacked_residual_columns(
    omega: np.ndarray, residual_terms: tuple[str, ...], residual_kind: int, weight: np.ndarray
) -> np.ndarray:
    """The residual-term columns of :func:`.modal_basis.model_columns`, real-stacked and
    multiplied by ``weight`` (L,) as in :func:`stacked_columns`: (2L, 2R)."""
    omega = np.ascontiguousarray(omega, dtype=np.float64)
    n_line = omega.shape[0]
    out = np.empty((2 * n_line, 2 * len(residual_terms)))
    if not residual_terms:
        return out
    lower, upper = residual_columns(omega, residual_kind)
    w = np.asarray(weight, dtype=np.float64)
    for r, term in enumerate(residual_terms):
        if term not in RESIDUAL_TERMS:
            raise AmiXrValueError(
                f"residual_terms: expected entries in {RESIDUAL_TERMS}, got {term!r}"
            )
        col = lower if term == "lower" else upper
        for c, z in ((2 * r, col), (2 * r + 1, 1j * col)):
            out[:n_line, c] = z.real * w
            out[n_line:, c] = z.imag * w
    return out
