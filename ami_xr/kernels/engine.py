"""Isolation Phase of the AMI (eq. 7) with the model-order check: one engine for the per-FRF
isolation (the paper) and the global SIMO isolation (Allen & Ginsberg).

The engine isolates a *group* of FRFs sharing their eigenvalues (one FRF per group, or all in
one). Each sweep takes the modes by decreasing SNR, isolates one mode's data by subtracting the
others (eq. 7), re-fits it on its band (:func:`~.single_mode.fit_single`) and replaces it; then
duplicates merge, insignificant modes drop, and the model-order check looks at the residual for
a significant peak (:mod:`.peak`) or a coherent residual in a mode's band (a split), restarting
the sweeps with one mode more. Data are in units of each FRF's noise floor; the two isolations
differ in their groups and in ``reweight``, ``se_fraction``, ``paper_sweeps`` (records:
:class:`IsolateParams`, :class:`ModeSet`, :class:`Work`, :class:`IsolateResult`; the jitted
steps here, the restarts of every group in :mod:`.groups` (which returns to its caller between
restarts and for the split's two-mode fit), checked wrappers in :mod:`.isolate`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ami_xr.kernels._numba import jit
from ami_xr.kernels.modal_basis import (
    add_mode,
    contribution_peak,
    mode_basis,
    nearest_line,
    tolerance_envelope,
)
from ami_xr.kernels.peak import (
    SPLIT_DELTA,
    band_energy_peak,
    nearest_within,
    peak_trial,
    pole_band,
)
from ami_xr.kernels.single_mode import FIT_OK, fit_single
from ami_xr.kernels.sorting import argsort_first

FREEZE_CHANGE = 1e-3
"""A mode's fit band is kept fixed once its eigenvalue changes less than this (relative)."""

STOP_FRACTION = 0.1
"""A sweep's step of an eigenvalue smaller than this fraction of its standard error counts as
converged (the change is far below what the data can resolve)."""

CYCLE_RATIO = 0.25
"""A step back to within this fraction of the step of the eigenvalue two sweeps before is a
two-state cycle (the mode then takes the mean of the two states and keeps its band)."""


class IsolateParams(NamedTuple):
    """Settings of the Isolation Phase kernels (see :func:`ami_xr.isolate` for their meaning)."""

    delta: float
    """Fit band: contiguous lines with ``|Y| >= delta`` times the peak."""
    tol: float
    """Convergence: relative change of Re and Im of every eigenvalue in a sweep (or a step
    below ``se_fraction`` of the eigenvalue's standard error)."""
    max_iter: int
    """Most sweeps per restart."""
    pfa: float
    """False-alarm probability of the model-order check."""
    min_points: int
    """Fewest lines in a fit band."""
    zeta_max: float
    """Largest accepted damping ratio."""
    merge_tol: float
    """Modes closer than this many half-power bandwidths merge."""
    max_modes: int
    """Most modes (the length of the output slots)."""
    reweight: bool
    """Weight each FRF of a group by its SNR for the mode (frozen after 3 sweeps)."""
    se_fraction: float
    """A step below this fraction of the eigenvalue's standard error also counts as settled
    (:data:`STOP_FRACTION`); 0: the relative change ``tol`` alone (the paper's criterion)."""
    paper_sweeps: bool
    """The paper's plain sweeps (per-FRF): order fixed per restart, bands over all lines, no
    cycle averaging, no pinning of re-added modes (the SIMO measures of :func:`sweeps`)."""


class ModeSet(NamedTuple):
    """The modes of one group; arrays of ``max_modes`` slots, updated in place."""

    lam: np.ndarray
    """Eigenvalues (max_modes,) complex, NaN past the current count."""
    res: np.ndarray
    """Residues (P, max_modes) complex, in noise units."""
    fails: np.ndarray
    """Failed fits of each mode (max_modes,) int."""


