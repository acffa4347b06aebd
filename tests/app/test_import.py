"""``import ami_xr`` stays light: public names load from their modules on first use."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import ami_xr

# Loaded by a function call, never by ``import ami_xr`` (each costs tenths of a second or more).
HEAVY = (
    "xarray",
    "pandas",
    "numpy",
    "matplotlib",
    "pyuff",
    "dask",
    "scipy.optimize",
    "scipy.signal",
    "numba",
    "ami_xr.plot",
    "ami_xr.plot.modal",
    "ami_xr.app",
    "ami_xr.app.report",
    "ami_xr.app.batch",
    "ami_xr.ami",
    "ami_xr.kernels",
    "ami_xr.app.cli",
)


# ``python -m ami_xr --help`` loads the command line itself, and nothing heavier.
CLI_ITSELF = ("ami_xr.app", "ami_xr.app.cli")


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


@pytest.mark.parametrize(
    "code",
    [
        "import ami_xr\nimport xarray as xr",  # xarray after ami_xr: the import hook registers
        "import xarray as xr\nimport ami_xr",  # xarray first: registered at once
        "import ami_xr, importlib\nxr = importlib.import_module('xarray')",
        "import ami_xr\nfrom xarray import Dataset\nimport xarray as xr",
    ],
)
def test_accessor_is_registered_whichever_loads_first(code):
    check = (
        "\nimport sys, importlib.resources\nassert hasattr(xr.Dataset(), 'ami')"
        "\nassert type(xr.Dataset().ami).__name__ == 'AmiAccessor'"
        # the hook leaves no trace: xarray keeps its own loader, the finder is gone
        "\nassert type(xr.__spec__.loader).__name__ == 'SourceFileLoader', xr.__spec__.loader"
        "\nassert xr.__loader__ is xr.__spec__.loader"
        "\nassert not any('PostImport' in type(f).__name__ for f in sys.meta_path)"
        "\nassert importlib.resources.files(xr).is_dir()"
    )
    loaded = _modules_after(code + check)
    assert "ami_xr.accessor" in loaded


def test_import_hook_calls_back_after_the_module_runs_and_reports_a_failure(tmp_path):
    (tmp_path / "watched_mod.py").write_text("VALUE = 42\n")
    code = (
        "import sys, warnings\n"
        f"sys.path.insert(0, {str(tmp_path)!r})\n"
        "from ami_xr.import_hook import call_when_imported\n"
        "seen = []\n"
        "call_when_imported('watched_mod', lambda: seen.append(sys.modules['watched_mod'].VALUE))\n"
        "assert seen == []\n"
        "import watched_mod\n"
        "assert seen == [42], seen\n"
        "call_when_imported('watched_mod', lambda: seen.append('again'))\n"  # already loaded
        "assert seen == [42, 'again'], seen\n"
        "def fail():\n    raise KeyError('boom')\n"
        "call_when_imported('json_other_mod', fail)\n"
        f"open({str(tmp_path / 'json_other_mod.py')!r}, 'w').write('X = 1')\n"
        "import importlib; importlib.invalidate_caches()\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    import json_other_mod\n"
        "assert json_other_mod.X == 1\n"
        "assert any(\"'json_other_mod'\" in str(x.message) and 'boom' in str(x.message)"
        " for x in w), [str(x.message) for x in w]\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_every_public_name_resolves_and_is_listed():
    assert set(ami_xr.__all__) <= set(dir(ami_xr))
    for name in ami_xr.__all__:
        assert getattr(ami_xr, name) is not None, name
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        ami_xr.no_such_name  # noqa: B018


@pytest.mark.parametrize("name", ["batch", "report"])
def test_function_keeps_its_name_when_its_module_loads_first(name):
    """``ami_xr.batch`` and ``ami_xr.report`` are the functions, whichever loads first: their
    modules live in ``ami_xr.app``, so loading them binds nothing on the package itself."""
    code = (
        f"import importlib, types, ami_xr\nimportlib.import_module('ami_xr.app.{name}')\n"
        f"assert callable(ami_xr.{name}) and ami_xr.{name}.__name__ == {name!r}\n"
        "assert type(ami_xr) is types.ModuleType"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize(
    "module",
    [
        "ami_xr.plot.modal",
        "ami_xr.plot.measurement",
        "ami_xr.plot.geometry",
        "ami_xr.plot.stability",
        "ami_xr.tables",
    ],
)
def test_figures_and_tables_load_nothing_of_the_application_layer(module):
    """Layers only downward: the figure modules and the modal table never load ``ami_xr.app``
    (the report draws the figures, never the reverse) nor matplotlib on import."""
    loaded = _modules_after(f"import {module}")
    assert sorted(m for m in loaded if m.startswith("ami_xr.app") or m == "matplotlib") == []


def test_python_dash_m_is_the_command_and_help_imports_no_heavy_module():
    code = (
        "import runpy, sys\nsys.argv = ['ami-xr', '--help']\n"
        "try:\n    runpy.run_module('ami_xr', run_name='__main__')\n"
        "except SystemExit as stop:\n    assert stop.code == 0, stop.code\n"
    )
    loaded = _modules_after(code)
    assert sorted(m for m in HEAVY if m in loaded and m not in CLI_ITSELF) == []
    done = subprocess.run(
        [sys.executable, "-m", "ami_xr", "--help"], capture_output=True, text=True, check=True
    )
    assert done.stdout.startswith("usage: ami-xr")
