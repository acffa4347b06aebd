"""Warnings that point at the user's line: :func:`warn` finds the first frame outside ami_xr.

A fixed ``stacklevel`` is right for one call path only; a warning raised three calls deep in
ami_xr and reached through ``ami_xr.identify`` or the accessor would show a line of ami_xr's
own source. :func:`stacklevel` counts the frames up to the caller outside the package instead.
"""

from __future__ import annotations

import os
import sys
import warnings

__all__ = ["stacklevel", "warn"]

_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__)) + os.sep


def stacklevel(extra: int = 0) -> int:
    """The ``stacklevel`` of the first frame outside ami_xr, seen from the caller of this
    function (plus ``extra`` frames the caller adds before it calls ``warnings.warn``)."""
    frame = sys._getframe(1)  # the function that will warn
    level = 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(_PACKAGE_DIR):
        frame = frame.f_back
        level += 1
    return level + extra


def warn(message: str, category: type[Warning]) -> None:
    """``warnings.warn(message, category)`` attributed to the user's line (first frame outside
    ami_xr; the outermost frame when every frame is ami_xr's, e.g. the ``ami-xr`` command)."""
    warnings.warn(message, category, stacklevel=stacklevel())