class Work(NamedTuple):
    """Arrays of one group's isolation, allocated once and reused by every sweep."""

    data: np.ndarray
    """(P, F) FRFs divided by their noise floors."""
    xn: np.ndarray
    """(P, F) isolated data (eq. 7) on the lines last computed."""
    rtmp: np.ndarray
    """(P,) residues of the last fit."""
    wts: np.ndarray
    """(P,) FRF weights of the current fit."""
    wts_all: np.ndarray
    """(max_modes, P) SNR weights of each mode (frozen after 3 sweeps)."""
    br: np.ndarray
    """(max_modes, F) Re b(lam) of every mode; ``bi``, ``bcr``, ``bci`` likewise."""
    bi: np.ndarray
    bcr: np.ndarray
    bci: np.ndarray
    tr: np.ndarray
    """(F,) scratch line (real part); ``ti`` the imaginary part."""
    ti: np.ndarray
    power: np.ndarray
    """(F,) power ``sum_j |xn_j|^2`` on the lines last computed."""
    back: np.ndarray
    """(max_modes,) each mode's eigenvalue before its last update (two-state cycle test)."""
    pinned: np.ndarray
    """(max_modes,) bool: modes kept at their model-order-check fit (not re-fitted)."""
    basis_lo: np.ndarray
    """(max_modes,) int: lines ``basis_lo..basis_hi-1`` hold each mode's current bases."""
    basis_hi: np.ndarray


class IsolateResult(NamedTuple):
    """What the engine finds in ``G`` groups of ``P`` FRFs each."""

    lam: np.ndarray
    """(G, max_modes) complex eigenvalues, NaN-padded."""
    res: np.ndarray
    """(G, P, max_modes) complex residues, NaN-padded."""
    n_modes: np.ndarray
    """(G,) number of modes."""
    iterations: np.ndarray
    """(G,) sweeps of all restarts."""
    converged: np.ndarray
    """(G,) bool: the last sweeps met the stopping rule and the model-order check ended."""


class SweepState(NamedTuple):
    """Per-mode state of the sweeps of one restart."""

    band_lo: np.ndarray
    band_hi: np.ndarray
    frozen: np.ndarray
    """A settled mode keeps its band."""
    fit_failed: np.ndarray
    """Sweeps in which its fit ran and failed."""


# entries of ``groups.Resume.counts``: group; its isolation started (0/1); restarts done;
# modes; added modes remembered; last restart (0/1); finished (0/1); converged (0/1); in the
# order check (0/1, waiting for a two-mode fit); the order check's try; the split's state,
# mode, band (lines AT_WL..AT_WH-1) and the fit's code (written by the caller)
AT_GROUP, AT_STARTED, AT_RESTART, AT_N, AT_N_TRIED, AT_LAST, AT_FINISHED, AT_CONVERGED = range(8)
AT_IN_CHECK, AT_TRY, AT_SPLIT, AT_KS, AT_WL, AT_WH, AT_SPLIT_CODE = range(8, 15)
SPLIT_NONE, SPLIT_ASKED, SPLIT_FITTED = 0, 1, 2

DONE, PAUSED, SPLIT_WANTED = 0, 1, -2
"""What :func:`~.groups.isolate_groups` returns: every group done; paused between restarts
(its work budget spent); a two-mode fit wanted (see :func:`~.groups.split_fit`).
``SPLIT_WANTED`` is also the order check's ``ks`` for it."""


def new_work(data, max_modes):
    """A :class:`Work` record for the group ``data`` (P, F) in noise units (plain numpy: the
    callers allocate it in Python and hand it to the kernels, so it costs no compilation)."""
    n_p, n_f = data.shape
    return Work(
        data=data,
        xn=np.empty((n_p, n_f), dtype=np.complex128),
        rtmp=np.empty(n_p, dtype=np.complex128),
        wts=np.ones(n_p),
        wts_all=np.ones((max_modes, n_p)),
        br=np.empty((max_modes, n_f)),
        bi=np.empty((max_modes, n_f)),
        bcr=np.empty((max_modes, n_f)),
        bci=np.empty((max_modes, n_f)),
        tr=np.empty(n_f),
        ti=np.empty(n_f),
        power=np.zeros(n_f),
        back=np.full(max_modes, complex(np.nan, np.nan)),
        pinned=np.zeros(max_modes, dtype=np.bool_),
        basis_lo=np.zeros(max_modes, dtype=np.int64),
        basis_hi=np.zeros(max_modes, dtype=np.int64),
    )


