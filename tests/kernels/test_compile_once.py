"""A first run compiles each kernel once, and says so once (issue 11 item 1).

* numba compiles a kernel called from another kernel once per integer or boolean *constant* it
  is given (it types them ``Literal[int](0)``): no kernel passes one to another kernel.
* After an identification every kernel dispatcher holds at most one specialisation, and a
  checked wrapper given another layout or dtype adds none.
* A process that must compile (numba cache miss) logs one notice at INFO on
  ``names.COMPILE_LOGGER``; the CLI prints it on stderr, the Python API prints nothing, and a
  warm run (cache hit) says nothing. Run in fresh processes with a throw-away cache folder.
"""

from __future__ import annotations

import ast
import importlib
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from ami_xr.kernels import _numba

pytestmark = pytest.mark.skipif(
    not hasattr(_numba.jit(lambda x: x), "signatures"), reason="NUMBA_DISABLE_JIT"
)

KERNELS = """
from ami_xr.kernels._numba import jit


@jit
def g(x, k):
    return x * k


@jit
def f(x):
    return g(x, 0) + g(x, 1) + g(x, -1) + g(x, int(x))
"""

RUN = """
import json, sys
{setup}
from kpkg.kern import f, g
value = f(3.0)
print(json.dumps({{"value": value, "g": len(g.signatures), "f": len(f.signatures)}}))
"""

CLI_SETUP = "from ami_xr.app.cli import _show_compile_notice; _show_compile_notice()"


def _run(tmp_path: Path, setup: str = "", cache: str = "cache") -> tuple[dict, str]:
    pkg = tmp_path / "kpkg"
    if not pkg.is_dir():
        pkg.mkdir()
        (pkg / "__init__.py").write_text("")
        (pkg / "kern.py").write_text(KERNELS)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / cache), AMI_XR_NUMBA_CACHE="1")
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env.get("PYTHONPATH", "")])
    env.pop("NUMBA_DISABLE_JIT", None)
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(RUN.format(setup=setup))],
        env=env,
        capture_output=True,
        text=True,
        check=True,
        cwd=tmp_path,
    )
    return json.loads(done.stdout.strip().splitlines()[-1]), done.stderr


def test_literal_arguments_compile_one_specialisation_each(tmp_path):
    """What the rule below guards against: numba compiles ``g`` once per constant."""
    out, _ = _run(tmp_path)
    assert out["value"] == 3.0 * (0 + 1 - 1 + 3)
    assert out["g"] == 4  # three constants and int64: why kernels pass variables
    assert out["f"] == 1


def _literal(node: ast.expr) -> bool:
    """An int or bool constant (floats are never typed as literals), possibly negated."""
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        node = node.operand
    return isinstance(node, ast.Constant) and isinstance(node.value, (bool, int))


def _kernel_calls_with_constants() -> list[str]:
    import ami_xr.kernels

    found = []
    for path in sorted(Path(ami_xr.kernels.__file__).parent.glob("*.py")):
        module = importlib.import_module(f"ami_xr.kernels.{path.stem}")
        for fn in ast.walk(ast.parse(path.read_text())):
            if not isinstance(fn, ast.FunctionDef):
                continue
            if not hasattr(getattr(module, fn.name, None), "py_func"):
                continue  # not a kernel
            for call in ast.walk(fn):
                if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Name)):
                    continue
                if not hasattr(getattr(module, call.func.id, None), "py_func"):
                    continue  # numpy, math or a builtin: not a dispatcher
                args = [*call.args, *(k.value for k in call.keywords)]
                if any(_literal(a) for a in args):
                    found.append(f"{path.name}:{call.lineno} {fn.name} -> {call.func.id}")
    return found


def test_no_kernel_passes_an_integer_constant_to_another_kernel():
    """Each such call costs a whole extra compilation of the callee on a first run. Pass
    ``np.int64(0)`` or a variable computed at run time (``zero = 0`` does not help: numba
    types it as the constant too), or restructure."""
    assert _kernel_calls_with_constants() == []


