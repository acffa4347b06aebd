"""Receptance, mobility and accelerance: :func:`convert_quantity` of an FRF Dataset, and
:func:`resolve_quantity`, the one rule that turns what a user gave (a response quantity, an FRF
type or one of its synonyms, units) into consistent ``response_quantity``/``frf_type``/units."""

from __future__ import annotations

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.core.checks import check_choice
from ami_xr.errors import AmiXrValueError
from ami_xr.provenance import add_history

QUANTITIES = tuple(names.QUANTITY_TO_FRF_TYPE)
_G = 9.80665  # m/s^2 per g

# Common names of the three FRF types (case, "-" and "_" ignored) -> the type ami_xr stores.
FRF_TYPE_SYNONYMS = {
    "receptance": "receptance",
    "compliance": "receptance",
    "dynamic flexibility": "receptance",
    "mobility": "mobility",
    "admittance": "mobility",
    "accelerance": "accelerance",
    "inertance": "accelerance",
}
DEFAULT_QUANTITY = "displacement"  # taken, with an AssumptionWarning, when nothing is given
ATTR_QUANTITY_ASSUMED = "response_quantity_assumed"  # why the quantity was assumed (not given)


def frf_type_of(frf_type: str) -> str:
    """The FRF type ami_xr stores for ``frf_type`` or one of its synonyms
    (:data:`FRF_TYPE_SYNONYMS`: inertance = accelerance, admittance = mobility,
    compliance and dynamic flexibility = receptance)."""
    key = " ".join(str(frf_type).strip().lower().replace("_", " ").replace("-", " ").split())
    if key not in FRF_TYPE_SYNONYMS:
        raise AmiXrValueError(
            f"frf_type: expected one of {tuple(FRF_TYPE_SYNONYMS)}, got {frf_type!r}"
        )
    return FRF_TYPE_SYNONYMS[key]


def resolve_quantity(
    response_quantity: str | None, frf_type: str | None, response_units: str | None
) -> tuple[str, str, str | None]:
    """``(response_quantity, response_units, assumed)`` from what a user gave.

    The quantity comes from ``response_quantity`` or from ``frf_type`` (a synonym is accepted);
    both given must agree. Units default to the SI units of the quantity (m, m/s, m/s^2).
    Nothing given: displacement in m is assumed and ``assumed`` says so (else None); the caller
    warns and records it in attribute :data:`ATTR_QUANTITY_ASSUMED`.
    """
    from_type = None
    if frf_type is not None:
        from_type = names.FRF_TYPE_TO_QUANTITY[frf_type_of(frf_type)]
    if response_quantity is not None and response_quantity not in QUANTITIES:
        # not ours to reject: the schema check reports it with every other problem at once
        units = response_units if response_units is not None else "m"
        return response_quantity, units, None
    if response_quantity is not None:
        if from_type is not None and from_type != response_quantity:
            raise AmiXrValueError(
                f"frf_type, response_quantity: a {frf_type!r} FRF has response quantity "
                f"{from_type!r}, not {response_quantity!r}; give one of them"
            )
    quantity = response_quantity or from_type
    assumed = None
    if quantity is None:
        quantity = DEFAULT_QUANTITY
        if response_units is not None:  # the units may tell the quantity
            hits = [q for q, us in names.RESPONSE_UNITS.items() if response_units in us]
            quantity = hits[0] if len(hits) == 1 else quantity
        if (
            response_units is None
            or quantity == DEFAULT_QUANTITY
            and response_units not in (names.RESPONSE_UNITS[DEFAULT_QUANTITY])
        ):
            assumed = (
                "response_quantity and frf_type not given: displacement (receptance, "
                f"{response_units or 'm'}) assumed; pass response_quantity= ('velocity' for "
                "mobility, 'acceleration' for accelerance) or frf_type="
            )
    if response_units is None:
        response_units = names.SI_RESPONSE_UNITS[quantity]
    return quantity, response_units, assumed


def convert_units(units: str, k_from: int, k_to: int) -> tuple[str, float]:
    """Response units after converting by ``(i w)^(k_to - k_from)``, and a scale (g -> m/s^2)."""
    scale = 1.0
    base = units
    if k_from == 2 and units == "g":
        base, scale = "m", _G
    else:
        suffix = ("", "/s", "/s^2")[k_from]
        if suffix and units.endswith(suffix):
            base = units[: -len(suffix)]
        elif suffix:
            raise AmiXrValueError(
                f"response_units: cannot convert {units!r} (expected units ending in {suffix!r})"
            )
    return base + ("", "/s", "/s^2")[k_to], scale