@jit(inline="always")
def _forget_bases(work, n):
    """The cached bases of modes ``0..n-1`` out of date (made again where next needed)."""
    for m in range(n):
        work.basis_lo[m] = 0
        work.basis_hi[m] = 0


@jit(inline="always")
def _bases_on(work, grid, lam, m, a, b):
    """Mode ``m``'s bases current on lines ``a..b-1``: only the lines not yet made since its
    last update are computed (a sweep's step looks at a window around one mode; every update
    of every mode used to remake all lines of its bases, most of a sweep's work)."""
    x, dt, n_samples = grid.x, grid.dt, grid.n_samples
    br, bi, bcr, bci = work.br[m], work.bi[m], work.bcr[m], work.bci[m]
    lo, hi = work.basis_lo[m], work.basis_hi[m]
    if hi <= lo:  # nothing current: start empty at ``a``
        lo = hi = a
    if a < lo:
        mode_basis(x, lam[m], dt, n_samples, br, bi, bcr, bci, a, lo)
        lo = a
    if b > hi:
        mode_basis(x, lam[m], dt, n_samples, br, bi, bcr, bci, hi, b)
        hi = b
    work.basis_lo[m] = lo
    work.basis_hi[m] = hi


@jit
def _isolated_lines(work, grid, lam, res, n, k, a, b):
    """eq. 7 on lines ``a..b-1`` of every FRF: ``xn = data - sum_{m != k}`` contributions (all
    ``n`` modes for ``k = -1``: the residual) from the cached bases (made current there first),
    and ``power[i] = sum_j |xn[j, i]|^2``."""
    for m in range(n):
        if m != k:
            _bases_on(work, grid, lam, m, a, b)
    xn, power, tr, ti = work.xn, work.power, work.tr, work.ti
    br, bi, bcr, bci = work.br, work.bi, work.bcr, work.bci
    power[a:b] = 0.0
    for j in range(work.data.shape[0]):
        for i in range(a, b):
            tr[i] = work.data[j, i].real
            ti[i] = work.data[j, i].imag
        for m in range(n):
            if m == k:
                continue
            rr = res[j, m].real
            ri = res[j, m].imag
            for i in range(a, b):
                tr[i] -= (rr * br[m, i] - ri * bi[m, i]) + (rr * bcr[m, i] + ri * bci[m, i])
                ti[i] -= (rr * bi[m, i] + ri * br[m, i]) + (rr * bci[m, i] - ri * bcr[m, i])
        for i in range(a, b):
            xn[j, i] = complex(tr[i], ti[i])
            power[i] += tr[i] * tr[i] + ti[i] * ti[i]


