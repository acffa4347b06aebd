"""Scalar argument checks and the message helpers they share: the one module of them.

Each check returns the value (converted) or raises ``error`` (an
:class:`~ami_xr.errors.AmiXrValueError` subclass; the AMI phases pass
:class:`~ami_xr.errors.IdentificationError`) with a message naming the argument, what is
allowed and what was given. Arguments are always in the order ``(value, argument, ...)``.
"""

from __future__ import annotations

from collections.abc import Iterable
from numbers import Real
from typing import Any

import numpy as np

from ami_xr.errors import AmiXrValueError

__all__ = [
    "check_choice",
    "check_fraction",
    "check_positive",
    "check_positive_int",
    "is_positive_number",
    "python_scalar",
    "shorten",
]


def check_choice(
    value: Any, argument: str, allowed: tuple[str, ...], error: type = AmiXrValueError
) -> str:
    """``value`` if it is one of the strings ``allowed``."""
    if not isinstance(value, str) or value not in allowed:
        raise error(f"{argument}: expected one of {tuple(allowed)}, got {value!r}")
    return value


def _number(value: Any) -> float:
    """``value`` as a float; NaN when it is none (a bool counts as none)."""
    if isinstance(value, bool):
        return np.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return np.nan


def check_fraction(value: Any, argument: str, error: type = AmiXrValueError) -> float:
    """``value`` as a float in the open interval (0, 1)."""
    v = _number(value)
    if not 0.0 < v < 1.0:
        raise error(f"{argument}: expected a number in (0, 1), got {value!r}")
    return v


def check_positive(value: Any, argument: str, error: type = AmiXrValueError) -> float:
    """``value`` as a finite float above 0."""
    v = _number(value)
    if not (v > 0 and np.isfinite(v)):
        raise error(f"{argument}: expected a positive number, got {value!r}")
    return v


def check_positive_int(
    value: Any, argument: str, minimum: int = 1, error: type = AmiXrValueError
) -> int:
    """``value`` as an int ``>= minimum`` (a bool is not an integer here)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise error(f"{argument}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def is_positive_number(value: Any) -> bool:
    """True for a finite real number above 0 (not a bool)."""
    return (
        isinstance(value, Real)
        and not isinstance(value, (bool, np.bool_))
        and bool(np.isfinite(value))
        and value > 0
    )


def python_scalar(value: Any) -> Any:
    """numpy scalars -> Python scalars so messages read ``3`` rather than ``np.int64(3)``."""
    return value.item() if isinstance(value, np.generic) else value


def shorten(values: Iterable[Any], limit: int = 8) -> str:
    """Up to ``limit`` values as ``[1, 2, ...]`` for a message (the count when more)."""
    values = list(values)
    text = ", ".join(repr(python_scalar(v)) for v in values[:limit])
    more = f", ... ({len(values)} in all)" if len(values) > limit else ""
    return f"[{text}{more}]"
