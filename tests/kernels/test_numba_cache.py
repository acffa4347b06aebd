"""numba's on-disk cache as the project uses it (``ami_xr.kernels._numba``).

A throw-away package of three kernel modules (``callee``; ``caller``, which calls ``callee``;
``other``, unrelated) is compiled in fresh processes with the project's :func:`jit`. After an
edit to ``callee`` the cached ``caller`` must run the new code, and an edit to ``other`` must
recompile ``other`` only. numba's own cache counters (``dispatcher.stats``) tell compiled
(miss) from loaded (hit). A cache folder that cannot be written means compiling in memory with
one notice; two processes whose first (compiling) runs overlap on an empty cache, as
``ami-xr batch --workers 2`` does, both succeed and leave a cache the next run loads.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time
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

out = {"folder": _numba._CACHE_DIRS.get("kpkg.caller")}
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
    assert first["folder"] is not None
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


@pytest.mark.slow
def test_cache_switched_off_compiles_every_time_and_writes_nothing(tmp_path):
    _write(tmp_path)
    for _ in range(2):
        out = _run(tmp_path, AMI_XR_NUMBA_CACHE="0")
        assert out["folder"] is None
        assert out["f"]["value"] == 3.0
        assert all(out[k]["hits"] == 0 for k in "fgh")
    assert not list(tmp_path.rglob("*.nbi"))


@pytest.mark.parametrize(
    "where",
    [
        "NUMBA_CACHE_DIR=plain file",
        "NUMBA_CACHE_DIR=below a plain file",
        "XDG_CACHE_HOME=read-only",
        "HOME=read-only",
    ],
)
def test_unwritable_cache_compiles_in_memory_with_one_notice(tmp_path, where):
    """A cache that cannot be written never stops a run: kernels compile in memory and one
    notice (logged at WARNING, so printed without any logging set-up) says what to do."""
    _write(tmp_path)
    plain = tmp_path / "plain"
    plain.write_text("not a folder")
    env = {
        "NUMBA_CACHE_DIR=plain file": {"NUMBA_CACHE_DIR": str(plain)},
        "NUMBA_CACHE_DIR=below a plain file": {"NUMBA_CACHE_DIR": str(plain / "sub")},
        # /proc refuses new folders, even to root (a chmod would not stop root)
        "XDG_CACHE_HOME=read-only": {"XDG_CACHE_HOME": "/proc/ami_xr_cache"},
        "HOME=read-only": {"HOME": "/proc/ami_xr_home", "XDG_CACHE_HOME": ""},
    }[where]
    environ = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    environ.pop("AMI_XR_NUMBA_CACHE", None)
    environ.pop("XDG_CACHE_HOME", None)
    environ["PYTHONPATH"] = os.pathsep.join([str(tmp_path), environ.get("PYTHONPATH", "")])
    environ.update(env)
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(RUN)],
        cwd=tmp_path,
        env=environ,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["folder"] is None
    assert (out["f"]["value"], out["g"]["value"], out["h"]["value"]) == (3.0, 2.0, 0.0)
    notices = [line for line in done.stderr.splitlines() if "not writable" in line]
    assert len(notices) == 1, done.stderr  # three modules, one notice
    assert "compiling in memory" in notices[0] and "NUMBA_CACHE_DIR" in notices[0]
    assert plain.read_text() == "not a folder"


CONCURRENT = """
import json, os, sys, time
import numpy as np
from ami_xr.kernels import modal_basis, peak, residues, single_mode
# both processes start compiling at the same moment: wait for the go file
while not os.path.exists(sys.argv[1]):
    time.sleep(0.01)
