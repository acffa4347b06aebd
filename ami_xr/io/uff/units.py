"""UFF units: the quantity and units of a dataset-58 record, dataset 164's conversion to SI, and
the attributes that record an assumption or a conversion (rules: :mod:`ami_xr.io.uff`).

Unit labels go through the one unit parser of every reader, :mod:`ami_xr.io.units`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ami_xr import errors
from ami_xr.caller import warn
from ami_xr.errors import DataFileError
from ami_xr.io.uff.codes import SI_UNITS, SPEC_FORCE, SPEC_TO_QUANTITY
from ami_xr.io.units import RESPONSE_UNIT_QUANTITY, force_unit, frf_unit, response_unit

__all__ = [
    "ATTR_QUANTITY_FROM_LABEL",
    "ATTR_UNITS_ASSUMED",
    "ATTR_UNITS_SCALED",
    "RecordUnits",
    "UnitSystem",
    "is_force",
    "record_units",
    "unit_attrs",
    "unit_part",
    "units_system",
]

ATTR_UNITS_ASSUMED = "uff_units_assumed"  # why SI units were assumed (no usable unit labels)
ATTR_UNITS_SCALED = "uff_units_scaled"  # how values were converted to SI by dataset 164
# the response quantity taken from the unit label (ordinate specific data type 0 or 1)
ATTR_QUANTITY_FROM_LABEL = "uff_quantity_from_label"
# the warning class for assumptions
_ASSUMPTION = errors.AssumptionWarning


def _ordinate_units(raw: Any) -> tuple[str | None, str | None]:
    """(response unit, force unit) an ordinate label names: ``"m/s^2" -> ("m/s^2", None)``,
    ``"(1/N)*(m/s²)" -> ("m/s^2", "N")``; None for what it does not name."""
    response = response_unit(raw)
    if response is not None:
        return response, None
    return frf_unit(raw) or (None, None)


class UnitSystem:
    """Dataset 164 of a file: factors that convert its length and force units to SI
    (SI value = file value / factor, as the UFF specification defines them)."""

    def __init__(self, record: dict | None):
        self.given = record is not None
        record = record or {}
        self.length = float(record.get("length", 1.0) or 1.0)
        self.force = float(record.get("force", 1.0) or 1.0)
        self.name = str(record.get("units_description", "") or "").strip() or (
            f"units code {record.get('units_code', '?')}"
        )

    @property
    def is_si(self) -> bool:
        return np.isclose(self.length, 1.0, rtol=1e-6) and np.isclose(self.force, 1.0, rtol=1e-6)

    @property
    def length_is_si(self) -> bool:
        return bool(np.isclose(self.length, 1.0, rtol=1e-6))

    def scaled(self, length: bool) -> str:
        factor = self.length if length else self.force
        what = "length" if length else "force"
        return f"{what} / {factor:.10g} (dataset 164: {self.name})"


def units_system(sets: list[dict]) -> UnitSystem:
    found = [s for s in sets if s.get("type") == 164]
    return UnitSystem(found[0] if found else None)


def unit_part(label: str | None, raw: Any, si: str, is_length: bool, system: UnitSystem, part: str):
    """(units, scale to SI, why assumed or "", how scaled or "") of one side of a record whose
    unit label names the known unit ``label`` (None: none)."""
    if label is not None:
        return label, 1.0, "", ""
    raw = str(raw or "").strip()
    if system.given:
        factor = system.length if is_length else system.force
        how = "" if system.is_si else f"{part} {system.scaled(is_length)}"
        return si, 1.0 / factor, "", how
    shown = f"unknown unit label {raw!r}" if raw and raw.upper() != "NONE" else "no label"
    return si, 1.0, f"{part} in {si} ({shown})", ""


def assumed_si(parts: Sequence[tuple]) -> str:
    """Why SI was assumed for the parts (from :func:`_part`) that found no units, or ""."""
    assumed = [p[2] for p in parts if p[2]]
    if not assumed:
        return ""
    return (
        "the file gives no usable unit label and no units dataset (164); assumed SI: "
        + ", ".join(assumed)
    )


@dataclass(frozen=True)
class RecordUnits:
    """Quantity and units of a dataset-58 record (see :func:`record_units`)."""

    quantity: str
    response: tuple  # (units, scale to SI, why assumed or "", how scaled or "")
    force: tuple  # the same for the force
    from_label: str = ""  # how the quantity came from the unit label, or ""
    key: tuple = field(init=False)  # what must agree between the records of one Dataset

    def __post_init__(self):
        key = (self.quantity, *self.response[:2], *self.force[:2])
        object.__setattr__(self, "key", key)

    @property
    def assumed(self) -> str:
        return assumed_si((self.response, self.force))

    @property
    def scaled(self) -> str:
        return "; ".join(p[3] for p in (self.response, self.force) if p[3])


def dof_text(record: dict) -> str:
    return f"DOF {record.get('rsp_node')}/{record.get('rsp_dir')}"


def record_quantity(record: dict, path: Path, response: str | None) -> tuple[str, str]:
    """Response quantity of a record and, when the unit label gave it, how."""
    spec = int(record.get("ordinate_spec_data_type", 0))
    if spec in SPEC_TO_QUANTITY:
        return SPEC_TO_QUANTITY[spec], ""
    if spec in (0, 1) and response is not None:
        quantity = RESPONSE_UNIT_QUANTITY[response]
        how = (
            f"ordinate specific data type {spec} ({'unknown' if spec == 0 else 'general'}): "
            f"{quantity} from the unit label {response!r}"
        )
        return quantity, how
    label = str(record.get("ordinate_axis_units_lab", "") or "").strip()
    raise DataFileError(
        f"{path}: dataset 58 record of {dof_text(record)} has ordinate specific data type "
        f"{spec} and unit label {label!r}, which name no response quantity; expected data type "
        "8 (displacement), 11 (velocity) or 12 (acceleration), or type 0/1 with a unit label "
        "such as m, m/s, m/s^2 or g (alone or over a force, as m/s^2/N)"
    )


def record_units(record: dict, path: Path, system: UnitSystem | None = None) -> RecordUnits:
    """Quantity and units of a dataset-58 record.

    The quantity comes from the ordinate's specific data type (8, 11, 12), or, for type 0
    (unknown) or 1 (general), from a unit label that names one. A known unit label wins (the
    ordinate label may hold the whole FRF unit, ``"(1/N)*(m/s²)"``); without one, dataset 164
    (when present) gives the units and the values are scaled to SI; without both, SI is assumed
    and the reason is kept."""
    response, label_force = _ordinate_units(record.get("ordinate_axis_units_lab"))
    quantity, from_label = record_quantity(record, path, response)
    if response is not None and RESPONSE_UNIT_QUANTITY[response] != quantity:
        response = None  # a unit of another quantity than the data type says: not usable
    force = force_unit(record.get("orddenom_axis_units_lab"))
    if force is not None and label_force is not None and force != label_force:
        raise DataFileError(
            f"{path}: dataset 58 record of {dof_text(record)}: the ordinate label "
            f"{record.get('ordinate_axis_units_lab')!r} is per {label_force} but the denominator "
            f"label is {force!r}; expected one force unit"
        )
    system = system or UnitSystem(None)
    raw = record.get("ordinate_axis_units_lab")
    return RecordUnits(
        quantity,
        unit_part(response, raw, SI_UNITS[quantity], True, system, "response"),
        unit_part(
            force or label_force,
            record.get("orddenom_axis_units_lab"),
            "N",
            False,
            system,
            "force",
        ),
        from_label,
    )


def tell_assumed(path: Path, why: str) -> None:
    warn(f"{path.name}: {why}; check the FRF units (attribute {ATTR_UNITS_ASSUMED})", _ASSUMPTION)


def unit_attrs(assumed: str, scaled: str) -> dict:
    """The attributes recording assumed or converted units of an FRF Dataset."""
    attrs = {}
    if assumed:
        attrs[ATTR_UNITS_ASSUMED] = assumed
    if scaled:
        attrs[ATTR_UNITS_SCALED] = f"values converted to SI: {scaled}"
    return attrs


def is_force(record: dict) -> bool:
    """A force record: specific data type 13 or 9, or 0/1 (unknown, general) with a force unit
    label."""
    spec = int(record.get("ordinate_spec_data_type", 0))
    if spec in SPEC_FORCE:
        return True
    label = force_unit(record.get("ordinate_axis_units_lab"))
    return spec in (0, 1) and label is not None
