"""Isolation Phase (eq. 7), the model-order check, and matching per-FRF estimates into modes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import xarray as xr

from ami_xr import interrupt, names
from ami_xr.ami import chunked as ch
from ami_xr.ami import common as c
from ami_xr.ami import subtract as sub_phase
from ami_xr.ami.settings import IsolateSettings, SubtractSettings, from_attrs, parameters, to_attrs
from ami_xr.caller import warn
from ami_xr.core import flags
from ami_xr.core.matching import gather, match_modes, n_labels, weighted_average
from ami_xr.core.model import resolve_model
from ami_xr.errors import CapWarning, IdentificationError, NoModesWarning
from ami_xr.kernels import isolate as ki
from ami_xr.kernels import modal_basis as kb
from ami_xr.kernels import noise as kn

METHODS = (names.METHOD_SIMO, names.METHOD_PER_FRF)
WEIGHTINGS = (names.WEIGHTING_SNR, names.WEIGHTING_MEAN)


# Outputs of the per-FRF isolation: IsolateResult field -> (core dims, dtype). The apply_ufunc
# call and the unpacking of its results both follow this table, so no output is matched by
# position.
_OUTPUTS = {
    "lam": ([names.SLOT], np.complex128),
    "res": ([names.SLOT], np.complex128),
    "n_modes": ([], np.int64),
    "iterations": ([], np.int64),
    "converged": ([], np.bool_),
}


def kernel_params(sub: SubtractSettings, settings: IsolateSettings) -> ki.IsolateParams:
    """The kernel's record of the subtraction's settings (read from the Dataset) and the
    isolation's (checked) settings."""
    paper = settings.method == names.METHOD_PER_FRF
    return ki.IsolateParams(
        **sub_phase.kernel_params(sub)._asdict(),  # the subtraction's kernel record, as it ran
        tol=settings.tol,
        max_iter=settings.max_iter,
        reweight=settings.snr_weighting,
        # the paper's per-FRF isolation: its plain sweeps, stopped on the relative change alone
        se_fraction=0.0 if paper else ki.STOP_FRACTION,
        paper_sweeps=paper,
    )


def _isolate_block(g, lam0, res0, n0, sigma, *, omega, dt, n_samples, params):
    """Per-FRF isolation of FRFs ``g`` (..., F) from the subtraction's candidates ``lam0``,
    ``res0`` (..., S), counts ``n0`` and noise floors ``sigma`` (...): the fields of
    ``_OUTPUTS`` in its order."""
    shape = g.shape[:-1]
    n_c = lam0.shape[-1]
    rows = (
        np.ascontiguousarray(g.reshape(-1, g.shape[-1]), dtype=np.complex128),
        lam0.reshape(-1, n_c),
        res0.reshape(-1, n_c),
        n0.reshape(-1).astype(np.int64),
        sigma.reshape(-1).astype(np.float64),
    )

    def kernel(g2, lam2, res2, n2, sigma2):
        return ki.isolate_batch(g2, omega, dt, n_samples, lam2, res2, n2, sigma2, params)

    out = sub_phase.by_pieces(kernel, rows)
    return tuple(
        getattr(out, name).reshape(shape + getattr(out, name).shape[1:]) for name in _OUTPUTS
    )


class Candidates(NamedTuple):
    """The subtraction's candidates the isolation starts from (arrays, point first)."""

    lam: np.ndarray  # (P, S) complex, NaN-padded
    res: np.ndarray  # (P, S) complex
    n_modes: np.ndarray  # (P,) int
    sigma: np.ndarray  # (P,) noise floor per FRF


def candidates_of(ds: xr.Dataset) -> Candidates:
    """The :class:`Candidates` in the output of :func:`ami_xr.subtract` ``ds``."""
    pc = (names.POINT, names.CANDIDATE)
    return Candidates(
        lam=np.asarray(ds[names.SUB_EIGENVALUE].transpose(*pc).values),
        res=np.asarray(ds[names.SUB_RESIDUE].transpose(*pc).values),
        n_modes=np.asarray(ds[names.SUB_N_MODES].transpose(names.POINT).values),
        sigma=np.asarray(ds[names.SUB_NOISE_FLOOR].transpose(names.POINT).values, dtype=float),
    )


