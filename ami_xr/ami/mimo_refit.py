"""The shared-pole refit of the multi-reference path (issues 13, 41).

:func:`ami_xr.ami.mimo.identify_multi_reference` runs the single-reference pipeline on the FRFs
of every reference stacked on ``point``. Two things can leave that set of poles short, and both
are repaired here by running the pipeline's shared-pole phases (global fit, refinement) again on
all FRFs from a larger set of poles:

* a pole one reference needs and the stacked detection missed (its FRFs drown in those of the
  references that do not see the mode): :func:`with_reference_proposals`, from the proposals of
  :mod:`ami_xr.ami.mimo_screen` (each reference screened against the stacked model, not a
  pipeline per reference);
* two close poles fitted as one: the pole's residue matrix (point x reference) is then not rank
  one, beyond the residues' noise (``A = lam1 phi1 L1^T + lam2 phi2 L2^T`` seen through one
  pole). :func:`with_close_pairs_split` starts a second pole next to it and keeps the pair when
  the likelihood says so (an exactly repeated root is one pole with a rank-two residue matrix:
  the second pole does not lower the cost, and the pair is left to the drive points). Each
  trial is screened first (:func:`ami_xr.ami.mimo_screen.split_gain`: the lines around the pole,
  its neighbours free): a split that gains too little there is not refitted on every pole.

The refits fit the eigenvalues and residues only (no model completion: each pole added is
tested on its own, and the first pass completed the model): they cost a fraction of a
pipeline. They run where the first pass ran: in the working quantity and with the line weights
of the noise model (:mod:`ami_xr.ami.whitening`, decided on the stacked FRFs, as
:func:`ami_xr.ami.pipeline.identify_single` decides it: one quantity for all references, the noise
of each (reference, point) FRF and line), and comes back in the quantity given.
"""

from __future__ import annotations

import warnings
from typing import Any, NamedTuple

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import common as c
from ami_xr.ami import mimo_screen as ms
from ami_xr.ami import pipeline as pl
from ami_xr.ami import whitening
from ami_xr.ami.global_fit import global_fit
from ami_xr.ami.refine import refine as refine_phase
from ami_xr.ami.settings import FrfAttributes, RefineSettings, from_attrs
from ami_xr.ami.subtract import band_of, power_of_two_scale
from ami_xr.core import flags
from ami_xr.core import mimo as cm
from ami_xr.core.modal import damping_ratio, natural_frequency
from ami_xr.core.policy import POLICY
from ami_xr.errors import AssumptionWarning

# The second pole of a suspected close pair starts this many |Re lam| above the first, which
# moves as far down: members of a pair a single pole absorbs lie well inside its half-power band
SPLIT_START = 0.25
# The tail pole starts this many half-power bandwidths above the last line
TAIL_START = 4.0
MAX_TAIL_POLES = 2
# The tail pole is tried only when a pole of the band lies within this many of its half-power
# bandwidths of the last line: farther, what lies above reaches the band as a smooth tail the
# upper residual term takes (the refits of the trial cost as much as the first pass)
TAIL_NEAR = 5.0


def _measured_poles(ds: xr.Dataset, result: xr.Dataset) -> np.ndarray:
    """The eigenvalues of ``result`` before the exponential-window correction (as the data
    hold them)."""
    beta = float(from_attrs(FrfAttributes, ds.attrs).exponential_window_decay)
    if not result.sizes.get(names.MODE, 0):
        return np.zeros(0, np.complex128)
    return np.asarray(result[names.EIGENVALUE].transpose(names.MODE).values) - beta


