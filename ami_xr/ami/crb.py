"""Cramér-Rao bound of the modal parameters for a known system and noise model.

The data model is the one :func:`ami_xr.refine` fits: FRF ``j`` on the lines of ``frf`` is the
modal model of the true eigenvalues and residues (exact discrete-time basis for FRFs from sampled
impulse responses, eq. 4 otherwise) plus independent complex Gaussian noise on every line. White
noise of variance ``s_j^2`` on the ``N`` samples of impulse response ``j`` gives every FRF line
(``dt * DFT``) noise of variance ``N dt^2 s_j^2`` (real and imaginary part each half of it; at DC
and Nyquist all of it in the real part). For the paper's eq. 15, ``s_j = alpha max_n |y_j(t_n)|
/ sqrt(3)`` (uniform ``r`` in (-1, 1)) or ``alpha max_n |y_j(t_n)|`` (Gaussian ``r``).

The Fisher information of all unknowns -- the eigenvalues and every residue of every FRF -- is
inverted exactly (the residues are eliminated by a Schur complement), so the bound on the
eigenvalues accounts for the unknown residues. Expected absolute errors of an efficient, unbiased
estimator follow as ``sqrt(2 / pi) * std`` for a scalar, and for a mode vector as the exact
expected Euclidean norm of its (real, Gaussian) error vector.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami.settings import FrfAttributes, from_attrs
from ami_xr.core import varpro
from ami_xr.core.modal import modal_std
from ami_xr.core.model import resolve_model, resolve_residual_terms
from ami_xr.errors import AmiXrValueError
from ami_xr.kernels.modal_basis import model_columns
from ami_xr.provenance import add_history


def expected_norm(cov: np.ndarray) -> float:
    """``E |x|`` for a real Gaussian vector ``x ~ N(0, cov)`` (exact, by one quadrature).

    Uses ``E|x| = (1/sqrt(pi)) int_0^inf (1 - prod_i (1 + 2 u^2 l_i)^(-1/2)) / u^2 du`` with
    ``l_i`` the eigenvalues of ``cov``; for one dimension this is ``sqrt(2/pi) sigma``.
    """
    from scipy import integrate  # lazy: keeps `import ami_xr` fast

    lam = np.clip(np.linalg.eigvalsh(np.asarray(cov, dtype=float)), 0.0, None)
    total = lam.sum()
    if total <= 0:
        return 0.0
    lam = lam / total  # scale out: E|x| = sqrt(total) * E|x'|

    def f(u):
        if u == 0.0:
            return 1.0  # limit: sum(l_i) = 1
        return -np.expm1(-0.5 * np.sum(np.log1p(2.0 * u * u * lam))) / (u * u)

    val = integrate.quad(f, 0.0, 1.0, limit=200)[0] + integrate.quad(f, 1.0, np.inf, limit=200)[0]
    return float(np.sqrt(total) * val / np.sqrt(np.pi))


def _clean_maxima(lam, residue, dt, n_samples, power):
    """``max_n |y_j(t_n)|`` of the noise-free impulse response ``2 Re sum_k A_jk exp(lam_k t)``."""
    t = np.arange(int(n_samples)) * dt
    out = np.empty(residue.shape[0])
    for j in range(residue.shape[0]):
        y = 2.0 * np.real(np.exp(np.outer(t, lam)) @ residue[j])
        out[j] = np.max(np.abs(y))
    return out


def cramer_rao_bound(
    truth: xr.Dataset,
    frf: xr.Dataset,
    *,
    noise_level: float | None = None,
    noise_kind: str | None = None,
    frf_noise_std: xr.DataArray | np.ndarray | float | None = None,
    band: str | tuple[float, float] = "all",
    residual_terms: str | tuple[str, ...] = "auto",
) -> xr.Dataset:
    """Cramér-Rao bound of eigenvalues, residues and mode vectors of a known system.

    Parameters
    ----------
    truth : xarray.Dataset
        ``eigenvalue`` (mode) and ``residue`` (point, mode) of the true system (for example the
        truth returned by :func:`ami_xr.simulate.benchmark`).
    frf : xarray.Dataset
        FRF Dataset that fixes the frequency lines, the data model (``frf_source``,
        ``sample_interval``, ``record_samples``), ``drive_point`` and ``response_quantity``;
        its ``frf`` values are not used.
    noise_level : float, optional
        alpha of eq. 15; default ``frf.attrs["noise_level"]``. Needs ``sample_interval`` and
        ``record_samples`` to find the impulse responses' maxima.
    noise_kind : {"uniform", "gaussian"}, optional
        Distribution of eq. 15's ``r``; default ``frf.attrs["noise_kind"]`` or ``"uniform"``.
    frf_noise_std : float or array (point), optional
        Instead of eq. 15: the noise of one FRF line, ``sqrt(E |noise|^2)``, per point
        (per (reference, point) for multi-reference FRFs).
    band, residual_terms
        As in :func:`ami_xr.refine` (the bound is for that estimator's model).

    Returns
    -------
    xarray.Dataset
        The truth's ``eigenvalue``, ``natural_frequency``, ``damping_ratio``, ``mode_vector`` and
        the bound: ``eigenvalue_std`` (complex, std of real + i std of imaginary part),
        ``natural_frequency_std`` (Hz), ``damping_ratio_std``, ``residue_std`` and
        ``mode_vector_std`` (point, mode; root mean square of the complex error), and expected
        absolute relative errors ``natural_frequency_error``, ``damping_ratio_error`` (fractions,
        ``sqrt(2/pi) std / value``) and ``mode_vector_error`` (mode; ``E |dPhi| / |Phi|``),
        plus ``frf_noise_std`` (point).

    Notes
    -----
    Multi-reference FRFs (``frf`` with dims (reference, point, frequency)): the truth needs
    ``mode_vector`` (point, mode) on the measured points and the references (a reference need
    not be measured); the residue of response ``p`` to a force at ``r`` is
    ``lam phi_p phi_r``. The bound is that of the shared-pole model with a free residue per
    (reference, point) FRF -- the model :func:`ami_xr.identify` fits to all references -- and
    ``residue_std`` and ``frf_noise_std`` are on (reference, point); no mode-vector bound is
    given (the mode vector of several references is a rank-one factorisation).
    """
    if names.REFERENCE in frf.dims:
        return _multi_reference_bound(
            truth,
            frf,
            noise_level=noise_level,
            noise_kind=noise_kind,
            frf_noise_std=frf_noise_std,
            band=band,
            residual_terms=residual_terms,
        )
    _check_inputs(truth, frf)
    data_model = resolve_model(frf.attrs, "exact")
    dt, n_samples = data_model.dt, data_model.n_samples
    terms = resolve_residual_terms(residual_terms, frf.attrs, names.RESIDUAL_COEFFICIENT in frf)
    omega = _angular_frequencies(frf, band, terms)
    residue_da = truth[names.RESIDUE].transpose(names.POINT, names.MODE)
    points = list(residue_da[names.POINT].values)
    lam = truth[names.EIGENVALUE].values.astype(np.complex128)
    residue = residue_da.values.astype(np.complex128)
    quantity = frf.attrs.get(names.ATTR_QUANTITY, "displacement")
    if quantity != "displacement":
        raise AmiXrValueError(
            f"frf: the bound is implemented for receptance (displacement) "
            f"FRFs, got response_quantity={quantity!r}"
        )
    power = 0
    decay = float(from_attrs(FrfAttributes, frf.attrs).exponential_window_decay)

    line_std = _line_noise_std(
        frf, frf_noise_std, noise_level, noise_kind, points, lam, residue, dt, n_samples, power
    )
    noise_var = 0.5 * line_std**2  # per real component
    drive = frf.attrs.get(names.ATTR_DRIVE_POINT, truth.attrs.get(names.ATTR_DRIVE_POINT))
    drive_index = points.index(drive) if drive in points else None
    cov = _covariance(
        lam, residue, omega, (dt, n_samples, terms), decay, noise_var, drive_index, power
    )
    out = _bound_dataset(truth, lam, points, cov, line_std)
    if drive_index is not None:
        mv_err = np.array(
            [
                _mode_vector_error(cov, k, drive_index, noise_var, power, lam[k])
                for k in range(lam.size)
            ]
        )
        out[names.MODE_VECTOR] = ((names.POINT, names.MODE), cov.mode_vector)
        out[names.MODE_VECTOR_STD] = ((names.POINT, names.MODE), np.sqrt(cov.mode_vector_var))
        out[names.MODE_VECTOR_ERROR] = ((names.MODE,), mv_err)
    out.attrs = {names.ATTR_DRIVE_POINT: drive, names.ATTR_CRB_MODEL: data_model.name}
    return add_history(
        out,
        "ami_xr.cramer_rao_bound",
        {
            "noise_level": noise_level,
            "noise_kind": noise_kind,
            "band": band,
            "residual_terms": terms,
        },
    )


def _check_inputs(truth: xr.Dataset, frf: xr.Dataset) -> None:
    """The truth's eigenvalues and residues and the FRF's frequency coordinate are there."""
    for var, dims in (
        (names.EIGENVALUE, (names.MODE,)),
        (names.RESIDUE, (names.POINT, names.MODE)),
    ):
        if var not in truth or set(truth[var].dims) != set(dims):
            raise AmiXrValueError(f"truth: expected variable {var!r} with dims {dims}")
    if names.FREQUENCY not in frf.coords:
        raise AmiXrValueError("frf: expected a Dataset with a 'frequency' coordinate (Hz)")


def _angular_frequencies(frf: xr.Dataset, band, terms) -> np.ndarray:
    """The lines of ``frf`` inside ``band`` in rad/s (0 Hz left out with a lower residual)."""
    freq = frf[names.FREQUENCY]
    if band != "all":
        freq = freq.sel({names.FREQUENCY: slice(float(band[0]), float(band[1]))})
    if "lower" in terms:
        freq = freq[freq > 0]
    return 2 * np.pi * freq.values.astype(float)


def _covariance(lam, residue, omega, sampling, decay, noise_var, drive_index, power):
    """The covariance of the fit (:func:`ami_xr.core.varpro.covariance`) at the truth, with
    ``sampling`` = (dt, n_samples, residual terms) of the data model."""
    dt, n_samples, terms = sampling
    n_point, n_mode = residue.shape
    # Noise-free model data at the truth, so that the projection returns the true residues.
    mu = lam - decay
    phi, _ = model_columns(omega, mu, dt, n_samples, terms)
    coef = np.zeros((n_point, phi.shape[1]))
    coef[:, 0 : 2 * n_mode : 2] = residue.real
    coef[:, 1 : 2 * n_mode : 2] = residue.imag
    model = coef @ phi.T
    prob = varpro.make_problem(
        model, omega, dt, n_samples, terms, nyquist=(np.pi / dt if dt else None)
    )
    proj = varpro.project(prob, mu)
    if not proj.ok:
        raise AmiXrValueError("truth: eigenvalues coincide; the Fisher information is singular")
    return varpro.covariance(
        prob, proj, noise_var, drive_index, quantity_power=power, lam_shift=decay
    )


def _bound_dataset(truth, lam, points, cov, line_std) -> xr.Dataset:
    """The truth's modal parameters with their bound (all but the mode-vector variables)."""
    c_t = cov.cov_theta
    wn = np.abs(lam)
    zeta = -lam.real / wn
    eig_std, fn_std, z_std = modal_std(lam, c_t)
    k_abs = np.sqrt(2.0 / np.pi)
    mode = truth[names.EIGENVALUE][names.MODE].values
    P, M = names.POINT, names.MODE
    return xr.Dataset(
        {
            names.EIGENVALUE: ((M,), lam, {names.ATTR_UNITS: names.ANGULAR_UNITS}),
            names.NATURAL_FREQUENCY: (
                (M,),
                wn / (2 * np.pi),
                {names.ATTR_UNITS: names.FREQUENCY_UNITS},
            ),
            names.DAMPING_RATIO: ((M,), zeta, {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}),
            names.EIGENVALUE_STD: ((M,), eig_std, {names.ATTR_UNITS: names.ANGULAR_UNITS}),
            names.NATURAL_FREQUENCY_STD: ((M,), fn_std, {names.ATTR_UNITS: names.FREQUENCY_UNITS}),
            names.DAMPING_RATIO_STD: ((M,), z_std, {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}),
            names.NATURAL_FREQUENCY_ERROR: ((M,), k_abs * fn_std * 2 * np.pi / wn),
            names.DAMPING_RATIO_ERROR: ((M,), k_abs * z_std / zeta),
            names.RESIDUE_STD: ((P, M), np.sqrt(cov.residue_var)),
            names.FRF_NOISE_STD: ((P,), line_std),
        },
        coords={M: mode, P: points},
    )


def _line_noise_std(
    frf, frf_noise_std, noise_level, noise_kind, points, lam, residue, dt, n_samples, power
) -> np.ndarray:
    """Noise of one FRF line, ``sqrt(E|e|^2)``, per point: given, or from eq. 15's alpha."""
    n_point = residue.shape[0]
    if frf_noise_std is not None:
        line_std = np.broadcast_to(np.asarray(frf_noise_std, dtype=float), (n_point,)).copy()
        if isinstance(frf_noise_std, xr.DataArray) and names.POINT in frf_noise_std.dims:
            line_std = frf_noise_std.sel({names.POINT: points}).values.astype(float)
    else:
        alpha = noise_level if noise_level is not None else frf.attrs.get(names.ATTR_NOISE_LEVEL)
        kind = noise_kind or frf.attrs.get(names.ATTR_NOISE_KIND, "uniform")
        if alpha is None or not np.isfinite(alpha) or alpha <= 0:
            raise AmiXrValueError(
                "noise_level: expected a positive alpha of eq. 15 (or frf_noise_std), "
                f"got {alpha!r}"
            )
        if kind not in names.NOISE_KINDS:
            raise AmiXrValueError(f"noise_kind: expected one of {names.NOISE_KINDS}, got {kind!r}")
        if not dt:
            raise AmiXrValueError(
                "frf: eq. 15 noise needs attrs sample_interval and record_samples "
                "(frf_source='impulse_response'); pass frf_noise_std otherwise"
            )
        y_max = _clean_maxima(lam, residue, dt, n_samples, power)
        s_time = alpha * y_max / (np.sqrt(3.0) if kind == "uniform" else 1.0)
        line_std = np.sqrt(n_samples) * dt * s_time
    if np.any(~np.isfinite(line_std)) or np.any(line_std <= 0):
        raise AmiXrValueError(f"frf_noise_std: expected positive values, got {line_std}")
    return line_std


def _mode_vector_error(cov, k, drive, noise_var, power, lam_k):
    """``E |dPhi_k| / |Phi_k|`` from the joint covariance of (lam_k, A_1k .. A_Pk)."""
    hj = cov.dc_dtheta  # (P, p, 2K)
    c_t = cov.cov_theta
    cov_lin = cov.cov_lin
    residue = cov.residue[:, k]
    phi = cov.mode_vector[:, k]
    n_point = residue.shape[0]
    sl = slice(2 * k, 2 * k + 2)
    # Variables z = [theta_k (2), c_1k (2), ..., c_Pk (2)]: their joint covariance.
    dz = np.zeros((2 + 2 * n_point, c_t.shape[0]))  # sensitivity to theta (all modes)
    dz[0:2] = np.eye(c_t.shape[0])[sl]
    for j in range(n_point):
        dz[2 + 2 * j : 4 + 2 * j] = hj[j, sl, :]
    big = dz @ c_t @ dz.T
    for j in range(n_point):
        big[2 + 2 * j : 4 + 2 * j, 2 + 2 * j : 4 + 2 * j] += noise_var[j] * cov_lin[sl, sl]
    # Jacobian of the real-stacked mode vector (2P) with respect to z.
    jac = np.zeros((2 * n_point, 2 + 2 * n_point))

    def put(row, col, f):
        jac[row : row + 2, col : col + 2] += [[f.real, -f.imag], [f.imag, f.real]]

    q = power
    for j in range(n_point):
        put(2 * j, 0, -0.5 * (1 + q) * phi[j] / lam_k)
        if j == drive:
            put(2 * j, 2 + 2 * drive, 0.5 * phi[j] / residue[drive])
        else:
            put(2 * j, 2 + 2 * j, phi[j] / residue[j])
            put(2 * j, 2 + 2 * drive, -0.5 * phi[j] / residue[drive])
    cov_phi = jac @ big @ jac.T
    return expected_norm(cov_phi) / np.linalg.norm(phi)


REPEATED_POLE = "repeated_pole"  # output of the multi-reference bound: mode shares its pole


def _multi_reference_bound(truth, frf, **kw) -> xr.Dataset:
    """:func:`cramer_rao_bound` of multi-reference FRFs: every (reference, point) FRF one more
    FRF of the same poles, stacked on ``point`` and bounded as one SIMO set."""
    if names.EIGENVALUE not in truth or names.MODE_VECTOR not in truth:
        raise AmiXrValueError(
            "truth: a multi-reference bound needs 'eigenvalue' (mode) and 'mode_vector' "
            "(point, mode) (the residues follow as lam phi_p phi_r)"
        )
    refs = list(np.asarray(frf[names.REFERENCE].values).tolist())
    points = list(np.asarray(frf[names.POINT].values).tolist())
    phi = truth[names.MODE_VECTOR]
    known = set(np.asarray(phi[names.POINT].values).tolist())
    missing = [x for x in refs + points if x not in known]
    if missing:
        raise AmiXrValueError(f"truth: 'mode_vector' has no entry for the labels {missing}")
    lam = truth[names.EIGENVALUE].transpose(names.MODE).values.astype(np.complex128)
    pp = phi.sel({names.POINT: points}).transpose(names.POINT, names.MODE).values
    pr = phi.sel({names.POINT: refs}).transpose(names.POINT, names.MODE).values
    residue = lam[None, None, :] * pr[:, None, :] * pp[None, :, :]  # (R, P, K)
    # An exactly repeated root is one pole of the data (its residues add up): bounded as one
    # pole, whose bound both members get.
    group = np.arange(lam.size)
    for k in range(lam.size):
        same = np.flatnonzero(np.abs(lam[:k] - lam[k]) <= 1e-12 * np.abs(lam[k]))
        group[k] = group[same[0]] if same.size else k
    poles, first = np.unique(group, return_index=True)
    pole_of = np.searchsorted(poles, group)
    summed = np.zeros((*residue.shape[:2], poles.size), np.complex128)
    np.add.at(summed, (slice(None), slice(None), pole_of), residue)
    labels = [f"{r}@{p}" for r in refs for p in points]
    stacked_truth = xr.Dataset(
        {
            names.EIGENVALUE: ((names.MODE,), lam[first]),
            names.RESIDUE: (
                (names.POINT, names.MODE),
                summed.reshape(len(refs) * len(points), poles.size),
            ),
        },
        coords={names.POINT: labels, names.MODE: np.arange(poles.size)},
    )
    stacked_frf = xr.Dataset(coords={names.FREQUENCY: frf[names.FREQUENCY]}, attrs=dict(frf.attrs))
    stacked_frf.attrs.pop(names.ATTR_DRIVE_POINT, None)
    std = kw.pop("frf_noise_std")
    if isinstance(std, xr.DataArray) and names.REFERENCE in std.dims:
        std = xr.DataArray(
            std.transpose(names.REFERENCE, names.POINT).values.ravel(),
            dims=(names.POINT,),
            coords={names.POINT: labels},
        )
    out = cramer_rao_bound(stacked_truth, stacked_frf, frf_noise_std=std, **kw)
    out = out.isel({names.MODE: pole_of}).assign_coords(
        {names.MODE: truth[names.EIGENVALUE][names.MODE].values}
    )
    shape = (len(refs), len(points))
    res_std = out[names.RESIDUE_STD].transpose(names.POINT, names.MODE).values
    line = out[names.FRF_NOISE_STD].values
    out = out.drop_vars([names.RESIDUE_STD, names.FRF_NOISE_STD, names.POINT])
    rp = (names.REFERENCE, names.POINT)
    out = out.assign_coords({names.REFERENCE: refs, names.POINT: points}).assign(
        {
            names.RESIDUE_STD: ((*rp, names.MODE), res_std.reshape(*shape, lam.size)),
            REPEATED_POLE: ((names.MODE,), np.bincount(pole_of)[pole_of] > 1),
            names.FRF_NOISE_STD: (rp, line.reshape(shape)),
        }
    )
    out.attrs.pop(names.ATTR_DRIVE_POINT, None)
    out.attrs[names.ATTR_MULTI_REFERENCE] = (
        f"{len(refs)} references: shared poles, a free residue per (reference, point) FRF; "
        "the members of an exactly repeated root share one pole's bound"
    )
    return out
