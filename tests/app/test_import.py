"""``import ami_xr`` stays light: public names load from their modules on first use."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import ami_xr

# Loaded by a function call, never by ``import ami_xr`` (each costs tenths of a second or more).
HEAVY = (
    "matplotlib",
    "pyuff",
    "dask",
    "scipy.optimize",
    "scipy.signal",
    "numba",
    "ami_xr.plot",
    "ami_xr.report",
    "ami_xr.batch",
    "ami_xr.ami",
    "ami_xr.kernels",
    "ami_xr.cli",
)


def _modules_after(code: str) -> set[str]:
    """The modules a fresh interpreter has loaded after running ``code``."""
    script = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    )
    return set(json.loads(done.stdout.splitlines()[-1]))


def test_import_loads_no_heavy_module():
    loaded = _modules_after("import ami_xr")
    assert sorted(m for m in HEAVY if m in loaded) == []


def test_accessor_is_registered_on_import():
    loaded = _modules_after("import ami_xr, xarray as xr\nassert hasattr(xr.Dataset(), 'ami')")
    assert "ami_xr.accessor" in loaded


def test_every_public_name_resolves_and_is_listed():
    assert set(ami_xr.__all__) <= set(dir(ami_xr))
    for name in ami_xr.__all__:
        assert getattr(ami_xr, name) is not None, name
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        ami_xr.no_such_name  # noqa: B018


@pytest.mark.parametrize("name", ["batch", "report"])
def test_function_keeps_its_name_when_its_module_loads_first(name):
    """``ami_xr.batch`` and ``ami_xr.report`` are the functions, whichever loads first."""
    code = (
        f"import importlib, ami_xr\nimportlib.import_module('ami_xr.{name}')\n"
        f"assert callable(ami_xr.{name}) and ami_xr.{name}.__name__ == {name!r}"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
