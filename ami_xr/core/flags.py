"""Status as data: the quality flags of the modes and the caps of a run, as named bits.

``quality_flags`` (dims ``mode``) is an int32 bit field in memory, in the API and on disk: bit
``k`` (``2**k``) is flag :data:`TABLE` ``[k]``, whose ``name`` and ``description`` are the one
table of words (the CF ``flag_masks``/``flag_meanings`` of a file are written from it). A phase
decides each flag where it knows it and sets or clears its bit (:func:`bit`, :func:`set_where`,
:func:`has`); text appears only where a person reads it: :func:`flag_text` for the tables and the
report, :func:`from_text` for the files of earlier versions (comma-joined names).

The caps that ended a phase of a run (attributes ``ami_capped`` and ``ami_capped_superseded``)
are a :class:`RunStatus`, an :class:`enum.IntFlag` with one bit per cap and the same two words
per bit (:data:`CAPS`); :meth:`RunStatus.of` reads either the int or the comma text of an earlier
file.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ami_xr import names
from ami_xr.errors import AmiXrValueError


@dataclass(frozen=True)
class Flag:
    """One quality flag: its name (:data:`ami_xr.names.FLAG_MEANINGS`), its bit and its words."""

    name: str
    mask: int
    description: str


DESCRIPTIONS: dict[str, str] = {
    names.FLAG_LOW_DRIVE_SNR: (
        "The mode barely rises above the noise at the drive point (where the force acts), so "
        "the scaling of its mode vector is unreliable; frequency and damping come from all FRFs."
    ),
    names.FLAG_UNSCALED: (
        "No response was measured where the force acts (no drive point), so the mode vector "
        "cannot be scaled: it is normalised to a largest entry of 1."
    ),
    names.FLAG_NOT_CONVERGED: (
        "The isolation phase reached its iteration limit before this mode settled, and no "
        "converged refinement replaced it: treat its frequency and damping with care."
    ),
    names.FLAG_SINGLE_FRF: (
        "Only one FRF showed this mode above its noise: it may be a local mode, a mode the "
        "other points barely see, or noise."
    ),
    names.FLAG_REFINE_NOT_CONVERGED: (
        "The refinement stopped at its iteration limit while this mode was still moving: its "
        "values are the last step, not a settled fit."
    ),
    names.FLAG_REFINE_FALLBACK: (
        "The refinement could not fit this mode and kept its first (AMI) estimate: frequency "
        "and damping are not refined."
    ),
    names.FLAG_ADDED_BY_REFINE: (
        "Found by the refinement in what the other modes left unexplained; no FRF detected it "
        "in the first pass, so it has no AMI estimate."
    ),
    names.FLAG_REPEATED_ROOT: (
        "Two modes may lie at (nearly) this frequency: the response near it shows more than one "
        "shape, which one mode cannot fit (within one reference's FRFs, or between references)."
    ),
    names.FLAG_REPEATED_ROOT_SEPARATED: (
        "Multi-reference: one of two modes at the same frequency that the references told "
        "apart; its partner is the neighbouring mode."
    ),
    names.FLAG_UNDER_RESOLVED: (
        "Its half-power bandwidth (2 zeta f_n) spans under 3 frequency lines: the line spacing "
        "and the window bias its damping, and damping_ratio_std is widened to cover that."
    ),
}


#: The quality flags in bit order: never reorder, only append (files hold the bits).
TABLE: tuple[Flag, ...] = tuple(
    Flag(name, 1 << k, DESCRIPTIONS[name]) for k, name in enumerate(names.FLAG_MEANINGS)
)
MEANINGS = tuple(f.name for f in TABLE)
MASKS = np.array([f.mask for f in TABLE], dtype=np.int32)
_BIT = {f.name: f.mask for f in TABLE}
#: every bit of the table set
ALL = int(np.bitwise_or.reduce(MASKS))
#: the fill of an integer variable for a mode added by a reindex: no flag decided yet
MISSING = -1


def bit(flag: str) -> int:
    """The mask of ``flag`` (one of :data:`ami_xr.names.FLAG_MEANINGS`)."""
    try:
        return _BIT[flag]
    except KeyError:
        raise AmiXrValueError(f"quality flag: expected one of {MEANINGS}, got {flag!r}") from None


def describe(flag: str) -> str:
    """The one-line description of ``flag`` (:data:`DESCRIPTIONS`)."""
    bit(flag)  # an unknown flag: the error naming the known ones
    return DESCRIPTIONS[flag]


def set_where(mask: np.ndarray, flag: str, where: Iterable[bool] | bool) -> np.ndarray:
    """``mask`` with the bit of ``flag`` set where ``where`` is True and cleared elsewhere."""
    b = np.int32(bit(flag))
    where = np.broadcast_to(np.asarray(where, dtype=bool), np.shape(mask))
    return np.where(where, mask | b, mask & ~b).astype(np.int32)


def has(mask: np.ndarray, flag: str) -> np.ndarray:
    """Where ``mask`` has the bit of ``flag`` set (bool, the shape of ``mask``)."""
    return (decode(mask) & bit(flag)) != 0


def names_of(mask: int) -> list[str]:
    """The flags set in one mask, in bit order."""
    return [f.name for f in TABLE if int(mask) & f.mask]


def flag_text(mask: np.ndarray) -> np.ndarray:
    """The words of each mask, for a table or a report: the flags set, in bit order, joined by
    ``","`` ("" for none). Accepts what :func:`decode` accepts."""
    mask = decode(mask)
    out = [names.FLAG_SEPARATOR.join(names_of(m)) for m in mask.ravel()]
    return np.array(out, dtype=str).reshape(mask.shape)


def from_text(value: np.ndarray, *, unknown: str = "raise") -> np.ndarray:
    """The int32 mask of each comma-joined flag text (``quality_flags`` as files of earlier
    versions hold it; the inverse of :func:`flag_text`: order and blanks do not matter).

    Parameters
    ----------
    value : array_like of str
        Comma-joined flag names.
    unknown : {"raise", "ignore"}
        A flag not in :data:`MEANINGS`: an error naming it, or left out of the mask.

    Returns
    -------
    numpy.ndarray
        int32, the shape of ``value``.
    """
    if unknown not in ("raise", "ignore"):
        raise AmiXrValueError(f"unknown: expected 'raise' or 'ignore', got {unknown!r}")
    value = np.asarray(value).astype(str)
    out = np.zeros(value.shape, np.int32)
    for index, entry in np.ndenumerate(value):
        for flag in filter(None, (f.strip() for f in entry.split(names.FLAG_SEPARATOR))):
            if unknown == "raise" or flag in _BIT:
                out[index] |= bit(flag)
    return out


def decode(value: Any, *, unknown: str = "raise") -> np.ndarray:
    """The int32 mask of ``quality_flags`` values: the bit field itself, or the comma text of an
    earlier version's file (:func:`from_text` with ``unknown``). A fill for a mode added by a
    reindex (NaN, or :data:`MISSING`) has no flag; a bit outside :data:`TABLE` is an error."""
    arr = np.asarray(value)
    if arr.dtype.kind in "USO":
        return from_text(arr, unknown=unknown)
    if arr.dtype.kind == "f":
        # xarray's reindex/alignment turns the int field into floats with NaN for a new mode:
        # no flag decided for it yet
        whole = np.isnan(arr) | (arr == np.round(arr))
        if not np.all(whole):
            raise AmiXrValueError(f"quality_flags: expected an integer bit field, got {arr}")
        arr = np.where(np.isnan(arr), 0, arr)
    elif arr.dtype.kind not in "iub" and arr.size:
        raise AmiXrValueError(f"quality_flags: expected an integer bit field, got {arr.dtype}")
    out = arr.astype(np.int32)
    # -1: the fill value ami_xr.ami.refine gives integer variables of a mode it adds
    out = np.where(out == MISSING, 0, out).astype(np.int32)
    if np.any(out & ~np.int32(ALL)):
        raise AmiXrValueError(
            f"quality_flags: bits {int(np.bitwise_or.reduce(out.ravel()) & ~ALL):#x} are not in "
            f"the flag table ({', '.join(MEANINGS)})"
        )
    return out


class RunStatus(enum.IntFlag):
    """The caps that ended a phase of a run, one bit each (attributes ``ami_capped``: the run is
    incomplete, and ``ami_capped_superseded``: a cap the refinement made moot). The words of
    each bit are in :data:`CAPS`."""

    NONE = 0
    SUBTRACT_MAX_MODES = 1
    SUBTRACT_MAX_REJECTED_PEAKS = 2
    ISOLATE_MAX_ITER = 4
    REFINE_MAX_ITER = 8
    REFINE_ADD_MODES = 16

    @classmethod
    def of(cls, value: Any) -> RunStatus:
        """The status held in an attribute: an int, a RunStatus, None/"" (none), or the comma
        text of an earlier version's file ("subtract:max_modes,refine:max_iter")."""
        if value is None or isinstance(value, (int, np.integer)):
            return cls(int(value or 0))
        if isinstance(value, bytes):
            value = value.decode()
        if isinstance(value, str):
            out = cls.NONE
            for entry in filter(None, (e.strip() for e in value.split(","))):
                if entry.isdigit():
                    out |= cls(int(entry))
                    continue
                if entry not in _CAP_BY_NAME:
                    raise AmiXrValueError(
                        f"run status: expected caps among {list(_CAP_BY_NAME)}, got {entry!r}"
                    )
                out |= _CAP_BY_NAME[entry]
            return out
        raise AmiXrValueError(f"run status: expected an int or text, got {type(value).__name__}")

    @property
    def entries(self) -> list[str]:
        """The names ("phase:cap") of the caps set, in bit order."""
        return [c.name for c in CAPS if self & c.status]

    def text(self) -> str:
        """The names joined by ``","`` ("" for none), for a person."""
        return ",".join(self.entries)


