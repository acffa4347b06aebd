"""The refinement's last fit with a line shape of the noise per group of FRFs (issue 41).

Variable projection shares one weighted basis among all FRFs, so the noise model of
:func:`ami_xr.core.refine.refine_arrays` is a level per FRF (profiled out) times one shape along
frequency for all of them. FRFs of several references do not share one shape (each force has its
own spectrum and coherence): one shape for all weights every reference's lines by a shape that is
not its own, and the eigenvalues lose the efficiency the multi-reference bound promises.

Here the FRFs come in groups, each with its own line shape: one weighted problem per group
(:mod:`ami_xr.core.varpro`, one basis each), the objective the sum of the groups' (each FRF's level
still profiled out), the eigenvalues shared. :func:`fit` polishes the eigenvalues by
Levenberg-Marquardt on the summed Gauss-Newton model, from the fit of the common shape (the
model-order tests run on that one: their decisions need a shared basis); :func:`covariance`
gives the standard errors from the summed Fisher information.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from ami_xr.core import varpro


class Groups(NamedTuple):
    """Per group: the rows (FRFs) of the full problem and the problem of those rows weighted
    by the group's line shape."""

    rows: list[np.ndarray]
    problems: list[varpro.Problem]
    fit: list  # [eigenvalues, projections] of the last fit kept (set by the caller)


class GroupFit(NamedTuple):
    lam: np.ndarray
    projections: list[varpro.Projection]
    cost: float
    n_iter: int
    converged: bool


def whitened(prob: varpro.Problem, line_noise: np.ndarray) -> varpro.Problem:
    """The problem with every line divided by its relative noise level (data and model alike,
    through the line weights)."""
    w = 1.0 / np.asarray(line_noise, dtype=np.float64)
    y = prob.y * np.concatenate([w, w])[None, :]
    return dataclasses.replace(prob, y=np.ascontiguousarray(y), line_weight=prob.line_weight * w)


def split(prob: varpro.Problem, shapes: np.ndarray, index: np.ndarray) -> Groups:
    """The unweighted problem ``prob`` as one problem per group: the rows ``index == g``
    weighted by ``shapes[g]`` (G, L)."""
    rows, problems = [], []
    for g in range(shapes.shape[0]):
        r = np.flatnonzero(index == g)
        if r.size:
            sub = dataclasses.replace(prob, y=np.ascontiguousarray(prob.y[r]))
            rows.append(r)
            problems.append(whitened(sub, shapes[g]))
    return Groups(rows, problems, [])


def stitched(groups: Groups, n_point: int, projections) -> tuple[np.ndarray, np.ndarray]:
    """The weighted data (P, 2L) and the residual sums of squares (P,) of all FRFs, in the
    full problem's row order."""
    y = np.empty((n_point, groups.problems[0].n_rows))
    rss = np.empty(n_point)
    for r, prob, proj in zip(groups.rows, groups.problems, projections, strict=True):
        y[r], rss[r] = prob.y, proj.rss
    return y, rss


def project(groups: Groups, lam: np.ndarray) -> tuple[list, float]:
    """Each group's projection at the eigenvalues ``lam`` and the summed objective."""
    projections = [varpro.project(p, lam) for p in groups.problems]
    cost = sum(varpro.objective(p, q) for p, q in zip(groups.problems, projections, strict=True))
    return projections, float(cost)


def _normal(groups: Groups, projections) -> tuple[np.ndarray, np.ndarray]:
    """The summed Gauss-Newton Hessian and gradient at each FRF's maximum-likelihood level."""
    h = g = 0.0
    for prob, proj in zip(groups.problems, projections, strict=True):
        hg, gg = varpro.gauss_newton(prob, proj, varpro.ml_weight(prob, proj))
        h, g = h + hg, g + gg
    return h, g


def fit(groups: Groups, lam0, free, *, max_iter: int, tol: float, stat_tol=1e-4) -> GroupFit:
    """Minimise the summed objective over the free eigenvalues (``free`` (K,) bool), from
    ``lam0``; only steps that lower it are taken. Converged as
    :func:`ami_xr.core.varpro.levenberg_marquardt` (relative change below ``tol``, Newton
    decrement below ``stat_tol``, or no decrease left at rounding level)."""
    lam = np.asarray(lam0, np.complex128).copy()
    idx = np.flatnonzero(np.repeat(np.asarray(free, bool), 2))
    projections, cost = project(groups, lam)
    n_iter, mu, converged = 0, 1e-3, idx.size == 0
    while not converged and n_iter < max_iter and np.isfinite(cost):
        n_iter += 1
        h, g = _normal(groups, projections)
        h, g = h[np.ix_(idx, idx)], g[idx]
        d = np.sqrt(np.maximum(np.diag(h), np.finfo(float).tiny))
        hs, gs = h / np.outer(d, d), g / d
        try:
            decrement = float(gs @ np.linalg.solve(hs, gs))
        except np.linalg.LinAlgError:
            decrement = np.inf
        if decrement < stat_tol or decrement < 2e-13 * max(abs(cost), 1.0):
            converged = True
            break
        trial = None
        while mu < 1e12 and trial is None:
            try:
                step = -np.linalg.solve(hs + mu * np.eye(idx.size), gs) / d
            except np.linalg.LinAlgError:
                step = None
            if step is not None:
                theta = np.column_stack([lam.real, lam.imag]).ravel()
                theta[idx] += step
                new = theta[0::2] + 1j * theta[1::2]
                if np.all(new.real < 0):
                    p_new, c_new = project(groups, new)
                    if np.isfinite(c_new) and c_new < cost:
                        trial = (new, p_new, c_new)
                        break
            mu *= 4.0
        if trial is None:  # no step lowers it: the minimum the arithmetic allows
            converged = decrement < 1e-6 * max(sum(p.n_points for p in groups.problems), 1)
            break
        mu = max(mu / 3.0, 1e-9)
        rel = float(np.max(np.abs(trial[0] - lam) / np.abs(lam)))
        lam, projections, cost = trial
        converged = rel < tol
    return GroupFit(lam, projections, cost, n_iter, converged)


def covariance(
    groups: Groups, projections, noise_var: np.ndarray, drive_index, decay: float
) -> varpro.Covariance:
    """:func:`ami_xr.core.varpro.covariance` of all FRFs (rows in the full problem's order):
    the eigenvalues' covariance from the Fisher information summed over the groups, each
    group's residues from its own basis; ``noise_var`` (P,) per FRF in its group's weighted
    units."""
    h = sum(
        varpro.gauss_newton(p, q, 1.0 / noise_var[r])[0]
        for r, p, q in zip(groups.rows, groups.problems, projections, strict=True)
    )
    cov_theta = np.linalg.pinv(h)
    parts = [
        varpro.covariance(p, q, noise_var[r], None, lam_shift=decay, cov_theta=cov_theta)
        for r, p, q in zip(groups.rows, groups.problems, projections, strict=True)
    ]
    n_point = int(sum(r.size for r in groups.rows))

    def gather(field):
        first = getattr(parts[0], field)
        out = np.empty((n_point, *first.shape[1:]), first.dtype)
        for r, part in zip(groups.rows, parts, strict=True):
            out[r] = getattr(part, field)
        return out

    out = dataclasses.replace(
        parts[0],
        residue=gather("residue"),
        residue_var=gather("residue_var"),
        dc_dtheta=gather("dc_dtheta"),
        cov_c_theta=gather("cov_c_theta"),
        residue_cov=gather("residue_cov"),
    )
    if drive_index is None:
        return out
    return varpro.with_mode_vectors(out, projections[0].lam + decay, drive_index)
