"""How the data-model checks name things in their messages: the import path of
:mod:`ami_xr.schema.messages` (:class:`Namer`; the value tests and ``shorten`` are
:mod:`ami_xr.core.checks`)."""

from __future__ import annotations

from ami_xr.schema.messages import Namer, is_positive_number, python_scalar, shorten

__all__ = ["Namer", "is_positive_number", "python_scalar", "shorten"]
