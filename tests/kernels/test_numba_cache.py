"""numba's on-disk cache follows calls across kernel modules (``ami_xr.kernels._numba``).

A throw-away package of three kernel modules (``callee``; ``caller``, which calls ``callee``;
``other``, unrelated) is compiled in fresh processes with the project's :func:`jit`. After an
edit to ``callee`` the cached ``caller`` must run the new code, and an edit to ``other`` must
recompile ``other`` only. numba's own cache counters (``dispatcher.stats``) tell compiled
(miss) from loaded (hit).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from ami_xr.kernels import _numba

CALLEE = """
from ami_xr.kernels._numba import jit

SCALE = {scale}


@jit
def g(x):
    return x * SCALE
"""

CALLER = """
from ami_xr.kernels._numba import jit
from kpkg.callee import g


@jit
def f(x):
    return g(x) + 1.0
"""

OTHER = """
from ami_xr.kernels._numba import jit


@jit
def h(x):
    return x - 1.0{comment}
"""

RUN = """
import json
from kpkg.callee import g
from kpkg.caller import f
from kpkg.other import h
from ami_xr.kernels import _numba

out = {"stamps": _numba.DEPENDENCY_STAMPS}
for name, fn in (("f", f), ("g", g), ("h", h)):
    value = fn(1.0)
    out[name] = {
        "value": value,
        "hits": sum(fn.stats.cache_hits.values()),
        "misses": sum(fn.stats.cache_misses.values()),
    }
print(json.dumps(out))
"""


def _write(root: Path, scale: float = 2.0, comment: str = "") -> None:
    """Write the package; a file whose text is unchanged is left alone (numba < 0.59 stamps a
    kernel's own file by mtime and size, so rewriting it would recompile it)."""
    pkg = root / "kpkg"
    pkg.mkdir(exist_ok=True)
    texts = {
        "__init__.py": "",
        "callee.py": CALLEE.format(scale=scale),
        "caller.py": CALLER,
        "other.py": OTHER.format(comment=comment),
    }
    for name, text in texts.items():
        path = pkg / name
        if not path.exists() or path.read_text() != text:
            path.write_text(text)


def _run(root: Path, **env: str) -> dict:
    environ = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    environ.pop("AMI_XR_NUMBA_CACHE", None)
    environ["PYTHONPATH"] = os.pathsep.join([str(root), environ.get("PYTHONPATH", "")])
    environ.update(env)
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(RUN)],
        cwd=root,
        env=environ,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def _compiled(out: dict) -> dict[str, bool]:
    """Per kernel: True if this process compiled it, False if it loaded it from the cache."""
    assert all(out[k]["hits"] + out[k]["misses"] == 1 for k in "fgh"), out
    return {k: out[k]["misses"] == 1 for k in "fgh"}


def test_edit_to_a_callee_module_recompiles_its_callers_and_nothing_else(tmp_path):
    _write(tmp_path)
    first = _run(tmp_path)
    assert first["stamps"] is True
    assert first["f"]["value"] == 3.0
    assert _compiled(first) == {"f": True, "g": True, "h": True}

    again = _run(tmp_path)
    assert _compiled(again) == {"f": False, "g": False, "h": False}

    # the callee changes: numba alone would load the stale f (its own file is unchanged)
    _write(tmp_path, scale=3.5)
    edited = _run(tmp_path)
    assert edited["f"]["value"] == 4.5 and edited["g"]["value"] == 3.5
    assert _compiled(edited) == {"f": True, "g": True, "h": False}

    # an unrelated module changes: only its own kernel is compiled again
    _write(tmp_path, scale=3.5, comment="  # edited")
    unrelated = _run(tmp_path)
    assert unrelated["f"]["value"] == 4.5
    assert _compiled(unrelated) == {"f": False, "g": False, "h": True}


def test_cache_switched_off_compiles_every_time_and_writes_nothing(tmp_path):
    _write(tmp_path)
    for _ in range(2):
        out = _run(tmp_path, AMI_XR_NUMBA_CACHE="0")
        assert out["stamps"] is False
        assert out["f"]["value"] == 3.0
        assert all(out[k]["hits"] == 0 for k in "fgh")
    assert not list(tmp_path.rglob("*.nbi"))


def test_unknown_numba_internals_fall_back_to_numba_defaults(monkeypatch):
    from numba.core import caching

    # the locator list is missing or not a list: nothing is installed
    monkeypatch.setattr(caching.CacheImpl, "_locator_classes", None)
    assert _numba._install_dependency_stamps() is False
    monkeypatch.undo()

    # the stamp cannot be worked out: the hook steps aside and numba picks its own locator
    def broken(name):
        raise RuntimeError("numba internals changed")

    def kernel(x):
        return x

    _numba._POLICY_FUNCTIONS.add(kernel)
    monkeypatch.setattr(_numba, "_dependency_stamp", broken)
    assert _numba._DependencyStampLocator.from_function(kernel, __file__) is None
    # a function not compiled with the project's policy is never touched
    assert _numba._DependencyStampLocator.from_function(len, __file__) is None


@pytest.mark.parametrize(
    ("module", "expected"),
    [
        ("ami_xr.kernels.linalg", {"_numba"}),
        ("ami_xr.kernels.single_mode", {"_numba", "linalg", "modal_basis"}),
    ],
)
def test_kernel_modules_are_stamped_with_the_kernel_modules_they_import(module, expected):
    import importlib

    importlib.import_module(module)
    names = {dep.rsplit(".", 1)[-1] for dep, _ in _numba._dependency_stamp(module)}
    assert names == expected
