"""Identification of many points: pole work on a compressed FRF set, residues per chunk.

For a large number of points the AMI phases (subtract, isolate, global_fit, refine) run on
``r`` virtual FRFs (:mod:`ami_xr.core.compress`: real combinations of the noise-weighted FRFs
that span their dominant column space), which gives the eigenvalues; then one last pass over the
points fits every FRF's residues at those eigenvalues by linear least squares (the fixed-pole
solver of eq. 9, :func:`ami_xr.kernels.residues.residues_fixed`), with mode vectors (eq. 8 at the
drive point, in the displacement convention of the uncompressed path:
:func:`ami_xr.ami.derive.receptance_mode_vectors`; the outputs built by
:func:`ami_xr.ami.derive.derived_from`, as the global fit's), synthesized FRFs, residuals and a
per-point noise estimate. The pole work does not grow with the number of points; the data are
read ``power_iterations + 2`` times plus once for the power-of-two scale, whatever ``P`` (the
first pass also finds all-zero FRFs, an error as on the uncompressed path).

Works on numpy- or dask-backed Datasets chunked along ``point``: each pass over the data is one
small graph of one task per chunk and a tree sum of the (r, r + 2L) partial results, computed on
whatever dask scheduler is active (a ``dask.distributed`` client included); only those sums
reach the client. The final pass is one ``xr.apply_ufunc`` (``dask="parallelized"``): the
synthesized FRFs and residuals stay lazy on a dask-backed input; residues and mode vectors (P, n)
are computed (the quality indicators need them).

What is exact and what is approximate: see :mod:`ami_xr.core.compress`. In short, the
eigenvalues are those of the weighted problem restricted to the kept subspace (the discarded
part is noise for a rank ``r`` well above ``2 n``); the residues, given the eigenvalues, are the
exact per-point least-squares solution on all lines (with lower and upper residual terms when the
refinement kept any), and so equal the uncompressed path's up to the difference in eigenvalues.
Variables that belong to single points in the phases (subtraction and isolation per point,
``point_eigenvalue``, ``detected``, ``residue_std``, ``mode_vector_std``, ``ami_residue``) are
not made on this path; the eigenvalue standard errors are those of the compressed problem.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import xarray as xr

from ami_xr import interrupt, names
from ami_xr.ami import common as c
from ami_xr.ami.derive import ResidueFit, derived_from
from ami_xr.ami.global_fit import RESIDUAL_KIND, band_mask
from ami_xr.ami.settings import FrfAttributes, GlobalFitSettings, IdentifySettings, from_attrs
from ami_xr.core import compress as cz
from ami_xr.core import flags
from ami_xr.core.model import resolve_model
from ami_xr.errors import IdentificationError
from ami_xr.kernels import modal_basis as kb
from ami_xr.kernels import noise as kn
from ami_xr.kernels import residues as kr

__all__ = ["DEFAULT_RANK", "CompressSettings", "compress", "uses_compression", "residues_at"]

DEFAULT_RANK = 48
"""Virtual FRFs kept by ``compress="auto"``: twice the real rank ``2 n`` of 12 modes, plus
margin for residual terms and out-of-band modes (``2 * max_modes + 8`` with the default
``max_modes=20``)."""

AUTO_FACTOR = 4
"""``compress="auto"`` compresses when there are more than ``AUTO_FACTOR * DEFAULT_RANK``
points (192): below that the phases on every point cost about as much."""

CHUNK_POINTS = 256
"""Points per chunk of a numpy-backed Dataset (a dask-backed one keeps its own chunks); an
interrupt checkpoint between chunks (256 x 4096 lines: about 0.1 s of work)."""

VIRTUAL_POINT = "virtual_point"
ATTR_COMPRESS_RANK = "compress_rank"
ATTR_COMPRESS_ENERGY = "compress_kept_energy"
ATTR_COMPRESS_POWER = "compress_power_iterations"


@dataclasses.dataclass(frozen=True)
class CompressSettings:
    """How the FRF set is compressed: at most ``rank`` virtual FRFs (those above the noise,
    :func:`ami_xr.core.compress.signal_rank`, plus ``extra``), ``power_iterations`` extra
    passes of the range finder, the ``seed`` of its Gaussian test matrix."""

    rank: int = DEFAULT_RANK
    power_iterations: int = 1
    seed: int = 0
    extra: int = 4


def resolve(compress: str | int | bool, n_points: int) -> CompressSettings | None:
    """The compression an ``identify(compress=...)`` setting asks for on ``n_points`` FRFs, or
    None for the phases on every point: "auto" compresses to :data:`DEFAULT_RANK` above
    ``AUTO_FACTOR * DEFAULT_RANK`` points; "off"/False never; an int ``r`` always, to ``r``
    virtual FRFs (when that is fewer than the points)."""
    if isinstance(compress, bool):
        compress = "auto" if compress else "off"
    if isinstance(compress, str):
        c.check_choice(compress, "compress", ("auto", "off"))
        if compress == "off" or n_points <= AUTO_FACTOR * DEFAULT_RANK:
            return None
        return CompressSettings()
    rank = c.check_positive_int(compress, "compress")
    if rank >= n_points:
        return None
    return CompressSettings(rank=rank)


def uses_compression(ds: xr.Dataset, settings: IdentifySettings) -> CompressSettings | None:
    """The compression :func:`ami_xr.identify` applies to ``ds`` (None: none). Data with an
    exponential window correction run uncompressed (the correction is applied per point)."""
    if from_attrs(FrfAttributes, ds.attrs).exponential_window_decay:
        return None
    return resolve(getattr(settings, "compress", "off"), ds.sizes.get(names.POINT, 0))


# --- map-reduce over chunks of points ----------------------------------------------------------


def _frf_array(ds: xr.Dataset):
    """The FRF (point, frequency) as a numpy or dask array, one chunk along frequency."""
    data = ds[names.FRF].transpose(names.POINT, names.FREQUENCY).data
    if hasattr(data, "dask") and len(data.chunks[1]) > 1:
        data = data.rechunk({1: -1})
    return data


def _weighted_terms(h: np.ndarray, z: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """One chunk's ``[G_c | S_c]`` of a pass, its FRFs weighted by their noise scales."""
    return cz.pass_terms(h, z, scale)