def convert_quantity(ds: xr.Dataset, to: str, *, dc: str = "nan") -> xr.Dataset:
    """Convert an FRF Dataset between receptance, mobility and accelerance.

    The FRF is multiplied by ``(i w)^k`` with ``k`` the difference of the derivative orders
    (displacement 0, velocity 1, acceleration 2); ``cross_spectrum`` and
    ``response_autospectrum`` follow (times ``(i w)^k`` and ``w^(2k)``).

    Parameters
    ----------
    ds : xarray.Dataset
        FRF Dataset with ``response_quantity`` and ``response_units`` attributes (units ending in
        ``"/s"`` or ``"/s^2"`` for velocity and acceleration; ``"g"`` is converted to m/s^2).
    to : {"displacement", "velocity", "acceleration"}
        Target response quantity (receptance, mobility, accelerance).
    dc : {"nan", "zero", "drop"}
        What integration (``k < 0``) does at 0 Hz, where dividing by ``i w`` is undefined: NaN,
        0, or drop the 0 Hz line. Differentiation gives 0 there.

    Returns
    -------
    xarray.Dataset
        A new Dataset. An FRF made from a sampled impulse response (``frf_source =
        "impulse_response"``) is no longer ``dt * DFT`` of a sampled impulse response after the
        conversion, so it becomes ``"measured"`` and loses ``sample_interval``/``record_samples``.
    """
    if not isinstance(ds, xr.Dataset) or names.FRF not in ds.data_vars:
        raise AmiXrValueError("ds: expected an FRF Dataset with an 'frf' variable")
    to = check_choice(to, "to", QUANTITIES)
    dc = check_choice(dc, "dc", ("nan", "zero", "drop"))
    src = ds.attrs.get(names.ATTR_QUANTITY)
    if src not in names.QUANTITY_POWER:
        raise AmiXrValueError(
            f"ds: attribute {names.ATTR_QUANTITY!r} must be one of {QUANTITIES}, got {src!r}"
        )
    k = names.QUANTITY_POWER[to] - names.QUANTITY_POWER[src]
    ru = ds.attrs.get(names.ATTR_RESPONSE_UNITS, "")
    new_units, scale = convert_units(ru, names.QUANTITY_POWER[src], names.QUANTITY_POWER[to])
    f = ds[names.FREQUENCY]
    iw = xr.DataArray(2j * np.pi * f.values, dims=[names.FREQUENCY])
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = scale * iw**k if k >= 0 else scale / iw ** (-k)
    if k < 0:
        at0 = f.values == 0
        factor = factor.where(
            ~xr.DataArray(at0, dims=[names.FREQUENCY]), np.nan if dc == "nan" else 0.0
        )
    out = ds.copy()
    out[names.FRF] = ds[names.FRF] * factor
    fu = ds.attrs.get(names.ATTR_FORCE_UNITS, "")
    out[names.FRF].attrs = {**ds[names.FRF].attrs, names.ATTR_UNITS: names.frf_units(new_units, fu)}
    if names.CROSS_SPECTRUM in ds:
        out[names.CROSS_SPECTRUM] = ds[names.CROSS_SPECTRUM] * factor
        out[names.CROSS_SPECTRUM].attrs = {names.ATTR_UNITS: f"{fu}*{new_units}/Hz"}
    if names.RESPONSE_AUTOSPECTRUM in ds:
        out[names.RESPONSE_AUTOSPECTRUM] = ds[names.RESPONSE_AUTOSPECTRUM] * np.abs(factor) ** 2
        out[names.RESPONSE_AUTOSPECTRUM].attrs = {names.ATTR_UNITS: f"({new_units})^2/Hz"}
    out.attrs = dict(ds.attrs)
    out.attrs[names.ATTR_QUANTITY] = to
    out.attrs[names.ATTR_FRF_TYPE] = names.QUANTITY_TO_FRF_TYPE[to]
    out.attrs[names.ATTR_RESPONSE_UNITS] = new_units
    if out.attrs.get(names.ATTR_SOURCE) == names.SOURCE_IMPULSE and k != 0:
        out.attrs[names.ATTR_SOURCE] = names.SOURCE_MEASURED
        out.attrs.pop(names.ATTR_DT, None)
        out.attrs.pop(names.ATTR_NSAMPLES, None)
    if k < 0 and dc == "drop":
        out = out.sel({names.FREQUENCY: f.values[f.values > 0]})
    return add_history(out, "ami_xr.convert_quantity", {"to": to, "dc": dc, "from": src})