@dataclass
class Isolated:
    """What either isolation method finds: K modes, P points."""

    eig: np.ndarray  # (K,) complex eigenvalues, by increasing natural frequency
    spread: np.ndarray  # (K,) complex std(Re) + i std(Im) of the per-point estimates
    detected: np.ndarray  # (P, K) bool
    point_lam: np.ndarray  # (P, K) complex per-point estimates, NaN where not detected
    point_snr: np.ndarray  # (P, K) peak |contribution| / noise floor
    iterations: np.ndarray  # (P,) int
    converged: np.ndarray  # (P,) bool
    n_modes: int


def isolate_variables(res: Isolated) -> dict:
    """The isolation's output variables (``xarray.Variable`` by name, plus the ``mode``
    coordinate 1..K) from its result ``res``."""
    eig, n_modes = np.asarray(res.eig, np.complex128), res.n_modes
    wn = np.abs(eig)
    m, pm = (names.MODE,), (names.POINT, names.MODE)
    angular = {names.ATTR_UNITS: names.ANGULAR_UNITS}
    return {
        names.EIGENVALUE: xr.Variable(m, eig, angular),
        names.NATURAL_FREQUENCY: xr.Variable(
            m, wn / (2 * np.pi), {names.ATTR_UNITS: names.FREQUENCY_UNITS}
        ),
        names.DAMPING_RATIO: xr.Variable(
            m, -np.real(eig) / wn if n_modes else wn, {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}
        ),
        names.EIGENVALUE_SPREAD: xr.Variable(
            m,
            np.asarray(res.spread, np.complex128),
            {**angular, names.ATTR_LONG_NAME: "std(Re) + i std(Im) of the per-FRF estimates"},
        ),
        names.DETECTED: xr.Variable(pm, np.asarray(res.detected, bool)),
        names.POINT_EIGENVALUE: xr.Variable(pm, np.asarray(res.point_lam, np.complex128), angular),
        names.POINT_SNR: xr.Variable(
            pm,
            np.asarray(res.point_snr, float),
            {names.ATTR_LONG_NAME: "peak |contribution| / noise floor"},
        ),
        names.ISO_ITERATIONS: xr.Variable((names.POINT,), res.iterations),
        names.ISO_CONVERGED: xr.Variable((names.POINT,), res.converged),
        names.MODE: xr.Variable(m, np.arange(1, n_modes + 1)),
    }


def _with_modes(ds: xr.Dataset, res: Isolated) -> xr.Dataset:
    """``ds`` with the isolation's results: modes (dim ``mode``), per-point estimates, and the
    convergence per point (earlier isolation and global-fit results dropped)."""
    new = isolate_variables(res)
    out = c.drop_results(ds, (c.ISOLATE_VARS, c.GLOBAL_VARS))
    return out.assign_coords({names.MODE: new.pop(names.MODE)}).assign(new)


def _per_frf_rows(frf: xr.DataArray, cand: Candidates, omega, data_model, params):
    """The per-FRF kernel on every FRF: an ``IsolateResult`` of arrays (point first); a lazy
    FRF chunk by chunk of points (one ``apply_ufunc``)."""
    kw = dict(omega=omega, dt=data_model.dt, n_samples=data_model.n_samples, params=params)
    if not ch.is_lazy(frf):
        g = np.asarray(frf.transpose(names.POINT, names.FREQUENCY).values)
        out = _isolate_block(g, cand.lam, cand.res, cand.n_modes, cand.sigma, **kw)
        return ki.IsolateResult(**dict(zip(_OUTPUTS, out, strict=True)))
    pc, p = (names.POINT, names.CANDIDATE), (names.POINT,)
    outs = xr.apply_ufunc(
        _isolate_block,
        frf.copy(deep=False),  # older xarray clears the input's coordinate attrs in place
        xr.DataArray(cand.lam, dims=pc),
        xr.DataArray(cand.res, dims=pc),
        xr.DataArray(cand.n_modes, dims=p),
        xr.DataArray(cand.sigma, dims=p),
        kwargs=kw,
        input_core_dims=[[names.FREQUENCY], [names.CANDIDATE], [names.CANDIDATE], [], []],
        output_core_dims=[dims for dims, _ in _OUTPUTS.values()],
        dask="parallelized",
        output_dtypes=[dtype for _, dtype in _OUTPUTS.values()],
        dask_gufunc_kwargs={"output_sizes": {names.SLOT: params.max_modes}},
        keep_attrs=False,
    )
    return ki.IsolateResult(
        **{
            name: o.transpose(names.POINT, ...).values
            for name, o in zip(_OUTPUTS, outs, strict=True)
        }
    )