@jit
def _mode_band(work, lam_all, res, n, k, scene, delta, wlo, whi):
    """Fit band of mode ``k`` (eigenvalue ``lam = lam_all[k]``) within lines ``wlo..whi-1``:
    the largest power within ``Im lam +- max(2 |Re lam|, 2 dw)`` and the contiguous lines
    around it with power ``>= delta^2`` times that peak. The isolated data is computed only on
    the lines looked at (the peak search range and the band grown from the peak). Returns
    ``(peak, lo, hi)``."""
    lam = lam_all[k]
    omega = scene.grid.omega
    power = work.power
    half = max(2.0 * abs(lam.real), 2.0 * scene.dw)
    c = nearest_line(omega, lam.imag)
    plo = max(nearest_line(omega, lam.imag - half), wlo)
    phi = min(nearest_line(omega, lam.imag + half), whi - 1)
    clo = min(plo, c)
    chi = max(phi, c) + 1
    _isolated_lines(work, scene.grid, lam_all, res, n, k, clo, chi)
    best = c
    for i in range(plo, phi + 1):
        if power[i] > power[best]:
            best = i
    level = delta * delta * power[best]
    chunk = 16  # lines isolated at a time as the band grows
    lo = best
    while lo > wlo:
        if lo - 1 < clo:
            a = max(wlo, lo - chunk)
            _isolated_lines(work, scene.grid, lam_all, res, n, k, a, clo)
            clo = a
        if not (power[lo - 1] >= level):
            break
        lo -= 1
    hi = best + 1
    while hi < whi:
        if hi >= chi:
            b = min(whi, hi + chunk)
            _isolated_lines(work, scene.grid, lam_all, res, n, k, chi, b)
            chi = b
        if not (power[hi] >= level):
            break
        hi += 1
    return best, lo, hi


@jit
def _mode_snr(grid, lam, res, k):
    """Mode ``k``'s squared peak contribution (noise units): ``(sum, max)`` over the FRFs."""
    omega, x, dt, n_samples = grid
    total = 0.0
    best = 0.0
    for j in range(res.shape[0]):
        c2 = contribution_peak(omega, x, lam[k], res[j, k], dt, n_samples) ** 2
        total += c2
        best = max(best, c2)
    return total, best


@jit(inline="always")
def merge_prune(scene, params, modes, n, pinned):
    """Duplicates (closer than ``merge_tol`` bandwidths) keep the mode with the larger total SNR;
    modes not above the noise floor in any FRF, or that failed too often, are removed.
    Returns ``(n, changed)``."""
    lam, res, fails = modes
    grid = scene.grid
    changed = False
    while True:
        drop = -1
        for k in range(n):
            m = nearest_within(lam, n, lam[k], params.merge_tol, k)
            if m >= 0:
                drop = (
                    m if _mode_snr(grid, lam, res, m)[0] <= _mode_snr(grid, lam, res, k)[0] else k
                )
                break
        for k in range(n if drop < 0 else 0):
            weak = _mode_snr(grid, lam, res, k)[1] < scene.t_line
            if weak or fails[k] > params.max_iter // 2:
                drop = k
                break
        if drop < 0:
            return n, changed
        for i in range(drop, n - 1):
            lam[i] = lam[i + 1]
            for j in range(res.shape[0]):
                res[j, i] = res[j, i + 1]
            fails[i] = fails[i + 1]
            pinned[i] = pinned[i + 1]
        lam[n - 1] = complex(np.nan, np.nan)
        res[:, n - 1] = complex(np.nan, np.nan)
        fails[n - 1] = 0
        pinned[n - 1] = False
        n -= 1
        changed = True


