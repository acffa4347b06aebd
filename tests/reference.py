"""Naive numpy oracles and tolerance-aware assertions shared by the test modules.

Each oracle is the textbook formula written with plain loops or one numpy call, independent of
the kernel it checks wherever that is possible (the FRF synthesis below is the exception: it
sums the package's one-mode basis function ``mode_contribution``, whose own closed form is
tested in ``tests/kernels``). Import them with a relative import::

    from ..reference import frf_from_residues, assert_fft_ratio_close

Tolerance helpers state the bound they test against in their docstrings; a test that uses
one need not restate it.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import scipy.signal

from ami_xr.kernels.modal_basis import mode_contribution

EPS = np.finfo(np.float64).eps

# The repository root and the shared measured-data folder beside it (skipped where absent).
REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"
HAMMER_LVM = SHARED_DATA / "impact_hammer.lvm"  # a measured five-hit hammer test
# The environment for subprocesses: they import this checkout whatever the working directory or
# the installed version.
SUBPROCESS_ENV = {
    **os.environ,
    "PYTHONPATH": os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]),
}

# --- shared test systems --------------------------------------------------------------------

# The paper's record: 60 s sampled at 2^12 points (the grid of sample_data/benchmark_impulse.nc).
PAPER_N = 4096
PAPER_DT = 60.0 / PAPER_N
PAPER_FREQUENCY = np.fft.rfftfreq(PAPER_N, PAPER_DT)  # Hz
PAPER_OMEGA = 2 * np.pi * PAPER_FREQUENCY  # rad/s
# Two lightly damped modes seen at two points: eigenvalues (mode,) in rad/s, residues
# (point, mode); the FFT tests transform their impulse responses on the paper's record.
TWO_MODE_LAM = np.array([-0.05 + 10.0j, -0.4 + 31.0j])
TWO_MODE_RES = np.array([[0.3 - 0.2j, 0.1 + 0.1j], [0.05j, -0.2 + 0.02j]])

# --- windows --------------------------------------------------------------------------------


def cosine_window(coeffs, n: int, sym: bool) -> np.ndarray:
    """Cosine-sum window in the textbook form sum_j (-1)^j a_j cos(2 pi j k / (m - 1))."""
    if n == 1:
        return np.ones(1)
    m = n if sym else n + 1
    k = np.arange(n)
    return sum((-1) ** j * a * np.cos(2 * np.pi * j * k / (m - 1)) for j, a in enumerate(coeffs))


def exponential_window(n: int, fs: float, decay: float) -> np.ndarray:
    """exp(-decay t) on the sample times t = k / fs."""
    return np.exp(-decay * np.arange(n) / fs)


def force_window(n: int, width: int, taper: int) -> np.ndarray:
    """Ones on ``width`` samples, then a falling half-cosine over ``taper`` samples, then 0."""
    w = np.zeros(n)
    for k in range(n):
        if k < width:
            w[k] = 1.0
        elif k < width + taper:
            w[k] = 0.5 * (1 + math.cos(math.pi * (k - width + 1) / (taper + 1)))
    return w


# --- spectra --------------------------------------------------------------------------------


def welch_spectra(x, y, fs, nperseg, noverlap, nfft, detrend, w):
    """Plain numpy Welch: loops over segments, np.polyfit for the linear trend.

    Returns the one-sided densities (Gxx, Gxy, Gyy) with scipy's scaling.
    """
    step = nperseg - noverlap
    starts = range(0, x.size - nperseg + 1, step)
    sxx = syy = 0.0
    sxy = 0.0
    t = np.arange(nperseg)
    for s in starts:
        segs = []
        for v in (x[s : s + nperseg], y[s : s + nperseg]):
            if detrend == "constant":
                v = v - v.mean()
            elif detrend == "linear":
                v = v - np.polyval(np.polyfit(t, v, 1), t)
            segs.append(np.fft.rfft(v * w, nfft))
        sxx = sxx + np.abs(segs[0]) ** 2
        syy = syy + np.abs(segs[1]) ** 2
        sxy = sxy + np.conj(segs[0]) * segs[1]
    scale = np.full(nfft // 2 + 1, 2.0 / (fs * np.sum(w**2) * len(starts)))
    scale[0] /= 2
    if nfft % 2 == 0:
        scale[-1] /= 2
    return sxx * scale, sxy * scale, syy * scale


# --- modal synthesis ------------------------------------------------------------------------


def frf_from_residues(omega, lam, residue, dt=None, n=None) -> np.ndarray:
    """sum_m b(lam_m, omega) A_jm per point j, shape (point, omega): eq. 4 (``dt=None``) or the
    dt-scaled DTFT of the sampled (``n=None``) or n-sample impulse response."""
    lam = np.atleast_1d(lam)
    residue = np.atleast_2d(residue)
    return np.array(
        [
            sum(mode_contribution(omega, lam[m], residue[j, m], dt, n) for m in range(lam.size))
            for j in range(residue.shape[0])
        ]
    )


def impulse_responses(lam, residue, n: int, dt: float) -> np.ndarray:
    """h_j(t_k) = 2 Re sum_m A_jm exp(lam_m k dt), shape (point, n)."""
    t = np.arange(n) * dt
    return 2 * np.real((residue[:, :, None] * np.exp(lam[None, :, None] * t)).sum(axis=1))


def sampled_response(force: np.ndarray, lam, residue, dt: float) -> np.ndarray:
    """Exact discrete response y = dt * (h conv f), h[n] = 2 Re sum_k A_k exp(lam_k n dt)."""
    out = np.zeros((residue.shape[0], force.size))
    for k, lk in enumerate(lam):
        s = scipy.signal.lfilter([1.0], [1.0, -np.exp(lk * dt)], force.astype(complex))
        out += 2 * dt * np.real(residue[:, k, None] * s[None, :])
    return out


def receptance_direct(M, C, K, omega, col: int) -> np.ndarray:
    """Column ``col`` of (K - w^2 M + i w C)^-1 by one dense solve per frequency."""
    n = M.shape[0]
    e = np.zeros(n)
    e[col] = 1.0
    return np.array([np.linalg.solve(K - w**2 * M + 1j * w * C, e) for w in omega]).T


def random_mck(n: int, seed: int):
    """A random SPD system (M, C, K) with general (non-proportional) damping."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    M = a @ a.T + n * np.eye(n)
    b = rng.normal(size=(n, n))
    K = 50.0 * (b @ b.T + n * np.eye(n))
    c = rng.normal(size=(n, n))
    C = 0.02 * (c @ c.T) + 0.01 * np.eye(n)
    return M, C, K