def _isolate_per_frf(frf, cand: Candidates, omega, data_model, sub, settings) -> Isolated:
    """The paper's isolation: each FRF on its own, then the estimates matched into modes and
    averaged (plain or ``snr^2``-weighted mean)."""
    dt, n_samples = data_model.dt, data_model.n_samples
    r = _per_frf_rows(frf, cand, omega, data_model, kernel_params(sub, settings))
    snr_p = kb.contribution_peaks(omega, dt, n_samples, r.lam, r.res) / cand.sigma[:, None]
    label = match_modes(r.lam, snr_p, settings.match_tol)
    n_modes = n_labels(label)
    point_lam = gather(r.lam, label, n_modes)
    point_snr = gather(snr_p + 0j, label, n_modes).real
    weight = (
        np.ones_like(point_snr)
        if settings.weighting == names.WEIGHTING_MEAN
        else np.nan_to_num(point_snr) ** 2
    )
    eig, spread = weighted_average(point_lam, weight)
    return Isolated(
        eig=eig,
        spread=spread,
        detected=np.isfinite(point_lam),
        point_lam=point_lam,
        point_snr=point_snr,
        iterations=np.asarray(r.iterations, dtype=np.int64),
        converged=np.asarray(r.converged, dtype=bool),
        n_modes=n_modes,
    )


def _checkpoint() -> None:
    interrupt.checkpoint()  # looked up at each call (a test may replace it)


def _isolate_simo_modes(frf, cand: Candidates, omega, data_model, sub, settings) -> Isolated:
    """Global SIMO isolation: the subtraction candidates matched into starting modes, each
    single-mode fit shared by all FRFs; per-point estimates where the mode is detected."""
    dt, n_samples = data_model.dt, data_model.n_samples
    sigma = cand.sigma
    t1 = kn.peak_threshold(omega.size, sub.pfa)
    # the SIMO kernel fits all FRFs jointly in memory: a lazy FRF is loaded once, here
    g = ch.loaded(frf, "isolate").transpose(names.POINT, names.FREQUENCY).values
    g = np.ascontiguousarray(g, dtype=np.complex128)
    n_p = g.shape[0]
    lam_c, res_c = np.asarray(cand.lam), np.asarray(cand.res)
    snr_c = (
        kb.contribution_peaks(
            omega, dt, n_samples, np.ascontiguousarray(lam_c), np.ascontiguousarray(res_c)
        )
        / sigma[:, None]
    )
    label = match_modes(lam_c, snr_c, settings.match_tol)
    n0 = n_labels(label)
    start = gather(lam_c, label, n0)
    w0 = np.where(np.isfinite(start), np.nan_to_num(gather(snr_c + 0j, label, n0).real) ** 2, 0.0)
    lam0, _ = weighted_average(start, w0)
    params = kernel_params(sub, settings)
    # the kernel returns between restarts to a checkpoint: a held Ctrl-C waits for one piece
    r = ki.isolate_simo(
        g, omega, dt, n_samples, lam0, min(n0, sub.max_modes), sigma, params, between=_checkpoint
    )
    order = np.argsort(np.abs(r.lam[: r.n_modes]))
    eig = r.lam[: r.n_modes][order]
    res_m = np.ascontiguousarray(r.res[:, : r.n_modes][:, order])
    peaks = kb.contribution_peaks(omega, dt, n_samples, eig[None, :], res_m)
    point_snr = peaks / sigma[:, None]
    detected = point_snr**2 >= t1
    est = ki.point_estimates(
        g,
        omega,
        dt,
        n_samples,
        np.ascontiguousarray(eig),
        res_m,
        delta=sub.delta,
        min_points=sub.min_points,
        zeta_max=sub.zeta_max,
    )
    point_lam = np.where(detected, est, np.nan + 0j)
    _, spread = weighted_average(point_lam, np.ones(point_lam.shape))
    return Isolated(
        eig=eig,
        spread=spread,
        detected=detected,
        point_lam=point_lam,
        point_snr=point_snr,
        iterations=np.full(n_p, r.iterations, dtype=np.int64),
        converged=np.full(n_p, r.converged),
        n_modes=r.n_modes,
    )


