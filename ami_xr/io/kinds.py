"""What a file holds (time histories, FRFs, modes), decided from its variables, so a reader asked
for one kind can refuse another with a message that says which command takes it.

A modes file written by ``ami-xr identify -o MODES.nc`` also holds the FRFs it was identified
from; identifying it again would mix the stored results with the new ones (and fail inside
xarray with "conflicting sizes for dimension 'mode'" when the mode counts differ).
"""

from __future__ import annotations

import os

import xarray as xr

from ami_xr import names
from ami_xr.errors import DataFileError
from ami_xr.provenance import history

__all__ = ["KINDS", "ModesFileError", "file_kind", "refuse_other_kind"]

#: The kinds :func:`file_kind` returns.
KINDS = ("modes", "frf", "time", "unknown")

# a Dataset holding these along ``mode`` holds modal results (identified or a simulator's truth)
_MODAL_VARIABLES = (names.EIGENVALUE, names.MODE_VECTOR, names.RESIDUE)


class ModesFileError(DataFileError):
    """A file of modal results was given where FRFs or time histories are wanted."""


def file_kind(ds: xr.Dataset) -> str:
    """``"modes"`` when ``ds`` holds modal results (``eigenvalue`` along ``mode`` and a mode
    vector or residue, FRFs or not), else ``"frf"`` (a ``frf`` variable), ``"time"`` (a
    ``time`` dim) or ``"unknown"``."""
    held = [v for v in _MODAL_VARIABLES if v in ds.data_vars and names.MODE in ds[v].dims]
    if names.EIGENVALUE in held and len(held) >= 2:
        return "modes"
    if names.FRF in ds.data_vars:
        return "frf"
    if names.TIME in ds.dims:
        return "time"
    return "unknown"


def refuse_other_kind(ds: xr.Dataset, path: str | os.PathLike, want: str) -> None:
    """Raise :class:`ModesFileError` when ``ds`` (read from ``path``) is a modes file and
    ``want`` (``"frf"`` or ``"time"``) is something else; other kinds are left to the
    consumer's own schema check, which names what is missing.

    Raises
    ------
    ModesFileError
        ``ds`` holds modal results.
    """
    if want == "modes" or file_kind(ds) != "modes":
        return
    name = os.fspath(path)
    made_by = set()
    for record in history(ds):  # a command's record holds identify as one of its steps
        if isinstance(record, dict):
            steps = record.get("steps")
            inner = steps if isinstance(steps, list) else []
            made_by |= {str(r.get("function", "")) for r in [record, *inner] if isinstance(r, dict)}
    identified = made_by & {"ami_xr.identify", "ami-xr identify"}
    origin = " (written by ami-xr identify)" if identified else ""
    wanted = {"frf": "an FRF file", "time": "a file of time histories"}.get(want, want)
    frf = (
        "; to identify again, give the FRF file it was made from"
        if want == "frf"
        else "; ami-xr frf takes time histories (force and response)"
    )
    raise ModesFileError(
        f"{name}: a modes file{origin}, with identified modes ('{names.EIGENVALUE}' along "
        f"'{names.MODE}'), where {wanted} is wanted: 'ami-xr report {name}' shows it and "
        f"'ami-xr convert {name} -o modes.uff' writes its mode shapes as UFF 55{frf}"
    )