# --- identification oracles -----------------------------------------------------------------


def single_mode_lstsq(rows, rhs, ws: float, dt=None) -> complex:
    """The single-mode eigenvalue from numpy's lstsq on the rows of eqs. 11-12.

    The first two unknowns are the scaled characteristic polynomial v^2 + c1 v + c0; its root
    with positive imaginary part, times ``ws``, is the eigenvalue (mapped back through the
    discrete-time model when ``dt`` is given).
    """
    sol = np.linalg.lstsq(rows, rhs, rcond=None)[0]
    c0, c1 = sol[0], sol[1]
    v1 = complex(-c1 / 2, math.sqrt(4 * c0 - c1**2) / 2)
    return ws * v1 if dt is None else np.log(1 / (1 - dt * ws * v1)) / dt


def esprit_poles(h: np.ndarray, order: int, dt: float) -> np.ndarray:
    """Poles of a sum of damped exponentials (ESPRIT on a Hankel matrix of h)."""
    L = h.size // 2
    hank = np.lib.stride_tricks.sliding_window_view(h, L)
    u, _, _ = np.linalg.svd(hank.T, full_matrices=False)
    u = u[:, :order]
    z = np.linalg.eigvals(np.linalg.pinv(u[:-1]) @ u[1:])
    lam = np.log(z.astype(complex)) / dt
    lam = lam[lam.imag > 0]
    return lam[np.argsort(lam.imag)]


