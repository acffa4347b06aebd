"""The paper's benchmark: a cantilever beam with three suspended spring-mass-dashpot absorbers.

Ginsberg & Allen, "Recent improvements of the Algorithm of Mode Isolation", section "Tuned
vibration absorber": steel cantilever (E = 207 GPa, rho = 7800 kg/m^3, I = 3.125e-7 m^4,
A = 0.0015 m^2, L = 2 m); absorbers at x = L/2, 3L/4, L with equal stiffness
``k = sigma rho A L w1^2`` (sigma = 1e-4, w1 = 65.3594 rad/s the beam's fundamental frequency),
masses ``m_j = k / Omega_j^2`` (Omega = 30.5555, 48.0392, 65.5228 rad/s) and dashpots
``c_j = 2 zeta sqrt(k m_j)`` (zeta = 0.015). The beam displacement is a Ritz series (eq. 13) of
the clamped-free beam modes (eq. 14) in the nondimensional coordinate ``xi = x / L``::

    Psi_j(xi) = sin(b_j xi) - sinh(b_j xi) - R_j (cos(b_j xi) - cosh(b_j xi)),
    R_j = (sinh b_j + sin b_j) / (cosh b_j + cos b_j),   cos b_j cosh b_j = -1,

(the paper writes ``alpha_j x``; ``b_1 = 1.8751`` applies to ``x / L``, which gives
``w1 = b_1^2 sqrt(E I / (rho A L^4)) = 65.3594 rad/s``). The beam itself is undamped; the
dashpots make the damping non-proportional.

Findings (tested in tests/test_beam.py):

* ``J = 1`` Ritz term reproduces every printed digit of the "Analytical" eigenvalues of
  Tables 1-2; ``J = 2`` already changes Re(lam_3) in the 5th digit (-0.39328 vs -0.39311).
* The tables' rows q2..q4 are the displacements of the three suspended masses (agree to ~2e-5).
  Row q1 is the first Ritz coordinate with the basis function MASS-NORMALISED,
  ``Psi_1 / sqrt(rho A L R_1^2)`` so that ``int rho A Psi^2 dx = 1`` (not eq. 14's ``Psi_1``,
  and not the tip displacement): tip = q1 * Psi_1(L) / sqrt(rho A L R_1^2) = 0.41345 q1.
  ``beam_absorbers(basis="mass")`` uses that basis, so its generalized coordinates are the
  tables' q. The tables' modes 1 and 2 have the opposite overall sign to ours (a mode vector's
  sign is arbitrary; residues do not depend on it).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr

from ami_xr.errors import AmiXrValueError
from ami_xr.simulate.modal import impulse_response, modal_model, time_axis
from ami_xr.simulate.noise import ATTR_NOISE_LEVEL, NOISE_KINDS, add_noise
from ami_xr.simulate.paper import ANALYTICAL_EIGENVALUES, ANALYTICAL_MODE_VECTORS

# Paper parameters (SI units).
E = 207e9
RHO = 7800.0
I_AREA = 3.125e-7
AREA = 0.0015
LENGTH = 2.0
SIGMA = 1e-4
OMEGA_ABSORBER = (30.5555, 48.0392, 65.5228)  # rad/s, fixed-base absorber frequencies
ZETA_ABSORBER = 0.015
X_ABSORBER = (0.5, 0.75, 1.0)  # positions as fractions of L

#: Labels of the measured points: beam tip (drive point), then the suspended masses.
POINT_LABELS = ("tip", "m1", "m2", "m3")
DRIVE_POINT = "tip"
DEFAULT_J = 1
BASES = ("paper", "mass")

# Tables 1-6 of the paper ("Analytical" columns), for tests and documentation.
PAPER_EIGENVALUES = ANALYTICAL_EIGENVALUES
#: Rows q1..q4, columns modes 1..4, already multiplied by 1e-6.
PAPER_MODE_VECTORS = ANALYTICAL_MODE_VECTORS


def clamped_free_roots(J: int) -> np.ndarray:
    """The first ``J`` roots ``b_j`` of ``cos b cosh b = -1`` (b_1 = 1.87510...)."""
    from scipy.optimize import brentq  # lazy: keeps `import ami_xr` fast

    _check_J(J)
    # cos b = -1/cosh b: root j lies within 0.31 of (j - 1/2) pi.
    f = lambda b: np.cos(b) + 1.0 / np.cosh(b)  # noqa: E731
    out = []
    for j in range(1, J + 1):
        c = (j - 0.5) * np.pi
        out.append(brentq(f, c - 0.5, c + 0.5, xtol=1e-15, rtol=1e-15, maxiter=200))
    return np.array(out)


def _check_J(J) -> int:
    if isinstance(J, bool) or int(J) != J or J < 1:
        raise AmiXrValueError(f"J: expected a positive integer number of Ritz terms, got {J!r}")
    return int(J)


def clamped_free_modes(b: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """``Psi_j(xi)`` of eq. 14 (with ``b_j xi``, ``xi = x / L``), shape (len(xi), len(b)).

    Evaluated in a form that avoids the cancellation of ``sinh - R cosh`` for large ``b``.
    """
    b = np.asarray(b, dtype=np.float64)[np.newaxis, :]
    x = b * np.asarray(xi, dtype=np.float64)[:, np.newaxis]
    eb = np.exp(-b)
    den = (1 + eb**2) / 2 + np.cos(b) * eb  # (cosh b + cos b) e^-b
    R = (1 - eb**2 + 2 * np.sin(b) * eb) / (1 + eb**2 + 2 * np.cos(b) * eb)
    # Psi = R (cosh x - cos x) - (sinh x - sin x); R cosh x - sinh x = ((R-1) e^x + (R+1) e^-x)/2
    r_minus_1 = (np.sin(b) - np.cos(b) - eb) * eb / den  # R - 1, computed without cancellation
    hyper = 0.5 * (r_minus_1 * np.exp(x) + (R + 1) * np.exp(-x))
    return hyper - R * np.cos(x) + np.sin(x)


def _ritz_ratio(b: np.ndarray) -> np.ndarray:
    eb = np.exp(-b)
    return (1 - eb**2 + 2 * np.sin(b) * eb) / (1 + eb**2 + 2 * np.cos(b) * eb)


def beam_absorbers(
    J: int = DEFAULT_J, *, basis: str = "paper"
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]:
    """Mass, damping and stiffness matrices of the benchmark and its output matrix.

    Parameters
    ----------
    J : int
        Number of Ritz terms (clamped-free beam modes). ``J = 1`` (default) reproduces the
        paper's tabulated eigenvalues to every printed digit.
    basis : {"paper", "mass"}
        ``"paper"``: ``Psi_j`` exactly as eq. 14 (``Psi_1(L) = 2.7244``). ``"mass"``: each
        ``Psi_j`` divided by ``sqrt(rho A L R_j^2)`` so that ``int rho A Psi_j^2 dx = 1``; then
        the generalized coordinate q1 is the tables' q1 row. Eigenvalues and the measured
        displacements do not depend on the choice.

    Returns
    -------
    M, C, K : ndarray, shape (J + 3, J + 3)
        Generalized coordinates ``[q_1 .. q_J, z_1, z_2, z_3]`` (Ritz coordinates, then the
        absolute displacements of the suspended masses at L/2, 3L/4, L).
    output : ndarray, shape (4, J + 3)
        Maps generalized coordinates to the measured displacements [tip, m1, m2, m3].
    labels : tuple of str
        ``("tip", "m1", "m2", "m3")``.
    """
    J = _check_J(J)
    if basis not in BASES:
        raise AmiXrValueError(f"basis: expected one of {BASES}, got {basis!r}")
    b = clamped_free_roots(J)
    R = _ritz_ratio(b)
    rho_a_l = RHO * AREA * LENGTH
    # int_0^1 Psi_j Psi_k dxi = R_j^2 delta_jk; int_0^1 Psi_j'' Psi_k'' dxi = b_j^4 R_j^2 delta_jk
    scale = 1.0 / np.sqrt(rho_a_l * R**2) if basis == "mass" else np.ones(J)
    m_beam = rho_a_l * R**2 * scale**2
    k_beam = E * I_AREA / LENGTH**3 * b**4 * R**2 * scale**2
    w1 = b[0] ** 2 * np.sqrt(E * I_AREA / (RHO * AREA * LENGTH**4))
    k_abs = SIGMA * rho_a_l * w1**2
    omega = np.asarray(OMEGA_ABSORBER)
    m_abs = k_abs / omega**2
    c_abs = 2 * ZETA_ABSORBER * np.sqrt(k_abs * m_abs)

    n = J + 3
    M = np.zeros((n, n))
    C = np.zeros((n, n))
    K = np.zeros((n, n))
    M[:J, :J] = np.diag(m_beam)
    K[:J, :J] = np.diag(k_beam)
    psi_at = clamped_free_modes(b, np.asarray(X_ABSORBER)) * scale  # (3, J)
    for i in range(3):
        # spring and dashpot act on the relative displacement z_i - w(x_i)
        v = np.zeros(n)
        v[:J] = -psi_at[i]
        v[J + i] = 1.0
        K += k_abs * np.outer(v, v)
        C += c_abs[i] * np.outer(v, v)
        M[J + i, J + i] = m_abs[i]
    output = np.zeros((4, n))
    output[0, :J] = psi_at[2]  # tip displacement w(L) = sum Psi_j(L) q_j
    output[1:, J:] = np.eye(3)
    return M, C, K, output, POINT_LABELS


def benchmark_model(J: int = DEFAULT_J) -> xr.Dataset:
    """Truth Dataset of the benchmark at the measured points, with residues for a tip force."""
    M, C, K, output, labels = beam_absorbers(J)
    truth = modal_model(M, C, K, point_labels=labels, output=output, drive_point=DRIVE_POINT)
    truth.attrs["ritz_terms"] = int(J)
    return truth


def frf_from_impulse(ts: xr.Dataset) -> xr.Dataset:
    """FRF Dataset ``dt * rfft(response)`` of an impulse-response Dataset.

    A thin wrapper of :func:`ami_xr.impulse_to_frf` (no window): the result has
    ``frf_source="impulse_response"``, ``sample_interval`` and ``record_samples``, and keeps the
    time Dataset's attributes (noise level, seed, ...).
    """
    from ami_xr.dsp.impulse import impulse_to_frf  # the signal layer imports io; keep lazy

    return impulse_to_frf(ts)


def benchmark(
    noise: float = 0.15,
    seed: int | None = 0,
    duration: float = 60.0,
    n_samples: int = 4096,
    J: int = DEFAULT_J,
    kind: str = "uniform",
) -> tuple[xr.Dataset, xr.Dataset, xr.Dataset]:
    """The paper's benchmark data: noisy tip-impulse responses, their FRFs, and the truth.

    Parameters
    ----------
    noise : float
        alpha of eq. 15 (0.15 in the paper); 0 gives noise-free data.
    seed : int, optional
        Seed of the noise generator (reproducible).
    duration : float
        Record length in s (60 s in the paper).
    n_samples : int
        Samples in the record (2^12 in the paper), ``dt = duration / n_samples``.
    J : int
        Ritz terms (1 reproduces the paper's tables).
    kind : {"uniform", "gaussian"}
        Noise distribution (the paper: uniform).

    Returns
    -------
    time : xarray.Dataset
        ``response`` (point, time) displacement per unit impulse at the tip, noise added.
    frf : xarray.Dataset
        ``dt * rfft(response)`` on ``k / duration`` Hz, ``frf_source="impulse_response"``.
    truth : xarray.Dataset
        Exact eigenvalues, natural frequencies, damping ratios, mode vectors and residues at the
        measured points [tip, m1, m2, m3] (all J + 3 modes; modes 1-4 are the paper's).
    """
    if kind not in NOISE_KINDS:
        raise AmiXrValueError(f"kind: expected one of {NOISE_KINDS}, got {kind!r}")
    truth = benchmark_model(J)
    t = time_axis((duration, n_samples))
    ts = impulse_response(truth, t, DRIVE_POINT)
    if noise:
        ts = add_noise(ts, noise, seed=seed, kind=kind)
    else:
        ts.attrs[ATTR_NOISE_LEVEL] = 0.0
    ts.attrs["ritz_terms"] = int(J)
    g = frf_from_impulse(ts)
    g.attrs["ritz_terms"] = int(J)
    return ts, g, truth


def paper_tables() -> dict[str, np.ndarray]:
    """The paper's analytical eigenvalues (Tables 1-2) and mode vectors (Tables 3-6)."""
    return {"eigenvalue": PAPER_EIGENVALUES.copy(), "mode_vector": PAPER_MODE_VECTORS.copy()}


__all__: Sequence[str] = (
    "beam_absorbers",
    "benchmark",
    "benchmark_model",
    "clamped_free_modes",
    "clamped_free_roots",
    "frf_from_impulse",
    "paper_tables",
)
