"""How the data-model checks name things in their messages, and small value tests.

``validate`` names Dataset parts ("variable 'frf'"); the ``make_*`` constructors name their own
arguments ("argument 'points'") - :class:`Namer` says which.
"""

from __future__ import annotations

from collections.abc import Mapping
from numbers import Real
from typing import Any

import numpy as np

__all__ = ["Namer", "is_positive_number", "python_scalar", "shorten"]


def shorten(values: Any, limit: int = 8) -> str:
    """Up to ``limit`` values as ``[1, 2, ...]`` for a message."""
    values = list(values)
    text = ", ".join(repr(python_scalar(v)) for v in values[:limit])
    return f"[{text}{', ...' if len(values) > limit else ''}]"


def python_scalar(value: Any) -> Any:
    """numpy scalars -> Python scalars so messages read ``3`` rather than ``np.int64(3)``."""
    return value.item() if isinstance(value, np.generic) else value


class Namer:
    """Says how a message refers to a variable, coordinate or attribute.

    ``validate`` names Dataset parts ("variable 'frf'"); the ``make_*`` constructors map them to
    their own argument names ("argument 'points'").
    """

    def __init__(self, arguments: Mapping[str, str] | None = None):
        self.arguments = dict(arguments or {})

    def _name(self, kind: str, name: str) -> str:
        if name in self.arguments:
            return f"argument {self.arguments[name]!r}"
        return f"{kind} {name!r}"

    def var(self, name: str) -> str:
        return self._name("variable", name)

    def coord(self, name: str) -> str:
        return self._name("coordinate", name)

    def attr(self, name: str) -> str:
        return self._name("attribute", name)

    def var_attr(self, var: str, attr: str) -> str:
        key = f"{var}.{attr}"
        if key in self.arguments:
            return f"argument {self.arguments[key]!r}"
        return f"attribute {attr!r} of variable {var!r}"


def is_positive_number(value: Any) -> bool:
    """True for a finite real number above 0 (not a bool)."""
    return (
        isinstance(value, Real)
        and not isinstance(value, (bool, np.bool_))
        and bool(np.isfinite(value))
        and value > 0
    )
