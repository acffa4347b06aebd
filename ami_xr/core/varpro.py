"""Variable projection and Levenberg-Marquardt: the optimiser of the joint refinement and the
Cramér-Rao bound (plain arrays, no xarray).

Variable projection: for given eigenvalues the residues of every FRF follow by linear least
squares on a basis that all FRFs share (one QR factorisation per evaluation); the eigenvalues,
shared by all FRFs, follow by Levenberg-Marquardt on the Kaufman Jacobian plus a secant estimate
of the curvature Gauss-Newton leaves out (Dennis-Gay-Welsch / NL2SOL idea). The objective is the
negative log-likelihood of independent Gaussian frequency lines whose variance is unknown per
FRF and profiled out, ``f = sum_j (n / 2) log |r_j|^2``, so each FRF is weighted by its own noise
level ``n / |r_j|^2`` at every iteration (maximum likelihood, not equal weights).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ami_xr.kernels.columns import stacked_columns, stacked_residual_columns
from ami_xr.kernels.modal_basis import line_variable
from ami_xr.kernels.projection import gram, matmul_small, normal_equations, project_points

# |r_j|^2 is floored at (RSS_FLOOR |y_j|)^2 so that noise-free data (residual at rounding
# level) keep a finite objective.
RSS_FLOOR = 1e-14


@dataclass
class Problem:
    """The data and model choices of one refinement, in real-stacked form."""

    y: np.ndarray  # (P, 2L) real-stacked, line-weighted data, one row per point
    omega: np.ndarray  # (L,) rad/s
    line_weight: np.ndarray  # (L,) sqrt weight per line (1/sqrt(2) at DC and Nyquist)
    dt: float | None
    n_samples: int | None
    residual_terms: tuple[str, ...] = ()
    residual_kind: int = 0
    y_norm2: np.ndarray = field(init=False)
    n_fits: int = field(init=False, default=0)  # Levenberg-Marquardt fits run on this problem
    # what every projection shares (the lines' variable, the weighted residual-term columns),
    # made on first use; dataclasses.replace makes a new problem, so they never go stale
    _lines: tuple | None = field(init=False, default=None, repr=False, compare=False)

    def __post_init__(self):
        self.y_norm2 = np.maximum(np.sum(self.y**2, axis=1), np.finfo(float).tiny)

    def lines(self) -> tuple[np.ndarray, float, int, np.ndarray]:
        """``(x, dt, n_samples, fixed)``: the line variable, the model's ``dt`` (0.0:
        continuous) and record length (0: none), the stacked residual-term columns."""
        if self._lines is None:
            dt = float(self.dt) if self.dt else 0.0
            fixed = stacked_residual_columns(
                self.omega, self.residual_terms, self.residual_kind, self.line_weight
            )
            x = line_variable(self.omega, dt)
            self._lines = (x, dt, int(self.n_samples or 0), fixed)
        return self._lines

    @property
    def n_rows(self) -> int:
        return self.y.shape[1]

    @property
    def n_points(self) -> int:
        return self.y.shape[0]


@dataclass
class Projection:
    """Everything the objective, the step and the covariance need at one set of eigenvalues."""

    lam: np.ndarray
    q: np.ndarray  # (2L, p) orthonormal basis of the model columns
    r: np.ndarray  # (p, p) triangular factor
    v: np.ndarray  # (2L, 2K) derivative columns
    coef: np.ndarray  # (P, p) residue (and residual-term) coefficients
    rss: np.ndarray  # (P,) residual sum of squares per point
    v_res: np.ndarray  # (P, 2K): V' r_j
    qtv: np.ndarray  # (p, 2K): Q' V
    vtv: np.ndarray  # (2K, 2K): V' V
    ok: bool


def make_problem(
    frf, omega, dt, n_samples, residual_terms=(), nyquist=None, residual_kind=0
) -> Problem:
    """Real-stack complex FRFs ``frf`` (P, L); DC and Nyquist lines get weight 1/sqrt(2)."""
    w = np.ones(omega.shape[0])
    # A real impulse response gives real DC and Nyquist lines: their noise is all in the real
    # part, with twice the variance of the real part elsewhere.
    w[np.isclose(omega, 0.0, rtol=0.0, atol=1e-12 * max(float(np.max(np.abs(omega))), 1.0))] = (
        2**-0.5
    )
    if nyquist is not None:
        w[np.isclose(omega, nyquist, rtol=1e-9, atol=0.0)] = 2**-0.5
    yc = np.asarray(frf, dtype=np.complex128) * w[None, :]
    y = np.ascontiguousarray(np.concatenate([yc.real, yc.imag], axis=1))
    return Problem(
        y, np.asarray(omega, float), w, dt, n_samples, tuple(residual_terms), int(residual_kind)
    )


def project(prob: Problem, lam: np.ndarray) -> Projection:
    """Residues by linear least squares for eigenvalues ``lam`` (all points at once)."""
    x, dt, n_samples, fixed = prob.lines()
    a, v = stacked_columns(x, lam, dt, n_samples, prob.line_weight, fixed)
    # a non-finite entry makes a column norm or V'V non-finite: checked there, not entry-wise
    q, r, ok = _cholesky_qr2(a)
    vtv = gram(v) if ok else None
    ok = ok and bool(np.all(np.isfinite(vtv)))
    if not ok:
        nan = np.full(1, np.nan)
        return Projection(lam, q, r, v, nan, np.full(prob.n_points, np.inf), nan, nan, nan, False)
    qty, rss, v_res = project_points(prob.y, q, v)
    # Q'V and V'V only: Q'Q is the identity (a Gram matrix of [Q V] cost a third more, and a
    # copy of both)
    coef = _solve_upper(r, qty.T).T
    return Projection(lam, q, r, v, coef, rss, v_res, q.T @ v, vtv, ok)


def _solve_upper(r, b):
    # np.linalg.solve, not scipy's solve_triangular: the latter calls a BLAS-3 kernel whose
    # threads stall on a busy machine, even for an 8 x 8 system.
    return np.linalg.solve(r, b)


def _cholesky_qr2(a):
    """Thin QR of a tall matrix by CholeskyQR2 on unit-norm columns.

    Two Cholesky passes give an orthogonality as good as Householder QR for condition numbers
    up to ~1e7 and need only small Gram matrices and triangular solves (LAPACK's QR of a tall
    matrix is slow when threads are contended). ``ok`` is False for a (numerically) rank
    deficient ``a`` -- coinciding eigenvalues -- where the residues are not unique.
    """
    # the unit-norm scaling folded into the small matrices: the column norms are the Gram
    # matrix's diagonal, and a / scale is never formed (two passes over ``a`` fewer)
    g = gram(a)
    scale = np.sqrt(np.diag(g))
    if np.any(scale == 0) or not np.all(np.isfinite(scale)):
        return a, np.eye(a.shape[1]), False
    try:
        r1 = np.linalg.cholesky(g / np.outer(scale, scale)).T
        q1 = matmul_small(a, np.linalg.inv(r1) / scale[:, None])
        r2 = np.linalg.cholesky(gram(q1)).T
        q = _solve_upper_right(q1, r2)
    except np.linalg.LinAlgError:
        return a, np.eye(a.shape[1]), False
    r = (r2 @ r1) * scale[None, :]
    diag = np.abs(np.diag(r)) / scale
    # q is finite when the columns and both factors are (a non-finite q1 makes its Gram
    # matrix, hence r2, non-finite): the small matrices are checked, not the tall one
    ok = bool(diag.min() > 1e-7) and bool(np.all(np.isfinite(r)))
    return q, r, ok


def _solve_upper_right(a, r):
    """``a @ inv(r)`` for a small upper-triangular ``r``: the explicit inverse of ``r`` is as
    accurate here as a triangular solve and much faster on a tall ``a`` when BLAS threads are
    contended."""
    return matmul_small(a, np.linalg.inv(r))


def objective(prob: Problem, proj: Projection) -> float:
    """Profiled negative log-likelihood ``sum_j (n/2) log |r_j|^2`` (up to a constant)."""
    if not proj.ok:
        return np.inf
    rss = np.maximum(proj.rss, (RSS_FLOOR**2) * prob.y_norm2)
    return 0.5 * prob.n_rows * float(np.sum(np.log(rss)))


def gauss_newton(prob: Problem, proj: Projection, weight: np.ndarray):
    """Normal equations ``(h, g)`` of ``1/2 sum_j w_j |r_j|^2`` in the eigenvalue parameters."""
    n_mode = proj.lam.shape[0]
    s_mat = proj.vtv - proj.qtv.T @ proj.qtv  # V' (I - Q Q') V
    return normal_equations(proj.coef, weight, s_mat, proj.v_res, n_mode)


def ml_weight(prob: Problem, proj: Projection) -> np.ndarray:
    rss = np.maximum(proj.rss, (RSS_FLOOR**2) * prob.y_norm2)
    return prob.n_rows / rss


@dataclass
class FitResult:
    lam: np.ndarray
    proj: Projection
    cost: float
    start_cost: float
    n_iter: int
    converged: bool
    message: str
    bad: np.ndarray | None = None  # modes that failed ``check``
    mode_step: np.ndarray | None = None  # last step of each mode in standard-error units^2


def _theta(lam):
    return np.column_stack([lam.real, lam.imag]).ravel()


def _lam(theta):
    return theta[0::2] + 1j * theta[1::2]


def _secant_update(s_corr: np.ndarray, s_prev: np.ndarray, y_sharp: np.ndarray) -> np.ndarray:
    """PSB update of the secant curvature correction ``s_corr`` after the step ``s_prev``.

    ``y_sharp`` is the gradient change the Gauss-Newton matrix does not explain; the old
    correction is first shrunk as in NL2SOL so that it never overstates the curvature.
    """
    sts = float(s_prev @ s_prev)
    ss = float(s_prev @ s_corr @ s_prev)
    if ss > 0:
        s_corr = s_corr * min(1.0, abs(float(s_prev @ y_sharp)) / ss)
    resid = y_sharp - s_corr @ s_prev
    if sts > 0:
        s_corr = (
            s_corr
            + (np.outer(resid, s_prev) + np.outer(s_prev, resid)) / sts
            - float(resid @ s_prev) * np.outer(s_prev, s_prev) / sts**2
        )
    return s_corr


def _mode_steps(step: np.ndarray, idx: np.ndarray, h_full: np.ndarray) -> np.ndarray:
    """Squared step of each mode measured by its own block of the Fisher information."""
    n_mode = h_full.shape[0] // 2
    full_step = np.zeros(2 * n_mode)
    full_step[idx] = step
    out = np.zeros(n_mode)
    for k in range(n_mode):
        blk = slice(2 * k, 2 * k + 2)
        out[k] = full_step[blk] @ h_full[blk, blk] @ full_step[blk]
    return out


def _scaled_model(h: np.ndarray, g: np.ndarray, s_corr: np.ndarray, previous):
    """The Levenberg-Marquardt model of one iteration, scaled by ``d = sqrt(diag(h))``.

    ``h``, ``g``: Gauss-Newton Hessian and gradient over the free parameters; ``previous``:
    the last accepted step and gradient (None at the first iteration), for the secant update of
    ``s_corr``. Returns the updated ``s_corr``, ``d``, the scaled Gauss-Newton Hessian ``hs``
    and gradient ``gs``, and the scaled model Hessian ``hq`` (with the secant term when that
    keeps it positive definite, else ``hs``)."""
    if previous is not None:
        s_prev, g_prev = previous
        s_corr = _secant_update(s_corr, s_prev, (g - g_prev) - h @ s_prev)
    d = np.sqrt(np.maximum(np.diag(h), np.finfo(float).tiny))
    hs = h / np.outer(d, d)
    gs = g / d
    hq = (h + s_corr) / np.outer(d, d)
    try:
        np.linalg.cholesky(hq + 1e-8 * np.eye(g.size))
    except np.linalg.LinAlgError:
        hq = hs  # the secant term made the model non-convex: plain Gauss-Newton
    return s_corr, d, hs, gs, hq


def _damped_step(prob: Problem, lam: np.ndarray, idx: np.ndarray, model, cost: float, mu, nu):
    """Raise the damping ``mu`` until a step of the scaled ``model = (hq, gs, d)`` lowers the
    objective below ``cost``.

    Returns ``((step, lam_new, proj_new, cost_new) or None, mu, nu)``: None when no step lowers
    it before ``mu`` reaches 1e12; ``mu`` and ``nu`` updated as in Nielsen's rule.
    """
    hq, gs, d = model
    while mu < 1e12:
        try:
            step_s = -np.linalg.solve(hq + mu * np.eye(idx.size), gs)
        except np.linalg.LinAlgError:
            mu *= nu
            nu *= 2.0
            continue
        step = step_s / d
        theta = _theta(lam)
        theta[idx] += step
        lam_new = _lam(theta)
        proj_new = project(prob, lam_new)
        cost_new = objective(prob, proj_new)
        pred = -(gs @ step_s) - 0.5 * step_s @ (hq @ step_s)
        if np.isfinite(cost_new) and cost_new < cost:
            rho = (cost - cost_new) / pred if pred > 0 else 0.0
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            return (step, lam_new, proj_new, cost_new), mu, 2.0
        mu *= nu
        nu *= 2.0
    return None, mu, nu


def levenberg_marquardt(
    prob: Problem,
    lam0: np.ndarray,
    *,
    max_iter: int = 50,
    tol: float = 1e-10,
    free: np.ndarray | None = None,
    trace: list | None = None,
    check=None,
    stat_tol: float = 1e-4,
    patience: int = 3,
) -> FitResult:
    """Minimise :func:`objective` over the eigenvalues, starting at ``lam0``.

    Only steps that lower the objective are taken, so the result is never worse than the start.
    ``free`` (K,) bool marks the eigenvalues that may move (others stay at ``lam0``).
    Converged when every free eigenvalue changes by less than ``tol`` relative to its modulus,
    when the Newton decrement ``g' H^-1 g`` -- the squared length of the next step in units of
    the statistical standard errors, since ``H`` is the Fisher information -- is below
    ``stat_tol`` (a step below 1 % of a standard error changes nothing that matters), or when
    the predicted decrease is at rounding level. ``check(lam)`` (optional) returns a code per
    mode: 0 fine, 1 outside its region, 2 impossible (unstable, merged); the iteration stops with
    ``FitResult.bad`` set as soon as a mode is impossible or has been outside its region for
    ``patience`` accepted steps in a row (a far start may overshoot for a step or two).

    The loop holds the stopping rules; :func:`_scaled_model` builds the scaled quadratic model
    and :func:`_damped_step` finds the damped step that lowers the objective.
    """
    lam = np.asarray(lam0, dtype=np.complex128).copy()
    n_mode = lam.shape[0]
    free = np.ones(n_mode, bool) if free is None else np.asarray(free, bool)
    idx = np.flatnonzero(np.repeat(free, 2))
    proj = project(prob, lam)
    cost = objective(prob, proj)
    start = cost
    if not np.isfinite(cost):
        return FitResult(lam, proj, cost, start, 0, False, "objective not finite at the start")
    if idx.size == 0:
        return FitResult(lam, proj, cost, start, 0, True, "no free eigenvalue")
    mu = 1e-3
    nu = 2.0
    n_iter = 0
    converged = False
    message = "iteration cap reached"
    # Rounding level of the objective: a change below it is not a change.
    cost_eps = 1e-13 * max(abs(cost), prob.n_points)
    outside = np.zeros(n_mode, int)
    mode_step = np.zeros(n_mode)
    # Secant estimate of the curvature Gauss-Newton leaves out (residual times second
    # derivatives; large for weakly excited modes in noise): a PSB update of the difference
    # between the true gradient change and H_GN s, sized as in NL2SOL. Without it convergence
    # is linear there.
    s_corr = np.zeros((idx.size, idx.size))
    previous = None
    while n_iter < max_iter:
        n_iter += 1
        w = ml_weight(prob, proj)
        h_full, g_full = gauss_newton(prob, proj, w)
        g = g_full[idx]
        s_corr, d, hs, gs, hq = _scaled_model(h_full[np.ix_(idx, idx)], g, s_corr, previous)
        try:
            decrement = float(gs @ np.linalg.solve(hs, gs))
        except np.linalg.LinAlgError:
            decrement = np.inf
        if trace is not None:
            trace.append((cost, decrement, mu))
        if decrement < 2 * cost_eps:
            converged = True
            message = "predicted decrease below rounding"
            break
        if decrement < stat_tol:
            converged = True
            message = "step below 1e-2 standard errors"
            break
        trial, mu, nu = _damped_step(prob, lam, idx, (hq, gs, d), cost, mu, nu)
        if trial is None:
            # No descent direction at rounding level: we are at the minimum the arithmetic allows.
            converged = decrement < 1e-6 * max(prob.n_points, 1)
            message = "no further decrease possible" if converged else "step rejected"
            break
        step, lam_new, proj_new, cost_new = trial
        previous = (step, g)
        rel = np.max(np.abs(lam_new - lam)[free] / np.abs(lam[free]))
        mode_step = _mode_steps(step, idx, h_full)
        decrease = cost - cost_new
        lam, proj, cost = lam_new, proj_new, cost_new
        if check is not None:
            code = np.where(free, np.asarray(check(lam), int), 0)
            outside = np.where(code > 0, outside + 1, 0)
            bad = (code == 2) | (outside >= patience)
            if bad.any():
                return FitResult(
                    lam, proj, cost, start, n_iter, False, "mode left its region", bad, mode_step
                )
        if rel < tol or decrease < cost_eps:
            converged = True
            message = "eigenvalue change below tol" if rel < tol else "objective flat"
            break
    return FitResult(lam, proj, cost, start, n_iter, converged, message, None, mode_step)


@dataclass
class Covariance:
    """Gauss-Newton (Fisher) covariances at one set of eigenvalues, from :func:`covariance`."""

    cov_theta: np.ndarray  # (2K, 2K) of (Re lam_1, Im lam_1, Re lam_2, ...)
    residue: np.ndarray  # (P, K) complex residues at the projection
    residue_var: np.ndarray  # (P, K) E|dA|^2
    n_coef: int  # linear coefficients per point (2K + 2R)
    dc_dtheta: np.ndarray  # (P, p, 2K) derivative of the coefficients by the eigenvalues
    cov_c_theta: np.ndarray  # (P, p, 2K) cov(coefficients, eigenvalues)
    cov_lin: np.ndarray  # (p, p) (R'R)^-1
    residue_cov: np.ndarray | None = None  # (P, K, 2, 2) of (Re A_jk, Im A_jk)
    mode_vector: np.ndarray | None = None  # (P, K) eq. 8, with a drive point only
    mode_vector_var: np.ndarray | None = None  # (P, K) E|dPhi|^2, with a drive point only


def covariance(
    prob: Problem,
    proj: Projection,
    noise_var: np.ndarray,
    drive_index: int | None,
    *,
    quantity_power: int = 0,
    lam_shift: float = 0.0,
    cov_theta: np.ndarray | None = None,
) -> Covariance:
    """Covariances of eigenvalues, residues and mode vectors at ``proj`` (Gauss-Newton / Fisher).

    ``noise_var`` (P,) is the noise variance of one real component of one (weighted) line. With
    the true parameters and the true variance this is the Cramér-Rao bound. The basis poles are
    ``proj.lam``; the physical eigenvalues used for the mode vectors are ``proj.lam + lam_shift``
    (an exponential window of decay rate ``b`` shifts every pole by ``-b``).

    ``cov_theta`` (2K, 2K): the eigenvalues' covariance when they are shared with FRFs outside
    ``prob`` (:mod:`ami_xr.core.grouped`: a problem per group of FRFs with its own line
    weights); default the inverse of this problem's Fisher information.

    Returns a :class:`Covariance`; its mode-vector fields are None without a drive point.
    """
    lam = proj.lam
    n_mode = lam.shape[0]
    n_point = proj.coef.shape[0]
    if cov_theta is None:
        cov_theta = np.linalg.pinv(gauss_newton(prob, proj, 1.0 / noise_var)[0])
    # c_j = R^-1 Q' (y_j - V M_j dtheta) -> dc_j/dtheta = -G0 M_j with G0 = R^-1 Q' V
    g0 = np.linalg.solve(proj.r, proj.qtv)  # (p, 2K)
    rinv = np.linalg.inv(proj.r)
    cov_lin = rinv @ rinv.T  # (R'R)^-1
    a1 = proj.coef[:, 0 : 2 * n_mode : 2]
    a2 = proj.coef[:, 1 : 2 * n_mode : 2]
    m = np.zeros((n_point, 2 * n_mode, 2 * n_mode))
    for k in range(n_mode):
        m[:, 2 * k, 2 * k] = a1[:, k]
        m[:, 2 * k, 2 * k + 1] = -a2[:, k]
        m[:, 2 * k + 1, 2 * k] = a2[:, k]
        m[:, 2 * k + 1, 2 * k + 1] = a1[:, k]
    hj = -np.einsum("pa,jab->jpb", g0, m)  # (P, p, 2K)
    hc = hj @ cov_theta  # cov(c_j, theta): (P, p, 2K)
    p = proj.coef.shape[1]
    residue = a1 + 1j * a2
    # Var of the residue A_jk: blocks (2k, 2k+1) of cov(c_j) = s_j^2 (R'R)^-1 + H_j C H_j'
    res_var = np.empty((n_point, n_mode))
    cov_cc_blocks = np.empty((n_point, n_mode, 2, 2))
    for k in range(n_mode):
        sl = slice(2 * k, 2 * k + 2)
        blk = noise_var[:, None, None] * cov_lin[None, sl, sl] + np.einsum(
            "jab,jcb->jac", hc[:, sl, :], hj[:, sl, :]
        )
        cov_cc_blocks[:, k] = blk
        res_var[:, k] = blk[:, 0, 0] + blk[:, 1, 1]
    out = Covariance(
        cov_theta=cov_theta,
        residue=residue,
        residue_var=res_var,
        n_coef=p,
        dc_dtheta=hj,
        cov_c_theta=hc,
        cov_lin=cov_lin,
        residue_cov=cov_cc_blocks,
    )
    if drive_index is None:
        return out
    return with_mode_vectors(out, lam + lam_shift, drive_index, quantity_power)


def with_mode_vectors(
    out: Covariance, lam: np.ndarray, drive_index: int, quantity_power: int = 0
) -> Covariance:
    """``out`` with the mode vectors (eq. 8 at the drive point ``drive_index``) of its residues
    and their variances, from its per-point blocks (``residue_cov``, ``dc_dtheta``,
    ``cov_c_theta``) and ``cov_theta``; ``lam`` the physical eigenvalues."""
    residue, cov_theta = out.residue, out.cov_theta
    hj, hc, cov_cc_blocks = out.dc_dtheta, out.cov_c_theta, out.residue_cov
    n_point, n_mode = residue.shape
    # Mode vectors (eq. 8) from displacement residues A_disp = A / lam^q.
    P_ = drive_index
    lam_b = lam[None, :]
    a_disp = residue / lam_b**quantity_power
    phi_p = np.sqrt(a_disp[P_] / lam)
    phi = a_disp / (lam_b * phi_p[None, :])
    phi[P_] = phi_p
    # Complex derivatives of Phi_jk with respect to A_jk, A_Pk and lam_k (holomorphic), where
    # a residue A (not A_disp) is the variable: A_disp = A lam^-q.
    with np.errstate(divide="ignore", invalid="ignore"):
        d_aj = phi / residue
        d_ap = -0.5 * phi / residue[P_][None, :]
        d_lam = -0.5 * (1 + quantity_power) * phi / lam_b
        # drive point: Phi_P = sqrt(A_P lam^-q / lam)
        d_aj[P_] = 0.0
        d_ap[P_] = 0.5 * phi_p / residue[P_]
        d_lam[P_] = -0.5 * (1 + quantity_power) * phi_p / lam

    # Linearise Phi_jk in the real variables (theta_k, c_jk, c_Pk): for a holomorphic
    # derivative f of z = x + i y, d(Re, Im)/d(x, y) = [[Re f, -Im f], [Im f, Re f]].
    def real_jac(f):
        return np.stack([np.stack([f.real, -f.imag], -1), np.stack([f.imag, f.real], -1)], -2)

    var = np.empty((n_point, n_mode))
    for k in range(n_mode):
        sl = slice(2 * k, 2 * k + 2)
        c_tt = np.broadcast_to(cov_theta[sl, sl], (n_point, 2, 2))
        c_pp = np.broadcast_to(cov_cc_blocks[P_, k], (n_point, 2, 2))
        c_pt = np.broadcast_to(hc[P_, sl, sl], (n_point, 2, 2))  # cov(c_P, theta_k)
        c_jj = cov_cc_blocks[:, k].copy()
        c_jp = hc[:, sl, :] @ hj[P_, sl, :].T  # cov(c_j, c_P) for j != P
        c_jt = hc[:, sl, sl].copy()
        c_jp[P_] = cov_cc_blocks[P_, k]
        big = np.concatenate(
            [
                np.concatenate([c_tt, np.swapaxes(c_jt, 1, 2), np.swapaxes(c_pt, 1, 2)], 2),
                np.concatenate([c_jt, c_jj, c_jp], 2),
                np.concatenate([c_pt, np.swapaxes(c_jp, 1, 2), c_pp], 2),
            ],
            1,
        )  # (P, 6, 6)
        jac = np.concatenate(
            [real_jac(d_lam[:, k]), real_jac(d_aj[:, k]), real_jac(d_ap[:, k])], 2
        )  # (P, 2, 6)
        var[:, k] = np.einsum("jab,jbc,jac->j", jac, big, jac)
    out.mode_vector = phi
    out.mode_vector_var = var
    return out
