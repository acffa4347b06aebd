"""``scripts/proc_harness.py`` for the tests: the one subprocess harness (issue 42) that the
fault campaign's cases and the process-level tests share, loaded once by path."""

from __future__ import annotations

import importlib.util
import sys

from ..reference import REPO

__all__ = ["H"]


def _load():
    name = "proc_harness"
    module = sys.modules.get(name)
    if module is None:
        spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / "proc_harness.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return module


H = _load()
