"""A fixed catalogue of random test systems and the scoring of identified modes against them.

:func:`catalogue` lists, deterministically, the cases of ``scripts/benchmark_catalogue.py``
(issue 10, item 7): random chains and grids from :func:`~ami_xr.simulate.random_system`, with
and without a closely spaced pair and a weakly excited mode, at noise 0, 1, 5 and 15 %. Every
block of 32 consecutive cases holds each of the 2 x 2 x 2 x 4 combinations once.
:func:`cluster_catalogue` lists the overlap cases of issue 20 (item 5): systems of
:func:`~ami_xr.simulate.clustered_system` with clusters of three and four modes at target
overlap 0.15, 0.35, 0.7 and 1.4, analytic and FFT'd impulse-response FRFs, at the same noise
levels; every block of 32 cases holds each of the 2 x 4 x 4 combinations once.

:func:`score_modes` matches identified modes to the true ones (one-to-one, nearest first) and
measures their errors, relative and over the Cramér-Rao bound. :func:`line_noise_std` and
:func:`identifiable` say which true modes the data can show at all:

* **Noise of one FRF line** ``sigma_j = sqrt(E |e_jn|^2)`` at point ``j``: for the analytic FRFs
  of ``random_system(noise=alpha)`` the real and the imaginary part get eq. 15 along frequency,
  so ``sigma_j^2 = c alpha^2 (max_n |Re H_jn|^2 + max_n |Im H_jn|^2)`` with the noise-free
  ``H``, ``c = 1/3`` for uniform and ``c = 1`` for Gaussian ``r``. For FFT'd impulse responses
  (``frf_source="impulse_response"``) eq. 15 is on the ``N`` samples of each response ``h_j``
  and the FRF is ``dt * rfft``, so ``sigma_j = alpha max_n |h_jn| dt sqrt(c N)``.
* **Peak SNR** of mode ``k`` at point ``j``: ``|A_jk| / |Re lam_k| / sigma_j`` -- the peak
  magnitude of the mode's own contribution ``A_jk / (i w - lam_k)`` (reached at
  ``w = Im lam_k``; see :func:`~ami_xr.simulate.mode_peaks`) over the noise of that FRF line.
* **Identifiable**: the peak SNR is at least ``snr_db`` (default 6 dB, an amplitude ratio of
  ``10**(6/20) = 2.0``) at one measured point at least. Without noise every mode is.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import product
from typing import Any, NamedTuple

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.core.matching import match_nearest
from ami_xr.errors import AmiXrValueError
from ami_xr.simulate.checks import check_int
from ami_xr.simulate.cluster import clustered_system
from ami_xr.simulate.modal import frf as model_frf
from ami_xr.simulate.modal import impulse_response
from ami_xr.simulate.noise import ATTR_NOISE_KIND, ATTR_NOISE_LEVEL
from ami_xr.simulate.random import TOPOLOGIES, mode_peaks, random_system

#: Noise levels of the catalogue (alpha of eq. 15 on the FRF's real and imaginary parts).
NOISE_LEVELS = (0.0, 0.01, 0.05, 0.15)
#: Every combination (topology, closely_spaced, weak_mode, noise), noise varying fastest.
COMBINATIONS = tuple(
    (topo, pair, weak, noise)
    for weak, pair, topo, noise in product((False, True), (False, True), TOPOLOGIES, NOISE_LEVELS)
)
#: Target overlap of the cluster cases, one in each overlap bin <0.25, 0.25-0.5, 0.5-1, 1-2.
CLUSTER_OVERLAPS = (0.15, 0.35, 0.7, 1.4)
#: Damping ratios of the cluster modes per target overlap: well separated modes with 8 %
#: damping would span more than the band, so the low-overlap clusters are lighter.
CLUSTER_DAMPING = {0.15: (0.005, 0.02), 0.35: (0.01, 0.04), 0.7: (0.02, 0.08), 1.4: (0.02, 0.08)}
CLUSTER_SOURCES = (names.SOURCE_ANALYTIC, names.SOURCE_IMPULSE)
#: Every combination (source, overlap, noise) of the cluster cases, noise varying fastest.
CLUSTER_COMBINATIONS = tuple(
    (src, ov, noise) for src, ov, noise in product(CLUSTER_SOURCES, CLUSTER_OVERLAPS, NOISE_LEVELS)
)
CLUSTER_LAYOUTS = ((3,), (4,), (3, 4))  # cluster sizes, drawn per case
MIN_MODES, MAX_MODES = 6, 12  # degrees of freedom of a catalogue system (absorbers included)
DEFAULT_SNR_DB = 6.0
DEFAULT_TOLERANCE = 1.0  # match radius in units of |Re lam_true| (half the half-power bandwidth)


class CatalogueCase(NamedTuple):
    """One catalogue system: the arguments of :func:`~ami_xr.simulate.random_system`."""

    index: int
    topology: str
    closely_spaced: bool
    weak_mode: bool
    noise: float
    n_points: int
    n_modes: int
    seed: int

    @property
    def name(self) -> str:
        """A short label such as ``07-grid-pair-weak-5%``."""
        parts = [f"{self.index:02d}", self.topology]
        parts += ["pair"] if self.closely_spaced else []
        parts += ["weak"] if self.weak_mode else []
        return "-".join([*parts, f"{100 * self.noise:g}%"])

    def build(self, **kwargs: Any) -> tuple[xr.Dataset, xr.Dataset]:
        """``random_system(...)`` of this case: ``(frf, truth)``; ``kwargs`` (for example
        ``n_frequencies``) are passed on."""
        return random_system(
            self.n_points,
            self.topology,
            n_modes=self.n_modes,
            closely_spaced=self.closely_spaced,
            weak_mode=self.weak_mode,
            noise=self.noise,
            seed=self.seed,
            **kwargs,
        )


def catalogue(n_cases: int = 32, seed: int = 0) -> list[CatalogueCase]:
    """The benchmark catalogue: ``n_cases`` random systems, the same for the same ``seed``.

    Case ``i`` has combination ``COMBINATIONS[i % 32]`` (topology chain/grid, with or without a
    closely spaced pair, with or without a weakly excited mode, noise 0/1/5/15 %; noise varies
    fastest), so any 32 consecutive cases cover every combination once. Its number of modes
    (6..12, absorbers included), of measured points (5..modes) and its system seed are drawn
    from ``numpy.random.default_rng(seed)``.
    """
    n_cases = check_int(n_cases, "n_cases", 1)
    seed = check_int(seed, "seed", 0)
    rng = np.random.default_rng(seed)
    cases = []
    for i in range(n_cases):
        topo, pair, weak, noise = COMBINATIONS[i % len(COMBINATIONS)]
        n_modes = int(rng.integers(MIN_MODES, MAX_MODES + 1))
        n_points = int(rng.integers(5, n_modes + 1))
        cases.append(
            CatalogueCase(i, topo, pair, weak, noise, n_points, n_modes, int(rng.integers(2**31)))
        )
    return cases


class ClusterCase(NamedTuple):
    """One overlap case: the arguments of :func:`~ami_xr.simulate.clustered_system`."""

    index: int
    source: str
    overlap: float
    cluster_sizes: tuple[int, ...]
    noise: float
    n_points: int
    n_modes: int
    seed: int

    @property
    def name(self) -> str:
        """A short label such as ``C05-imp-ov0.35-3+4-1%``."""
        src = "imp" if self.source == names.SOURCE_IMPULSE else "ana"
        sizes = "+".join(str(m) for m in self.cluster_sizes)
        return f"C{self.index:02d}-{src}-ov{self.overlap:.2f}-{sizes}-{100 * self.noise:g}%"

    def build(self, **kwargs: Any) -> tuple[xr.Dataset, xr.Dataset]:
        """``clustered_system(...)`` of this case: ``(frf, truth)``; ``kwargs`` (for example
        ``n_frequencies`` for analytic FRFs) are passed on."""
        if self.source == names.SOURCE_IMPULSE:
            kwargs.pop("n_frequencies", None)
        return clustered_system(
            self.n_points,
            cluster_sizes=self.cluster_sizes,
            overlap=self.overlap,
            n_modes=self.n_modes,
            cluster_damping=CLUSTER_DAMPING[self.overlap],
            noise=self.noise,
            seed=self.seed,
            source=self.source,
            **kwargs,
        )


def cluster_catalogue(n_cases: int = 32, seed: int = 0) -> list[ClusterCase]:
    """The overlap cases: ``n_cases`` clustered systems, the same for the same ``seed``.

    Case ``i`` has combination ``CLUSTER_COMBINATIONS[i % 32]`` (source analytic/impulse
    response, target overlap 0.15/0.35/0.7/1.4, noise 0/1/5/15 %; noise varies fastest). Its
    clusters (one of three, one of four, or both), number of modes (clusters + 2..5 isolated
    ones), measured points (5..modes) and system seed come from
    ``numpy.random.default_rng(seed)``.
    """
    n_cases = check_int(n_cases, "n_cases", 1)
    seed = check_int(seed, "seed", 0)
    rng = np.random.default_rng(seed)
    cases = []
    for i in range(n_cases):
        src, ov, noise = CLUSTER_COMBINATIONS[i % len(CLUSTER_COMBINATIONS)]
        sizes = CLUSTER_LAYOUTS[int(rng.integers(len(CLUSTER_LAYOUTS)))]
        n_modes = sum(sizes) + int(rng.integers(2, 6))
        n_points = int(rng.integers(5, n_modes + 1))
        cases.append(
            ClusterCase(i, src, ov, sizes, noise, n_points, n_modes, int(rng.integers(2**31)))
        )
    return cases


def line_noise_std(frf: xr.Dataset, truth: xr.Dataset) -> xr.DataArray:
    """``sigma_j = sqrt(E |e|^2)`` of one FRF line per point for an FRF of
    :func:`~ami_xr.simulate.random_system` or :func:`~ami_xr.simulate.clustered_system`,
    analytic or FFT'd impulse responses (see the module docstring); zeros without noise."""
    source = frf.attrs.get(names.ATTR_SOURCE)
    if source not in (names.SOURCE_ANALYTIC, names.SOURCE_IMPULSE):
        raise AmiXrValueError(
            f"frf: expected a simulated FRF (attribute {names.ATTR_SOURCE}="
            f"{names.SOURCE_ANALYTIC!r} or {names.SOURCE_IMPULSE!r}), got {source!r}"
        )
    points = frf[names.POINT].values
    alpha = float(frf.attrs.get(ATTR_NOISE_LEVEL, 0.0) or 0.0)
    if alpha == 0.0:
        return xr.DataArray(np.zeros(points.size), dims=[names.POINT], coords={names.POINT: points})
    kind = frf.attrs.get(ATTR_NOISE_KIND, "uniform")
    c = 1.0 / 3.0 if kind == "uniform" else 1.0
    drive = truth.attrs[names.ATTR_DRIVE_POINT]
    if source == names.SOURCE_IMPULSE:
        dt, n = float(frf.attrs["sample_interval"]), int(frf.attrs["record_samples"])
        h = impulse_response(truth, (n * dt, n), drive)[names.RESPONSE]
        peak = np.abs(h.sel({names.POINT: points}).transpose(names.POINT, names.TIME).values)
        std = alpha * peak.max(axis=1) * dt * np.sqrt(c * n)
        return xr.DataArray(std, dims=[names.POINT], coords={names.POINT: points})
    clean = model_frf(truth, frf[names.FREQUENCY].values, drive)
    h = clean[names.FRF].sel({names.POINT: points}).transpose(names.POINT, names.FREQUENCY).values
    var = np.abs(h.real).max(axis=1) ** 2 + np.abs(h.imag).max(axis=1) ** 2
    return xr.DataArray(alpha * np.sqrt(c * var), dims=[names.POINT], coords={names.POINT: points})