def with_reference_proposals(
    stacked: xr.Dataset,
    result: xr.Dataset,
    n_ref: int,
    settings,
    working: Working | SharedWorking | None = None,
) -> tuple[xr.Dataset, np.ndarray]:
    """``result`` (the stacked pipeline's) refitted with the poles each reference's FRFs need
    beyond its poles (:func:`ami_xr.ami.mimo_screen.proposals`: a screen of each reference's
    residual against the stacked model and the completion's order test on its lines);
    unchanged when no reference needs one.

    Detection on the stacked FRFs weighs every FRF alike, so the modes one reference sees
    clearly can drown in the FRFs of a reference that does not see them (a reference on a
    nodal line, a noisier one, the second member of a close pair). The poles proposed join
    the set and the shared-pole phases (global fit and refinement) run again on all FRFs.
    Returns the result and the added eigenvalues (measured, rad/s)."""
    lam = _measured_poles(stacked, result)
    band = band_of(stacked, settings.fmin, settings.fmax, "identify")
    got = ms.proposals(band, lam, n_ref, RefineSettings.add_pfa, _frozen(result))
    if not got:
        return result, np.zeros(0, np.complex128)
    n_point = stacked.sizes[names.POINT] // n_ref
    det_added = np.zeros((stacked.sizes[names.POINT], len(got)), bool)
    for k, p in enumerate(got):
        det_added[p.reference * n_point : (p.reference + 1) * n_point, k] = True
    added = np.array([p.lam for p in got])
    out = refit(stacked, result, np.append(lam, added), det_added, settings, working=working)
    return out, added


def not_rank_one(result: xr.Dataset, n_ref: int, ratio_max: float, noise_factor: float):
    """Per mode of the stacked ``result``: how far its residue matrix (point x reference) is from
    rank one -- ``s2`` over ``noise_factor`` times the residues' standard error (``residue_std``;
    ``s2 / s1`` over ``ratio_max`` without them) -- where ``s2 / s1`` exceeds ``ratio_max`` and
    ``s2`` the noise; 0 elsewhere (and for every mode with one reference)."""
    n_k = result.sizes.get(names.MODE, 0)
    if n_ref < 2 or not n_k or names.RESIDUE not in result:
        return np.zeros(n_k)
    res = result[names.RESIDUE].transpose(names.POINT, names.MODE).values
    a = res.reshape(n_ref, -1, n_k).transpose(2, 1, 0)  # stacked reference-major -> (K, P, R)
    _, s1, _, ratio = cm.rank_one(a)
    score = ratio / ratio_max
    if names.RESIDUE_STD in result:
        std = result[names.RESIDUE_STD].transpose(names.POINT, names.MODE).values
        noise = np.sqrt(np.sum(np.abs(std) ** 2, axis=0))
        with np.errstate(invalid="ignore", divide="ignore"):
            score = np.where(np.isfinite(noise), ratio * s1 / (noise_factor * noise), score)
    with np.errstate(invalid="ignore"):
        return np.where((ratio > ratio_max) & (score > 1), score, 0.0)


# trials of a split in one identification, strongest evidence first
MAX_SPLIT_TRIALS = 3


def with_close_pairs_split(
    stacked: xr.Dataset,
    result: xr.Dataset,
    n_ref: int,
    settings,
    ratio_max: float,
    noise_factor: float,
    tail: list | None = None,
    working: Working | SharedWorking | None = None,
) -> tuple[xr.Dataset, np.ndarray]:
    """``result`` refitted with a second pole next to poles whose residue matrix is not rank one
    (:func:`not_rank_one` with ``ratio_max`` and ``noise_factor``; ``n_ref`` references stacked)
    and that lie within the lines analysed.
    One pole at a time, strongest evidence first (a pole fitted to a close pair biases its
    neighbours, whose residue matrices then look rank two too): the split is kept when the
    likelihood-ratio test of the refinement's objective (``2 (cost - cost')`` against
    chi-square with ``2 + 2 n_FRF`` degrees of freedom, false-alarm probability ``add_pfa``)
    supports it and the pair holds one pole more than before, none frozen at its start
    (``refine_fallback``); after a kept split the evidence is taken anew. At most
    ``MAX_SPLIT_TRIALS`` trials; a trial whose screen (:func:`_split_screened`) stays below the
    threshold is not refitted (``working``: :func:`working_data`, shared by the refits). A
    trial whose second pole goes above the lines, supported by the likelihood, keeps that pole
    as a tail pole (its frequency appended to ``tail``) and tries the pair again. Returns the
    result and the natural frequencies (Hz) of the poles split (empty when none)."""
    evidence = not_rank_one(result, n_ref, ratio_max, noise_factor)
    if not np.any(evidence > 0) or not pl.refines(settings):
        return result, np.zeros(0)
    lines = band_of(stacked, settings.fmin, settings.fmax, "identify")[names.FREQUENCY].values
    tried: list[complex] = []
    split: list[float] = []
    for _ in range(MAX_SPLIT_TRIALS):
        cost0 = result.attrs.get(names.ATTR_REFINE_COST)
        lam = _measured_poles(stacked, result)
        fn = natural_frequency(lam)
        # a pole beyond the lines fits the tail of what lies there: no pair can be seen in it
        ok = (evidence > 0) & (fn >= lines[0]) & (fn <= lines[-1])
        ok &= ~np.array([any(abs(x - t) <= abs(x.real) for t in tried) for x in lam], bool)
        if cost0 is None or not ok.any():
            break
        k = int(np.argmax(np.where(ok, evidence, -np.inf)))
        tried.append(lam[k])
        if not _split_screened(stacked, result, lam, k, settings, working):
            continue  # the refit of every pole would not support it either: not run
        out, better, held = _split_trial(stacked, result, lam, k, float(cost0), settings, working)
        above = _above(stacked, out, lines[-1])
        if held:
            result = out
            split.append(float(fn[k]))
            evidence = not_rank_one(result, n_ref, ratio_max, noise_factor)
        elif better and above.size > _above(stacked, result, lines[-1]).size:
            # the second pole went above the lines and the likelihood supports it: the tail
            # of the modes beyond the band, which had drawn the pair's fit (a tail pole the
            # tail trial could not place): kept as such, and the pair tried again with it
            result = out
            tried.pop()
            if tail is not None:
                tail.append(float(above.max()))
            evidence = not_rank_one(result, n_ref, ratio_max, noise_factor)
    return result, np.asarray(split)


