"""Settings of the AMI phases: one frozen dataclass per phase, and the one helper pair that
writes them to and reads them from a Dataset's attributes.

A later phase reads what an earlier one used from the Dataset (so a reopened file continues
exactly): :func:`ami_xr.isolate` reads :class:`SubtractSettings`, :func:`ami_xr.refine` reads the
drive-point threshold of :class:`GlobalFitSettings`. Each field that travels this way names its
attribute (from :mod:`ami_xr.names`) in the ``attr`` metadata; the defaults written here are the
defaults of the public functions' signatures.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, MutableMapping
from dataclasses import dataclass, field
from numbers import Integral, Real
from typing import Any, TypeVar

from ami_xr import names
from ami_xr.errors import AmiXrValueError

_S = TypeVar("_S")


def _attr(default: Any, name: str) -> Any:
    """A dataclass field stored in the attribute ``name``."""
    return field(default=default, metadata={"attr": name})


@dataclass(frozen=True)
class SubtractSettings:
    """Settings of :func:`ami_xr.subtract` (see its docstring); the isolation reuses them.

    ``model`` is the basis actually used ("discrete" or "continuous") once resolved.
    """

    delta: float = _attr(0.5, names.ATTR_AMI_DELTA)
    max_modes: int = _attr(20, names.ATTR_AMI_MAX_MODES)
    pfa: float = _attr(1e-3, names.ATTR_AMI_PFA)
    min_points: int = _attr(3, names.ATTR_AMI_MIN_POINTS)
    zeta_max: float = _attr(0.25, names.ATTR_AMI_ZETA_MAX)
    merge_tol: float = _attr(0.5, names.ATTR_AMI_MERGE_TOL)
    model: str = _attr("auto", names.ATTR_AMI_MODEL)


@dataclass(frozen=True)
class IsolateSettings:
    """Settings of :func:`ami_xr.isolate` (see its docstring)."""

    tol: float = _attr(1e-4, names.ATTR_AMI_TOL)
    max_iter: int = 100
    method: str = _attr(names.METHOD_SIMO, names.ATTR_AMI_METHOD)
    weighting: str = _attr(names.WEIGHTING_SNR, names.ATTR_AMI_WEIGHTING)
    match_tol: float = 0.5
    snr_weighting: bool = True


@dataclass(frozen=True)
class GlobalFitSettings:
    """Settings of :func:`ami_xr.global_fit` (see its docstring); ``band`` may be "all"."""

    band: float | str = _attr(1.0, names.ATTR_AMI_BAND)
    residual_terms: bool = _attr(False, names.ATTR_AMI_RESIDUAL_TERMS)
    drive_snr_min: float = _attr(3.0, names.ATTR_AMI_DRIVE_SNR_MIN)


@dataclass(frozen=True)
class RefineSettings:
    """Settings of :func:`ami_xr.refine` (see its docstring).

    ``residual_terms`` is "auto" or a tuple of "lower"/"upper"; once resolved the terms are
    stored (comma-separated) in ``refine_residual_terms``.
    """

    max_iter: int = 50
    tol: float = 1e-10
    band: str | tuple[float, float] = "all"
    residual_terms: str | tuple[str, ...] = _attr("auto", names.ATTR_REFINE_RESIDUAL_TERMS)
    max_shift: float = 3.0
    add_modes: int = 50  # a safety cap: additions stop when the statistics say so
    add_pfa: float = 1e-3
    drop_modes: bool = True


@dataclass(frozen=True)
class FrfAttributes:
    """What the attributes of an FRF Dataset tell every phase, with the defaults that apply when
    one is absent: the FRF type (which residual terms), the decay rate (1/s) of an exponential
    window applied to the data, and the decay already corrected in the eigenvalues."""

    frf_type: str = _attr("receptance", names.ATTR_FRF_TYPE)
    exponential_window_decay: float = _attr(0.0, names.ATTR_EXP_DECAY)
    exponential_window_corrected: float = _attr(0.0, names.ATTR_EXP_CORRECTED)


@dataclass(frozen=True)
class IdentifySettings:
    """Settings of :func:`ami_xr.identify` (see its docstring): the single- and the
    multi-reference pipelines take this one record. ``refine=None``: refine unless
    ``method="paper"``."""

    method: str = IsolateSettings.method
    refine: bool | None = None
    delta: float = SubtractSettings.delta
    tol: float = IsolateSettings.tol
    max_iter: int = IsolateSettings.max_iter
    band: float | str = GlobalFitSettings.band
    residual_terms: bool = GlobalFitSettings.residual_terms
    pfa: float = SubtractSettings.pfa
    max_modes: int = SubtractSettings.max_modes
    zeta_max: float = SubtractSettings.zeta_max
    fmin: float | None = None
    fmax: float | None = None
    compress: str | int = "auto"  # ami_xr.ami.scale: pole work on virtual FRFs for many points
    complete: bool = True  # the refinement's model-order step (ami_xr.core.order)


def _encode(value: Any) -> Any:
    """netCDF attributes hold numbers and strings: bools become 0/1, tuples comma lists."""
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, tuple):
        return ",".join(str(v) for v in value)
    return value


def _decode(value: Any, default: Any) -> Any:
    """The inverse of :func:`_encode`, typed after the field's default (raises TypeError or
    ValueError for a value that is not of that type: :func:`from_attrs` names the attribute)."""
    if isinstance(default, int):  # bool too
        if isinstance(value, Real) and not isinstance(value, Integral):
            if not float(value).is_integer():
                raise ValueError(value)
        number = int(value)
        if isinstance(default, bool):
            if number not in (0, 1):
                raise ValueError(value)
            return bool(number)
        return number
    if isinstance(default, float):
        if isinstance(value, str) and value in _WORDS:
            return value  # band may be "all"
        return float(value)
    if isinstance(default, str) and isinstance(value, str) and "," in value:
        return tuple(value.split(","))
    return value


#: Words a number-valued setting may hold instead of a number (``band="all"``).
_WORDS = ("all",)


def _expected(f: dataclasses.Field) -> str:
    if isinstance(f.default, bool):
        return "0 or 1 (a flag)"
    if isinstance(f.default, int):
        return "an integer"
    if isinstance(f.default, float):
        words = " or ".join(repr(w) for w in _WORDS)
        return "a number" + (f" (or {words})" if "str" in str(f.type) else "")
    return "a string"


def to_attrs(settings: Any, attrs: MutableMapping[str, Any]) -> None:
    """Write the fields of ``settings`` that have an attribute into ``attrs`` (in place)."""
    for f in dataclasses.fields(settings):
        name = f.metadata.get("attr")
        if name is not None:
            attrs[name] = _encode(getattr(settings, f.name))


def from_attrs(cls: type[_S], attrs: Mapping[str, Any]) -> _S:
    """The settings of class ``cls`` stored in ``attrs``; a missing attribute gives the default."""
    values = {}
    for f in dataclasses.fields(cls):
        name = f.metadata.get("attr")
        if name is not None and attrs.get(name) is not None:  # None: not set
            try:
                values[f.name] = _decode(attrs[name], f.default)
            except (TypeError, ValueError, OverflowError):
                raise AmiXrValueError(
                    f"attribute {name!r}: expected {_expected(f)}, got "
                    f"{attrs[name]!r}; it records a setting of an earlier phase (a corrupt or "
                    "hand-edited file? remove the attribute to use the default)"
                ) from None
    return cls(**values)


def parameters(settings: Any) -> dict[str, Any]:
    """All fields of ``settings`` as a dict, for the provenance record."""
    return dataclasses.asdict(settings)