@dataclass(frozen=True)
class Cap:
    """One cap of a run: its bit, its name ("phase:cap") and what it means in words."""

    status: RunStatus
    name: str
    description: str


#: The caps in bit order, with the words a report shows.
CAPS: tuple[Cap, ...] = (
    Cap(
        RunStatus.SUBTRACT_MAX_MODES,
        "subtract:max_modes",
        "the subtraction phase stopped at its limit of candidate modes per FRF (max_modes)",
    ),
    Cap(
        RunStatus.SUBTRACT_MAX_REJECTED_PEAKS,
        "subtract:max_rejected_peaks",
        "the subtraction phase stopped after examining its limit of peaks (3 max_modes + 10)",
    ),
    Cap(
        RunStatus.ISOLATE_MAX_ITER,
        "isolate:max_iter",
        "the isolation phase reached its iteration limit (max_iter) at some FRF (its modes "
        "carry not_converged; the refinement, refine=True, re-fits them)",
    ),
    Cap(
        RunStatus.REFINE_MAX_ITER,
        "refine:max_iter",
        "the refinement stopped at its iteration limit before converging",
    ),
    Cap(
        RunStatus.REFINE_ADD_MODES,
        "refine:add_modes",
        "the refinement stopped adding modes at its limit (add_modes)",
    ),
)
_CAP_BY_NAME = {c.name: c.status for c in CAPS}
#: the subtraction's caps: they end the list of candidate peaks, which the refinement completes
SUBTRACT_CAPS = RunStatus.SUBTRACT_MAX_MODES | RunStatus.SUBTRACT_MAX_REJECTED_PEAKS


def run_status(attrs: dict, key: str = names.ATTR_AMI_CAPPED) -> RunStatus:
    """The :class:`RunStatus` held in ``attrs[key]`` (none when absent)."""
    return RunStatus.of(attrs.get(key))


def add_caps(attrs: dict, caps: RunStatus | Iterable[str], key: str = names.ATTR_AMI_CAPPED):
    """Set the bits of ``caps`` (a RunStatus, or cap names) in ``attrs[key]`` (an int)."""
    status = caps if isinstance(caps, RunStatus) else RunStatus.of(",".join(caps))
    attrs[key] = int(run_status(attrs, key) | status)