@jit(inline="always")
def _fit_mode(scene, params, modes, n, k, work, state, it):
    """One sweep's update of mode ``k``: its band (kept while frozen), the fit on the isolated
    data of the group (FRFs weighted by the mode's SNR with ``reweight``), the two-state cycle
    test. Returns the step's score (< 1: settled, see :func:`sweeps`), -1 when not updated."""
    omega, x, dt, n_samples = scene.grid
    lam, res, fails = modes
    n_p = res.shape[0]
    lk = lam[k]
    # isolated data where the fit looks: +- max(20 |Re lam|, 40 lines), the last band (paper: all)
    wide = np.inf if params.paper_sweeps else max(20.0 * abs(lk.real), 40.0 * scene.dw)
    wlo = nearest_line(omega, lk.imag - wide)
    whi = nearest_line(omega, lk.imag + wide) + 1
    lo, hi = state.band_lo[k], state.band_hi[k]
    if hi > 0:
        wlo = min(wlo, lo)
        whi = max(whi, hi)
    if state.frozen[k] and omega[lo] <= lk.imag and lk.imag <= omega[hi - 1]:
        # a settled mode keeps its band (while it stays inside): lines entering and leaving a
        # data-defined band make the iteration map discontinuous and can cause limit cycles
        peak = (lo + hi) // 2
        _isolated_lines(work, scene.grid, lam, res, n, k, lo, hi)
    else:
        peak, lo, hi = _mode_band(work, lam, res, n, k, scene, params.delta, wlo, whi)
    state.band_lo[k] = lo
    state.band_hi[k] = hi
    code = -1
    new = complex(np.nan, np.nan)
    if hi - lo >= params.min_points:
        for j in range(n_p):
            if params.reweight and it <= 3:
                # each FRF weighted by its SNR for this mode (frozen after 3 sweeps: a fixed point)
                work.wts_all[k, j] = max(
                    contribution_peak(omega, x, lk, res[j, k], dt, n_samples), 1.0
                )
            work.wts[j] = work.wts_all[k, j] if params.reweight else 1.0
        ws = omega[peak] if omega[peak] > 0.0 else scene.dw
        nan = complex(np.nan, np.nan)  # no previous pole: unweighted lines
        new, code = fit_single(
            work.xn, scene.grid, lo, hi, ws, scene.limits, nan, work.wts, work.rtmp
        )
        if code != FIT_OK:
            state.fit_failed[k] += 1
    if code != FIT_OK:
        fails[k] += 1
        return -1.0
    ch = max(abs(new.real - lk.real) / abs(new.real), abs(new.imag - lk.imag) / abs(new.imag))
    step = abs(new - lk)
    cycle = abs(new - work.back[k]) < CYCLE_RATIO * step and not params.paper_sweeps
    score = ch / params.tol
    if params.se_fraction > 0.0:
        # standard error of the eigenvalue: 1 / sqrt(J), Fisher information J = sum_j c_j^2
        # sum_i (Re lam)^2 / |i w_i - lam|^4 (c_j the peak contribution in FRF j; residues known)
        cs = 0.0
        for j in range(n_p):
            cs += contribution_peak(omega, x, new, work.rtmp[j], dt, n_samples) ** 2
        g = 0.0
        for i in range(lo, hi):
            d = 1j * omega[i] - new
            q = d.real * d.real + d.imag * d.imag
            g += new.real * new.real / (q * q)
        se = 1.0 / np.sqrt(cs * g) if cs * g > 0.0 else np.inf
        score = min(score, step / (params.se_fraction * se))
    state.frozen[k] = ch < FREEZE_CHANGE or cycle
    if cycle:
        new = 0.5 * (new + lk)
    work.back[k] = lk
    for j in range(n_p):
        res[j, k] = work.rtmp[j]
    lam[k] = new
    work.basis_lo[k] = 0  # its bases are made again where next needed
    work.basis_hi[k] = 0
    return score


