"""FRFs and modes in one file: identify the FRFs, compare with the file's modes.

A common export holds a test's FRFs with the modes someone fitted to them (UFF 58 + 55, or the
netCDF ``ami-xr identify -o`` writes). :func:`split_frf_and_modes` separates the measurement
(the FRF Dataset, without any stored identification result) from the modes; after identifying
the FRFs, :func:`compare_modes` carries the file's modes in the result as a reference set,
along the dim ``reference_mode``: ``reference_natural_frequency``, ``reference_damping_ratio``,
``reference_eigenvalue``, ``reference_mode_vector`` (point, reference_mode), the MAC
``reference_mac`` (mode, reference_mode) on the points both hold, and per identified mode the
reference mode of largest MAC (``reference_match``, the label, or -1 when no MAC reaches
:data:`MATCH_MAC`). :func:`format_reference_table` prints them side by side.
"""

from __future__ import annotations

import os

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError

__all__ = [
    "frfs_and_modes",
    "MATCH_MAC",
    "REFERENCE_MODE",
    "compare_modes",
    "format_reference_table",
    "split_frf_and_modes",
]

#: Dimension of the file's modes in an identification result.
REFERENCE_MODE = "reference_mode"
PREFIX = "reference_"
REFERENCE_MAC = "reference_mac"
REFERENCE_MATCH = "reference_match"
ATTR_REFERENCE_SOURCE = "reference_modes_source"
#: Smallest MAC for an identified mode to be matched with a reference mode.
MATCH_MAC = 0.5
# dims only identification results (or a simulator's truth) have
_RESULT_DIMS = (names.MODE, names.MODE_2, names.CANDIDATE, names.RESIDUAL_TERM, REFERENCE_MODE)
# per-point (or per-line) variables identify adds
_RESULT_VARIABLES = (
    names.SUB_NOISE_FLOOR,
    names.SUB_STOP_STATISTIC,
    names.SUB_STOP_REASON,
    names.SUB_N_MODES,
    names.ISO_ITERATIONS,
    names.ISO_CONVERGED,
    names.FRF_SYNTHESIZED,
    names.FRF_RESIDUAL,
    names.FRF_NOISE_STD,
)
# attributes of the identification settings and results; a stored band would be kept by identify
_RESULT_ATTR_PREFIXES = ("ami_", "refine_", "analysis_band_", "crb_", "stability_", PREFIX)
_KEPT_ATTR_PREFIXES = ("ami_xr_",)
_RESULT_ATTRS = (
    names.ATTR_EXP_CORRECTED,
    names.ATTR_MULTI_REFERENCE,
    names.ATTR_RANK_ONE_RATIO_MAX,
)
# the file's modal variables carried as the reference set
_MODAL = (
    names.EIGENVALUE,
    names.NATURAL_FREQUENCY,
    names.DAMPING_RATIO,
    names.MODE_VECTOR,
)


def _is_result_attr(key: str) -> bool:
    if key.startswith(_KEPT_ATTR_PREFIXES):
        return False
    return key.startswith(_RESULT_ATTR_PREFIXES) or key in _RESULT_ATTRS