def mode_vector_error(phi, phi_true) -> np.ndarray:
    """|phi - phi_true| / |phi_true| per mode (column), up to the sign of eq. 8's square root."""
    out = []
    for k in range(phi_true.shape[1]):
        n = np.linalg.norm(phi_true[:, k])
        out.append(
            min(
                np.linalg.norm(phi[:, k] - phi_true[:, k]),
                np.linalg.norm(phi[:, k] + phi_true[:, k]),
            )
            / n
        )
    return np.array(out)


# --- norms and tolerance-aware assertions ---------------------------------------------------


def rel_err(a, b) -> float:
    """max |a - b| / max |b|: a norm-wise relative error, safe where b has near-zero entries."""
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


def assert_close_to_scale(got, want, rtol: float) -> None:
    """|got - want| <= rtol * (|want| + max |want|) elementwise.

    The absolute part, relative to the largest entry, covers entries near zero (bins emptied by
    detrending, nulls of a spectrum), whose rounding error is set by the largest terms of the
    sums that produced them, not by their own size.
    """
    got, want = np.asarray(got), np.asarray(want)
    assert got.shape == want.shape
    scale = np.max(np.abs(want))
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * scale)


def assert_fft_ratio_close(got, y, f) -> None:
    """``got`` equals ``rfft(y) / rfft(f)`` to the rounding error of the two FFTs.

    A length-n FFT has a norm-wise relative rounding error of about eps * log2(n) (Higham,
    *Accuracy and Stability of Numerical Algorithms*, ch. 24), so one bin of Y = rfft(y) may be
    off by eps * log2(n) * ||Y|| = eps * log2(n) * sqrt(n) * ||y|| in absolute terms, and
    likewise F. To first order the ratio is then off by (dY + |Y / F| dF) / |F| in each bin: an
    elementwise relative tolerance would fail (CPU-dependently) wherever |F| is small. The
    factor 10 covers the constants of the bound.
    """
    n = y.shape[-1]
    big_y, big_f = np.fft.rfft(y, axis=-1), np.fft.rfft(f)
    unit = 10 * EPS * np.log2(n) * np.sqrt(n)
    d_y = unit * np.linalg.norm(y, axis=-1, keepdims=True)
    d_f = unit * np.linalg.norm(f)
    want = big_y / big_f
    tol = (d_y + np.abs(want) * d_f) / np.abs(big_f)
    err = np.abs(got - want)
    assert np.all(err <= tol), f"max error / bound = {np.max(err / tol):.3g}"


# --- environment ----------------------------------------------------------------------------


def forbid_compute(*args, **kwargs):
    """A dask scheduler that fails: ``dask.config.set(scheduler=forbid_compute)`` proves
    that nothing was computed."""
    raise AssertionError("a dask computation ran (data was read) although it should stay lazy")


def normal_file_mode() -> int:
    """The permission bits of a freshly created file: 0o666 less the umask."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def two_point_time_dataset(force, response, fs: float = 256.0, **attrs):
    """A time Dataset of two displacement responses (points 0 and 1, drive point 0) and a force
    in N, sampled at ``fs`` Hz: the FRF-estimation tests' input."""
    import ami_xr

    return ami_xr.make_time_dataset(
        response,
        fs=fs,
        force=force,
        points=[0, 1],
        drive_point=0,
        response_quantity="displacement",
        response_units="m",
        force_units="N",
        **attrs,
    )


def damped_chain(point_labels=(1, 2, 3, 4, 5)):
    """A damped 5-DOF chain (truth Dataset), modes near 8.4, 22.7, 39.2, 45.8 and 52.3 Hz
    (zeta 1-3.4 %): the multi-reference tests' system."""
    from ami_xr.simulate import modal

    m = np.diag([1.0, 1.3, 0.9, 1.1, 0.8])
    springs = [4e4, 3e4, 3.5e4, 2.5e4, 3e4]
    k = np.zeros((5, 5))
    for i, s in enumerate(springs):
        k[i, i] += s
        if i + 1 < 5:
            k[i, i] += springs[i + 1]
            k[i, i + 1] = k[i + 1, i] = -springs[i + 1]
    return modal.modal_model(m, 2e-4 * k + 0.5 * m, k, point_labels=list(point_labels))
