"""How the data-model checks name things in their messages (the value tests and ``shorten``
are :mod:`ami_xr.core.checks`, re-exported here).

``validate`` names Dataset parts ("variable 'frf'"); the ``make_*`` constructors name their own
arguments ("argument 'points'") - :class:`Namer` says which.
"""

from __future__ import annotations

from collections.abc import Mapping

from ami_xr.core.checks import is_positive_number, python_scalar, shorten

__all__ = ["Namer", "is_positive_number", "python_scalar", "shorten"]


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
