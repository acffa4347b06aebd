"""The one place for numba policy, written against numba's public API only.

* Lazy compilation: no eager signatures, so ``import ami_xr`` and ``ami-xr --help`` compile nothing.
* ``cache=True`` so a compiled kernel is reused by the next process (set ``AMI_XR_NUMBA_CACHE=0``
  to switch the on-disk cache off). A cache folder that cannot be written (read-only home or
  install, ``NUMBA_CACHE_DIR`` unwritable or a plain file) means compiling in memory, with one
  notice: it never stops a run.
* ``fastmath`` stays off: results must match the numpy references to rounding.
* ``NUMBA_DISABLE_JIT=1`` (numba's own switch) runs every kernel as plain Python for debugging
  and coverage.

Where the cache lives, and why it follows calls across files
------------------------------------------------------------
numba stamps a cached kernel with its own source file only, but a kernel that calls a jitted
function of another module has that function compiled into it: after an edit to
``single_mode.py`` the cached kernels of ``isolate.py`` would still run the old code. So each
kernel module caches into a folder of its own dependencies' version::

    <NUMBA_CACHE_DIR, else $XDG_CACHE_HOME or ~/.cache, + /ami_xr-numba>/<stamp>/...

where ``<stamp>`` hashes the text of every *kernel module* the module imports, transitively
(a kernel module is one that imports :func:`jit`; this policy file counts too, since a policy
change such as ``fastmath`` is not part of numba's cache key). numba's own per-file stamp covers
the module itself. An edit to one kernel module therefore recompiles its own kernels (numba) and
those of the modules that import it, directly or not (a new folder), and no others. The folder
is handed to numba as ``numba.config.CACHE_DIR`` (``NUMBA_CACHE_DIR``) while the decorator runs,
which is when numba picks a function's cache location, and restored at once, so other numba
users in the process are not affected. Folders of superseded versions stay behind (a few MB
each); deleting the ``ami_xr-numba`` folder at any time is safe.

The first compilation of a process (a cache miss) is announced once, through numba's event API
(``numba.core.event``, the ``"numba:compile"`` event, sent only when a kernel really compiles).
"""

from __future__ import annotations

import hashlib
import logging
import os
import sys
import tempfile
import threading
from typing import Any

import numba
from numba.core import event

CACHE = os.environ.get("AMI_XR_NUMBA_CACHE", "1").strip().lower() not in ("0", "false", "no", "off")

#: What a cold ``ami-xr demo`` spends compiling, in seconds on a 2-core machine (measured with
#: ``scripts/bench_first_run.py``).
FIRST_RUN_SECONDS = 20

# The notices go to logging.getLogger(names.COMPILE_LOGGER): the first-compilation one at INFO
# (the CLI prints it on stderr; the Python API leaves it to the caller's logging set-up), the
# unwritable-cache one at WARNING (Python prints it on stderr when logging is not set up).
_COMPILE_LOGGER = "ami_xr.compile"  # names.COMPILE_LOGGER: kernels import numpy and numba only

_LOCK = threading.Lock()
_POLICY_FUNCTIONS: set[Any] = set()  # Python functions compiled here (their code objects)
_CACHE_DIRS: dict[str, str | None] = {}  # kernel module -> its cache folder (None: in memory)
_UNWRITABLE: list[str] = []  # the unwritable-cache notice, once per process
_NOTICE_GIVEN: list[bool] = []


def cache_base() -> str:
    """The folder under which the kernels' cache folders go (``NUMBA_CACHE_DIR`` when set)."""
    base = os.environ.get("NUMBA_CACHE_DIR", "").strip()
    if base:
        return base
    home = os.environ.get("XDG_CACHE_HOME", "").strip() or os.path.join(
        os.path.expanduser("~"), ".cache"
    )
    return os.path.join(home, "ami_xr-numba")


def first_run_notice(location: str | None = None) -> str:
    """The text of the first-compilation notice (``location``: the cache folder, if any)."""
    where = f"cached in {location}" if CACHE and location else "on-disk cache off"
    return (
        "ami-xr: first run on this machine: compiling numeric kernels "
        f"(about {FIRST_RUN_SECONDS} s, once; {where})"
    )


def unwritable_notice(folder: str, reason: str) -> str:
    """The text of the notice given once when the cache folder cannot be used."""
    return (
        f"ami-xr: numba cache folder {folder} is not writable ({reason}): compiling in memory, "
        "so every run compiles again; set NUMBA_CACHE_DIR to a writable folder, or "
        "AMI_XR_NUMBA_CACHE=0 to switch the cache off and this notice with it"
    )


# --- where each kernel module caches --------------------------------------------------------


def _source(module: Any) -> str | None:
    path = getattr(module, "__file__", None)
    if isinstance(path, str) and path.endswith(".py") and os.path.isfile(path):
        return path
    return None


def _is_kernel_module(module: Any) -> bool:
    """Whether ``module`` compiles kernels with this policy (it holds :func:`jit`)."""
    try:
        return any(v is jit for v in vars(module).values())
    except TypeError:
        return False