def _above(stacked: xr.Dataset, result: xr.Dataset, f_last: float) -> np.ndarray:
    """Natural frequencies (Hz) of ``result``'s poles above ``f_last`` not frozen at their
    start (``refine_fallback``)."""
    fn = natural_frequency(_measured_poles(stacked, result))
    return fn[(fn > f_last) & ~_frozen(result)]


def _split_screened(
    stacked, result, lam, k: int, settings, working: Working | SharedWorking | None
) -> bool:
    """Whether the split of pole ``k`` passes the screen of
    :func:`ami_xr.ami.mimo_screen.split_gain` on all FRFs: its likelihood ratio, with only the
    pole's neighbours free, above the trial's threshold (:func:`_trial`; the residual terms
    ``result`` fitted; True when the screen cannot say). Where the refit of every pole would
    gain little more (an exactly repeated root: its second pole fits noise), the trial is not
    run: several references cost about one pipeline."""
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    work = _resolved(working, stacked, settings).work
    terms = tuple(t for t in str(result.attrs.get(names.ATTR_REFINE_RESIDUAL_TERMS, "")).split(","))
    prob = ms.stacked_problem(work, tuple(t for t in terms if t))
    gain = ms.split_gain(prob, lam, k, SPLIT_START, POLICY.trial_iterations)
    limit = chi2.isf(RefineSettings.add_pfa, 2 + 2 * stacked.sizes[names.POINT])
    return not gain <= limit  # NaN: the screen could not say


def _split_trial(stacked, result, lam, k: int, cost0: float, settings, working=None):
    """The refit with pole ``k`` split, whether the likelihood ratio supports the added pole
    and whether its pair held (False when it does not)."""
    step = 1j * SPLIT_START * abs(lam[k].real)
    lam_set = np.append(lam, lam[k] + step)
    lam_set[k] = lam[k] - step
    det = np.ones((stacked.sizes[names.POINT], 1), bool)
    if names.DETECTED in result:
        det = result[names.DETECTED].transpose(names.POINT, names.MODE).values[:, [k]]
    out, better = _trial(stacked, result, lam_set, det, cost0, settings, working)
    return out, better, better and _pair_held(out, lam, stacked, lam[k])


def _trial(
    stacked, result, lam_set, det, cost0: float, settings, working=None
) -> tuple[xr.Dataset, bool]:
    """The refit from the poles ``lam_set`` (one more than ``result``'s; ``det`` its detection
    column), and whether the likelihood-ratio test of the refinement's objective supports the
    added pole: ``2 (cost0 - cost)`` above chi-square with ``2 + 2 n_FRF`` degrees of freedom
    (the pole and a residue per FRF; two more per FRF for each residual term it switched on)
    at false-alarm probability ``add_pfa``."""
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a rejected trial says nothing; a kept one is reported
        # a trial's fit stops early, as the completion's do: an unfinished fit only overstates
        # the cost of the larger model (conservative for adding); what is kept is polished
        out = refit(
            stacked, result, lam_set, det, settings, POLICY.trial_iterations, working=working
        )
    cost = out.attrs.get(names.ATTR_REFINE_COST)
    n_frf = stacked.sizes[names.POINT]
    # residual terms the added pole switched on (:func:`_residual_terms`): a complex
    # coefficient per FRF each, unknowns of the test too
    terms = [_n_terms(x) for x in (result, out)]
    dof = 2 + 2 * n_frf + 2 * n_frf * max(terms[1] - terms[0], 0)
    limit = chi2.isf(RefineSettings.add_pfa, dof)
    return out, cost is not None and bool(2.0 * (cost0 - float(cost)) > limit)


