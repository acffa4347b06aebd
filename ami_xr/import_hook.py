"""Run a function once a module has been imported, without importing it first.

``import ami_xr`` must register the ``ds.ami`` accessor, and registering needs xarray; importing
xarray (with pandas and numpy) takes about 0.3 s, ten times the rest of ``import ami_xr``. A user
who has no xarray Dataset yet needs no accessor either, so the registration waits for xarray:
when xarray is already loaded it happens at once; otherwise a finder at the front of
:data:`sys.meta_path` wraps xarray's own loader so that the registration runs right after
xarray's module code, then removes itself and puts xarray's loader back. Nothing else is
intercepted, and the module is loaded by the finder that would have loaded it anyway.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable
from typing import Any

__all__ = ["call_when_imported"]


def call_when_imported(name: str, callback: Callable[[], object]) -> None:
    """Call ``callback()`` once the top-level module ``name`` is imported (now, if it is already).

    Parameters
    ----------
    name : str
        A top-level module name, e.g. ``"xarray"``.
    callback : callable
        Called with no arguments right after the module's code has run. An exception it raises
        is turned into a :class:`RuntimeWarning`, so a failing callback never breaks the import
        of ``name`` for the user's own code.
    """
    if name in sys.modules:
        callback()
        return
    sys.meta_path.insert(0, _PostImportFinder(name, callback))


class _PostImportFinder:
    """Finds nothing itself: wraps the loader that the finders after it find for ``name``."""

    def __init__(self, name: str, callback: Callable[[], object]):
        self.name = name
        self.callback = callback

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> Any:
        if fullname != self.name or self not in sys.meta_path:
            return None
        # Finders before this one have already declined; ask those after it, as the import
        # system would have.
        later = sys.meta_path[sys.meta_path.index(self) + 1 :]
        for finder in later:
            find = getattr(finder, "find_spec", None)
            spec = find(fullname, path, target) if find is not None else None
            if spec is not None:
                break
        else:
            return None
        if spec.loader is None or not hasattr(spec.loader, "exec_module"):
            return spec  # a namespace package or a legacy loader: leave the import alone
        spec.loader = _CallbackLoader(spec.loader, self)
        return spec

    def loaded(self) -> None:
        if self in sys.meta_path:
            sys.meta_path.remove(self)
        try:
            self.callback()
        except Exception as exc:  # noqa: BLE001 - reported, and the user's import goes on
            warnings.warn(
                f"ami_xr: could not run its hook after importing {self.name!r}: "
                f"{type(exc).__name__}: {exc}",
                RuntimeWarning,
                stacklevel=2,
            )


class _CallbackLoader:
    """The original loader, plus the finder's callback after ``exec_module``."""

    def __init__(self, loader: Any, finder: _PostImportFinder):
        self._loader = loader
        self._finder = finder

    def create_module(self, spec: Any) -> Any:
        return self._loader.create_module(spec)

    def exec_module(self, module: Any) -> None:
        # The module sees its own loader (importlib.resources, reload): no trace of this wrapper.
        module.__loader__ = self._loader
        if getattr(module, "__spec__", None) is not None:
            module.__spec__.loader = self._loader
        self._loader.exec_module(module)
        self._finder.loaded()

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._loader, attr)