def _kernel_imports(module: Any) -> set[Any]:
    """The already imported kernel modules that ``module`` uses: modules it holds, and the
    modules of the functions (jitted or not) it holds (so a re-export is followed to its
    source)."""
    found = set()
    for value in list(vars(module).values()):
        owner = value
        if not isinstance(value, type(sys)):
            # a dispatcher's Python function; with NUMBA_DISABLE_JIT the kernel is that function
            func = getattr(value, "py_func", value)
            name = getattr(func, "__module__", None) if callable(func) else None
            owner = sys.modules.get(name or "")
        if owner is not None and owner is not module and _is_kernel_module(owner):
            found.add(owner)
    return found


def dependency_stamp(module_name: str) -> tuple[tuple[str, str], ...]:
    """``(module, sha256 of its text)`` of this policy file and of every kernel module that
    module ``module_name`` uses, transitively, sorted by name (the module itself left out:
    numba's own stamp covers it). Read when the module defines its first kernel, so only what
    it imported above that line counts (kernel modules import at the top)."""
    module = sys.modules[module_name]
    seen: dict[str, Any] = {__name__: sys.modules[__name__]}
    todo = [module]
    while todo:
        for dep in _kernel_imports(todo.pop()):
            if dep.__name__ not in seen and dep is not module:
                seen[dep.__name__] = dep
                todo.append(dep)
    stamp = []
    for name in sorted(seen):
        path = _source(seen[name])
        if path is not None:
            with open(path, "rb") as fh:
                stamp.append((name, hashlib.sha256(fh.read()).hexdigest()))
    return tuple(stamp)


def _writable(folder: str) -> str | None:
    """``None`` when ``folder`` can be created and written, else why not."""
    try:
        os.makedirs(folder, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as err:
        return err.strerror or type(err).__name__
    return None


def _cache_dir(module_name: str) -> str | None:
    """The cache folder of a kernel module, created; ``None`` (and one notice in the process)
    when it cannot be written."""
    if module_name not in _CACHE_DIRS:
        try:
            stamp = dependency_stamp(module_name)
        except (KeyError, OSError):  # not a module with a source file: numba's stamp alone
            stamp = ()
        digest = hashlib.sha256(repr(stamp).encode()).hexdigest()[:16]
        folder = os.path.join(cache_base(), digest)
        reason = _writable(folder)
        _CACHE_DIRS[module_name] = None if reason else folder
        if reason:
            _notice_unwritable(folder, reason)
    return _CACHE_DIRS[module_name]


def _notice_unwritable(folder: str, reason: str) -> None:
    if not _UNWRITABLE:
        _UNWRITABLE.append(folder)
        logging.getLogger(_COMPILE_LOGGER).warning(unwritable_notice(folder, reason))


# --- the decorator ----------------------------------------------------------------------------


def jit(func=None, *, parallel: bool = False, **options):
    """``numba.njit`` with the project's policy: lazy, cached (per dependency version, see the
    module docstring; in memory where the cache cannot be written), no fastmath, no GIL."""
    options.setdefault("fastmath", False)
    options.setdefault("nogil", True)
    want_cache = options.pop("cache", CACHE)

    def decorate(f):
        folder = _cache_dir(f.__module__) if want_cache else None
        _POLICY_FUNCTIONS.add(f.__code__)
        if folder is None:
            return numba.njit(parallel=parallel, cache=False, **options)(f)
        with _LOCK:
            saved = numba.config.CACHE_DIR
            numba.config.CACHE_DIR = folder
            try:
                return numba.njit(parallel=parallel, cache=True, **options)(f)
            except RuntimeError as err:  # numba found no usable cache location after all
                _notice_unwritable(folder, str(err))
                return numba.njit(parallel=parallel, cache=False, **options)(f)
            finally:
                numba.config.CACHE_DIR = saved

    return decorate if func is None else decorate(func)


prange = numba.prange


# --- the first-compilation notice --------------------------------------------------------------


class _FirstCompile(event.Listener):
    """Logs :func:`first_run_notice` once per process, when a kernel of this policy starts to
    compile (numba sends ``"numba:compile"`` only on a cache miss). It stays registered (a
    listener removed while numba broadcasts would make numba skip the next one); after the
    notice it costs one check per compilation."""

    def on_start(self, ev: event.Event) -> None:
        dispatcher = (ev.data or {}).get("dispatcher")
        code = getattr(getattr(dispatcher, "py_func", None), "__code__", None)
        if _NOTICE_GIVEN or code not in _POLICY_FUNCTIONS:
            return
        _NOTICE_GIVEN.append(True)
        module = getattr(dispatcher.py_func, "__module__", "")
        location = _CACHE_DIRS.get(module) if CACHE else None
        logging.getLogger(_COMPILE_LOGGER).info(first_run_notice(location))

    def on_end(self, ev: event.Event) -> None:
        pass


event.register("numba:compile", _FirstCompile())