def peak_snr(truth: xr.Dataset, noise_std: xr.DataArray) -> xr.DataArray:
    """Peak SNR (amplitude ratio, not dB) of every mode at every point: ``|A_jk| / |Re lam_k|
    / sigma_j`` (``inf`` where ``sigma_j = 0``)."""
    points = noise_std[names.POINT].values
    peaks = xr.concat([mode_peaks(truth, p) for p in points], dim=names.POINT)
    peaks = peaks.assign_coords({names.POINT: points})
    with np.errstate(divide="ignore", invalid="ignore"):
        return peaks / noise_std


def identifiable(
    truth: xr.Dataset, noise_std: xr.DataArray, snr_db: float = DEFAULT_SNR_DB
) -> np.ndarray:
    """Per true mode: is its peak SNR at least ``snr_db`` (20 log10 of the amplitude ratio)
    at one measured point at least?"""
    snr = peak_snr(truth, noise_std).transpose(names.POINT, names.MODE).values
    return np.asarray((snr >= 10.0 ** (snr_db / 20.0)).any(axis=0))


@dataclass(frozen=True)
class ModeScore:
    """What :func:`score_modes` returns. Arrays over matches are ordered by true mode."""

    true_index: np.ndarray  # (match,) 0-based true mode of each match
    identified_index: np.ndarray  # (match,) 0-based identified mode of each match
    found: np.ndarray  # (true mode,) bool
    spurious: np.ndarray  # 0-based identified modes left unmatched
    frequency_error: np.ndarray  # (match,) |fn_id - fn| / fn
    damping_error: np.ndarray  # (match,) |zeta_id - zeta| / zeta
    frequency_over_crb: np.ndarray  # (match,) |fn_id - fn| / fn_std (NaN without a bound)
    damping_over_crb: np.ndarray  # (match,) |zeta_id - zeta| / zeta_std (NaN without a bound)

    @property
    def n_true(self) -> int:
        return int(self.found.size)

    @property
    def n_found(self) -> int:
        return int(self.found.sum())

    @property
    def n_spurious(self) -> int:
        return int(self.spurious.size)


