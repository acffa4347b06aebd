"""Array core of the joint maximum-likelihood refinement (plain arrays, no xarray).

:func:`refine_arrays` fits every eigenvalue and residue to every FRF at once by variable
projection (:mod:`ami_xr.core.varpro`), keeps each mode inside a region around its AMI value
(freezing it there otherwise), checks the model order by likelihood-ratio tests (drops
insignificant modes, adds modes AMI missed) and returns a :class:`RefineResult`. The labeled
wrapper is :func:`ami_xr.refine`; the method is described in :mod:`ami_xr.ami.refine`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np

from ami_xr.core import grouped, varpro
from ami_xr.core.matching import match_by_distance
from ami_xr.core.modal import modal_std, mode_vectors
from ami_xr.core.model import RESIDUAL_TERMS
from ami_xr.core.order import State, fit_modes, is_exact, order_tests, set_stage, well_posed
from ami_xr.kernels.modal_basis import model_columns

# Status of each refined mode, decided here, where it is known: STATUS_FALLBACK only for a mode
# whose eigenvalue is still its AMI value (frozen there by the first fit, or nothing could be
# fitted); a mode frozen later, at a value an earlier stage refined, is STATUS_OK.
STATUS_OK, STATUS_NOT_CONVERGED, STATUS_FALLBACK = 0, 1, 2


class RefineOptions(Protocol):
    """The settings :func:`refine_arrays` reads: the fields of
    :class:`ami_xr.ami.settings.RefineSettings` (read by attribute, so this array core does not
    import the labeled layer)."""

    max_iter: int
    tol: float
    max_shift: float
    add_modes: int
    add_pfa: float
    drop_modes: bool


class RefineModel(NamedTuple):
    """What the data say about the model: the basis (``dt = 0``: continuous; else the discrete
    basis of ``n_samples``), the residual terms (resolved) and their kind (0 receptance, 1
    mobility, 2 accelerance), the drive point's row (None: no drive point) and the decay rate
    (1/s) of an exponential window already corrected in the starting eigenvalues;
    ``line_noise``: the noise level of each line relative to the others (L,), from the per-line
    noise model (None: the same on every line), or one such shape per group of FRFs (G, L)
    with ``line_group`` (P,) the group of each FRF (:mod:`ami_xr.core.grouped`: the FRFs of
    each reference of a multi-reference test)."""

    dt: float
    n_samples: int
    residual_terms: tuple[str, ...]
    residual_kind: int
    drive_index: int | None
    decay: float
    line_noise: np.ndarray | None = None
    line_group: np.ndarray | None = None


class Trace(Protocol):
    """Progress counter the labeled layer may pass (:class:`ami_xr.progress.Iterations`)."""

    stage: str
    modes: int

    def append(self, item: object) -> None: ...

    def show(self) -> None: ...


@dataclass
class RefineResult:
    """What :func:`refine_arrays` returns, per output mode (K') and point (P).

    Output modes are the AMI modes that survive, in AMI order, then the added ones.
    """

    lam: np.ndarray  # (K',) complex eigenvalues, rad/s
    eig_std: np.ndarray  # (K',) complex: std(Re) + i std(Im)
    fn_std: np.ndarray  # (K',) Hz
    zeta_std: np.ndarray  # (K',)
    residue: np.ndarray  # (P, K') complex
    residue_std: np.ndarray  # (P, K') sqrt(E|dA|^2)
    mode_vector: np.ndarray  # (P, K') complex, eq. 8
    mode_vector_std: np.ndarray  # (P, K') sqrt(E|dPhi|^2)
    noise_std: np.ndarray  # (P,) complex noise std of one FRF line
    residual_coefficient: np.ndarray  # (P, 2) complex (lower, upper), NaN where not fitted
    status: np.ndarray  # (K',) int8: STATUS_OK, STATUS_NOT_CONVERGED or STATUS_FALLBACK
    origin: np.ndarray  # (K',) int64: AMI mode index of each output mode, -1 when added
    n_iter: np.int64  # Levenberg-Marquardt iterations in all
    n_full_fits: np.int64  # fits on all lines (the local trial fits on a band not counted)
    cost_start: np.float64  # objective at the start
    cost: np.float64  # objective at the optimum
    pair_supported: np.ndarray  # (K',) bool: one of a close pair the order test kept
    merged_fn: np.ndarray  # (K',) Hz of a split duplicate merged into the mode, NaN if none
    capped: np.bool_  # mode additions stopped at add_modes while the residual showed more


def refine_arrays(
    frf: np.ndarray,
    freq: np.ndarray,
    lam0: np.ndarray,
    res0: np.ndarray,
    settings: RefineOptions,
    model: RefineModel,
    trace: Trace | None = None,
) -> RefineResult:
    """Refine on plain arrays: frf (P, L), freq (L,) Hz, lam0 (K,), res0 (P, K).

    ``settings`` are those of :func:`ami_xr.refine` (a ``RefineSettings``), ``model`` what the
    data say (:class:`RefineModel`); ``trace`` counts the iterations and names the stage for a
    progress bar (None: nothing reported).
    """
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    n_point = frf.shape[0]
    decay = model.decay
    omega = 2.0 * np.pi * np.asarray(freq, dtype=np.float64)
    base = varpro.make_problem(
        frf,
        omega,
        model.dt,
        model.n_samples,
        model.residual_terms,
        nyquist=np.pi / model.dt if model.dt else None,
        residual_kind=model.residual_kind,
    )
    shapes, index = _noise_groups(model, n_point)
    # the order tests need one basis: they run on one shape for all FRFs (the median)
    common = model.line_noise if shapes is None else _common_shape(shapes, index)
    prob = base if common is None else grouped.whitened(base, common)
    # An exponential window multiplies exp(lam t) by exp(-decay t): data poles are lam - decay.
    lam0 = np.asarray(lam0, dtype=np.complex128)
    min_width = 2.0 * (omega[1] - omega[0]) if omega.size > 1 else 0.0
    opts = dict(
        decay=decay,
        max_iter=settings.max_iter,
        tol=settings.tol,
        max_shift=settings.max_shift,
        min_width=min_width,
        trace=trace,
    )
    set_stage(trace, "fit")
    keep = well_posed(prob, lam0 - decay)  # coincident poles cannot all be fitted
    fit, free, n_iter, start_cost = fit_modes(prob, lam0[keep] - decay, lam0[keep], **opts)
    # the first fit starts at AMI's values: a mode frozen there is a fallback
    origin = np.flatnonzero(keep)
    state = State(fit, free, lam0[keep], res0[:, keep], origin, n_iter, at_ami=~free)
    state.changed = not keep.all()
    order_tests(prob, state, settings, opts, n_point, chi2, min_width)
    n_ami = state.modes.origin.size  # AMI modes kept (the added ones follow them)
    if state.changed and np.isfinite(state.fit.cost):  # polish the new model (frozen stay so)
        set_stage(trace, "polish")
        fit, free = state.fit, state.modes.free
        ref = np.where(free, state.modes.lam0, fit.lam + decay)
        # the polish has its own budget: the order tests' trial fits have theirs
        polish = fit_modes(prob, fit.lam, ref, free=free, **opts)
        state.n_iter += polish[2]
        if polish[0].cost <= fit.cost:
            # a mode the polish froze stays at its start: at AMI's value only if it was there
            state.fit, state.modes.free = polish[0], free & polish[1]
            state.modes.at_ami = state.modes.at_ami & ~polish[1]
    groups = None
    if shapes is not None and state.fit.proj.ok and np.isfinite(state.fit.cost):
        set_stage(trace, "noise per group")
        groups = grouped.split(base, shapes, index)
        start_cost = _grouped_fit(groups, state, lam0[keep] - decay, settings, min_width, trace)
        prob = dataclasses.replace(prob, y=grouped.stitched(groups, n_point, groups.fit[1])[0])
    return _result(prob, state, n_ami, start_cost, model.drive_index, decay, min_width, groups)


def _noise_groups(model: RefineModel, n_point: int):
    """The line shapes (G, L) and the group of each FRF (P,) when the FRFs come in two groups or
    more with a shape each; ``(None, None)`` otherwise."""
    if model.line_noise is None or model.line_group is None:
        return None, None
    shapes = np.atleast_2d(np.asarray(model.line_noise, dtype=np.float64))
    index = np.asarray(model.line_group, dtype=np.int64)
    if index.shape != (n_point,) or index.min() < 0 or index.max() >= shapes.shape[0]:
        raise ValueError(f"line_group: expected {n_point} indices into {shapes.shape[0]} shapes")
    if np.unique(index).size < 2:
        return None, None
    return shapes, index


def _common_shape(shapes: np.ndarray, index: np.ndarray) -> np.ndarray:
    """One line shape for all FRFs (median over the FRFs of their group's shape, median 1)."""
    shape = np.median(shapes[index], axis=0)
    return shape / np.median(shape)


def _grouped_fit(groups, state: State, start, settings, min_width, trace) -> float:
    """The eigenvalues of ``state`` polished with each group's line shape
    (:func:`ami_xr.core.grouped.fit`); a polish that takes a mode farther than ``max_shift``
    half-power bandwidths is not kept (the fit of the common shape stays). Stores the fit in
    ``groups.fit`` (as ``(lam, projections)``) and ``state.fit``; returns the objective at the
    starting eigenvalues ``start`` (the data's poles of the first fit's start)."""
    fit = state.fit
    free = state.modes.free
    got = grouped.fit(groups, fit.lam, free, max_iter=settings.max_iter, tol=settings.tol)
    state.n_iter += got.n_iter
    if trace is not None:
        trace.append(got.n_iter)
    width = np.maximum(2.0 * np.abs(fit.lam.real), min_width)
    moved = np.abs(got.lam - fit.lam) > settings.max_shift * width
    if not np.all(np.isfinite(got.lam)) or moved.any():
        lam, converged = fit.lam, fit.converged
        projections, cost = grouped.project(groups, lam)
    else:
        lam, converged, projections, cost = got.lam, got.converged, got.projections, got.cost
    rss = grouped.stitched(groups, state.fit.proj.rss.size, projections)[1]
    coef = np.empty((rss.size, projections[0].coef.shape[1]))
    for r, proj in zip(groups.rows, projections, strict=True):
        coef[r] = proj.coef
    ok = all(p.ok for p in projections)
    proj = dataclasses.replace(projections[0], lam=lam, coef=coef, rss=rss, ok=ok)
    state.fit = dataclasses.replace(
        fit, lam=lam, proj=proj, cost=cost, converged=converged, mode_step=None
    )
    groups.fit[:] = [lam, projections]
    return grouped.project(groups, start)[1]


def _result(
    prob, state: State, n_ami: int, start_cost, drive_index, decay, min_width, groups=None
) -> RefineResult:
    """Statuses, standard errors, mode vectors and residual terms of the final fit, with the
    output modes matched to their AMI modes (``groups``: the FRFs' groups of
    :func:`_grouped_fit`, whose Fisher information gives the standard errors)."""
    fit, modes = state.fit, state.modes
    free, lam0 = modes.free, modes.lam0
    n_point = prob.n_points
    residual_terms = prob.residual_terms
    n_mode = lam0.size
    res0 = np.concatenate([modes.res0, np.full((n_point, n_mode - n_ami), np.nan + 0j)], axis=1)
    origin = np.concatenate([modes.origin, np.full(n_mode - n_ami, -1)])
    supported, merged_fn = modes.supported, modes.merged_fn
    status = np.full(n_mode, STATUS_OK, dtype=np.int8)
    added = np.arange(n_mode) >= n_ami
    # an exact fit (noise-free data, rounding-level residual) is at its optimum whatever the
    # step test said: Levenberg-Marquardt rejects steps there against a noise level estimated
    # from a residual near zero (the noise-free ring of benchmark_mimo.py ended not converged)
    if not fit.converged and not is_exact(prob, fit):
        # flag the modes still moving (a mode wandering in noise must not flag the others)
        moving = fit.mode_step > 1e-4 if fit.mode_step is not None else np.ones(n_mode, bool)
        # (a frozen mode is not moving: it is a fallback or sits at a value refined before)
        status[free & (moving if moving[free].any() else True)] = STATUS_NOT_CONVERGED
    status[modes.at_ami] = STATUS_FALLBACK  # frozen at a refined value: not a fallback
    proj = fit.proj
    lam = fit.lam + decay
    n_coef = 2 * n_mode + 2 * len(residual_terms)
    if proj.ok:
        dof = max(prob.n_rows - n_coef - 2.0 * free.sum() / max(n_point, 1), 1.0)
        noise_var = np.maximum(proj.rss, 1e-300) / dof
        if groups is None:
            cov = varpro.covariance(prob, proj, noise_var, drive_index, lam_shift=decay)
        else:
            cov = grouped.covariance(groups, groups.fit[1], noise_var, drive_index, decay)
        residue = cov.residue
        cov_theta = cov.cov_theta
        res_std = np.sqrt(np.maximum(cov.residue_var, 0.0))
        coef = proj.coef
    else:  # nothing could be fitted: AMI values, no standard errors
        noise_var = np.full(n_point, np.nan)
        residue = np.array(res0, dtype=np.complex128)
        cov_theta = np.full((2 * n_mode, 2 * n_mode), np.nan)
        res_std = np.full((n_point, n_mode), np.nan)
        coef = np.full((n_point, n_coef), np.nan)
        status[:] = STATUS_FALLBACK
        cov = None
    # Frozen modes keep AMI's eigenvalue; their residues are the projection at that eigenvalue
    # (the least-squares residues given the other modes), unless nothing could be fitted.
    eig_std, fn_std, zeta_std = modal_std(lam, cov_theta)
    if cov is not None and cov.mode_vector is not None:
        mode_vector = cov.mode_vector
        mv_std = np.sqrt(np.maximum(cov.mode_vector_var, 0.0))
    else:
        mode_vector = mode_vectors(residue, lam, drive_index)
        mv_std = np.full((n_point, n_mode), np.nan)
    res_terms = np.full((n_point, 2), np.nan + 0j)  # (lower, upper)
    for r, term in enumerate(residual_terms):
        value = coef[:, 2 * n_mode + 2 * r] + 1j * coef[:, 2 * n_mode + 2 * r + 1]
        res_terms[:, RESIDUAL_TERMS.index(term)] = value
    # per-line complex noise std (E|e|^2 = 2 s^2 for the two real components)
    noise_std = np.sqrt(2.0 * noise_var)
    # Output mode c is the refined mode matched to AMI mode c (close modes may swap in the fit).
    if np.all(np.isfinite(lam)):
        width = np.maximum(2.0 * np.abs(lam0.real), min_width)
        order = np.argsort(match_by_distance(lam, lam0, width))
        lam, eig_std, fn_std, zeta_std, status, added, origin, supported, merged_fn = (
            a[order]
            for a in (lam, eig_std, fn_std, zeta_std, status, added, origin, supported, merged_fn)
        )
        residue, res_std, mode_vector, mv_std = (
            a[:, order] for a in (residue, res_std, mode_vector, mv_std)
        )
    return RefineResult(
        lam=lam,
        eig_std=eig_std,
        fn_std=fn_std,
        zeta_std=zeta_std,
        residue=residue,
        residue_std=res_std,
        mode_vector=mode_vector,
        mode_vector_std=mv_std,
        noise_std=noise_std,
        residual_coefficient=res_terms,
        status=status,
        origin=origin,
        n_iter=np.int64(state.n_iter),
        n_full_fits=np.int64(prob.n_fits),
        cost_start=np.float64(start_cost),
        cost=np.float64(fit.cost),
        pair_supported=supported,
        merged_fn=merged_fn,
        capped=np.bool_(state.capped),
    )


def synthesize(
    omega: np.ndarray,
    mu: np.ndarray,
    residue: np.ndarray,
    residual_coefficient: np.ndarray,
    residual_terms: tuple[str, ...],
    residual_kind: int,
    dt: float,
    n_samples: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The refined model on the lines ``omega``: ``(synth (P, L), columns (L, 2K + 2R))``.

    ``mu`` (K,) are the data's poles (eigenvalues minus any window decay), ``residue`` (P, K),
    ``residual_coefficient`` (P, 2) as in :class:`RefineResult`. The columns are those of
    :func:`ami_xr.kernels.modal_basis.model_columns` (the residue of mode ``k`` multiplies columns
    ``2k`` and ``2k + 1``).
    """
    cols, _ = model_columns(omega, mu, dt, n_samples, residual_terms, residual_kind)
    n_mode = mu.size
    coef = np.zeros((residue.shape[0], cols.shape[1]))
    coef[:, 0 : 2 * n_mode : 2] = residue.real
    coef[:, 1 : 2 * n_mode : 2] = residue.imag
    for r, term in enumerate(residual_terms):
        value = residual_coefficient[:, RESIDUAL_TERMS.index(term)]
        coef[:, 2 * n_mode + 2 * r] = value.real
        coef[:, 2 * n_mode + 2 * r + 1] = value.imag
    return coef @ cols.T, cols


def contribution_peaks(cols: np.ndarray, residue: np.ndarray) -> np.ndarray:
    """Peak ``|contribution|`` of each mode (K,) for one point's residues ``residue`` (K,), on
    the model columns ``cols`` of :func:`synthesize`."""
    n_mode = residue.size
    contribution = (
        cols[:, 0 : 2 * n_mode : 2] * residue.real + cols[:, 1 : 2 * n_mode : 2] * residue.imag
    )
    return np.max(np.abs(contribution), axis=0)