@jit(inline="always")
def sweeps(scene, params, modes, n, work):
    """Isolation sweeps until every eigenvalue has settled, or the early pruning after 3 sweeps
    finds an insignificant mode. Returns ``(iterations, converged)``.

    Stopping rule: a mode has settled in a sweep when its Re and Im change less than ``tol``
    (relative) or (``se_fraction > 0``) its step is below ``se_fraction`` of its standard error;
    the sweeps have converged when every mode has settled in the same sweep. The standard error
    term makes the rule reachable at any noise level: close modes converge only linearly, and a
    relative change of ``tol`` there costs tens of sweeps that move the eigenvalues by a small
    fraction of their uncertainty. A mode that steps back to where it was two sweeps before
    (``|lam_new - lam_back| < CYCLE_RATIO |lam_new - lam_old|``) is in a two-state cycle (its
    band switching between two data-defined choices): it takes the mean of the two states and
    keeps its band, so the cycle dies out. Modes in ``work.pinned`` are not re-fitted. With
    ``paper_sweeps`` (the per-FRF isolation, measured against the paper's figures) the order
    is fixed per restart and there is no cycle averaging.
    """
    omega, x, dt, n_samples = scene.grid
    lam, res, fails = modes
    m = lam.shape[0]
    state = SweepState(
        band_lo=np.zeros(m, dtype=np.int64),
        band_hi=np.zeros(m, dtype=np.int64),
        frozen=np.zeros(m, dtype=np.bool_),
        fit_failed=np.zeros(m, dtype=np.int64),
    )
    _forget_bases(work, n)  # a restart: modes merged, pruned, added or split
    for k in range(n):
        work.back[k] = complex(np.nan, np.nan)
    it = 0
    converged = n == 0
    tot = np.empty(m)
    order = np.arange(n)
    for it in range(1, params.max_iter + 1 if n > 0 else 1):
        if it == 1 or not params.paper_sweeps:  # the paper: the order of the restart's start
            for k in range(n):
                tot[k] = -_mode_snr(scene.grid, lam, res, k)[0]
            order = argsort_first(tot, n)  # by decreasing total SNR
        change = 0.0
        for k in order:
            if not work.pinned[k]:
                change = max(change, _fit_mode(scene, params, modes, n, k, work, state, it))
        if change < 1.0:
            converged = True
            break
        if it == 3:
            # early pruning: spurious candidates of single FRFs leave once residues are fitted
            weak = False
            for k in range(n):
                weak = weak or _mode_snr(scene.grid, lam, res, k)[1] < scene.t_line
            if weak:
                break
    # a fit that ran and failed in every sweep (at least 2) marks the mode for merge-and-prune; a
    # band too narrow to fit does not (a lightly damped mode on a coarse grid spans 1-3 lines:
    # measurement.uff lost 4 of its 6 modes so); the significance test still removes noise
    for k in range(n if it >= 2 else 0):
        if state.fit_failed[k] >= it:
            fails[k] = max(fails[k], params.max_iter // 2 + 1)
    return it, converged


@jit(inline="always")
def order_check(scene, params, modes, n, work, masked, c, split_lam, split_res):
    """Model-order check: a significant peak of the residual's power (over the noise and the
    residual that eigenvalue errors of size ``tol`` leave) where a physical mode fits adds it; a
    coherent residual inside a mode's ``+- 3 |Re lam|`` band splits that mode by a two-mode fit.
    A window tried is masked. Returns ``(n, added, ks, iso)``: ``ks`` the mode split, -1 for an
    added mode.

    The two-mode fit is the caller's (compiled only when a split is tried): the check returns
    ``ks = SPLIT_WANTED`` with the isolated data ``iso`` (P, F) of the mode to split (its band
    in the counts ``c``, :attr:`~.groups.Resume.counts`); called again once ``split_lam``,
    ``split_res`` and the fit's code are in (the :class:`~.groups.Resume` arrays), it takes the
    split or goes on with its next try, as in one pass. The arrays, not the record: every
    record passed into inlined code is reference-counted array by array (compile time)."""
    omega, x, dt, n_samples = scene.grid
    lam, res, fails = modes
    n_p, n_f = work.data.shape
    no_iso = np.empty((0, 0), dtype=np.complex128)
    _forget_bases(work, n)  # merge_prune may have moved modes between slots
    _isolated_lines(work, scene.grid, lam, res, n, np.int64(-1), np.int64(0), n_f)
    stat = np.zeros(n_f)
    for j in range(n_p):
        env = tolerance_envelope(omega, lam, res[j], n, params.tol)
        for i in range(n_f):
            stat[i] += abs(work.xn[j, i]) ** 2 / (1.0 + env[i] ** 2)
    first = c[AT_TRY]
    if c[AT_SPLIT] == SPLIT_FITTED:  # the caller's two-mode fit of try ``first``
        c[AT_SPLIT] = SPLIT_NONE
        first += 1
        ks = c[AT_KS]
        if c[AT_SPLIT_CODE] == FIT_OK:
            lam[ks] = split_lam[0]
            for j in range(n_p):
                res[j, ks] = split_res[j, 0]
            lam[n] = split_lam[1]
            for j in range(n_p):
                res[j, n] = split_res[j, 1]
            fails[n] = 0
            c[AT_TRY] = 0
            return n + 1, True, ks, no_iso
    c[AT_TRY] = 0
    for _try in range(first, 8):
        peak = -1
        for i in range(n_f):
            if not masked[i] and (peak < 0 or stat[i] > stat[peak]):
                peak = i
        if peak < 0 or stat[peak] < scene.t_sum:
            peak = band_energy_peak(stat, omega, lam, n, n_p, params.pfa, params.min_points, masked)
            if peak < 0:
                break
        ks = -1  # the mode whose +- 3 |Re lam| window holds the peak
        for k in range(n):
            off = abs(omega[peak] - lam[k].imag)
            if off <= 3.0 * abs(lam[k].real) and (ks < 0 or off < abs(omega[peak] - lam[ks].imag)):
                ks = k
        r_new = np.empty(n_p, dtype=np.complex128)
        if ks >= 0:
            # a coherent residual inside a mode's band: two close modes were probably fitted as
            # one; a two-mode fit to its isolated data replaces it when both modes are physical
            wl, wh = pole_band(omega, lam[ks], SPLIT_DELTA, max(params.min_points, 6))
            masked[wl:wh] = True
            iso = work.xn.copy()
            for j in range(n_p):
                add_mode(iso[j], x, lam[ks], res[j, ks], dt, n_samples, 1.0, np.int64(0), n_f)
                work.wts[j] = work.wts_all[ks, j] if params.reweight else 1.0
            c[AT_SPLIT], c[AT_KS], c[AT_WL], c[AT_WH], c[AT_TRY] = SPLIT_ASKED, ks, wl, wh, _try
            return n, False, SPLIT_WANTED, iso
        else:
            # no duplicate test here: a coherent residual next to a mode (two close modes fitted
            # as one) must be able to split it; true duplicates merge after the restart
            work.wts[:] = 1.0
            new, _lo, _hi, code = peak_trial(
                work.xn,
                work.power,
                scene,
                peak,
                params.delta,
                params.min_points,
                work.wts,
                work.rtmp,
                masked,
            )
            if code != FIT_OK:
                continue
            for j in range(n_p):
                r_new[j] = work.rtmp[j]
        lam[n] = new
        for j in range(n_p):
            res[j, n] = r_new[j]
        fails[n] = 0
        return n + 1, True, ks, no_iso
    return n, False, -1, no_iso


@jit
def point_estimates_kernel(data, lam, res, scene, delta, min_points, work):
    """Per-FRF single-mode estimates of the modes ``lam`` (K,) on each row of ``data`` (P, F)
    isolated with the residues ``res`` (P, K) (eq. 7; noise units): ``(P, K)`` complex, NaN
    where the band is too narrow or the fit fails. ``work``: :func:`new_work` of one row of
    ``F`` lines for ``max(K, 1)`` modes."""
    omega, x, dt, n_samples = scene.grid
    n_p, n_f = data.shape
    n_k = lam.shape[0]
    out = np.full((n_p, n_k), complex(np.nan, np.nan))
    _forget_bases(work, n_k)
    for j in range(n_p):
        for i in range(n_f):
            work.data[0, i] = data[j, i]
        for k in range(n_k):
            at = np.int64(0)
            peak, lo, hi = _mode_band(work, lam, res[j : j + 1], n_k, k, scene, delta, at, n_f)
            if hi - lo < min_points:
                continue
            ws = omega[peak] if omega[peak] > 0.0 else scene.dw
            nan = complex(np.nan, np.nan)
            new, code = fit_single(
                work.xn, scene.grid, lo, hi, ws, scene.limits, nan, work.wts, work.rtmp
            )
            if code == FIT_OK:
                out[j, k] = new
    return out
