"""The one unit parser of every reader: unit labels as files write them -> the units ami_xr knows.

A CSV header ``p1_re [m/s²/N]``, a UFF ordinate label ``(1/N)*(m/s²)``, a LabVIEW
``Y_Unit_Label`` ``Newtons`` and a MATLAB ``channel_units`` cell ``'m/s2'`` all go through
:func:`unit_name` (one unit) and :func:`frf_unit` (a response unit over a force unit), so every
format accepts the same spellings:

* case does not matter where it is unambiguous (``"G"`` is ``"g"``, ``"n"`` is ``"N"``);
* superscripts and powers: ``"m/s²"``, ``"m/s**2"``, ``"m/s2"``, ``"m/s/s"`` are ``"m/s^2"``;
* spaces are ignored (``"m / s^2"``); ``"µm"`` is ``"um"``; ``"Newtons"``, ``"lbs"`` are forces;
* an FRF unit is ``<response>/<force>`` in any of ``"m/s^2/N"``, ``"(m/s^2)/N"``,
  ``"(m/s^2)/(N)"``, ``"(1/N)*(m/s^2)"``, ``"(m/s^2)*(1/N)"``.

The known units are :data:`ami_xr.names.RESPONSE_UNITS` and :data:`ami_xr.names.FORCE_UNITS`.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

from ami_xr import names

__all__ = [
    "RESPONSE_UNIT_QUANTITY",
    "force_unit",
    "frf_unit",
    "quantity_of_unit",
    "response_unit",
    "unit_name",
]

#: Response unit -> the quantity it measures (``"g"`` -> ``"acceleration"``).
RESPONSE_UNIT_QUANTITY = {u: q for q, units in names.RESPONSE_UNITS.items() for u in units}
_POWERS = {"²": "^2", "³": "^3", "**": "^"}
# spellings (lower case, no spaces, powers as ^) that are not a known unit in another case
_ALIASES = {
    "m/s2": "m/s^2",
    "m/s/s": "m/s^2",
    "mm/s2": "mm/s^2",
    "in/s2": "in/s^2",
    "µm": "um",
    "μm": "um",
    "newton": "N",
    "newtons": "N",
    "kilonewton": "kN",
    "lbs": "lbf",
    "lb": "lbf",
}
_FRF_FORMS = (
    re.compile(r"^\(?1/(?P<f>[^()*/]+)\)?\*\(?(?P<r>[^()*]+?)\)?$"),
    re.compile(r"^\(?(?P<r>[^()*]+?)\)?\*\(?1/(?P<f>[^()*/]+)\)?$"),
    re.compile(r"^\((?P<r>[^()*]+)\)/\(?(?P<f>[^()*/]+?)\)?$"),
    re.compile(r"^(?P<r>[^()*]+)/\(?(?P<f>[^()*/]+?)\)?$"),
)


def _plain(raw: Any) -> str:
    """The label without spaces and with powers as ``^``."""
    text = "".join(str(raw if raw is not None else "").split())
    for sign, plain in _POWERS.items():
        text = text.replace(sign, plain)
    return text


def unit_name(raw: Any, allowed: Sequence[str]) -> str | None:
    """The unit of ``allowed`` a label names, else None (an empty label or ``"NONE"`` too).

    Parameters
    ----------
    raw : str or None
        A unit label as a file writes it.
    allowed : sequence of str
        The units to recognise, e.g. :data:`ami_xr.names.FORCE_UNITS`.

    Returns
    -------
    str or None
        The unit as spelled in ``allowed``.
    """
    text = _plain(raw)
    if not text or text.upper() == "NONE":
        return None
    if text in allowed:
        return text
    text = _ALIASES.get(text.lower(), text)
    by_lower = {a.lower(): a for a in allowed}
    return text if text in allowed else by_lower.get(text.lower())


def response_unit(raw: Any) -> str | None:
    """The response unit (:data:`ami_xr.names.RESPONSE_UNITS`) a label names, else None."""
    return unit_name(raw, tuple(RESPONSE_UNIT_QUANTITY))


def force_unit(raw: Any) -> str | None:
    """The force unit (:data:`ami_xr.names.FORCE_UNITS`) a label names, else None."""
    return unit_name(raw, names.FORCE_UNITS)


def quantity_of_unit(raw: Any) -> str | None:
    """The response quantity a unit label measures (``"m/s²"`` -> acceleration), else None."""
    unit = response_unit(raw)
    return None if unit is None else RESPONSE_UNIT_QUANTITY[unit]


def frf_unit(raw: Any) -> tuple[str, str] | None:
    """``(response unit, force unit)`` of an FRF unit label, else None.

    ``"m/s^2/N"``, ``"m/s²/N"``, ``"(m/s^2)/N"``, ``"(1/N)*(m/s²)"`` and ``"g/lbf"`` are FRF
    units; a label naming one unit alone is not (see :func:`response_unit`).
    """
    text = _plain(raw)
    for form in _FRF_FORMS:
        match = form.match(text)
        if match is None:
            continue
        response, force = response_unit(match["r"]), force_unit(match["f"])
        if response is not None and force is not None:
            return response, force
    return None
