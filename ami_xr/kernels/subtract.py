"""Subtraction Phase of the AMI (eq. 6): one FRF at a time, the strongest peak of the residual
is tried as a single mode (the peak trial of :mod:`.peak`) and subtracted, until no significant
peak is left.

Checked wrapper: :func:`subtract_batch` (settings in a :class:`SubtractParams` record, results
in a :class:`SubtractResult`). The stop reasons are ``STOP_*`` codes; :data:`STOP_REASONS`
names them.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.modal_basis import add_mode
from ami_xr.kernels.noise import noise_floor
from ami_xr.kernels.peak import check_inputs, nearest_within, peak_trial, scene
from ami_xr.kernels.single_mode import FIT_OK

# Stop codes of the Subtraction Phase (mapped to strings in the labeled layer).
STOP_BELOW_FLOOR = 0
STOP_MAX_MODES = 1
STOP_MAX_ATTEMPTS = 2
STOP_REASONS = ("below_noise_floor", "max_modes", "max_rejected_peaks")
"""Names of the ``STOP_*`` codes, by code."""


class SubtractParams(NamedTuple):
    """Settings of the Subtraction Phase kernel (see :func:`ami_xr.subtract` for their meaning)."""

    delta: float
    """Fit band: contiguous lines with ``|Y| >= delta`` times the peak."""
    max_modes: int
    """Most candidate modes per FRF."""
    pfa: float
    """False-alarm probability of the peak test over all lines."""
    min_points: int
    """Fewest lines in a fit band."""
    zeta_max: float
    """Largest accepted damping ratio."""
    merge_tol: float
    """Candidates closer than this many half-power bandwidths merge."""


class SubtractResult(NamedTuple):
    """What the Subtraction Phase finds in ``P`` FRFs, ``max_modes`` candidate slots each."""

    lam: np.ndarray
    """(P, max_modes) complex candidate eigenvalues, NaN-padded."""
    res: np.ndarray
    """(P, max_modes) complex residues, NaN-padded."""
    band_low: np.ndarray
    """(P, max_modes) lower edge of each candidate's fit band, rad/s."""
    band_high: np.ndarray
    """(P, max_modes) upper edge, rad/s."""
    sigma: np.ndarray
    """(P,) noise floor of each FRF."""
    statistic: np.ndarray
    """(P,) the last examined peak ``|Y|^2 / sigma^2``."""
    reason: np.ndarray
    """(P,) ``STOP_*`` code."""
    n_modes: np.ndarray
    """(P,) number of candidates."""