#: How the warning of an isolation stopped at ``max_iter`` begins.
NOT_CONVERGED = "isolate: not converged"


def isolate(
    ds: xr.Dataset,
    tol: float = IsolateSettings.tol,
    max_iter: int = IsolateSettings.max_iter,
    *,
    method: str = IsolateSettings.method,
    weighting: str = IsolateSettings.weighting,
    match_tol: float = IsolateSettings.match_tol,
    snr_weighting: bool | None = None,
) -> xr.Dataset:
    """Isolation Phase: refine every mode on data with the other modes subtracted (eq. 7).

    Runs on the output of :func:`ami_xr.subtract` (its candidates, noise floors, ``delta``,
    ``pfa``, basis and limits are read from the Dataset, so a reopened file continues exactly).

    Each sweep brings every mode into focus in order of its contribution, fits it on the
    isolated data over its ``delta`` band and updates it; sweeps repeat until the real and
    imaginary parts of every eigenvalue change by less than ``tol`` (relative) or, with
    ``method="simo"``, by less than a tenth of the eigenvalue's own standard error (a change
    the data cannot resolve; a mode cycling between two states takes their mean and keeps its
    band), or ``max_iter`` sweeps (then ``isolation_converged`` is False and a
    ConvergenceWarning is issued; never a hang). Then the paper's model-order check: modes
    closer than ``merge_tol`` half-power bandwidths merge (the stronger stays); a mode whose
    peak contribution is not significant (``|c|^2 / sigma^2 < t`` of the Subtraction Phase) is
    removed; if the subtraction residual of all modes still has a significant peak (the
    statistic of :func:`subtract`, with the residual that eigenvalue errors of size ``tol`` can
    leave added to the noise floor) and a physical mode fits there, it is added; isolation
    restarts after any change. (SIMO: a mode added, lost in the merge and added again is kept at
    its fit and ends the model-order check, so the restarts cannot cycle.)

    Parameters
    ----------
    ds : xarray.Dataset
        Output of :func:`ami_xr.subtract`.
    tol : float
        Relative convergence tolerance on Re and Im of every eigenvalue (1e-4 = 0.01 %).
    max_iter : int
        Cap on isolation sweeps per restart.
    method : {"simo", "per_frf"}
        "per_frf" (the paper): each FRF is isolated on its own, then the estimates are matched
        and averaged. "simo" (Allen & Ginsberg's global SIMO AMI): the subtraction candidates
        are matched into starting modes, and each single-mode fit estimates one eigenvalue from
        the isolated data of all FRFs at once with a residue per FRF (FRFs weighted by their
        noise floor and, with ``snr_weighting``, by the mode's SNR in them).
    weighting : {"snr", "mean"}
        per_frf averaging: plain mean (the paper) or weights ``snr^2`` (peak contribution over
        noise floor, squared: inverse variance).
    match_tol : float
        Largest normalised distance (half-power bandwidths) for two estimates to be one mode.
    snr_weighting : bool, optional
        SIMO only: weight each FRF's rows by the mode's SNR in it (default True).

    Returns
    -------
    xarray.Dataset
        The input plus, on dim ``mode``: ``eigenvalue`` (rad/s), ``natural_frequency`` (Hz),
        ``damping_ratio``, ``eigenvalue_spread`` (std(Re) + i std(Im) across FRFs);
        on (point, mode): ``detected``, ``point_eigenvalue`` (NaN where not detected),
        ``point_snr``; on point: ``isolation_iterations``, ``isolation_converged``.
    """
    c.check_frf(ds, "isolate")
    for v in (names.SUB_EIGENVALUE, names.SUB_RESIDUE, names.SUB_NOISE_FLOOR, names.SUB_N_MODES):
        if v not in ds:
            raise IdentificationError(f"ds: isolate needs {v!r}; run ami_xr.subtract first")
    settings = isolate_settings(tol, max_iter, method, weighting, match_tol, snr_weighting)
    sub = from_attrs(SubtractSettings, ds.attrs)
    data_model = resolve_model(ds.attrs, "auto")
    res = isolate_modes(ds[names.FRF], candidates_of(ds), c.omega_of(ds), data_model, sub, settings)
    out = _with_modes(ds, res)
    isolate_record(res, out.attrs, settings, ch.is_lazy(ds[names.FRF]))
    warn_isolation(res, ds[names.POINT].values, settings)
    return c.finish(out, "ami_xr.isolate", "isolate", parameters(settings))


