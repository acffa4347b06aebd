"""One reference that cannot separate a repeated pair says so (issue 22 item 2, issue 41 item 1).

One reference sees a pair of modes through one column of the FRF matrix. Two poles ``lam`` and
``lam + delta`` closer than their bandwidth, with residue vectors ``a1`` and ``a2``, give within
the band ``(a1 + a2) b(lam) + delta a2 b'(lam) + O(delta^2)`` (``b`` the unit-residue pole basis,
``b'`` its derivative in ``lam``): the mode's part of the data over (point x line) is rank two,
its second line direction the pole's derivative. One pole fits it only when ``a2`` is
proportional to ``a1 + a2``, that is when the shape does not change across the band.
:func:`band_shift_statistics` fits that rank-2 model for every identified mode:

* ``D = frf_residual + a_k b(lam_k)`` over the lines within ``band_widths`` half-power
  half-bandwidths ``|Re lam_k|`` of the mode (the data less every other term of the fitted
  model), per point ``p`` its coefficient ``c_p`` on ``b'``: what would shift that FRF's
  eigenvalue by ``d_p = c_p / a_p`` on its own. The coefficients of all modes come from one
  least-squares fit of each FRF's residual on every mode's ``b`` and ``b'`` over the lines of
  all bands, so that a neighbour's own shifts, whose tails reach into a mode's band, stay the
  neighbour's.
* Each ``c_p`` is weighted by its noise: the noise level of FRF ``p`` is estimated from the
  residual's line-to-line roughness (the median of its second difference over ``noise_widths``
  half-bandwidths of the mode: a smooth misfit, a missed mode or a model error cancels there).
* Less the shift common to every point (the fitted eigenvalue absorbs it) and, with
  ``transducer_mass``, a shift proportional to ``|a_p|^2`` (a roving transducer's mass ``dm``
  moves mode ``k`` by about ``-dm phi_pk^2 / 2`` in the FRF of point ``p``, and ``|a_p|`` is
  proportional to ``|phi_pk|``), ``T = sum w_p |c_p - fit_p|^2`` is chi-square with ``P - 2``
  (``P - 1`` without the mass term) complex degrees of freedom for one pole plus noise:
  ``z = (T - dof) / sqrt(dof)`` says whether the shape changes across the band at all, and
  ``spread`` (the information-weighted rms of the per-point shifts beyond what the noise gives,
  over the half-power half-bandwidth ``|Re lam_k|``) how much.
  The noise level never goes below ``noise_floor`` of the FRF's largest value in the band.

:func:`suspected` flags a mode whose ``z`` exceeds ``z_min`` and whose ``spread`` exceeds
``spread_range`` times the model-error allowance: the median ``spread`` of the other modes,
but at least ``spread_floor`` (at a high signal-to-noise ratio the second-order terms of any
per-FRF shift are significant). The half-bandwidth is the unit: a measured peak's model error
(the estimator's bias at the peak, leakage, drift) changes its shape on the scale of its own
bandwidth, and a split is seen in proportion to it. On sdypy-EMA's measured beam
(``/work/shared/data``, eleven single modes at 0.15-0.9 % damping) the spread of each peak is
0.04-0.16 of its half-bandwidth, but 0.6e-4 to 7e-4 of ``|lam|``: the mode with the most
damping stood out four to ten times in those units. Measured
data have a model error at every peak (each FRF measured at another time, temperature or
transducer position sees the mode at a slightly different eigenvalue: rank two in exactly this
form), a split pair only at its own peak. The median, not the lower quartile that the
model-order step's split test takes (:func:`ami_xr.core.model_error.within_scatter`): the
per-FRF scatter differs from mode to mode by more than the quartile's margin allows (a mode
whose shape is small where the shifts act is barely moved), and the lower quartile flags the
largest of them. A mode with another identified mode within its band is two poles already (a
resolved pair, or a model-order split): it is neither flagged nor counted in the allowance.
With fewer than ``min_peaks`` other modes there is no typical value and significance alone
decides.

What one reference cannot identify: an exactly repeated root (split 0) is one pole with the
residue vector ``a1 + a2`` in every column of the FRF matrix -- the FRFs of one reference are
exactly those of a single mode with that residue vector, and no statistic of them can tell it
from one mode; two references resolve it (:mod:`ami_xr.ami.mimo`). A split whose
``delta a2 b'`` term is below the noise (``T`` of its noise-free data comparable to ``dof``) is
not identifiable either; ``scripts/benchmark_mimo.py --repeated`` prints both.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import chunked as ch
from ami_xr.core.model import resolve_model
from ami_xr.kernels.modal_basis import pole_basis


@dataclass(frozen=True)
class RepeatedPolicy:
    """The knobs of the one-reference repeated-root flag, with where each value comes from."""

    #: lines within this many half-power half-bandwidths ``|Re lam|`` of a mode: the band
    #: over which a split below the bandwidth changes the shape (``b'`` is ``b^2``: most of its
    #: power lies within two half-bandwidths)
    band_widths: float = 2.0
    #: the noise level of an FRF near a mode: its residual's second difference over this many
    #: half-bandwidths either side (at least ``noise_lines`` lines)
    noise_widths: float = 10.0
    noise_lines: int = 21
    #: significance of the shape change, in standard deviations of ``T`` (chi-square with
    #: ``dof`` complex degrees of freedom): single modes of the simulated rings and chains of
    #: ``scripts/benchmark_mimo.py --repeated`` reach about 3 (the fit's own error, uniform
    #: rather than Gaussian noise)
    z_min: float = 6.0
    #: ``spread`` over the allowance (the median over the other peaks) that flags a mode: the
    #: model-order step's ``scatter_range`` (the range of a dozen draws of a spread is below 4)
    spread_range: float = 4.0
    #: the smallest allowance, in half-power half-bandwidths ``|Re lam|`` (0.5 %): at a high
    #: signal-to-noise ratio the second-order terms of any per-FRF shift (a transducer's mass
    #: of 1 % on the chain of ``scripts/benchmark_mimo.py --repeated``: 0.2 % of the
    #: bandwidth) are significant; a 0.1 % split at 1 % damping is 4.6 %
    spread_floor: float = 0.005
    #: other peaks needed for a typical model error (the model-order step's ``scatter_peaks``)
    min_peaks: int = 3
    #: points needed for a spread (two give one difference)
    min_points: int = 3
    #: the noise level is never below this share of the FRF's largest value in the band (the
    #: resolution of a 20-bit acquisition): noise-free data have a rounding-level roughness,
    #: against which the fit's own convergence error would count as a shape change
    noise_floor: float = 1e-6
    #: allow, besides the shift common to every point, the one a roving transducer's mass
    #: gives: ``d_p`` proportional to the mode's shape squared at the point, ``|a_p|^2``
    transducer_mass: bool = True


POLICY = RepeatedPolicy()


class RepeatedStatistics(NamedTuple):
    """Per reference and mode (R, K): :func:`band_shift` of each reference's FRFs."""

    spread: np.ndarray  # relative rms eigenvalue shift across the points beyond the noise
    z: np.ndarray  # significance of the shape change across the band
    alone: np.ndarray  # bool: no other identified mode within the band