def _n_terms(ds: xr.Dataset) -> int:
    """The number of residual terms the refinement of ``ds`` fitted."""
    return len([t for t in str(ds.attrs.get(names.ATTR_REFINE_RESIDUAL_TERMS, "")).split(",") if t])


def with_tail_poles(
    stacked: xr.Dataset,
    result: xr.Dataset,
    settings,
    working: Working | SharedWorking | None = None,
    keep_frozen: bool = False,
) -> tuple[xr.Dataset, np.ndarray]:
    """``result`` refitted with poles above the last line analysed, one at a time (at most
    ``MAX_TAIL_POLES``), each kept when the likelihood-ratio test supports it (:func:`_trial`)
    and it is not frozen at its start.

    Modes above the band reach into it as more than the upper residual term (a constant) can
    take when the nearest lie within a few bandwidths of the last line: the misfit then shows
    at the FRFs' top lines, inflates their noise estimate and biases the modes nearest the edge
    (a pole fitted to a close pair there goes to the tail instead). A pole above the lines
    models that tail; it is not reported (:func:`ami_xr.ami.pipeline.drop_beyond_lines`). Its
    start: ``TAIL_START`` half-power bandwidths above the last line or the highest pole above
    it, at the median damping ratio of the poles. Tried only when a pole of the band lies
    within ``TAIL_NEAR`` half-power bandwidths of the last line (:func:`near_the_edge`).
    ``keep_frozen`` (the trial after a kept split, :mod:`ami_xr.ami.mimo`): a further tail pole
    (one lies above the lines already) that the refinement froze at its start from both starts
    is kept there when the likelihood supports it. What lies beyond the first tail pole reaches
    the band as a smooth remainder: the likelihood is flat in where its pole sits (the plate of
    ``scripts/benchmark_mimo.py`` at 0.1 % noise: a gain of 760-800 anywhere in 25-40 Hz at
    any damping from 0.2 to 16 %, the test's threshold 117), so its fit wanders off its region,
    while at its start its residues still take that remainder (refused, the modes nearest the
    edge carried a bias of about 1.7 standard errors).
    Returns the result and the natural frequencies (Hz) of the poles added."""
    lines = band_of(stacked, settings.fmin, settings.fmax, "identify")[names.FREQUENCY].values
    f_last = float(lines[-1])
    if not near_the_edge(_measured_poles(stacked, result), f_last):
        return result, np.zeros(0)
    added: list[float] = []
    farther = False  # set once after a tail pole frozen at its start
    while len(added) < MAX_TAIL_POLES:
        cost0 = result.attrs.get(names.ATTR_REFINE_COST)
        lam = _measured_poles(stacked, result)
        if cost0 is None or not lam.size or not pl.refines(settings):
            break
        fn = natural_frequency(lam)
        # a pole the refinement froze near the last line stood for that tail: the tail pole
        # replaces it (held at its start it would keep the tail pole from its place)
        keep = np.flatnonzero(~(_frozen(result) & (fn <= f_last) & _near(lam, f_last)))
        base = result if keep.size == lam.size else c.select_modes(result, keep.tolist())
        start = _tail_start(lam[keep], f_last, farther)
        det = np.ones((stacked.sizes[names.POINT], 1), bool)
        out, better = _trial(stacked, base, start, det, float(cost0), settings, working)
        got = natural_frequency(_measured_poles(stacked, out))
        above = got > f_last
        if better and not farther and _frozen(out)[above].any():
            farther = True  # it left its region: what lies above is farther than the start
            continue
        frozen = bool(_frozen(out)[above].any())
        if keep_frozen and farther and np.any(fn > f_last):
            frozen = False  # a further tail pole held at its start: a fixed basis of the tail
        if not better or above.sum() <= np.sum(fn > f_last) or frozen:
            break
        result, farther = out, False
        added.append(float(got[above].max()))
    return result, np.asarray(added)