def _eigenvalues(x: Any, name: str) -> np.ndarray:
    if isinstance(x, xr.Dataset):
        if names.EIGENVALUE not in x:
            raise AmiXrValueError(f"{name}: the Dataset has no {names.EIGENVALUE!r} variable")
        x = x[names.EIGENVALUE].values
    lam = np.asarray(x)
    if lam.ndim != 1 or not np.issubdtype(lam.dtype, np.number):
        raise AmiXrValueError(f"{name}: expected a 1-D array of eigenvalues, got {lam.shape}")
    lam = lam.astype(np.complex128)
    return np.where(lam.imag < 0, lam.conj(), lam)  # upper half plane


def score_modes(
    identified: Any,
    truth: Any,
    *,
    tolerance: float = DEFAULT_TOLERANCE,
    crb: xr.Dataset | None = None,
) -> ModeScore:
    """Match identified modes to true ones and measure the errors.

    A pair (identified ``i``, true ``k``) may match when ``|lam_i - lam_k| < tolerance *
    |Re lam_k|``; the default tolerance 1 is half the half-power bandwidth ``2 |Re lam_k|``.
    Pairs are taken nearest first (in units of ``|Re lam_k|``), each mode at most once, so two
    identified modes near one true mode give one match and one spurious mode. Identified modes
    with a NaN eigenvalue match nothing (they count as spurious).

    Parameters
    ----------
    identified, truth : xarray.Dataset or array_like
        Datasets with ``eigenvalue`` (mode), or the eigenvalues themselves (rad/s; lower
        half-plane values are conjugated).
    tolerance : float
        Match radius in units of ``|Re lam_true|``.
    crb : xarray.Dataset, optional
        :func:`ami_xr.cramer_rao_bound` of the truth (same modes, same order): gives the errors
        over ``natural_frequency_std`` and ``damping_ratio_std``.

    Returns
    -------
    ModeScore
    """
    lam_id = _eigenvalues(identified, "identified")
    lam_t = _eigenvalues(truth, "truth")
    if isinstance(tolerance, bool) or not np.isscalar(tolerance) or not tolerance > 0:
        raise AmiXrValueError(f"tolerance: expected a number > 0, got {tolerance!r}")
    if np.any(~np.isfinite(lam_t)) or np.any(lam_t.real >= 0):
        raise AmiXrValueError("truth: expected finite eigenvalues with negative real parts")
    if crb is not None:
        for var in (names.NATURAL_FREQUENCY_STD, names.DAMPING_RATIO_STD):
            if var not in crb or crb[var].size != lam_t.size:
                raise AmiXrValueError(
                    f"crb: expected {var!r} with one value per true mode ({lam_t.size})"
                )
    tk, ti = match_nearest(lam_id, lam_t, tolerance)
    found = np.zeros(lam_t.size, bool)
    found[tk] = True
    used_id = np.zeros(lam_id.size, bool)
    used_id[ti] = True

    def fn_zeta(lam):
        return np.abs(lam) / (2 * np.pi), -lam.real / np.abs(lam)

    f_id, z_id = fn_zeta(lam_id[ti])
    f_t, z_t = fn_zeta(lam_t[tk])
    if crb is None:
        f_crb = z_crb = np.full(tk.size, np.nan)
    else:
        f_crb = np.abs(f_id - f_t) / crb[names.NATURAL_FREQUENCY_STD].values[tk]
        z_crb = np.abs(z_id - z_t) / crb[names.DAMPING_RATIO_STD].values[tk]
    return ModeScore(
        true_index=tk,
        identified_index=ti,
        found=found,
        spurious=np.flatnonzero(~used_id),
        frequency_error=np.abs(f_id - f_t) / f_t,
        damping_error=np.abs(z_id - z_t) / z_t,
        frequency_over_crb=f_crb,
        damping_over_crb=z_crb,
    )


__all__: Sequence[str] = (
    "CLUSTER_COMBINATIONS",
    "COMBINATIONS",
    "ClusterCase",
    "cluster_catalogue",
    "NOISE_LEVELS",
    "CatalogueCase",
    "ModeScore",
    "catalogue",
    "identifiable",
    "line_noise_std",
    "peak_snr",
    "score_modes",
)