def split_frf_and_modes(
    ds: xr.Dataset, path: str | os.PathLike | None = None
) -> tuple[xr.Dataset, xr.Dataset | None]:
    """The FRF Dataset and the modes a Dataset holds.

    Parameters
    ----------
    ds : xarray.Dataset
        A Dataset with ``frf`` and, perhaps, modes (``eigenvalue`` along ``mode``): a UFF file
        with datasets 58 and 55, an identification result.
    path : str or path-like, optional
        The file it came from, named in errors and stored (file name only) as
        ``reference_modes_source``.

    Returns
    -------
    frf : xarray.Dataset
        ``ds`` without the modes and without any stored identification result (variables along
        ``mode``, ``candidate``, ..., the per-point results and the settings attributes), ready
        for :func:`ami_xr.identify`.
    modes : xarray.Dataset or None
        ``eigenvalue``, ``natural_frequency``, ``damping_ratio`` (computed from the eigenvalue
        where absent) and ``mode_vector`` along ``mode``; None when ``ds`` holds no modes.

    Raises
    ------
    AmiXrValueError
        ``ds`` holds no ``frf`` variable (naming ``path``).
    """
    where = os.fspath(path) if path is not None else "ds"
    if names.FRF not in ds.data_vars:
        raise AmiXrValueError(
            f"{where}: holds no FRFs (variable {names.FRF!r}); nothing to identify"
        )
    modes = None
    if names.EIGENVALUE in ds.data_vars and names.MODE in ds[names.EIGENVALUE].dims:
        lam = ds[names.EIGENVALUE]
        parts = {names.EIGENVALUE: lam}
        wn = np.abs(lam)
        parts[names.NATURAL_FREQUENCY] = ds.get(names.NATURAL_FREQUENCY, wn / (2 * np.pi))
        parts[names.DAMPING_RATIO] = ds.get(names.DAMPING_RATIO, -lam.real / wn)
        if names.MODE_VECTOR in ds.data_vars:
            parts[names.MODE_VECTOR] = ds[names.MODE_VECTOR]
        modes = xr.Dataset(parts)
        if path is not None:
            modes.attrs[ATTR_REFERENCE_SOURCE] = os.path.basename(os.fspath(path))
    frf = ds.drop_dims([d for d in _RESULT_DIMS if d in ds.dims])
    frf = frf.drop_vars([v for v in _RESULT_VARIABLES if v in frf.variables])
    frf.attrs = {k: v for k, v in ds.attrs.items() if not _is_result_attr(k)}
    return frf, modes