def noise_variance(residual: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """``E|e|^2`` per FRF (P,) from the residual's roughness on ``lines`` (indices, ascending):
    ``r_i - (r_(i-1) + r_(i+1)) / 2`` has 1.5 times the variance of white noise and cancels
    what is smooth from line to line; the median over the lines, over ``ln 2`` (for complex
    Gaussian noise ``|e|^2`` is exponential), is robust to a few lines of misfit."""
    r = residual[:, lines]
    d = r[:, 1:-1] - 0.5 * (r[:, :-2] + r[:, 2:])
    return np.median(np.abs(d) ** 2, axis=1) / 1.5 / np.log(2.0)


def band_shift(
    residual: np.ndarray,
    omega: np.ndarray,
    lam: np.ndarray,
    residue: np.ndarray,
    basis: np.ndarray,
    derivative: np.ndarray,
    policy: RepeatedPolicy = POLICY,
    noise_var: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rank-2 fit of each mode's own part of the data within its band (the module
    docstring), on plain arrays.

    Parameters
    ----------
    residual : ndarray of complex (P, F)
        Data minus the fitted model: a numpy array, or a dask array chunked along the points,
        reduced chunk by chunk (:func:`ami_xr.ami.chunked.map_reduce`; only per-mode 3 x 3
        factors reach the caller).
    omega : ndarray (F,)
        Angular frequencies, ascending (rad/s).
    lam : ndarray of complex (K,)
        The fitted eigenvalues (the positive poles).
    residue : ndarray of complex (P, K)
        The fitted residues.
    basis, derivative : ndarray of complex (K, F)
        ``b(lam_k, w)`` (unit residue) and its derivative in ``lam_k``.
    policy : RepeatedPolicy
        Band, noise window and floor, the minimum number of points, the transducer's mass.
    noise_var : ndarray (P,), optional
        ``E|e|^2`` of each FRF's lines when it is known (what noise-free data would show at a
        given noise level: ``scripts/benchmark_mimo.py``'s identifiability); by default
        estimated from the residual's roughness near each mode (:func:`noise_variance`).

    Returns
    -------
    spread : ndarray (K,)
        Information-weighted rms of the per-point eigenvalue shifts beyond the noise, over
        the half-power half-bandwidth ``|Re lam_k|`` (0 where ``T`` is within three standard
        deviations of the noise).
    z : ndarray (K,)
        ``(T - dof) / sqrt(dof)``, ``dof`` the points less the shifts allowed (one, or two
        with ``transducer_mass``).
    alone : ndarray of bool (K,)
        No other mode of ``lam`` within the band.

    NaN (``spread``, ``z``) with fewer than ``min_points`` FRFs with a noise level and a
    residue (or no degree of freedom left), or fewer than three lines in the band.
    """
    setup = _setup(omega, lam, basis, derivative, policy)
    return _band_shift(residual, lam, residue, setup, policy, noise_var)


def _band_shift(residual, lam, residue, setup: dict, policy: RepeatedPolicy, noise_var=None):
    """:func:`band_shift` with its :func:`_setup` made (one for every reference of a result:
    the lines, design and noise windows depend on the poles only)."""
    n_k = lam.size
    spread = np.full(n_k, np.nan)
    z = np.full(n_k, np.nan)
    if noise_var is not None:  # one value per FRF, cut into blocks with them
        noise_var = np.broadcast_to(np.asarray(noise_var, dtype=float), residual.shape[:1])
    if setup["lines"].size >= 3:
        total = ch.map_reduce(
            _chunk_terms, _combine, [residual, residue, noise_var], setup, split_every=16
        )
        for k, part in enumerate(total):
            if part is not None:
                spread[k], z[k] = _finish(part, lam[k], policy)
    return spread, z, setup["alone"]


def _setup(omega, lam, basis, derivative, policy: RepeatedPolicy) -> dict:
    """What every chunk of points shares: the lines of all bands and each mode's own lines,
    the least-squares design on them and the noise window of each mode."""
    n_k = lam.size
    half = policy.band_widths * np.abs(lam.real)
    alone = np.array(
        [not np.any(np.abs(np.delete(lam.imag, k) - lam[k].imag) <= half[k]) for k in range(n_k)],
        dtype=bool,
    )
    in_band = np.abs(omega[None, :] - lam.imag[:, None]) <= half[:, None]
    lines = np.flatnonzero(in_band.any(axis=0))
    setup = {"alone": alone, "lines": lines, "policy": policy, "modes": [None] * n_k}
    if lines.size < 3:
        return setup
    # one least-squares fit of every FRF on the lines of all bands: each mode's basis (its
    # residue's correction) and its derivative (that FRF's own shift of the mode), so that a
    # neighbour's shifts, whose tails reach into a mode's band, are not counted as its own
    x = np.concatenate([basis[:, lines], derivative[:, lines]]).T  # (L, 2K)
    cov = np.linalg.pinv(x.conj().T @ x)  # per unit noise variance
    n_line = omega.size
    for k in range(n_k):
        cols = np.flatnonzero(in_band[k])
        var_c = float(cov[n_k + k, n_k + k].real)
        if cols.size < 3 or not var_c > 0:
            continue
        reach = max(policy.noise_widths * abs(lam[k].real), 0.0)
        near = np.flatnonzero(np.abs(omega - lam[k].imag) <= reach)
        centre = int(np.clip(np.searchsorted(omega, lam[k].imag), 0, n_line - 1))
        lo = min(near.min() if near.size else centre, centre - policy.noise_lines // 2)
        hi = max(near.max() if near.size else centre, centre + policy.noise_lines // 2)
        window = np.arange(max(lo, 0), min(hi, n_line - 1) + 1)
        if window.size >= 5:
            setup["modes"][k] = (cols, var_c, window, basis[k, cols])
    # lstsq's minimum-norm solution (singular values below eps max(L, 2K) of the largest
    # dropped) as one matrix: each chunk of points is then a product, not an SVD per call
    u, sv, vh = np.linalg.svd(x, full_matrices=False)
    keep = sv > np.finfo(float).eps * max(x.shape) * sv[0]
    setup["solve"] = (vh[keep].conj().T / sv[keep]) @ u[:, keep].conj().T  # (2K, L)
    return setup


class _Part(NamedTuple):
    """A chunk's (or several chunks') share of one mode's weighted fit of the shifts: the R
    factor of ``sqrt(w) [xs | c]`` with the shape column scaled by ``top``, the information
    ``sum w |a|^2``, the number of points and ``top``, their largest ``|a|``."""

    r: np.ndarray
    info: float
    count: int
    top: float


def _chunk_terms(residual, residue, noise_var, setup: dict) -> list:
    """Each mode's :class:`_Part` of the FRFs ``residual`` (p, F) with residues ``residue``
    (p, K) (None where the mode has no statistic)."""
    residual = np.asarray(residual)
    residue = np.asarray(residue)
    policy = setup["policy"]
    lines = setup["lines"]
    n_k = len(setup["modes"])
    out: list = [None] * n_k
    if "solve" not in setup:
        return out
    coef = setup["solve"] @ residual[:, lines].T  # (2K, p): least squares on every FRF
    for k, mode in enumerate(setup["modes"]):
        if mode is None:
            continue
        cols, var_c, window, basis_k = mode
        s2 = noise_variance(residual, window) if noise_var is None else np.asarray(noise_var)
        a = residue[:, k] + coef[k]
        ok = np.isfinite(s2) & (s2 > 0) & np.isfinite(a) & (a != 0)
        a, c = a[ok], coef[n_k + k, ok]
        if not a.size:
            out[k] = _Part(None, 0.0, 0, 0.0)
            continue
        data = residual[np.ix_(ok, cols)] + np.outer(residue[ok, k], basis_k)
        floor = (policy.noise_floor * np.abs(data).max(axis=1)) ** 2
        w = 1.0 / (np.maximum(s2[ok], floor) * var_c)  # 1 / var(c_p)
        top = float(np.abs(a).max())
        # the shift every FRF shares (the fitted eigenvalue absorbs it) and, with a
        # transducer's mass, the one proportional to the shape squared at the point
        xs = [a, a * (np.abs(a) / top) ** 2] if policy.transducer_mass else [a]
        r = np.linalg.qr(np.column_stack([*xs, c]) * np.sqrt(w)[:, None], mode="r")
        out[k] = _Part(r, float(np.sum(w * np.abs(a) ** 2)), int(a.size), top)
    return out


def _combine(parts: list) -> list:
    """The :class:`_Part` of several chunks, mode by mode: their R factors stacked (the shape
    column brought to the largest ``top``) and factored again."""
    out = []
    for per_mode in zip(*parts, strict=True):
        got = [p for p in per_mode if p is not None and p.r is not None]
        if not got:
            out.append(next((p for p in per_mode if p is not None), None))
            continue
        top = max(p.top for p in got)
        stack = []
        for p in got:
            r = p.r.copy()
            if r.shape[1] == 3:
                r[:, 1] *= (p.top / top) ** 2  # the shape column of the largest |a|
            stack.append(r)
        r = np.linalg.qr(np.vstack(stack), mode="r")
        out.append(_Part(r, sum(p.info for p in got), sum(p.count for p in got), top))
    return out


def _finish(part: _Part, lam_k: complex, policy: RepeatedPolicy) -> tuple[float, float]:
    """``spread`` and ``z`` of one mode from its pooled :class:`_Part` (NaN where too few
    points or no degree of freedom is left)."""
    dof = part.count - (2 if policy.transducer_mass else 1)
    if part.r is None or part.count < policy.min_points or dof < 1:
        return np.nan, np.nan
    # |sqrt(w) (xs beta - c)|^2 = |R[:, :-1] beta - R[:, -1]|^2 for every beta
    x, y = part.r[:, :-1], part.r[:, -1]
    beta = np.linalg.lstsq(x, y, rcond=None)[0]
    t = float(np.sum(np.abs(x @ beta - y) ** 2))
    z = (t - dof) / np.sqrt(dof)
    beyond = max(t - dof - 3.0 * np.sqrt(dof), 0.0)
    return np.sqrt(beyond / part.info * part.count / dof) / abs(lam_k.real), z


def band_shift_statistics(
    result: xr.Dataset, policy: RepeatedPolicy = POLICY
) -> RepeatedStatistics:
    """:func:`band_shift` of every reference of ``result`` (the output of the pipeline, dims
    (point, frequency) or (reference, point, frequency)), arrays (R, K) with R = 1 without a
    reference dim; NaN where the residual or the residues are missing."""
    n_k = result.sizes.get(names.MODE, 0)
    need = (names.FRF_RESIDUAL, names.RESIDUE, names.EIGENVALUE)
    have = n_k > 0 and all(v in result for v in need)
    refs = [None]
    if have and names.REFERENCE in result[names.FRF_RESIDUAL].dims:
        refs = list(result[names.REFERENCE].values)
    shape = (len(refs), n_k)
    spread, z, alone = np.full(shape, np.nan), np.full(shape, np.nan), np.ones(shape, bool)
    if not have:
        return RepeatedStatistics(spread, z, alone)
    model = resolve_model(result.attrs, "auto")
    omega = 2 * np.pi * np.asarray(result[names.FREQUENCY].values, dtype=float)
    lam = np.asarray(result[names.EIGENVALUE].transpose(names.MODE).values, np.complex128)
    # the data are the windowed FRFs: their poles are the measured ones, before the correction
    lam = lam - float(result.attrs.get(names.ATTR_EXP_CORRECTED, 0.0) or 0.0)

    def basis_at(lk: complex) -> np.ndarray:
        return pole_basis(omega, lk, model.dt, model.n_samples)

    basis = np.array([basis_at(lk) for lk in lam])
    step = 1e-6 * np.maximum(np.abs(lam.real), 1e-12 * np.abs(lam))  # central difference
    derivative = np.array(
        [(basis_at(lk + h) - basis_at(lk - h)) / (2 * h) for lk, h in zip(lam, step, strict=True)]
    )
    setup = _setup(omega, lam, basis, derivative, policy)  # the same for every reference

    def rows(name: str, *dims: str):
        da = result[name]  # (reference, ...) with one reference row when it has no such dim
        if names.REFERENCE in da.dims:
            return da.transpose(names.REFERENCE, *dims).data
        return da.transpose(*dims).data[None]  # a dask residual stays lazy: reduced per chunk

    residual = rows(names.FRF_RESIDUAL, names.POINT, names.FREQUENCY)
    residue = np.asarray(rows(names.RESIDUE, names.POINT, names.MODE))
    for i in range(len(refs)):
        j = i if residue.shape[0] > 1 else 0
        spread[i], z[i], alone[i] = _band_shift(residual[i], lam, residue[j], setup, policy)
    return RepeatedStatistics(spread, z, alone)


def suspected(
    spread: np.ndarray,
    z: np.ndarray,
    alone: np.ndarray | None = None,
    policy: RepeatedPolicy = POLICY,
) -> np.ndarray:
    """Where the band statistics (:func:`band_shift_statistics`) say two poles, per mode (K,):
    in any reference, ``z > z_min`` and ``spread`` above ``spread_range`` times the allowance,
    the median ``spread`` of the other modes that are alone in their band (none with fewer than
    ``min_peaks`` of them) but at least ``spread_floor``; never where
    ``alone`` is False."""
    spread = np.atleast_2d(np.asarray(spread, dtype=float))
    z = np.atleast_2d(np.asarray(z, dtype=float))
    alone = np.ones(spread.shape, bool) if alone is None else np.atleast_2d(alone)
    flag = np.zeros(spread.shape, bool)
    for r in range(spread.shape[0]):
        for k in range(spread.shape[1]):
            if not (alone[r, k] and z[r, k] > policy.z_min):
                continue
            pool = np.delete(spread[r], k)[np.delete(alone[r], k)]
            pool = pool[np.isfinite(pool)]
            typical = np.median(pool) if pool.size >= policy.min_peaks else 0.0
            allowance = max(typical, policy.spread_floor)
            flag[r, k] = spread[r, k] > policy.spread_range * allowance
    return flag.any(axis=0)


# the name the pipeline and the multi-reference path call (issue 22)
band_rank_statistics = band_shift_statistics
