"""Multi-reference identification: one set of poles for all references (issue 13).

The FRFs of every (reference, point) pair share the poles, so :func:`identify_multi_reference`
runs the SIMO machinery (subtract -> isolate -> global_fit -> refine, unchanged) on them
stacked as one ``point`` dim: each FRF of each reference is one more FRF of the same system.
It runs once; each reference is then only screened against the stacked model for the poles its
own FRFs need (:mod:`ami_xr.ami.mimo_screen`), and the shared-pole refits
(:mod:`ami_xr.ami.mimo_refit`) add those, a pole for the modes above the band and the second
member of close pairs (after a pair is split, a pole for the modes above the band is tried
once more: the pair had drawn the first trials' pole); a split is screened on the lines around
its pole before it is refitted: several references cost about one pipeline, not one per
reference.
The stacked fit gives the poles and a residue per (reference, point, mode). For each mode the
residue matrix ``A`` (point x reference) is rank one in theory, ``A = lam phi L^T``; its best
rank-one approximation (SVD) gives the mode vector direction and the participation factors,
``s2 / s1`` says how far from rank one it is (``rank_one_ratio``; a second mode at the same
pole makes it rank two), and eq. 8 at every drive point (a reference on a measured point)
gives a scale of the mode vector: their spread is ``drive_point_consistency`` (a reciprocity
check), the scale of the drive point with the largest SNR is used. A mode whose residue
matrix is rank two (``rank_one_ratio`` above ``RANK_ONE_RATIO_MAX`` and the residues' noise) is
a repeated root: with two drive points that see both modes it is separated into two modes at
the one eigenvalue (:func:`ami_xr.core.mimo.split_repeated`), otherwise flagged.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import common as c
from ami_xr.ami import mimo_refit as mr
from ami_xr.ami import pipeline as pl
from ami_xr.ami import repeated as rp
from ami_xr.ami.global_fit import (
    ATTR_MODE_VECTOR_CONVENTION,
    MODE_VECTOR_CONVENTION,
    mode_vector_units,
    receptance_residues,
)
from ami_xr.ami.line_noise import NOISE_GROUP
from ami_xr.ami.pipeline import identify_single, with_quality
from ami_xr.ami.settings import GlobalFitSettings, IdentifySettings, from_attrs
from ami_xr.core import flags
from ami_xr.core import mimo as cm
from ami_xr.core.modal import mac_matrix, natural_frequency
from ami_xr.errors import AssumptionWarning, IdentificationError

# s2/s1 above this flags a repeated root. Noise alone gives s2 of the order of the residues'
# standard errors (s2 <= ||dA||_F), far below 5 % of s1 for any mode worth reporting (1 % FRF
# noise gives s2/s1 ~ 1e-3 on the test systems); non-proportional damping keeps A rank one
# (complex phi). A second mode sharing the pole whose residues are at least 5 % of the first
# one's is flagged; when residue standard errors are known, s2 must also exceed 3 ||dA||_F.
RANK_ONE_RATIO_MAX = 0.05
NOISE_FACTOR = 3.0

_SEP = "@"  # stacked FRF label "reference@point"

# attribute: natural frequencies (Hz) of the poles a reference's FRFs needed and the stacked
# detection missed (its screen's proposals), added before the shared-pole fit ("" when none)
ATTR_UNION_ADDED = "multi_reference_union_added"
# attribute: natural frequencies (Hz) of the poles whose residue matrix was not rank one and
# that the shared-pole refit split into two close poles ("" when none)
ATTR_PAIRS_SPLIT = "multi_reference_close_pairs_split"
# attribute: natural frequencies (Hz) of the poles above the lines the shared-pole refit added
# to model the modes beyond the band (not reported; "" when none)
ATTR_TAIL_POLES = "multi_reference_tail_poles"

# SIMO outputs whose meaning the stacking changes: recomputed here from the residue matrices
_RECOMPUTED = (
    names.MODE_VECTOR,
    names.MODE_VECTOR_STD,
    names.AMI_PREFIX + names.MODE_VECTOR,
    names.MODE_VECTOR_NORMALISED,
    names.MPC,
    names.MPD,
    names.COMPLEXITY,
    names.MAC,
    names.DRIVE_POINT_SNR,
)


def is_multi_reference(ds: Any) -> bool:
    """True for a Dataset whose ``frf`` has the ``reference`` dim."""
    return (
        isinstance(ds, xr.Dataset)
        and names.FRF in ds.data_vars
        and names.REFERENCE in ds[names.FRF].dims
    )


def _check(ds: xr.Dataset) -> tuple[list, list]:
    frf = ds[names.FRF]
    if set(frf.dims) != {names.REFERENCE, names.POINT, names.FREQUENCY}:
        raise IdentificationError(
            f"{names.FRF}: expected dims ({names.REFERENCE}, {names.POINT}, {names.FREQUENCY}), "
            f"got {frf.dims}"
        )
    for dim in (names.REFERENCE, names.POINT):
        if dim not in ds.coords:
            raise IdentificationError(f"coordinate {dim!r}: missing (labels are needed)")
    refs = np.asarray(ds[names.REFERENCE].values).tolist()
    points = np.asarray(ds[names.POINT].values).tolist()
    if len(set(map(str, refs))) != len(refs):
        raise IdentificationError(
            f"coordinate {names.REFERENCE!r}: expected unique labels, got {refs}"
        )
    return refs, points


def _stacked(ds: xr.Dataset, refs: list, points: list) -> xr.Dataset:
    """The SIMO Dataset of all FRFs: ``point`` = (reference, point) pairs, reference-major,
    labelled ``"reference@point"``. Per-point variables on (frequency) (e.g. coherence) are
    repeated for each reference; per-reference ones without ``point`` (force autospectra) are
    combined by the minimum over references (the band is valid for every force)."""
    R, P = len(refs), len(points)
    labels = [f"{r}{_SEP}{p}" for r in refs for p in points]
    out = xr.Dataset(coords={names.FREQUENCY: ds[names.FREQUENCY]})
    for name, da in ds.data_vars.items():
        dims = set(da.dims)
        if not dims <= {names.REFERENCE, names.POINT, names.FREQUENCY}:
            continue
        if names.POINT in dims:
            full = da.broadcast_like(ds[names.FRF]) if names.REFERENCE not in dims else da
            rest = [d for d in full.dims if d not in (names.REFERENCE, names.POINT)]
            vals = full.transpose(names.REFERENCE, names.POINT, *rest).values
            out[name] = xr.DataArray(
                vals.reshape(R * P, *vals.shape[2:]), dims=(names.POINT, *rest), attrs=da.attrs
            )
        elif names.REFERENCE in dims:
            out[name] = da.min(names.REFERENCE, keep_attrs=True).drop_vars(
                names.REFERENCE, errors="ignore"
            )
        else:
            out[name] = da
    # each reference's FRFs share a line shape of the noise model (its force's), not the others'
    group = (names.POINT, np.repeat(np.arange(R), P))
    out = out.assign_coords({names.POINT: labels, NOISE_GROUP: group})
    out.attrs = {k: v for k, v in ds.attrs.items() if k != names.ATTR_DRIVE_POINT}
    drives = [i * P + points.index(r) for i, r in enumerate(refs) if r in points]
    if drives:  # the SIMO phases' own drive point (flags, provisional scaling): the first one
        out.attrs[names.ATTR_DRIVE_POINT] = labels[drives[0]]
    return out


def _unstack(result: xr.Dataset, ds: xr.Dataset, R: int, P: int) -> xr.Dataset:
    """Every variable on the stacked ``point`` dim back on (reference, point); ``detected``
    (point, mode) is "detected for some reference". Built in one go from plain variables
    (assigning them one by one would align every time)."""
    variables = {}
    for name, da in result.data_vars.items():
        if name in _RECOMPUTED:
            continue
        var = da.variable  # frf too: the analysis band's lines, as the SIMO output holds
        if names.POINT in var.dims:
            rest = [d for d in var.dims if d != names.POINT]
            vals = var.transpose(names.POINT, *rest).values
            vals = vals.reshape(R, P, *vals.shape[1:])
            dims = (names.REFERENCE, names.POINT, *rest)
            if name == names.DETECTED:
                vals, dims = vals.any(axis=0), dims[1:]
            var = xr.Variable(dims, vals, attrs=var.attrs)
        variables[name] = var
    coords = {k: v.variable for k, v in result.coords.items() if names.POINT not in v.dims}
    coords[names.REFERENCE] = ds[names.REFERENCE].variable
    coords.update({k: v.variable for k, v in ds.coords.items() if set(v.dims) <= {names.POINT}})
    return xr.Dataset(variables, coords=coords, attrs=dict(result.attrs))


def _drive_snr(a: np.ndarray, lam: np.ndarray, pairs: list, sigma) -> np.ndarray:
    """(K, D) drive-point SNR: the mode's peak ``|A_pr| / |Re lam|`` over the FRF's noise
    floor (the peak alone when the floor is unknown or 0)."""
    peaks = np.abs(a) / np.abs(lam.real)[:, None, None]
    snr = np.full((a.shape[0], len(pairs)), np.nan)
    for d, (p, r) in enumerate(pairs):
        floor = float(sigma[p, r]) if sigma is not None else np.nan
        snr[:, d] = peaks[:, p, r] / floor if floor > 0 else peaks[:, p, r]
    return snr


@dataclass
class _Modes:
    """Per mode (K) what the residue matrices give: mode vectors ``phi`` (K, P), participation
    ``part`` (K, R), residues ``a`` (K, P, R) of the FRFs as measured, ``to_receptance`` (K,)
    the factor that makes them receptance residues (the displacement convention of
    :func:`ami_xr.ami.global_fit.receptance_residues`, in which ``phi`` and ``part`` are),
    eigenvalues, the scale's spread over the drive points, the SNR at the drive point used,
    ``s2/s1``, the scaling reference and the flags decided here."""

    phi: np.ndarray
    part: np.ndarray
    a: np.ndarray
    to_receptance: np.ndarray
    lam: np.ndarray
    spread: np.ndarray
    best_snr: np.ndarray
    ratio: np.ndarray
    scaling_ref: np.ndarray
    repeated: np.ndarray
    separated: np.ndarray

    def take(self, index: list[int]) -> _Modes:
        """The modes at positions ``index`` (repeated positions copy a mode)."""
        return _Modes(**{f.name: getattr(self, f.name)[index] for f in fields(self)})


def identify_multi_reference(
    ds: xr.Dataset, settings: IdentifySettings, progress=False
) -> xr.Dataset:
    """:func:`ami_xr.identify` on FRFs with dims (reference, point, frequency).

    Parameters
    ----------
    ds : xarray.Dataset
        Multi-reference FRF Dataset (``reference`` labels in the point labels' type; a
        reference whose label is a point label is that point's drive point).
    settings : IdentifySettings
        The settings of :func:`ami_xr.identify`, used unchanged by the single-reference pipeline
        on the stacked FRFs.
    progress : bool or callable
        As for :func:`ami_xr.identify`.

    Returns
    -------
    xarray.Dataset
        The SIMO outputs with every per-FRF variable on (reference, point, ...) -- ``residue``
        (reference, point, mode), ``frf_synthesized``, ``point_eigenvalue``, ... -- and, per
        mode, ``mode_vector`` (point, mode) from the rank-one residue matrices scaled by eq. 8
        at the drive point of largest SNR (``scaling_reference``; unit largest entry when no
        reference is a point), ``participation`` (mode, reference) with ``A = lam phi L^T``,
        ``rank_one_ratio`` (s2/s1; NaN with one reference), ``drive_point_consistency``
        (largest relative deviation of the other drive points' scales; 0 with one drive
        point, NaN with none), ``drive_point_snr``, ``mac`` and the quality indicators;
        ``quality_flags`` gain ``repeated_root_suspected`` (``rank_one_ratio`` above the
        attribute ``rank_one_ratio_max`` and above the residues' noise) and
        ``low_drive_point_snr`` is decided at the drive point used. A flagged mode that two
        drive points separate becomes two modes at its eigenvalue, flagged
        ``repeated_root_separated`` instead (their ``drive_point_consistency`` is the
        reciprocity misfit of the pair's factorisation; an AssumptionWarning says that the
        pair's basis in its plane is a choice).
    """
    refs, points = _check(ds)
    R, P = len(refs), len(points)
    stacked = _stacked(ds, refs, points)
    result = identify_single(stacked, settings, progress, final=R == 1)
    added = np.zeros(0, np.complex128)
    split = tail = np.zeros(0)
    if R > 1:
        work = mr.SharedWorking(stacked, settings)  # what every refit shares, decided once
        result, added = mr.with_reference_proposals(stacked, result, R, settings, work)
        result, tail = mr.with_tail_poles(stacked, result, settings, work)
        more: list[float] = []
        result, split = mr.with_close_pairs_split(
            stacked, result, R, settings, RANK_ONE_RATIO_MAX, NOISE_FACTOR, more, work
        )
        if split.size:  # a pair fitted as one pole had drawn the tail trials' poles
            result, again = mr.with_tail_poles(stacked, result, settings, work, keep_frozen=True)
            more += again.tolist()
        tail = np.append(tail, more)
        if tail.size or split.size:  # the trials' fits stopped early
            result = mr.polished(stacked, result, settings, work)
        result = pl.drop_beyond_lines(result, stacked)
    out = _unstack(result, ds, R, P)
    pairs = [(points.index(r), i) for i, r in enumerate(refs) if r in points]
    out.attrs.pop(names.ATTR_DRIVE_POINT, None)
    out.attrs[names.ATTR_MULTI_REFERENCE] = (
        f"{R} references stacked as {R * P} FRFs sharing the poles; mode vectors from the "
        "rank-one residue matrices, scaled by eq. 8 at the drive point of largest SNR"
    )
    out.attrs[names.ATTR_RANK_ONE_RATIO_MAX] = RANK_ONE_RATIO_MAX
    if R > 1:
        out.attrs[ATTR_UNION_ADDED] = ",".join(f"{x:.6g}" for x in natural_frequency(added))
        out.attrs[ATTR_PAIRS_SPLIT] = ",".join(f"{x:.6g}" for x in split)
        out.attrs[ATTR_TAIL_POLES] = ",".join(f"{x:.6g}" for x in tail)
    if not pairs:
        warnings.warn(
            f"identify: no reference {refs} is a measured point; mode vectors are normalised "
            "to a unit largest entry (not scaled) and participation factors are relative",
            AssumptionWarning,
            stacklevel=3,
        )
    if out.sizes.get(names.MODE, 0) == 0 or names.RESIDUE not in out:
        return out
    sigma = None
    if names.SUB_NOISE_FLOOR in out:
        sigma = out[names.SUB_NOISE_FLOOR].transpose(names.POINT, names.REFERENCE).values
    modes = _rank_one_modes(out, refs, pairs, sigma)
    if len(pairs) >= 2:
        out, modes = _separate_repeated(out, modes, refs, pairs, sigma)
    # a pair no two references separate may still show in one reference's band (issue 22)
    modes.repeated |= rp.suspected(*rp.band_rank_statistics(out)) & ~modes.separated
    out = _with_mode_outputs(out, modes, ds, bool(pairs))
    if np.any(modes.repeated):
        warnings.warn(
            "identify: the residue matrix of mode(s) "
            f"{np.asarray(out[names.MODE].values)[modes.repeated].tolist()} is not rank one "
            f"(s2/s1 > {RANK_ONE_RATIO_MAX}): two modes at the same frequency suspected "
            f"(flag {names.FLAG_REPEATED_ROOT})",
            AssumptionWarning,
            stacklevel=3,
        )
    return with_quality(out)


def receptance_factor(out: xr.Dataset, lam: np.ndarray) -> tuple[np.ndarray, str]:
    """Per mode (K,) the factor that turns the FRF residues of ``out`` into receptance
    residues (1 for receptance, ``1 / lam`` for mobility, ``1 / lam^2`` for accelerance, with
    the unit factor of g), and the receptance units."""
    frf_units = str(out[names.FRF].attrs.get(names.ATTR_UNITS, "")) if names.FRF in out else ""
    return receptance_residues(np.ones(lam.size), lam, out.attrs, frf_units)


def _rank_one_modes(out: xr.Dataset, refs: list, pairs: list, sigma) -> _Modes:
    """Mode vectors, participation factors and the rank-one diagnostics of every mode, scaled
    by eq. 8 at the drive point of largest SNR (unit largest entry without a drive point)."""
    n_k = out.sizes[names.MODE]
    lam = np.asarray(out[names.EIGENVALUE].transpose(names.MODE).values, dtype=np.complex128)
    a = out[names.RESIDUE].transpose(names.MODE, names.POINT, names.REFERENCE).values
    # mode vectors and participation in the displacement convention whatever the FRF type
    conv = receptance_factor(out, lam)[0]
    u, s1, w, ratio = cm.rank_one(a * conv[:, None, None])
    snr = _drive_snr(a, lam, pairs, sigma)
    if pairs:
        scales = cm.drive_point_scales(u, s1, w, lam, pairs)
        best = np.argmax(np.where(np.isfinite(snr), snr, -np.inf), axis=1)
        scale = scales[np.arange(n_k), best]
        spread = cm.aligned_spread(scales, best)
        best_snr = snr[np.arange(n_k), best]
        scaling_ref = np.array([str(refs[pairs[b][1]]) for b in best], dtype=object)
    else:
        scale = cm.unit_scales(u)
        spread = np.full(n_k, np.nan)
        best_snr = np.full(n_k, np.nan)
        scaling_ref = np.array([""] * n_k, dtype=object)  # "r1,r2" for a separated pair
    noisy = np.zeros(n_k, bool)  # s2 within the residues' noise (known from the refinement)
    if names.RESIDUE_STD in out:
        std = out[names.RESIDUE_STD].transpose(names.MODE, names.POINT, names.REFERENCE).values
        noise = np.abs(conv) * np.sqrt(np.sum(np.abs(std) ** 2, axis=(1, 2)))
        with np.errstate(invalid="ignore"):
            noisy = np.isfinite(noise) & ~(ratio * s1 > NOISE_FACTOR * noise)
    with np.errstate(invalid="ignore"):
        repeated = (ratio > RANK_ONE_RATIO_MAX) & ~noisy
    return _Modes(
        phi=u * scale[:, None],
        part=cm.participation(s1, w, lam, scale),
        a=a,
        to_receptance=conv,
        lam=lam,
        spread=spread,
        best_snr=best_snr,
        ratio=ratio,
        scaling_ref=scaling_ref,
        repeated=repeated,
        separated=np.zeros(n_k, bool),
    )


def _separate_repeated(
    out: xr.Dataset, modes: _Modes, refs: list, pairs: list, sigma
) -> tuple[xr.Dataset, _Modes]:
    """Each repeated root that two drive points separate becomes two modes at its eigenvalue
    (flag ``repeated_root_separated``); ``out``'s modes and residues follow."""
    split = {}
    for k in np.flatnonzero(modes.repeated):
        got = cm.split_repeated(modes.a[k] * modes.to_receptance[k], modes.lam[k], pairs)
        if got is not None:
            split[int(k)] = got
    if not split:
        return out, modes
    n_k = modes.lam.size
    src = [k for k in range(n_k) for _ in range(2 if k in split else 1)]
    modes = modes.take(src)
    both = ",".join(str(refs[r]) for _, r in pairs)
    for k, (phi2, part2, asym) in split.items():
        j = src.index(k)
        for m in (0, 1):
            modes.phi[j + m], modes.part[j + m] = phi2[:, m], part2[:, m]
            rec = modes.lam[j + m] * np.outer(phi2[:, m], part2[:, m])
            modes.a[j + m] = rec / modes.to_receptance[j + m]  # back to the FRF's residues
            modes.spread[j + m], modes.scaling_ref[j + m] = asym, both
            modes.separated[j + m], modes.repeated[j + m] = True, False
            snr = _drive_snr(modes.a[j + m][None], modes.lam[[j]], pairs, sigma)
            modes.best_snr[j + m] = np.nanmax(snr)
    out = _reselected(out, src, modes.a)
    warnings.warn(
        f"identify: {len(split)} repeated root(s) separated into two modes at one eigenvalue "
        f"by the drive points {both} (flag {names.FLAG_REPEATED_ROOT_SEPARATED}); the "
        "pair's two mode vectors are one basis of its plane, fixed by the factorisation of "
        "the drive-point residues (at an exactly repeated root any rotation fits the data)",
        AssumptionWarning,
        stacklevel=4,
    )
    return out, modes


def _reselected(out: xr.Dataset, src: list[int], residue: np.ndarray) -> xr.Dataset:
    """``out`` with the modes at positions ``src`` (repeated positions copy a mode), labelled
    1..n on ``mode`` (and ``mode_2``), and ``residue`` (K, P, R) as its residues: built once
    from its variables (a selection, two coordinates and a variable assigned one by one copy
    the Dataset each time)."""
    index = np.asarray(src, dtype=int)
    mode_dims = [d for d in (names.MODE, names.MODE_2) if d in out.dims]
    variables = {}
    for name, var in out.variables.items():
        pick = {d: index for d in mode_dims if d in var.dims}
        variables[name] = var.isel(pick) if pick else var
    labels = np.arange(1, index.size + 1)
    for d in mode_dims:
        variables[d] = xr.IndexVariable((d,), labels)
    var = variables[names.RESIDUE]
    order = [(names.MODE, names.POINT, names.REFERENCE).index(d) for d in var.dims]
    variables[names.RESIDUE] = var.copy(data=np.transpose(residue, order))
    coords = {k: variables.pop(k) for k in out.coords}
    return xr.Dataset(variables, coords=coords, attrs=out.attrs)


def _with_mode_outputs(out: xr.Dataset, modes: _Modes, ds: xr.Dataset, scaled: bool):
    """``out`` with the per-mode outputs of the residue matrices and their flags."""
    units = mode_vector_units(receptance_factor(out, modes.lam)[1], scaled)
    one = {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}
    scaling = (
        "eq. 8 at the drive point of largest SNR (rank-one residues)"
        if scaled
        else "unit largest entry (no drive point)"
    )
    k = (names.MODE,)
    new = {
        names.MODE_VECTOR: (
            (names.POINT, names.MODE),
            modes.phi.T,
            {
                names.ATTR_SCALING: scaling,
                ATTR_MODE_VECTOR_CONVENTION: MODE_VECTOR_CONVENTION,
                **units,
            },
        ),
        names.PARTICIPATION: (
            (names.MODE, names.REFERENCE),
            modes.part,
            {**units, names.ATTR_LONG_NAME: "modal participation factor L (A = lam phi L^T)"},
        ),
        names.RANK_ONE_RATIO: (
            k,
            modes.ratio,
            {**one, names.ATTR_LONG_NAME: "s2/s1 of the residue matrix (point x reference)"},
        ),
        names.DRIVE_POINT_CONSISTENCY: (
            k,
            modes.spread,
            {
                **one,
                names.ATTR_LONG_NAME: "largest relative deviation of the mode-vector "
                "scale from the other drive points",
            },
        ),
        names.SCALING_REFERENCE: (k, modes.scaling_ref.astype(str)),
        names.DRIVE_POINT_SNR: (k, modes.best_snr, one),
        names.MAC: ((names.MODE, names.MODE_2), mac_matrix(modes.phi.T), one),
    }
    variables = dict(out.variables)
    variables.update({name: xr.Variable(*spec) for name, spec in new.items()})
    coords = list(out.coords)
    if names.MODE_2 not in out.coords:
        variables[names.MODE_2] = xr.IndexVariable((names.MODE_2,), out[names.MODE].values)
        coords.append(names.MODE_2)
    if names.QUALITY_FLAGS in out:
        mask = c.flag_mask(out)
        mask = flags.set_where(mask, names.FLAG_REPEATED_ROOT, modes.repeated)
        mask = flags.set_where(mask, names.FLAG_REPEATED_ROOT_SEPARATED, modes.separated)
        if scaled:
            smin = from_attrs(GlobalFitSettings, out.attrs).drive_snr_min
            mask = flags.set_where(mask, names.FLAG_LOW_DRIVE_SNR, ~(modes.best_snr >= smin))
        flagged = variables[names.QUALITY_FLAGS]
        variables[names.QUALITY_FLAGS] = flagged.copy(data=np.asarray(mask, np.int32))
    # one build (assigning the outputs, a coordinate and the flags one by one copies it 3 times)
    coords = {name: variables.pop(name) for name in coords}
    return xr.Dataset(variables, coords=coords, attrs=out.attrs)
