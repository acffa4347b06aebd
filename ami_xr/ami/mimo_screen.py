"""What each reference sees that the stacked model misses: proposals for the shared poles
(issue 41).

:func:`ami_xr.ami.mimo.identify_multi_reference` identifies the FRFs of every reference stacked as
one set; its detection and order tests weigh every FRF alike, so a mode one reference sees clearly
can drown in the FRFs of the references that do not (a reference on a nodal line, a noisier one,
the second member of a close pair). Running the whole single-reference pipeline once more per
reference finds such modes at R times the cost. Here each reference is only screened against the
stacked model, with the order test of the completion (:mod:`ami_xr.core.order`) on its own lines:

* the stacked poles are fixed and the reference's residues fitted to its FRFs in the quantity
  given (variable projection, lower and upper residual terms: what lies beyond the band is not
  a missing mode; each line weighted by that reference's own noise shape when the FRFs carry a
  per-line noise model);
* where the noise-normalised residual power of its FRFs shows a bump above the chi-square level
  of false-alarm probability ``screen_pfa`` (smoothed over the modes' bandwidth), a pole is
  started, fitted with the stacked poles within a few bandwidths of it, and kept when the
  likelihood ratio on that reference's FRFs passes the completion's test (``2 + 2 P`` degrees
  of freedom at ``add_pfa`` over the lines).

The poles kept are proposals: the caller refits all FRFs from the stacked poles and them.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami.global_fit import RESIDUAL_KIND
from ami_xr.ami.line_noise import line_noise_shape
from ami_xr.ami.settings import RefineSettings
from ami_xr.core import grouped, varpro
from ami_xr.core.model import resolve_model
from ami_xr.core.policy import POLICY
from ami_xr.core.regions import fit_modes, residual_peaks

# proposals per reference (each a likelihood-ratio test on its FRFs)
MAX_PROPOSALS = 2
# residual bumps tried, strongest first, before a reference is passed as seeing nothing more
MAX_BUMPS = 4
# a proposal is fitted with the stacked poles within this many of its half-power bandwidths
# (a pole that stands for a close pair moves when its second member is added)
NEIGHBOURS = 3.0
# iterations of a proposal's fit (a screen: the refit of all FRFs polishes what is kept)
FIT_ITERATIONS = 20


class Proposal(NamedTuple):
    """A pole (measured, rad/s) one reference needs beyond the stacked poles, its reference's
    index and its likelihood ratio ``2 (cost - cost')`` over the test's threshold."""

    lam: complex
    reference: int
    gain: float


def reference_problems(stacked: xr.Dataset, n_ref: int) -> list[varpro.Problem]:
    """Per reference (reference-major rows of ``stacked``, the band's lines): its FRFs as a
    variable-projection problem with lower and upper residual terms, each line weighted by the
    reference's own noise shape when the FRFs carry a per-line noise model."""
    frf = stacked[names.FRF].transpose(names.POINT, names.FREQUENCY)
    omega = 2.0 * np.pi * np.asarray(stacked[names.FREQUENCY].values, dtype=np.float64)
    model = resolve_model(stacked.attrs, "exact")
    kind = RESIDUAL_KIND.get(str(stacked.attrs.get(names.ATTR_FRF_TYPE, "")), 0)
    shape, group = line_noise_shape(stacked, frf)
    values = np.asarray(frf.values, dtype=np.complex128)
    n_point = values.shape[0] // n_ref
    out = []
    for i in range(n_ref):
        rows = slice(i * n_point, (i + 1) * n_point)
        prob = varpro.make_problem(
            values[rows],
            omega,
            model.dt,
            model.n_samples,
            ("lower", "upper"),
            nyquist=np.pi / model.dt if model.dt else None,
            residual_kind=kind,
        )
        line = shape if group is None or shape is None else shape[group[i * n_point]]
        out.append(prob if line is None else grouped.whitened(prob, line))
    return out


def _bumps(prob: varpro.Problem, proj: varpro.Projection, lam: np.ndarray) -> list[complex]:
    """Starting poles where the noise-normalised residual power of ``prob``'s FRFs at the
    eigenvalues ``lam`` stands above its screen level (the completion's residual screen,
    :func:`ami_xr.core.regions.residual_peaks`; at most ``MAX_BUMPS``, strongest first)."""
    return residual_peaks(prob, proj, lam, MAX_BUMPS, POLICY.screen_pfa)[0]


def screen(
    prob: varpro.Problem, lam: np.ndarray, add_pfa: float
) -> tuple[np.ndarray, list[tuple[complex, float]]]:
    """The poles one reference's FRFs (``prob``) need beyond the poles ``lam`` (measured), one
    at a time: a residual bump's pole (strongest first, :func:`_bumps`) fitted with its
    neighbours among the poles (the others fixed) is kept when ``2 (cost - cost')`` on these
    FRFs exceeds the completion's threshold (chi-square, ``2 + 2 P`` degrees of freedom,
    ``add_pfa`` over the lines), it was not frozen at its start and lies within the lines;
    then the screen runs again on the poles with it (at most ``MAX_PROPOSALS``). Returns the
    poles (``lam`` as fitted, the kept ones appended) and ``(pole, gain over threshold)`` per
    pole kept."""
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    lam = np.asarray(lam, dtype=np.complex128)
    kept: list[tuple[complex, float]] = []
    if not lam.size:
        return lam, kept
    threshold = chi2.isf(add_pfa / max(prob.omega.size, 1), 2 + 2 * prob.n_points)
    for _ in range(MAX_PROPOSALS):
        proj = varpro.project(prob, lam)
        if not proj.ok:
            break
        got = None
        for start in _bumps(prob, proj, lam):
            width = np.maximum(np.abs(lam.real), abs(start.real))
            near = np.abs(lam - start) <= NEIGHBOURS * width
            # the gain of the added pole alone: its neighbours fitted to these FRFs on both
            # sides of the test (the poles came from other FRFs)
            cost = varpro.objective(prob, proj)
            if near.any():
                cost = _fit(prob, lam, near)[0].cost
            fit, moved = _fit(prob, np.append(lam, start), np.append(near, True))
            gain = 2.0 * (cost - fit.cost)
            new = complex(fit.lam[-1])
            inside = prob.omega[0] <= new.imag <= prob.omega[-1]
            # a pole frozen at its start left its region: what it fitted is not a mode there
            if moved[-1] and np.isfinite(gain) and gain > threshold and new.real < 0 and inside:
                got = (fit.lam, new, float(gain / threshold))
                break
        if got is None:
            break
        lam = got[0]
        kept.append(got[1:])
    return lam, kept


def _fit(prob: varpro.Problem, lam: np.ndarray, free: np.ndarray):
    """The refinement's fit of ``lam`` (``free`` move), each mode held inside its region
    around its start (:func:`ami_xr.core.regions.fit_modes`: a neighbour does not wander off
    to take what lies beyond the band). Returns the fit and which modes stayed free."""
    dw = prob.omega[1] - prob.omega[0] if prob.omega.size > 1 else 0.0
    return fit_modes(
        prob,
        lam,
        lam,
        decay=0.0,
        max_iter=FIT_ITERATIONS,
        tol=RefineSettings.tol,
        max_shift=RefineSettings.max_shift,
        min_width=2.0 * dw,
        free=free,
    )[:2]


def proposals(
    stacked: xr.Dataset, lam: np.ndarray, n_ref: int, add_pfa=None, frozen=None
) -> list[Proposal]:
    """Per reference of ``stacked`` (its band's lines, reference-major), in turn, the poles its
    FRFs need beyond the stacked poles ``lam`` and those the references before it proposed
    (:func:`screen`: two references that see the same missing mode propose it once). Poles
    marked ``frozen`` (held at their start by the refinement: what they fit is not a mode
    there) are left out of the model the references are screened against."""
    pfa = RefineSettings.add_pfa if add_pfa is None else add_pfa
    out = []
    lam = np.asarray(lam, dtype=np.complex128)
    if frozen is not None:
        lam = lam[~np.asarray(frozen, bool)]
    for i, prob in enumerate(reference_problems(stacked, n_ref)):
        lam, kept = screen(prob, lam, pfa)
        out += [Proposal(x, i, g) for x, g in kept]
    return out


def stacked_problem(work: xr.Dataset, terms: tuple[str, ...]) -> varpro.Problem:
    """All FRFs of ``work`` (the stacked band's lines in the working quantity, as the refit
    fits them) as one variable-projection problem with the residual terms ``terms``, each line
    weighted by the median of the FRFs' noise shapes (the refinement's first fit, before its
    per-group polish; lines alike without a per-line noise model)."""
    frf = work[names.FRF].transpose(names.POINT, names.FREQUENCY)
    omega = 2.0 * np.pi * np.asarray(work[names.FREQUENCY].values, dtype=np.float64)
    model = resolve_model(work.attrs, "exact")
    kind = RESIDUAL_KIND.get(str(work.attrs.get(names.ATTR_FRF_TYPE, "")), 0)
    prob = varpro.make_problem(
        np.asarray(frf.values, dtype=np.complex128),
        omega,
        model.dt,
        model.n_samples,
        tuple(terms),
        nyquist=np.pi / model.dt if model.dt else None,
        residual_kind=kind,
    )
    shape, group = line_noise_shape(work, frf)
    if shape is None:
        return prob
    if group is not None:
        shape = np.median(shape[group], axis=0)
        shape = shape / np.median(shape)
    return grouped.whitened(prob, shape)


# the split screen fits the lines within this many half-power bandwidths |Re lam| of the pole,
# with the poles within three times that and lower and upper residual terms for the rest
SPLIT_WINDOW = 20.0


def _window(prob: varpro.Problem, lam: np.ndarray, k: int) -> tuple[varpro.Problem, np.ndarray]:
    """``prob`` on the lines within ``SPLIT_WINDOW`` half-power bandwidths of pole ``k`` (at
    least 8 lines each side; residual terms lower and upper) and which poles of ``lam`` it
    keeps (those within three times that of pole ``k``; the others' tails go to the terms)."""
    half = max(SPLIT_WINDOW * abs(lam[k].real), 8.0 * float(np.median(np.diff(prob.omega))))
    lines = np.flatnonzero(np.abs(prob.omega - lam[k].imag) <= half)
    keep = np.abs(lam.imag - lam[k].imag) <= 3.0 * half
    cols = np.concatenate([lines, lines + prob.omega.size])
    sub = dataclasses.replace(
        prob,
        y=np.ascontiguousarray(prob.y[:, cols]),
        omega=prob.omega[lines],
        line_weight=prob.line_weight[lines],
        residual_terms=("lower", "upper"),
    )
    return sub, keep


# the first-order screen of a split (:func:`first_order_gain`) refuses it when its gain is
# within the noise's at this false-alarm probability (chi-square, 2 per FRF): the split's term
# explains nothing the noise does not
FIRST_ORDER_PFA = 0.01


def first_order_gain(prob: varpro.Problem, proj: varpro.Projection, k: int) -> float:
    """``2 (cost - cost')`` on ``prob`` of the first-order term of a split of pole ``k``: each
    FRF's own coefficient on the pole's derivative ``b'(lam_k)`` (what two poles
    ``lam_k -+ d`` add to one to first order in ``d``, whatever their residues), the poles
    held at the projection ``proj``'s. A linear fit on the projection's own columns (no
    iteration): each FRF's residual on the derivative columns, less their part in the model
    columns. NaN when the projection failed."""
    if not proj.ok:
        return float("nan")
    cols = slice(2 * k, 2 * k + 2)
    qtv = proj.qtv[:, cols]
    gram = proj.vtv[cols, cols] - qtv.T @ qtv  # V_k' (I - Q Q') V_k
    v_res = proj.v_res[:, cols]  # V_k' r_j (r_j is orthogonal to Q)
    try:
        drop = np.einsum("pi,ij,pj->p", v_res, np.linalg.inv(gram), v_res)
    except np.linalg.LinAlgError:
        return float("nan")
    # the objective's floor of each FRF's residual (noise-free data: rounding level)
    floor = (varpro.RSS_FLOOR**2) * prob.y_norm2
    before = np.maximum(proj.rss, floor)
    gain = prob.n_rows * float(np.sum(np.log(before / np.maximum(before - drop, floor))))
    return gain if np.isfinite(gain) else float("nan")


def split_gain(prob: varpro.Problem, lam: np.ndarray, k: int, start: float, max_iter: int) -> float:
    """An upper estimate of ``2 (cost - cost')`` on ``prob`` of a second pole next to pole ``k``
    of ``lam`` (measured, as fitted to all FRFs): the pole split into
    ``lam[k] -+ i start |Re lam[k]|`` and fitted with the poles within ``NEIGHBOURS`` of their
    half-power bandwidths of it (the others held) against the poles as they are, on the lines
    around the pole (:func:`_window`). A screen for the refit of every pole: the gain is the
    added pole's and its neighbours' (fitted on one side only, which can only add to it); NaN
    when the window cannot be fitted (let the refit say).

    First the split's first-order term (:func:`first_order_gain`, one linear fit): where it is
    within the noise (chi-square with 2 degrees of freedom per FRF at ``FIRST_ORDER_PFA``,
    below the trial's threshold) that gain is returned and no pole is fitted. An exactly
    repeated root is one pole with a rank-two residue matrix: its split adds nothing but noise
    to first order (on the ring of ``scripts/benchmark_mimo.py`` the fit of the split cost a
    quarter of the stacked pipeline); a close pair fitted as one pole shows there first (on
    the plate's 22.35 Hz pair, 98-100 % of the fitted split's gain)."""
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    lam = np.asarray(lam, dtype=np.complex128)
    sub, keep = _window(prob, lam, k)
    local = lam[keep]
    j = int(np.sum(keep[:k]))
    if sub.omega.size < 4 * (local.size + 3):
        return float("nan")
    proj = varpro.project(sub, local)
    first = first_order_gain(sub, proj, j)
    if first < chi2.isf(FIRST_ORDER_PFA, 2 * sub.n_points):
        return first
    width = np.maximum(np.abs(local.real), abs(local[j].real))
    near = np.abs(local - local[j]) <= NEIGHBOURS * width
    cost0 = varpro.objective(sub, proj)
    step = 1j * start * abs(local[j].real)
    two = np.append(local, local[j] + step)
    two[j] = local[j] - step
    fit = varpro.levenberg_marquardt(sub, two, max_iter=max_iter, free=np.append(near, True))
    gain = 2.0 * (cost0 - fit.cost)
    return float(gain) if np.isfinite(gain) else float("nan")