def _mac(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """MAC between the columns of ``a`` (point, m) and ``b`` (point, n): (m, n)."""
    num = np.abs(a.conj().T @ b) ** 2
    den = np.outer(np.sum(np.abs(a) ** 2, axis=0), np.sum(np.abs(b) ** 2, axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.nan)


def compare_modes(result: xr.Dataset, reference: xr.Dataset) -> xr.Dataset:
    """``result`` with ``reference``'s modes as a reference set (see the module docstring).

    Parameters
    ----------
    result : xarray.Dataset
        An identification result (``eigenvalue`` and ``mode_vector`` along ``mode``).
    reference : xarray.Dataset
        Modes to compare with (the second output of :func:`split_frf_and_modes`).

    Returns
    -------
    xarray.Dataset
        A new Dataset; ``reference_mac`` and ``reference_match`` only where both hold mode
        vectors at common points.

    Raises
    ------
    AmiXrValueError
        ``reference`` has no ``eigenvalue`` along ``mode``.
    """
    if names.EIGENVALUE not in reference or names.MODE not in reference[names.EIGENVALUE].dims:
        raise AmiXrValueError(f"reference: expected modes ({names.EIGENVALUE!r} along 'mode')")
    ref = reference.rename({names.MODE: REFERENCE_MODE})
    out = result.copy()
    for v in _MODAL:
        if v in ref:
            da = ref[v]
            if names.POINT in da.dims:  # the identified points only: one point coordinate
                da = da.reindex({names.POINT: result[names.POINT].values})
            out[PREFIX + v] = da.drop_vars(
                [c for c in da.coords if c not in da.dims], errors="ignore"
            )
    if ATTR_REFERENCE_SOURCE in reference.attrs:
        out.attrs[ATTR_REFERENCE_SOURCE] = reference.attrs[ATTR_REFERENCE_SOURCE]
    if names.MODE_VECTOR not in ref or names.MODE_VECTOR not in result:
        return out
    common = [p for p in result[names.POINT].values if p in set(ref[names.POINT].values)]
    if not common or result.sizes.get(names.MODE, 0) == 0:
        return out
    a = result[names.MODE_VECTOR].sel({names.POINT: common}).transpose(names.POINT, ...).values
    b = ref[names.MODE_VECTOR].sel({names.POINT: common}).transpose(names.POINT, ...).values
    mac = _mac(a, b)
    out[REFERENCE_MAC] = (
        (names.MODE, REFERENCE_MODE),
        mac,
        {names.ATTR_LONG_NAME: f"MAC with the reference modes on {len(common)} common points"},
    )
    labels = ref[REFERENCE_MODE].values
    best = np.nanargmax(np.nan_to_num(mac, nan=-1.0), axis=1)
    match = np.where(np.nan_to_num(mac[np.arange(mac.shape[0]), best]) >= MATCH_MAC, best, -1)
    out[REFERENCE_MATCH] = (
        names.MODE,
        np.where(match >= 0, labels[np.maximum(match, 0)], -1).astype(np.int64)
        if np.issubdtype(labels.dtype, np.integer)
        else np.where(match >= 0, match + 1, -1).astype(np.int64),
        {
            names.ATTR_LONG_NAME: "reference mode of largest MAC with this mode "
            f"(-1: no MAC >= {MATCH_MAC:g})"
        },
    )
    return out


def format_reference_table(result: xr.Dataset) -> str:
    """Identified and reference modes side by side: frequency (Hz), damping (%), MAC, and the
    differences, one line per identified mode (then the reference modes nothing matched)."""
    if PREFIX + names.NATURAL_FREQUENCY not in result:
        return ""
    source = result.attrs.get(ATTR_REFERENCE_SOURCE, "the file")
    lines = [
        f"reference modes from {source}: identified vs reference",
        f"{'mode':>4} {'f [Hz]':>10} {'zeta [%]':>8}   {'ref':>4} {'f [Hz]':>10} "
        f"{'zeta [%]':>8} {'df [%]':>7} {'MAC':>5}",
    ]
    rf = result[PREFIX + names.NATURAL_FREQUENCY]
    rz = result[PREFIX + names.DAMPING_RATIO].values
    ref_labels = list(rf[REFERENCE_MODE].values)
    match = result[REFERENCE_MATCH].values if REFERENCE_MATCH in result else None
    used = set()
    for k, label in enumerate(result[names.MODE].values if names.MODE in result.dims else []):
        f = float(result[names.NATURAL_FREQUENCY].values[k])
        z = 100 * float(result[names.DAMPING_RATIO].values[k])
        head = f"{label!s:>4} {f:10.4f} {z:8.3f}"
        j = None
        if match is not None and int(match[k]) != -1:
            j = ref_labels.index(match[k]) if match[k] in ref_labels else int(match[k]) - 1
        if j is None:
            lines.append(f"{head}   {'-':>4}")
            continue
        used.add(j)
        fr = float(rf.values[j])
        mac = float(result[REFERENCE_MAC].values[k, j])
        lines.append(
            f"{head}   {ref_labels[j]!s:>4} {fr:10.4f} {100 * rz[j]:8.3f} "
            f"{100 * (f - fr) / fr:7.3f} {mac:5.3f}"
        )
    for j, label in enumerate(ref_labels):
        if j not in used:
            lines.append(
                f"{'-':>4} {'':>10} {'':>8}   {label!s:>4} {float(rf.values[j]):10.4f} "
                f"{100 * rz[j]:8.3f}  (not matched)"
            )
    return "\n".join(lines)


def frfs_and_modes(ds: xr.Dataset, rel: str) -> tuple[xr.Dataset, xr.Dataset | None]:
    """``(FRF or time Dataset, the modes the file holds or None)``: a file of FRFs and modes (a
    test with the modes someone fitted) has its FRFs identified and its modes compared; a file
    of modes alone, or of neither, is refused naming what it holds (``rel``: the file's name).

    Raises
    ------
    DataFileError
        Modes without FRFs, or neither FRFs nor time histories.
    """
    from ami_xr.io.kinds import file_kind

    if file_kind(ds) == "modes":
        if names.FRF not in ds:
            raise DataFileError(
                f"{rel}: a modes file ({ds.sizes.get(names.MODE, 0)} mode(s), no FRFs): nothing to "
                "identify; 'ami-xr report' shows it, 'ami-xr convert' writes it as netCDF or UFF 55"
            )
        return split_frf_and_modes(ds, rel)
    if names.FRF not in ds and names.RESPONSE not in ds:
        raise DataFileError(
            f"{rel}: neither an FRF Dataset ('{names.FRF}') nor a time Dataset "
            f"('{names.RESPONSE}'); found variables {sorted(map(str, ds.data_vars))}"
        )
    return ds, None
