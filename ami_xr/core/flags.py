"""Quality flags of the modes as named bits: the one place they are encoded.

A phase decides each flag where it knows it and sets or clears its bit in an int32 mask per mode
(:func:`bit`, :func:`set_where`); :func:`encode` turns the mask into the text of
``quality_flags`` (the flags set, in the order of :data:`ami_xr.names.FLAG_MEANINGS`, joined by
``","``) and :func:`decode` reads it back. Bit ``k`` is ``2**k`` for ``FLAG_MEANINGS[k]``, as in
the CF ``flag_masks``/``flag_meanings`` field written to files. :data:`DESCRIPTIONS` says in one
line what each flag means, for a reader who has not read the docs (the report's legend; the flag
table of docs/identification.md states the same texts).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ami_xr import names
from ami_xr.errors import AmiXrValueError

MEANINGS = names.FLAG_MEANINGS
MASKS = np.array([1 << k for k in range(len(MEANINGS))], dtype=np.int32)
_BIT = dict(zip(MEANINGS, MASKS.tolist(), strict=True))

#: One plain-language line per flag, in bit order: what it says about the mode and what to make
#: of it. The report's flag legend shows these; docs/identification.md's flag table states the
#: same texts (tests/ami/test_flags.py compares them).
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
    return (np.asarray(mask, dtype=np.int32) & bit(flag)) != 0


def encode(mask: np.ndarray) -> np.ndarray:
    """The text of each mask: the flags set, in bit order, joined by ``","`` ("" for none)."""
    mask = np.asarray(mask, dtype=np.int32)
    out = [names.FLAG_SEPARATOR.join(f for f, b in _BIT.items() if m & b) for m in mask.ravel()]
    return np.array(out, dtype=str).reshape(mask.shape)


def decode(text: np.ndarray, *, unknown: str = "raise") -> np.ndarray:
    """The int32 mask of each flag text (the inverse of :func:`encode`; order and blanks
    around a flag do not matter).

    Parameters
    ----------
    text : array_like of str
        Comma-joined flags, as in ``quality_flags``.
    unknown : {"raise", "ignore"}
        A flag not in :data:`MEANINGS`: an error naming it, or left out of the mask (the CF bit
        field of a file, which has no bit for a flag it cannot name).

    Returns
    -------
    numpy.ndarray
        int32, the shape of ``text``.
    """
    if unknown not in ("raise", "ignore"):
        raise AmiXrValueError(f"unknown: expected 'raise' or 'ignore', got {unknown!r}")
    text = np.asarray(text).astype(str)
    out = np.zeros(text.shape, np.int32)
    for index, value in np.ndenumerate(text):
        for flag in filter(None, (f.strip() for f in value.split(names.FLAG_SEPARATOR))):
            if unknown == "raise" or flag in _BIT:
                out[index] |= bit(flag)
    return out