w = np.linspace(1.0, 60.0, 41)
lam = np.array([-0.5 + 20j, -1.0 + 45j])
h = modal_basis.synthesize(w, lam[None, :], np.array([[1.0 - 2j, 0.5 + 1j]]))
fitted = residues.residues_fixed(h, w, lam)[0]
peaks = modal_basis.contribution_peaks(w, None, None, lam[None, :], fitted[None, :])[0]
# jitted kernels (the numpy helpers above compile nothing): one mode fitted exactly
one = modal_basis.synthesize(w, lam[None, :1], np.array([[1.0 - 2j]]))[0]
pole, _, code = single_mode.fit_single_mode(one, w)
band = peak.pole_band(w, lam[0], 0.5, 3)  # a second one
stats = [
    d.stats for m in (modal_basis, peak, single_mode) for d in vars(m).values()
    if hasattr(d, "stats")
]
print(json.dumps({
    "residues": [fitted.real.tolist(), fitted.imag.tolist()],
    "peaks": peaks.tolist(),
    "pole": [pole.real, pole.imag, code],
    "band": [int(band[0]), int(band[1])],
    "misses": sum(sum(s.cache_misses.values()) for s in stats),
    "hits": sum(sum(s.cache_hits.values()) for s in stats),
}))
"""


@pytest.mark.slow
def test_two_first_runs_at_once_both_succeed_and_leave_a_good_cache(tmp_path):
    """numba issue 4807: concurrent first runs on one cache (``batch --workers 2``). Both
    processes compile into an empty cache folder at the same moment and give the right
    results; a third process then loads everything from that cache and agrees."""
    import numpy as np

    go = tmp_path / "go"
    environ = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    environ.pop("AMI_XR_NUMBA_CACHE", None)
    environ["NUMBA_CACHE_DIR"] = str(tmp_path / "cache")
    cmd = [sys.executable, "-c", CONCURRENT, str(go)]
    procs = [
        subprocess.Popen(
            cmd, env=environ, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        for _ in range(2)
    ]
    time.sleep(1.0)  # both interpreters up and waiting
    go.write_text("")
    results = []
    for proc in procs:
        stdout, stderr = proc.communicate(timeout=600)
        assert proc.returncode == 0, stderr
        results.append(json.loads(stdout.strip().splitlines()[-1]))
    again = subprocess.run(
        cmd, env=environ, capture_output=True, text=True, timeout=300, check=True
    )
    warm = json.loads(again.stdout.strip().splitlines()[-1])
    assert warm["misses"] == 0 and warm["hits"] >= 2  # the cache the two first runs wrote
    # the folder was empty: every kernel the warm run loads was compiled by one of the two at
    # least. Which one compiled which depends on timing: each may load kernels the other wrote
    # first (both had hits in a min-versions run), so no single run need have compiled them all
    assert sum(r["misses"] for r in results) >= warm["hits"]

    w = np.linspace(1.0, 60.0, 41)
    lam = np.array([-0.5 + 20j, -1.0 + 45j])
    res = np.array([1.0 - 2j, 0.5 + 1j])
    # the residues come back from their own synthesis; the peaks against a numpy reference
    b = 1.0 / (1j * w[:, None] - lam) * res + 1.0 / (1j * w[:, None] - np.conj(lam)) * np.conj(res)
    peaks = []
    for k in range(2):
        c = int(np.argmin(np.abs(w - lam[k].imag)))
        peaks.append(np.abs(b[max(c - 1, 0) : c + 2, k]).max())
    for r in (*results, warm):
        np.testing.assert_allclose(r["residues"][0] + 1j * np.asarray(r["residues"][1]), res)
        np.testing.assert_allclose(r["peaks"], peaks, rtol=1e-12)
        # eqs. 11-12 are exact on one noise-free mode: the pole to the rounding of the solve
        assert r["pole"][2] == 0
        assert r["band"] == results[0]["band"]
        np.testing.assert_allclose(r["pole"][0] + 1j * r["pole"][1], lam[0], rtol=1e-10)


@pytest.mark.parametrize(
    ("module", "expected"),
    [
        ("ami_xr.kernels.linalg", {"_numba"}),
        ("ami_xr.kernels.residues", {"_numba", "linalg", "modal_basis"}),
    ],
)
def test_kernel_modules_are_stamped_with_the_kernel_modules_they_import(module, expected):
    import importlib

    importlib.import_module(module)
    names = {dep.rsplit(".", 1)[-1] for dep, _ in _numba.dependency_stamp(module)}
    assert names == expected