def _tail_start(lam: np.ndarray, f_last: float, farther: bool) -> np.ndarray:
    """The poles ``lam`` and a tail pole's start: ``TAIL_START`` half-power bandwidths (twice
    as many when ``farther``) above the last line or the highest pole above it, at the median
    damping ratio of the poles."""
    fn = natural_frequency(lam)
    zeta = float(np.median(damping_ratio(lam)))
    w = 2.0 * np.pi * max(f_last, fn.max()) * (1.0 + 2.0 * TAIL_START * (1 + farther) * zeta)
    return np.append(lam, -zeta * w + 1j * w * np.sqrt(1.0 - zeta**2))


def polished(
    stacked: xr.Dataset,
    result: xr.Dataset,
    settings,
    working: Working | SharedWorking | None = None,
) -> xr.Dataset:
    """``result`` (a kept trial's: its fit stopped early) refitted from its poles to
    convergence."""
    lam = _measured_poles(stacked, result)
    none = np.zeros((stacked.sizes[names.POINT], 0), bool)
    return refit(stacked, result, lam, none, settings, working=working)


def near_the_edge(lam: np.ndarray, f_last: float) -> bool:
    """Whether a pole of ``lam`` (measured) at or below ``f_last`` (Hz) lies within
    ``TAIL_NEAR`` of its half-power bandwidths ``2 zeta f_n`` of it."""
    fn = natural_frequency(lam)
    return bool(np.any(np.isfinite(fn) & (fn <= f_last) & _near(lam, f_last)))


def _near(lam: np.ndarray, f_last: float) -> np.ndarray:
    """Per pole: within ``TAIL_NEAR`` of its half-power bandwidths below ``f_last`` (Hz)."""
    fn, zeta = natural_frequency(lam), damping_ratio(lam)
    return f_last - fn <= TAIL_NEAR * 2.0 * zeta * fn


def _frozen(out: xr.Dataset) -> np.ndarray:
    """Per mode of ``out``: frozen at its start by the refinement (``refine_fallback``)."""
    if names.QUALITY_FLAGS not in out:
        return np.zeros(out.sizes.get(names.MODE, 0), bool)
    mask = flags.decode(np.asarray(out[names.QUALITY_FLAGS].values), unknown="ignore")
    return flags.has(mask, names.FLAG_REFINE_FALLBACK)


def _pair_held(out: xr.Dataset, lam: np.ndarray, stacked: xr.Dataset, x: complex) -> bool:
    """Whether ``out`` holds one pole more within ``|Re x|`` of the split pole ``x`` than the
    poles ``lam`` before the split, none of them frozen (``refine_fallback``)."""
    got = _measured_poles(stacked, out)
    frozen = _frozen(out)
    near = np.abs(got - x) <= abs(x.real)
    before = int(np.sum(np.abs(lam - x) <= abs(x.real)))
    return bool(near.sum() > before and not frozen[near].any())


def _residual_terms(given: xr.Dataset, lam: np.ndarray, settings) -> bool:
    """Whether the refit's global fit (and so the refinement, ``residual_terms="auto"``) fits
    residual terms: as ``settings`` say, and also on FRFs marked exact
    (``frf_source="analytic"``, where "auto" means none) when a pole of ``lam`` lies beyond the
    lines: modes outside the band are then in the data, and the exact model of the band's
    modes alone is not the data's (the poles fitted beyond the lines take the nearest of
    them, the terms the rest)."""
    if settings.residual_terms or given.attrs.get(names.ATTR_SOURCE) != names.SOURCE_ANALYTIC:
        return bool(settings.residual_terms)
    f = np.asarray(given[names.FREQUENCY].values, dtype=float)
    fn = natural_frequency(np.asarray(lam))
    return bool(np.any((fn > f[-1]) | (fn < f[0])))


class Working(NamedTuple):
    """The stacked band's lines as given, the noise model's decision, the lines in the working
    quantity (:func:`working_data`)."""

    given: xr.Dataset
    white: Any
    work: xr.Dataset