def _tree_sum(parts: list, split_every: int = 8):
    """Sum of delayed arrays as a tree (depth log_8 of the number of chunks)."""
    import dask

    add = dask.delayed(sum, pure=True)
    while len(parts) > 1:
        parts = [add(parts[i : i + split_every]) for i in range(0, len(parts), split_every)]
    return parts[0]


def _row_peaks(h: np.ndarray) -> np.ndarray:
    """The largest magnitude of each FRF of a chunk (p,)."""
    return np.max(np.abs(np.asarray(h)), axis=-1)


def _noise_scale(h: np.ndarray) -> np.ndarray:
    return cz.noise_scale(np.asarray(h))


def _map_sum(data, z: np.ndarray, scale: np.ndarray | None = None):
    """``sum over chunks of _weighted_terms(chunk, z, scale)``: one graph (a task per chunk, a
    tree sum, ``z`` sent once) for a dask array, a loop over row blocks for a numpy one.
    ``scale`` None (the first pass): the noise scales (P,) are found from the same read of each
    chunk, and every FRF's largest magnitude (P,) too; returns ``(total, scale, peaks)``, the
    scales and peaks None when ``scale`` was given (they are made once, not in every pass)."""
    first = scale is None
    if hasattr(data, "dask"):
        import dask

        z_task = dask.delayed(z, pure=True)
        term = dask.delayed(_weighted_terms, pure=True)
        blocks = data.to_delayed().ravel()
        if first:
            scales = [dask.delayed(_noise_scale, pure=True)(block) for block in blocks]
            tops = [dask.delayed(_row_peaks, pure=True)(block) for block in blocks]
        else:  # each chunk's scales, cut at its rows (P floats in all)
            bounds = np.cumsum((0,) + data.chunks[0])
            scales = [scale[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
            tops = []
        parts = [term(block, z_task, s) for block, s in zip(blocks, scales, strict=True)]
        if not first:
            (total,) = dask.compute(_tree_sum(parts))
            return np.asarray(total), None, None
        total, scales, tops = dask.compute(_tree_sum(parts), scales, tops)
        return np.asarray(total), np.concatenate(scales), np.concatenate(tops)
    total, scales, tops = 0.0, [], []
    for lo in range(0, data.shape[0], CHUNK_POINTS):
        interrupt.checkpoint()  # a Ctrl-C lands between chunks
        block = data[lo : lo + CHUNK_POINTS]
        s = _noise_scale(block) if first else scale[lo : lo + CHUNK_POINTS]
        total = total + _weighted_terms(block, z, s)
        if first:
            scales.append(s)
            tops.append(_row_peaks(block))
    if not first:
        return total, None, None
    return total, np.concatenate(scales), np.concatenate(tops)


def compress(ds: xr.Dataset, settings: CompressSettings = CompressSettings()) -> xr.Dataset:
    """The virtual FRF Dataset of ``ds``: ``r`` FRFs on ``point`` labelled ``v0, v1, ...``
    (ordered by energy), the same frequencies and attributes except ``drive_point`` (a virtual
    FRF has none); attrs ``compress_rank``, ``compress_kept_energy`` (squared singular values
    kept over the weighted data's total energy) and ``compress_power_iterations``.

    Parameters
    ----------
    ds : xarray.Dataset
        FRF Dataset (point, frequency), numpy- or dask-backed (chunked along ``point``).
    settings : CompressSettings

    Raises
    ------
    IdentificationError
        An all-zero FRF, naming its points (as :func:`ami_xr.subtract` does on every point;
        found in the first pass, not by another read of the data).
    """
    data = _frf_array(ds)
    n_points, n_lines = data.shape
    rank = min(settings.rank, n_points)
    z = cz.start_matrix(n_lines, rank, settings.seed)
    scale = None  # the noise scales, found in the first pass
    for i in range(settings.power_iterations + 1):
        total, found, peak = _map_sum(data, z, scale)
        if i == 0:
            # as the phases on every point do; all-zero FRFs would leave no direction to keep
            c.check_peaks(peak, np.asarray(ds[names.POINT].values))
            scale = found
        b = cz.orthonormal_rows(total)
        z = b.T
    virtual, s = cz.virtual_frfs(b)
    keep = cz.signal_rank(s, n_points, n_lines, settings.extra)
    virtual, s = virtual[:keep], s[:keep]
    # the total weighted energy is the trace of the last pass's data Gram, sum |Hr_w|^2, which
    # the pass did not form; the kept fraction is judged against the basis' own energy instead
    energy = float(np.sum(s**2))
    attrs = {k: v for k, v in ds.attrs.items() if k != names.ATTR_DRIVE_POINT}
    attrs[ATTR_COMPRESS_RANK] = int(virtual.shape[0])
    attrs[ATTR_COMPRESS_POWER] = int(settings.power_iterations)
    attrs[ATTR_COMPRESS_ENERGY] = energy
    frf_attrs = dict(ds[names.FRF].attrs)
    frf_attrs[names.ATTR_LONG_NAME] = "virtual FRF (noise-weighted combination of FRFs)"
    variables = {
        names.FRF: xr.Variable((names.POINT, names.FREQUENCY), virtual, frf_attrs),
        names.POINT: xr.Variable((names.POINT,), [f"v{i}" for i in range(virtual.shape[0])]),
        names.FREQUENCY: ds.variables[names.FREQUENCY],
    }
    return c.built(variables, (names.POINT, names.FREQUENCY), attrs, like=ds)


# --- the final pass: residues at fixed eigenvalues ---------------------------------------------


def _residue_block(g, *, omega, lam, use, dt, n_samples, kind):
    """Residues (..., n), residual coefficients (..., 2), synthesized FRFs (..., F) and the RMS
    residual (...) of FRFs ``g`` (..., F) at the eigenvalues ``lam``."""
    shape = g.shape[:-1]
    g2 = np.ascontiguousarray(g.reshape(-1, g.shape[-1]), dtype=np.complex128)
    coef = np.zeros((g2.shape[0], lam.size + (2 if kind >= 0 else 0)), np.complex128)
    for lo in range(0, g2.shape[0], CHUNK_POINTS):
        interrupt.checkpoint()  # numpy-backed: one call for all points; a Ctrl-C lands here
        part = g2[lo : lo + CHUNK_POINTS]
        coef[lo : lo + CHUNK_POINTS] = kr.residues_fixed(part, omega, lam, use, dt, n_samples, kind)
    n_k = lam.size
    res = np.ascontiguousarray(coef[:, :n_k])
    # every FRF shares the basis: one (n, F) basis and a product, not a basis per FRF
    basis = np.array([kb.pole_basis(omega, lk, dt, n_samples) for lk in lam]).reshape(n_k, -1)
    conj_basis = np.array([kb.pole_basis(omega, np.conj(lk), dt, n_samples) for lk in lam])
    synth = res @ basis + res.conj() @ conj_basis.reshape(n_k, -1)
    if kind >= 0:
        rc = np.ascontiguousarray(coef[:, n_k:])
        synth = synth + kb.synthesize_residual_terms(omega, rc, kind)
    else:
        rc = np.zeros((g2.shape[0], 2), np.complex128)
    rms = np.sqrt(np.mean(np.abs(g2 - synth)[:, use] ** 2, axis=-1))
    return (
        res.reshape(shape + (n_k,)),
        rc.reshape(shape + (2,)),
        synth.reshape(shape + (omega.size,)),
        rms.reshape(shape),
    )


def residues_at(
    ds: xr.Dataset, lam: np.ndarray, *, use: np.ndarray, residual_kind: int, model_attrs: dict
) -> tuple[xr.DataArray, ...]:
    """Residues (point, mode), residual coefficients (point, residual_term), synthesized FRFs
    (point, frequency) and RMS residual (point) of every FRF of ``ds`` at the eigenvalues
    ``lam``, fitted on the lines ``use`` (one apply_ufunc; lazy on a dask-backed ``ds``)."""
    data_model = resolve_model(model_attrs, model_attrs.get(names.ATTR_REFINE_MODEL, "auto"))
    lam = np.ascontiguousarray(lam, dtype=np.complex128)
    frf = ds[names.FRF]
    if hasattr(frf.data, "dask"):
        frf = frf.chunk({names.FREQUENCY: -1})
    return xr.apply_ufunc(
        _residue_block,
        frf,
        kwargs=dict(
            omega=c.omega_of(ds),
            lam=lam,
            use=use,
            dt=data_model.dt,
            n_samples=data_model.n_samples,
            kind=residual_kind,
        ),
        input_core_dims=[[names.FREQUENCY]],
        output_core_dims=[[names.MODE], [names.RESIDUAL_TERM], [names.FREQUENCY_OUT], []],
        exclude_dims={names.FREQUENCY},
        dask="parallelized",
        output_dtypes=[np.complex128, np.complex128, np.complex128, np.float64],
        dask_gufunc_kwargs={
            "output_sizes": {
                names.MODE: lam.size,
                names.RESIDUAL_TERM: 2,
                names.FREQUENCY_OUT: frf.sizes[names.FREQUENCY],
            }
        },
        keep_attrs=False,
    )


def _final_lines(ds: xr.Dataset, virtual: xr.Dataset, lam: np.ndarray, refined: bool):
    """The lines of the final residue fit and the residual-term kind, as the last phase used
    them: every line with the refinement's residual terms (both, when it kept either), or the
    global fit's bands and terms without refinement."""
    omega = c.omega_of(ds)
    frf_type = from_attrs(FrfAttributes, ds.attrs).frf_type
    if refined:
        use = np.ones(omega.size, bool)
        terms = str(virtual.attrs.get(names.ATTR_REFINE_RESIDUAL_TERMS, ""))
        kind = RESIDUAL_KIND.get(frf_type, 0) if terms else -1
    else:
        band = virtual.attrs.get(names.ATTR_AMI_BAND_USED, virtual.attrs.get(names.ATTR_AMI_BAND))
        use = band_mask(omega, lam, band if band == "all" else float(band))
        kind = (
            RESIDUAL_KIND.get(frf_type, 0)
            if int(virtual.attrs.get(names.ATTR_AMI_RESIDUAL_TERMS, 0))
            else -1
        )
    if kind in (0, 1):
        use = use & (omega > 0)  # the lower residual is singular at 0 Hz
    if 2 * int(use.sum()) < 2 * lam.size + (4 if kind >= 0 else 0) + 1:
        raise IdentificationError(
            f"{names.FREQUENCY}: {int(use.sum())} lines for the residues of {lam.size} modes"
        )
    return use, kind


def identify_compressed(
    work: xr.Dataset, settings: IdentifySettings, refined: bool, progress, phases, how
) -> xr.Dataset:
    """``phases(virtual, settings, refined, progress)`` (the pipeline's phases) on the virtual
    FRFs of ``work`` compressed as ``how`` says, then every point's residues at the
    eigenvalues found; the result has the dims of the uncompressed path's (point, mode)."""
    virtual = compress(work, how)
    vres = phases(virtual, settings, refined, progress)
    # the per-mode outputs of the virtual FRFs' phases (with their coordinates) join work's
    # variables; the output is built once, at the end
    skip = (names.POINT, names.CANDIDATE, names.MODE_2)
    keep = {k: v for k, v in vres.data_vars.items() if not any(d in v.dims for d in skip)}
    variables = dict(work.variables)
    coords = set(work.coords)
    for k, v in keep.items():
        variables[k] = v.variable
        for name, coord in vres.coords.items():  # as a DataArray brings them along
            if set(coord.dims) <= set(v.dims):
                variables[name] = coord.variable
                coords.add(name)
    attrs = dict(work.attrs)
    attrs.update({k: v for k, v in vres.attrs.items() if k != names.ATTR_DRIVE_POINT})
    if names.ATTR_DRIVE_POINT in work.attrs:
        attrs[names.ATTR_DRIVE_POINT] = work.attrs[names.ATTR_DRIVE_POINT]
    if vres.sizes.get(names.MODE, 0) == 0:
        return c.built(variables, coords, attrs, like=work)
    lam = np.asarray(vres[names.EIGENVALUE].values, dtype=np.complex128)
    use, kind = _final_lines(work, vres, lam, refined)
    res, rc, synth, rms = residues_at(
        work, lam, use=use, residual_kind=kind, model_attrs=dict(vres.attrs)
    )
    res = np.asarray(res.transpose(names.POINT, names.MODE).values)  # computed
    units = work[names.FRF].attrs.get(names.ATTR_UNITS, "")
    drive = c.drive_index(work)
    mask = c.flag_mask(vres)
    for flag in (names.FLAG_UNSCALED, names.FLAG_SINGLE_FRF, names.FLAG_LOW_DRIVE_SNR):
        mask = flags.set_where(mask, flag, False)  # decided for virtual FRFs: decide again
    dt_model = resolve_model(dict(vres.attrs), vres.attrs.get(names.ATTR_REFINE_MODEL, "auto"))
    noise = np.full(work.sizes[names.POINT], np.nan)
    if drive is not None:  # only the drive point's noise floor is needed (its SNR)
        g_drive = work[names.FRF].transpose(names.POINT, names.FREQUENCY).isel({names.POINT: drive})
        noise[drive] = kn.noise_floor(np.asarray(g_drive.values, np.complex128)[None, :])[0]
    fit = ResidueFit(
        eigenvalue=lam,
        residue=res,
        synthesized=xr.Variable(
            tuple(names.FREQUENCY if d == names.FREQUENCY_OUT else d for d in synth.dims),
            synth.data,
        ),
        residual_coefficient=rc if kind >= 0 else None,
        dt=dt_model.dt,
        n_samples=dt_model.n_samples,
        noise_floor=noise,
        mask=mask,
        drive_snr_min=from_attrs(GlobalFitSettings, vres.attrs).drive_snr_min,
    )
    modes = variables[names.MODE].values
    omega, points = c.omega_of(work), work[names.POINT].values
    more, derived = derived_from(fit, work[names.FRF], attrs, omega, modes, points)
    variables.update({**more, **derived})
    coords |= set(more)
    noise_attrs = {names.ATTR_UNITS: units} if units else {}
    variables[names.FRF_NOISE_STD] = xr.Variable(rms.dims, rms.data, noise_attrs)
    attrs[ATTR_COMPRESS_RANK] = vres.attrs[ATTR_COMPRESS_RANK]
    return c.built(variables, coords, attrs, like=work)