def isolate_record(res: Isolated, attrs: dict, settings: IsolateSettings, lazy: bool) -> None:
    """The attributes the isolation records in ``attrs``: its settings, a lazy FRF loaded."""
    to_attrs(settings, attrs)
    if settings.method == names.METHOD_SIMO and lazy:
        ch.note_loaded(attrs, "isolate")


def isolate_settings(
    tol, max_iter, method, weighting, match_tol=IsolateSettings.match_tol, snr_weighting=None
) -> IsolateSettings:
    """The checked settings of :func:`isolate` (an error naming the first bad one)."""
    tol = c.check_positive(tol, "tol")
    max_iter = c.check_positive_int(max_iter, "max_iter")
    c.check_choice(method, "method", METHODS)
    c.check_choice(weighting, "weighting", WEIGHTINGS)
    match_tol = c.check_positive(match_tol, "match_tol")
    snr_weighting = IsolateSettings.snr_weighting if snr_weighting is None else bool(snr_weighting)
    return IsolateSettings(
        tol=tol,
        max_iter=max_iter,
        method=method,
        weighting=weighting,
        match_tol=match_tol,
        snr_weighting=snr_weighting,
    )


def isolate_modes(frf, cand: Candidates, omega, data_model, sub, settings) -> Isolated:
    """The isolation (``settings.method``) of the FRFs ``frf`` (a DataArray (point,
    frequency), in memory or lazy) from the subtraction's candidates ``cand``: the core of
    :func:`isolate`, which :func:`ami_xr.identify` calls on its arrays."""
    simo = settings.method != names.METHOD_PER_FRF
    return (_isolate_simo_modes if simo else _isolate_per_frf)(
        frf, cand, omega, data_model, sub, settings
    )


def warn_isolation(res: Isolated, points: np.ndarray, settings: IsolateSettings) -> None:
    """The isolation's warnings: stopped at ``max_iter`` somewhere, or no mode."""
    if not np.all(res.converged):
        bad = points[~res.converged].tolist()
        max_iter, tol = settings.max_iter, settings.tol
        message = (
            f"{NOT_CONVERGED} within max_iter={max_iter} sweeps at point(s) {bad} (tol={tol}; "
            f"see {names.ISO_CONVERGED}): the eigenvalues of the modes detected there still "
            "moved between sweeps (often a mode that alternates between two fits, which more "
            f"sweeps do not settle), so they carry {names.FLAG_NOT_CONVERGED}. The refinement "
            "(identify's default, refine=True; not --no-refine or --method paper) re-fits "
            "every mode and replaces these estimates when it converges; on isolate's own "
            "output run ami_xr.global_fit and ami_xr.refine, or loosen tol"
        )
        # at the user's line, also when reached through identify; the pipeline tells it by
        # its status bit (it drops it when a converged refinement re-fitted every mode)
        warn(CapWarning(message, flags.RunStatus.ISOLATE_MAX_ITER), CapWarning)
    if res.n_modes == 0:
        warn("isolate: no mode identified", NoModesWarning)