def test_cli_says_once_that_a_first_run_compiles(tmp_path):
    out, err = _run(tmp_path, CLI_SETUP)
    notices = [line for line in err.splitlines() if "compiling numeric kernels" in line]
    assert len(notices) == 1, err  # two kernels compile, one notice
    assert notices[0].startswith("ami-xr: first run on this machine: compiling numeric kernels")
    assert str(tmp_path / "cache") in notices[0]  # where the compiled kernels go
    # warm: the cache filled by the first run is used and nothing is said
    out, err = _run(tmp_path, CLI_SETUP)
    assert "compiling" not in err, err


@pytest.mark.slow
def test_python_api_prints_nothing_and_logs_at_info(tmp_path):
    _, err = _run(tmp_path, cache="api")
    assert err.strip() == ""
    setup = "import logging; logging.basicConfig(level=logging.INFO, format='%(name)s %(message)s')"
    _, err = _run(tmp_path, setup, cache="api_logged")
    assert err.count("ami_xr.compile ami-xr: first run on this machine") == 1, err


def test_notice_text_names_the_cache():
    text = _numba.first_run_notice("/some/where")
    assert "compiling numeric kernels" in text and "once" in text
    assert ("cached in /some/where" in text) == _numba.CACHE


IDENTIFY = """
import json, sys
import ami_xr
from numba.core.dispatcher import Dispatcher
_, g, _ = ami_xr.simulate.benchmark(noise=0.02, seed=3)
ami_xr.identify(g.isel(frequency=slice(0, 1025)))
many = {}
for name, module in list(sys.modules.items()):
    if name.startswith("ami_xr.kernels") and module is not None:
        for attr, obj in vars(module).items():
            if isinstance(obj, Dispatcher) and len(obj.signatures) > 1:
                many[f"{name}.{attr}"] = [str(s) for s in obj.signatures]
print(json.dumps(many))
"""


def test_identify_compiles_each_kernel_once():
    """Every kernel an identification uses holds one specialisation (the project's cache, so
    mostly loaded; a kernel compiled twice or loaded for two argument types shows here)."""
    done = subprocess.run(
        [sys.executable, "-c", IDENTIFY], capture_output=True, text=True, check=True
    )
    many = json.loads(done.stdout.strip().splitlines()[-1])
    assert many == {}


def test_public_wrappers_take_any_layout():
    """The checked wrappers hand the kernels C-contiguous float64 arrays: a Fortran-ordered,
    strided or integer input adds no specialisation."""
    from ami_xr.kernels import single_mode

    omega = np.linspace(1.0, 60.0, 33)
    lam = -1.0 + 20j
    clean = 1.0 / (1j * omega - lam) + 1.0 / (1j * omega - np.conj(lam))
    for w in (omega, np.asfortranarray(omega), np.repeat(omega, 2)[::2]):
        for data in (clean, np.repeat(clean, 2)[::2], np.asfortranarray(np.vstack([clean] * 2))):
            single_mode.fit_single_mode(data, w)
            assert len(single_mode.fit_single.signatures) == 1


SUBTRACT = """
import json
import numpy as np
from ami_xr.kernels import peak, subtract
w = np.linspace(1.0, 60.0, 400)
lam = np.array([-0.3 + 20j, -0.4 + 41j])
g = sum(1.0 / (1j * w - l) + 1.0 / (1j * w - np.conj(l)) for l in lam)
rng = np.random.default_rng(1)
g = np.vstack([g, 2 * g]) + 1e-4 * (rng.standard_normal((2, 400)) + 1j * rng.standard_normal((2, 400)))
subtract.subtract_batch(g, w, None, None, subtract.SubtractParams(0.5, 6, 1e-3, 3, 0.25, 0.5))
print(json.dumps({"peak_trial": len(peak.peak_trial.signatures),
                  "nearest_within": len(peak.nearest_within.signatures)}))
"""


@pytest.mark.slow
def test_subtraction_compiles_its_callees_once(tmp_path):
    """On an empty cache (so callees compile and show their specialisations): a variable that
    starts as a constant (``n = 0``, ``peak = -1``) and is passed to a kernel made numba compile
    the callee once more for the constant (``Literal[int]``) before the loop types it int64."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), AMI_XR_NUMBA_CACHE="1")
    env.pop("NUMBA_DISABLE_JIT", None)
    done = subprocess.run(
        [sys.executable, "-c", SUBTRACT], env=env, capture_output=True, text=True, check=True
    )
    counts = json.loads(done.stdout.strip().splitlines()[-1])
    assert counts == {"peak_trial": 1, "nearest_within": 1}
