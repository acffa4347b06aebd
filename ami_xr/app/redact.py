"""No machine path in an output file: messages written into outputs (``batch_summary.csv``) name
files relative to the folders the user gave, never by this machine's absolute paths.

:func:`relative_paths` rewrites an error or warning text: each file it knows by the short name
given, any other path under a known folder relative to that folder, whatever spelling the text
holds (as given, absolute, resolved through symlinks).
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping
from pathlib import Path

__all__ = ["relative_paths"]

# where a path may start in a message: not inside a word or another path (``data/`` is not the
# end of ``metadata/``, nor of ``/x/data/``)
_START = r"(?<![\w.~/-])"


def _spellings(path: str | os.PathLike) -> list[str]:
    """The spellings of ``path`` a message may hold: as given, absolute, resolved."""
    given = Path(path)
    forms = {str(given), str(given.absolute())}
    try:
        forms.add(str(given.resolve()))
    except (OSError, RuntimeError):  # a symlink loop: the other spellings still apply
        pass
    return [f for f in forms if f not in ("", ".")]


def relative_paths(
    text: str,
    files: Mapping[str | os.PathLike, str],
    folders: Iterable[str | os.PathLike] = (),
) -> str:
    """``text`` with each file of ``files`` (path -> short name) replaced by its short name and
    every other path under one of ``folders`` made relative to that folder.

    Examples
    --------
    >>> relative_paths("/data/camp/day1/a.nc: truncated", {}, ["/data/camp"])
    'day1/a.nc: truncated'
    """
    if not text:
        return text
    swaps = [(form, short) for path, short in files.items() for form in _spellings(path)]
    swaps += [(form.rstrip(os.sep) + os.sep, "") for d in folders for form in _spellings(d)]
    # longest first: a file before the folder that holds it, an absolute spelling before the
    # relative one it ends with
    for form, short in sorted(swaps, key=lambda swap: len(swap[0]), reverse=True):
        text = re.sub(_START + re.escape(form), short.replace("\\", r"\\"), text)
    return text