@jit
def _subtract_batch(data, scene, params):
    """Subtraction Phase on every row of ``data`` (P, F), in units of each row's noise floor
    (residues in those units; ``sigma`` left at 1 for the wrapper); each line's power weighted
    by ``scene.line_w`` (the noise's shape along frequency)."""
    omega, x, dt, n_samples = scene.grid
    n_p, n_f = data.shape
    m = params.max_modes
    nan = complex(np.nan, np.nan)
    out = SubtractResult(
        lam=np.full((n_p, m), nan),
        res=np.full((n_p, m), nan),
        band_low=np.full((n_p, m), np.nan),
        band_high=np.full((n_p, m), np.nan),
        sigma=np.ones(n_p),
        statistic=np.zeros(n_p),
        reason=np.full(n_p, STOP_MAX_ATTEMPTS),
        n_modes=np.zeros(n_p, dtype=np.int64),
    )
    y = np.empty((1, n_f), dtype=np.complex128)
    power = np.empty(n_f)
    masked = np.empty(n_f, dtype=np.bool_)
    wts = np.ones(1)
    r = np.empty(1, dtype=np.complex128)
    line_w = scene.line_w
    for j in range(n_p):
        lam_j, res_j = out.lam[j], out.res[j]
        for i in range(n_f):
            y[0, i] = data[j, i]
        masked[:] = False
        n = np.int64(0)  # typed, not a literal: one specialisation of its callees
        for _attempt in range(3 * m + 10):
            if n >= m:
                out.reason[j] = STOP_MAX_MODES
                break
            # the largest peak first (as given: its tail biases the others' fits most), among
            # the lines significant against their own noise (``line_w``: 1 / its shape^2)
            peak = np.int64(-1)
            top = 0.0
            largest = -1.0  # |Y|^2 as given at ``peak``
            for i in range(n_f):
                raw = abs(y[0, i]) ** 2
                power[i] = raw * line_w[i]
                if masked[i]:
                    continue
                top = max(top, power[i])
                if power[i] >= scene.t_line and raw > largest:
                    peak, largest = i, raw
            out.statistic[j] = top
            if peak < 0:
                out.reason[j] = STOP_BELOW_FLOOR
                break
            lam, lo, hi, code = peak_trial(
                y, power, scene, peak, params.delta, params.min_points, wts, r, masked
            )
            if code != FIT_OK:
                continue
            k = nearest_within(lam_j, n, lam, params.merge_tol, np.int64(-1))
            if k >= 0:
                # a duplicate of an earlier candidate: the residual left near that pole; fold the
                # residue into the earlier candidate (poles this close add their residues)
                res_j[k] += r[0]
            else:
                lam_j[n] = lam
                res_j[n] = r[0]
                out.band_low[j, n] = omega[lo]
                out.band_high[j, n] = omega[hi - 1]
                n += 1
            # the residual recomputed from the data (eq. 6 with the current candidates)
            for i in range(n_f):
                y[0, i] = data[j, i]
            for k in range(n):
                add_mode(y[0], x, lam_j[k], res_j[k], dt, n_samples, -1.0, np.int64(0), n_f)
        out.n_modes[j] = n
    return out


def subtract_batch(
    data: np.ndarray,
    omega: np.ndarray,
    dt: float | None,
    n_samples: int | None,
    params: SubtractParams,
    line_shape: np.ndarray | None = None,
) -> SubtractResult:
    """Subtraction Phase on every FRF (rows of ``data``; ``data``, ``omega``, ``dt`` and
    ``n_samples`` as :func:`~.peak.check_inputs` takes them), with the settings ``params``
    (a :class:`SubtractParams`).

    Returns
    -------
    SubtractResult
        Candidates (NaN-padded), their band edges, the noise floors, the last peak statistic,
        the stop reason and the number of candidates of every FRF.
    """
    data, omega, dt, n = check_inputs(data, omega, dt, n_samples)
    if not isinstance(params, SubtractParams):
        raise AmiXrValueError(
            f"params: expected a SubtractParams record, got {type(params).__name__}"
        )
    if int(params.max_modes) < 1 or int(params.min_points) < 1:
        raise AmiXrValueError(
            f"params: max_modes and min_points must be >= 1, got {params.max_modes}, "
            f"{params.min_points}"
        )
    line_w = None
    white = data
    if line_shape is not None:
        shape = np.asarray(line_shape, dtype=np.float64)
        if shape.shape != omega.shape or not np.all(np.isfinite(shape) & (shape > 0)):
            raise AmiXrValueError(
                f"line_shape: expected {omega.size} finite positive values, got shape {shape.shape}"
            )
        white = data / shape
        line_w = 1.0 / shape**2
    # the noise floor, bounded below by rounding (a noise-free FRF) and 1 for an all-zero FRF
    peak = np.max(np.abs(white), axis=1) if data.size else np.zeros(data.shape[0])
    sigma = np.maximum(noise_floor(white), 1e-14 * peak) if data.shape[0] else np.ones(0)
    sigma = np.where(sigma > 0.0, sigma, 1.0)
    where = scene(omega, dt, n, params.zeta_max, params.pfa, 1, line_w)
    out = _subtract_batch(data / sigma[:, None], where, params)
    return out._replace(res=out.res * sigma[:, None], sigma=sigma)