def working_data(stacked: xr.Dataset, settings) -> Working:
    """The band's lines of ``stacked`` as given, the noise model's decision and the lines in the
    working quantity (:mod:`ami_xr.ami.whitening`): what every refit of one identification
    shares (decided once)."""
    given = band_of(stacked, settings.fmin, settings.fmax, "identify")
    white = whitening.decide(given)
    return Working(given, white, whitening.to_working(given, white))


class SharedWorking:
    """:func:`working_data` of one identification, decided on first use (none when no refit
    or screen needs it) and then shared."""

    def __init__(self, stacked: xr.Dataset, settings):
        self._args = (stacked, settings)
        self._value: Working | None = None

    def get(self) -> Working:
        if self._value is None:
            self._value = working_data(*self._args)
        return self._value


def _resolved(working, stacked: xr.Dataset, settings) -> Working:
    """``working`` as a :class:`Working` (a :class:`SharedWorking` asked, None decided here)."""
    if isinstance(working, SharedWorking):
        return working.get()
    return working if working is not None else working_data(stacked, settings)


def refit(
    stacked,
    result,
    lam,
    det_added,
    settings,
    max_iter=None,
    working: Working | SharedWorking | None = None,
) -> xr.Dataset:
    """The shared-pole phases (global fit, refinement) on the stacked FRFs from the poles
    ``lam`` (measured): what :func:`identify_single` does after the isolation, in the working
    quantity and with the line weights of its noise model (:mod:`ami_xr.ami.whitening`;
    ``working``: :func:`working_data` or a :class:`SharedWorking`, decided here when None)."""
    given, white, ds = _resolved(working, stacked, settings)
    peak = np.abs(ds[names.FRF]).max(skipna=False).values
    scale = float(power_of_two_scale(peak))
    work = ds if scale == 1.0 else ds.assign({names.FRF: ds[names.FRF] * scale})
    start = work.copy()
    floor = result[names.SUB_NOISE_FLOOR] if names.SUB_NOISE_FLOOR in result else None
    if floor is not None and not white.k:  # per-FRF noise floors (drive-point SNR), same units
        start[names.SUB_NOISE_FLOOR] = floor * scale
    det = np.zeros((work.sizes[names.POINT], lam.size), bool)
    if names.DETECTED in result and result.sizes.get(names.MODE, 0):
        n0 = min(result.sizes[names.MODE], lam.size - det_added.shape[1])
        det[:, :n0] = result[names.DETECTED].transpose(names.POINT, names.MODE).values[:, :n0]
    det[:, lam.size - det_added.shape[1] :] = det_added
    start = start.assign(
        {
            names.EIGENVALUE: (names.MODE, lam),
            names.NATURAL_FREQUENCY: (names.MODE, natural_frequency(lam)),
            names.DAMPING_RATIO: (names.MODE, damping_ratio(lam)),
            names.DETECTED: ((names.POINT, names.MODE), det),
        }
    ).assign_coords({names.MODE: np.arange(1, lam.size + 1)})
    if names.ISO_CONVERGED in result:
        start[names.ISO_CONVERGED] = result[names.ISO_CONVERGED]
    start.attrs = {k: v for k, v in result.attrs.items() if not k.startswith("refine_")}
    start.attrs.update(work.attrs)  # the working quantity's attributes (units, noise model)
    terms = _residual_terms(given, lam, settings)
    out = global_fit(start, band=settings.band, residual_terms=terms)
    if pl.refines(settings):
        # no order tests on the stacked FRFs here: each added pole passed those of the
        # reference that found it, and the stacked test is the one that lost it (the FRFs of
        # references that do not see a mode dilute its likelihood ratio); the stacked poles
        # passed theirs in the first run
        capped = {} if max_iter is None else {"max_iter": int(max_iter)}
        out = refine_phase(out, add_modes=0, drop_modes=False, **capped)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AssumptionWarning)  # the first pass said it
        out, noise_model = pl.given_back(out, ds, scale, given, white)
    more = {}
    if floor is not None and names.SUB_NOISE_FLOOR not in out:
        more[names.SUB_NOISE_FLOOR] = floor.variable
    # identify's one output step: the window's correction, the band, sorted, the resolution
    # check and the quality indicators (repeated roots: decided on every reference, in mimo)
    window = from_attrs(FrfAttributes, given.attrs)
    return pl.reported(out, stacked, pl.refines(settings), noise_model, window=window, more=more)
