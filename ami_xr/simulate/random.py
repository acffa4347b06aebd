"""Random lumped-mass systems with exactly known modal parameters, for tests and benchmarks.

A structure of point masses and springs (a grounded ``chain`` or a ``grid`` clamped along its
first row) gets non-proportional damping: modal damping plus dashpots to ground at a few random
masses. Optionally, as in the paper's benchmark, small spring-mass-dashpot absorbers are hung
from the structure:

* ``closely_spaced=True``: an absorber TUNED to a structural mode splits it into two modes whose
  frequencies differ by about ``pair_gap`` (relative), comparable to their half-power bandwidth
  (mode coupling).
* ``weak_mode=True``: a light absorber DETUNED between two structural modes, hung far from the
  drive point, gives a localized mode whose drive-point contribution is at most ``weak_level``
  times the median drive-point peak of the other modes, and at its natural frequency it is at
  most 10 % of the other modes' drive-point FRF (see :func:`contrast`); at the absorber's own
  point it stands out as a peak.

Every absorber is a degree of freedom and is always measured. The truth Dataset records
``closely_spaced_pair`` (two mode numbers) and ``weak_mode`` (one mode number) as attributes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import scipy.linalg
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.provenance import add_history
from ami_xr.simulate.beam import frf_from_impulse
from ami_xr.simulate.checks import (
    SOURCES,  # noqa: F401 - read from here too
    check_int,
    check_positive,
    check_range,
    sampling_of,
)
from ami_xr.simulate.modal import frf, impulse_response, modal_model
from ami_xr.simulate.noise import (
    ATTR_NOISE_KIND,
    ATTR_NOISE_LEVEL,
    ATTR_NOISE_SEED,
    add_noise,
)

TOPOLOGIES = ("chain", "grid")
MIN_POINTS, MAX_POINTS = 5, 50
ATTR_PAIR = "closely_spaced_pair"
ATTR_WEAK = "weak_mode"


def _structure(n: int, topology: str, rng: np.random.Generator):
    """Masses and springs of the structure: (m, list of (i, j, k)), j = -1 means ground."""
    m = rng.uniform(0.5, 2.0, n)
    springs = []
    if topology == "chain":
        springs.append((0, -1, rng.uniform(0.5, 2.0)))
        for i in range(1, n):
            springs.append((i - 1, i, rng.uniform(0.5, 2.0)))
    else:
        nx = int(np.ceil(np.sqrt(n)))
        for i in range(n):
            r, c = divmod(i, nx)
            if r == 0:
                springs.append((i, -1, rng.uniform(0.5, 2.0)))  # clamped first row
            if c > 0:
                springs.append((i - 1, i, rng.uniform(0.5, 2.0)))
            if r > 0:
                springs.append((i - nx, i, rng.uniform(0.5, 2.0)))
    return m, springs


def _assemble(n: int, elements) -> np.ndarray:
    out = np.zeros((n, n))
    for i, j, v in elements:
        out[i, i] += v
        if j >= 0:
            out[j, j] += v
            out[i, j] -= v
            out[j, i] -= v
    return out


def _undamped(M, K):
    w2, phi = scipy.linalg.eigh(K, M)
    return np.sqrt(w2), phi


class _Structure(NamedTuple):
    """The damped structure before any absorber: matrices, masses and undamped modes."""

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    m: np.ndarray  # masses
    w: np.ndarray  # undamped natural frequencies (rad/s), ascending
    phi: np.ndarray  # undamped mode shapes (columns)


def _damped_structure(n, topology, fmax, damping, rng) -> _Structure:
    """Masses and springs scaled so the highest mode is at ``0.8 fmax``; damping: modal part
    70 %, dashpots to ground at ~1/3 of the masses the rest (non-proportional)."""
    m, springs = _structure(n, topology, rng)
    M = np.diag(m)
    K = _assemble(n, springs)
    w, phi = _undamped(M, K)
    K *= (2 * np.pi * 0.8 * fmax / w[-1]) ** 2
    w, phi = _undamped(M, K)
    zeta = rng.uniform(damping[0], damping[1], n)
    C = M @ phi @ np.diag(0.7 * 2 * zeta * w) @ phi.T @ M
    grounded = rng.choice(n, size=max(1, n // 3), replace=False)
    for i in grounded:
        C[i, i] += 0.3 * 2 * np.mean(zeta) * np.mean(w) * m[i] * rng.uniform(0.5, 1.5)
    return _Structure(M, C, K, m, w, phi)


def _grow(M, C, K, at, mass, stiff, damp):
    """The system with one more mass hung from degree of freedom ``at`` by a spring and dashpot."""
    n = M.shape[0]
    M2, C2, K2 = (np.zeros((n + 1, n + 1)) for _ in range(3))
    M2[:n, :n], C2[:n, :n], K2[:n, :n] = M, C, K
    M2[n, n] = mass
    v = np.zeros(n + 1)
    v[at], v[n] = -1.0, 1.0
    return M2, C2 + damp * np.outer(v, v), K2 + stiff * np.outer(v, v)


def _add_pair_absorber(st: _Structure, pair_gap, rng):
    """Hang an absorber tuned to a structural mode in the lower half that is well separated from
    its neighbours (grids can have near-repeated modes), at its largest amplitude. Returns the
    structure's ``M, C, K`` grown by it and the tuning frequency (rad/s)."""
    w, phi = st.w, st.phi
    rel_gap = np.diff(w) / w[:-1]
    sep = np.minimum(np.r_[np.inf, rel_gap], np.r_[rel_gap, np.inf])
    lower = np.arange(w.size) < max(2, (w.size + 1) // 2)
    good = np.flatnonzero(lower & (sep > 4 * pair_gap))
    r = int(rng.choice(good)) if good.size else int(np.argmax(np.where(lower, sep, 0)))
    at = int(np.argmax(np.abs(phi[:, r])))
    mass = pair_gap**2 / phi[at, r] ** 2  # splitting ~ w_r sqrt(m_a phi^2)
    stiff = mass * w[r] ** 2
    M, C, K = _grow(st.M, st.C, st.K, at, mass, stiff, 2 * 0.01 * np.sqrt(stiff * mass))
    return M, C, K, w[r]


def _weak_site(st: _Structure, topology, pair_target, rng) -> tuple[int, float, float]:
    """Where the weak absorber hangs, its first mass and its frequency: between two structural
    modes away from any absorber tuning, far from the drive point (near the grounded end of a
    chain, the far corner of a grid)."""
    w, n = st.w, st.w.size
    cands = [
        s
        for s in range(n - 1)
        if pair_target is None or not (w[s] <= pair_target * 1.3 and w[s + 1] >= pair_target / 1.3)
    ]
    s = int(rng.choice(cands)) if cands else 0
    w_weak = np.sqrt(w[s] * w[s + 1])
    at = int(rng.integers(0, max(1, n // 3))) if topology == "chain" else n - 1
    return at, 0.02 * st.m.mean(), w_weak


def _choose_points(must: list[int], n_points: int, n_dof: int, rng) -> list[int]:
    """The measured degrees of freedom: ``must`` and a random choice of the others."""
    others = [i for i in range(n_dof) if i not in must]
    extra = (
        rng.choice(others, size=n_points - len(must), replace=False) if n_points > len(must) else []
    )
    return sorted(must + [int(i) for i in extra])


def _add_weak_absorber(M, C, K, site, points, drive, weak_level):
    """Hang the weak absorber, halving its mass until its mode is weak enough (see
    :func:`random_system`). Returns the grown ``M, C, K``, the truth and the weak mode's index."""
    at, mass, w_weak = site
    n_dof = M.shape[0] + 1
    for _ in range(60):
        stiff = mass * w_weak**2
        M2, C2, K2 = _grow(M, C, K, at, mass, stiff, 2 * 0.01 * np.sqrt(stiff * mass))
        truth = modal_model(
            M2, C2, K2, output=np.eye(n_dof)[points], point_labels=points, drive_point=drive
        )
        weak_k, ratio = _weakest(truth, drive, n_dof - 1)
        if ratio <= weak_level and contrast(truth, weak_k, drive) <= 0.1:
            return M2, C2, K2, truth, weak_k
        mass *= 0.5
    raise AmiXrValueError(  # pragma: no cover - the mass halves 60 times; never seen
        "weak_level: could not make the weak mode that weak"
    )


def _noisy(out: xr.Dataset, noise, kind, seed) -> xr.Dataset:
    """Analytic FRFs with eq. 15 applied to the real and imaginary parts along frequency."""
    if not noise:
        return out
    re = add_noise(out[names.FRF].real, noise, seed=seed, kind=kind, dim=names.FREQUENCY)
    im = add_noise(
        out[names.FRF].imag,
        noise,
        seed=None if seed is None else seed + 1,
        kind=kind,
        dim=names.FREQUENCY,
    )
    out[names.FRF] = (re + 1j * im).assign_attrs(out[names.FRF].attrs)
    return out


def random_system(
    n_points: int = 8,
    topology: str = "chain",
    *,
    n_modes: int | None = None,
    closely_spaced: bool = False,
    weak_mode: bool = False,
    noise: float = 0.0,
    noise_kind: str = "uniform",
    seed: int | None = 0,
    frequency: Any = None,
    source: str = names.SOURCE_ANALYTIC,
    max_frequency_hz: float = 50.0,
    damping: tuple[float, float] = (0.005, 0.03),
    pair_gap: float = 0.02,
    weak_level: float = 0.01,
    n_frequencies: int = 4096,
    duration: float | None = None,
    n_samples: int | None = None,
) -> tuple[xr.Dataset, xr.Dataset]:
    """A random lumped-mass system: its FRFs at the measured points and the exact truth.

    Parameters
    ----------
    n_points : int
        Number of measured points, 5..50.
    topology : {"chain", "grid"}
        Masses in a line grounded at one end, or on a square grid clamped along its first row.
    n_modes : int, optional
        Degrees of freedom = number of modes (default ``n_points``; must be >= ``n_points``).
        Absorbers (below) count among them. With more modes than points, the drive point, the
        absorbers and a random choice of the other masses are measured.
    closely_spaced : bool
        Add an absorber tuned to a structural mode: two modes about ``pair_gap`` apart.
    weak_mode : bool
        Add a light detuned absorber far from the drive point: a weakly excited mode.
    noise : float
        Noise level alpha. ``source="impulse_response"``: eq. 15 on the impulse responses
        (per channel, before the FFT). ``source="analytic"``: the same model applied to the
        real and the imaginary part of each FRF along frequency.
    noise_kind : {"uniform", "gaussian"}
    seed : int, optional
        Seeds the system's parameters and the noise (reproducible).
    frequency : array_like, optional
        FRF frequencies in Hz for ``source="analytic"`` (default ``n_frequencies`` points from
        0 to ``max_frequency_hz``). Not allowed with ``source="impulse_response"``.
    source : {"analytic", "impulse_response"}
        Exact eq. 4 on a frequency grid, or ``dt * rfft`` of sampled impulse responses.
    max_frequency_hz : float
        The highest structural natural frequency is ``0.8 * max_frequency_hz``.
    damping : (float, float)
        Range of the modal damping part; dashpots to ground add some non-proportional damping.
    pair_gap : float
        Target relative frequency gap of the closely spaced pair (0 < pair_gap < 0.2).
    weak_level : float
        Upper bound of the weak mode's drive-point peak relative to the median of the others.
    n_frequencies : int
        Length of the default analytic frequency grid.
    duration, n_samples : optional
        Impulse-response record (defaults: until the slowest mode decays by e^-8; Nyquist at
        least ``1.25 * max_frequency_hz``, a power of two).

    Returns
    -------
    frf : xarray.Dataset
        FRF Dataset (displacement receptance, drive point attribute, ``frf_source``).
    truth : xarray.Dataset
        Exact ``eigenvalue``, ``natural_frequency``, ``damping_ratio``, ``mode_vector`` and
        ``residue`` at the measured points (all modes), attributes ``topology``,
        ``closely_spaced_pair`` and ``weak_mode`` (mode numbers, 1-based; absent when not asked).
    """
    n_points, n_modes, n_struct = _check_size(
        n_points, topology, n_modes, closely_spaced, weak_mode
    )
    sampling = sampling_of(locals())
    zeta = check_range(damping, "damping", 0.3)
    pair_gap, weak_level = _check_absorbers(pair_gap, weak_level)
    seed = sampling.seed

    rng = np.random.default_rng(seed)
    noise_seed = None if seed is None else int(rng.integers(2**31))
    absorbers = (closely_spaced, pair_gap, weak_mode, weak_level)
    truth, drive = _random_truth(
        n_struct, n_points, n_modes, topology, sampling.max_frequency_hz, zeta, absorbers, rng
    )
    truth.attrs["seed"] = -1 if seed is None else seed
    truth = add_history(
        truth,
        "ami_xr.simulate.random_system",
        {
            "n_points": n_points,
            "topology": topology,
            "n_modes": n_modes,
            "closely_spaced": bool(closely_spaced),
            "weak_mode": bool(weak_mode),
            "seed": seed,
        },
    )
    out = system_frfs(truth, drive, **sampling.frf_options(), noise_seed=noise_seed)
    out = add_history(
        out, "ami_xr.simulate.random_system", {"source": source, "noise": noise, "seed": seed}
    )
    return out, truth


def _check_size(n_points, topology, n_modes, closely_spaced, weak_mode) -> tuple[int, int, int]:
    """Checked ``n_points``, ``n_modes`` and the structural modes (those not of an absorber)."""
    n_points = check_int(n_points, "n_points", MIN_POINTS, MAX_POINTS)
    if topology not in TOPOLOGIES:
        raise AmiXrValueError(f"topology: expected one of {TOPOLOGIES}, got {topology!r}")
    n_modes = n_points if n_modes is None else check_int(n_modes, "n_modes", n_points, 400)
    n_abs = int(bool(closely_spaced)) + int(bool(weak_mode))
    n_struct = n_modes - n_abs
    if n_struct < 4:
        raise AmiXrValueError(
            f"n_modes: need at least {4 + n_abs} modes with {n_abs} absorber(s), got {n_modes}"
        )
    return n_points, n_modes, n_struct


def _check_absorbers(pair_gap, weak_level) -> tuple[float, float]:
    """Checked relative gap of the closely spaced pair and peak ratio of the weak mode."""
    pair_gap = check_positive(pair_gap, "pair_gap")
    if pair_gap >= 0.2:
        raise AmiXrValueError(f"pair_gap: expected a relative gap < 0.2, got {pair_gap}")
    weak_level = check_positive(weak_level, "weak_level")
    if weak_level >= 1:
        raise AmiXrValueError(f"weak_level: expected a ratio < 1, got {weak_level}")
    return pair_gap, weak_level


def _random_truth(n_struct, n_points, n_modes, topology, fmax, zeta, absorbers, rng):
    """The random structure with its absorbers (``absorbers``: closely_spaced, pair_gap,
    weak_mode, weak_level), the measured points, and its exact truth with the ``topology``,
    ``closely_spaced_pair`` and ``weak_mode`` attributes; and the drive point."""
    closely_spaced, pair_gap, weak_mode, weak_level = absorbers
    st = _damped_structure(n_struct, topology, fmax, zeta, rng)
    M, C, K = st.M, st.C, st.K
    drive = n_struct - 1 if topology == "chain" else 0  # free end / clamped-edge corner
    pair_dof = pair_target = None
    if closely_spaced:
        M, C, K, pair_target = _add_pair_absorber(st, pair_gap, rng)
        pair_dof = M.shape[0] - 1
    if weak_mode:
        site = _weak_site(st, topology, pair_target, rng)
    must = [drive] + [d for d in (pair_dof, n_modes - 1 if weak_mode else None) if d is not None]
    points = _choose_points(list(dict.fromkeys(must)), n_points, n_modes, rng)
    weak_k = None
    if weak_mode:
        M, C, K, truth, weak_k = _add_weak_absorber(M, C, K, site, points, drive, weak_level)
    else:
        truth = modal_model(
            M, C, K, output=np.eye(n_modes)[points], point_labels=points, drive_point=drive
        )

    truth.attrs["topology"] = topology
    if closely_spaced:
        lam = truth[names.EIGENVALUE].values
        # the pair: the two modes nearest the tuning frequency
        near = np.argsort(np.abs(np.abs(lam) - pair_target))[:2]
        pair = sorted(int(x) + 1 for x in near)
        truth.attrs[ATTR_PAIR] = np.array(pair, dtype=np.int64)
    if weak_mode:
        truth.attrs[ATTR_WEAK] = int(weak_k) + 1
    return truth, drive


def system_frfs(
    truth: xr.Dataset,
    drive,
    *,
    source: str,
    frequency: Any,
    max_frequency_hz: float,
    n_frequencies: int,
    duration: float | None,
    n_samples: int | None,
    noise: float,
    noise_kind: str,
    noise_seed: int | None,
) -> xr.Dataset:
    """The FRFs of a truth Dataset as :func:`random_system` makes them (arguments checked by the
    caller): analytic eq. 4 on ``frequency`` (default ``n_frequencies`` lines from 0 to
    ``max_frequency_hz``) with eq. 15 on the real and imaginary parts, or ``dt * rfft`` of
    impulse responses with eq. 15 on each channel (record: until the slowest mode decays by
    e^-8, Nyquist at least ``1.25 max_frequency_hz``, a power of two samples)."""
    if source == names.SOURCE_ANALYTIC:
        f = (
            np.linspace(0.0, max_frequency_hz, n_frequencies)
            if frequency is None
            else np.asarray(frequency, dtype=np.float64)
        )
        out = _noisy(frf(truth, f, drive), noise, noise_kind, noise_seed)
    else:
        lam = truth[names.EIGENVALUE].values
        if duration is None:
            duration = float(np.ceil(8.0 / np.min(-lam.real)))
        if n_samples is None:
            n_samples = int(2 ** np.ceil(np.log2(2 * 1.25 * max_frequency_hz * duration)))
        ts = impulse_response(truth, (duration, n_samples), drive)
        if noise:
            ts = add_noise(ts, noise, seed=noise_seed, kind=noise_kind)
        out = frf_from_impulse(ts)
    if noise:
        out.attrs[ATTR_NOISE_LEVEL] = float(noise)
        out.attrs[ATTR_NOISE_KIND] = noise_kind
        if noise_seed is not None:
            out.attrs[ATTR_NOISE_SEED] = noise_seed
    return out


def contrast(truth: xr.Dataset, mode: int, point) -> float:
    """``|G_k| / |sum of the other modes|`` at point ``point`` and the natural frequency of
    mode ``mode`` (0-based): above 1 the mode makes its own peak there, far below 1 it is
    masked by the others."""
    fk = truth[names.NATURAL_FREQUENCY].values[mode]
    others = [i for i in range(truth.sizes[names.MODE]) if i != mode]
    one = frf(truth.isel({names.MODE: [mode]}), [fk])[names.FRF].sel({names.POINT: point})
    rest = frf(truth.isel({names.MODE: others}), [fk])[names.FRF].sel({names.POINT: point})
    return float(np.abs(one.values[0]) / np.abs(rest.values[0]))


def _peaks(truth: xr.Dataset, point) -> np.ndarray:
    """Approximate peak magnitude |A| / (zeta w) ~ |A| / |Re lam| of each mode's contribution."""
    a = truth[names.RESIDUE].sel({names.POINT: point}).values
    lam = truth[names.EIGENVALUE].values
    return np.abs(a) / np.abs(lam.real)


def _weakest(truth: xr.Dataset, drive, weak_dof) -> tuple[int, float]:
    """The absorber-localized mode and its drive-point peak relative to the others' median."""
    phi = truth[names.MODE_VECTOR]
    local = np.abs(phi.sel({names.POINT: weak_dof}).values) / np.sqrt(
        (np.abs(phi.values) ** 2).sum(axis=0)
    )
    k = int(np.argmax(local))
    peaks = _peaks(truth, drive)
    others = np.delete(peaks, k)
    return k, float(peaks[k] / np.median(others))


def mode_peaks(truth: xr.Dataset, point=None) -> xr.DataArray:
    """Peak magnitude ``|A_jk| / |Re(lam_k)|`` of each mode's FRF contribution at ``point``.

    Useful to see which modes are weakly excited (default point: the drive point).
    """
    point = truth.attrs[names.ATTR_DRIVE_POINT] if point is None else point
    return xr.DataArray(
        _peaks(truth, point), dims=[names.MODE], coords={names.MODE: truth[names.MODE].values}
    )


__all__: Sequence[str] = ("random_system", "mode_peaks", "contrast")
