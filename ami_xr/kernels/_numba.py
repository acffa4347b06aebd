"""The one place for numba policy.

* Lazy compilation: no eager signatures, so ``import ami_xr`` and ``ami-xr --help`` compile nothing.
* ``cache=True`` so a compiled kernel is reused by the next process (set ``AMI_XR_NUMBA_CACHE=0``
  to switch the on-disk cache off, e.g. on a read-only install).
* ``fastmath`` stays off: results must match the numpy references to rounding.
* ``NUMBA_DISABLE_JIT=1`` (numba's own switch) runs every kernel as plain Python for debugging
  and coverage.

Cache stamps that follow calls across files
-------------------------------------------
numba stamps a cached kernel with its own source file only, but a kernel that calls a jitted
function of another module has that function compiled into it: after an edit to
``single_mode.py`` the cached kernels of ``isolate.py`` would still run the old code. So every
function compiled through :func:`jit` or :func:`guvectorize` gets a stamp made of numba's own
stamp of its file plus the content hash of each *kernel module* its module imports,
transitively (a kernel module is one that imports this policy module; this file counts too,
since a policy change such as ``fastmath`` is not part of numba's cache key). An edit to one
kernel module therefore recompiles its own kernels and those of the modules that import it,
directly or not, and no others; a ``touch`` or a checkout that leaves the text unchanged
recompiles nothing extra.

This hooks into numba's cache-locator list (``numba.core.caching.CacheImpl._locator_classes``, a
private interface, present from numba 0.58 to at least 0.68). If that interface is missing or
behaves differently, or the dependencies cannot be worked out, the kernels fall back to numba's
default per-file stamp; the hook never makes a kernel fail to compile or to cache.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib.util
import os
import sys
import weakref
from collections.abc import Callable
from typing import Any

import numba
import numba.core.registry
import numba.core.sigutils
import numba.core.types

CACHE = os.environ.get("AMI_XR_NUMBA_CACHE", "1").strip().lower() not in ("0", "false", "no", "off")

# Python functions compiled with this policy: only their cache stamps are widened.
_POLICY_FUNCTIONS: weakref.WeakSet = weakref.WeakSet()


# The first-compilation notice goes to logging.getLogger(names.COMPILE_LOGGER) at INFO: the CLI
# prints it on stderr; the Python API leaves it to the caller's logging set-up (silent by default).
#: What a cold ``ami-xr demo`` spends compiling, in CPU seconds on a 2-core machine (measured
#: with ``scripts/bench_first_run.py``: 45-48 s CPU for the whole cold demo, 28 s compiling).
FIRST_RUN_SECONDS = 45
_NOTICE_GIVEN: list[bool] = []


def _cache_location(dispatcher: Any) -> str | None:
    """The cache folder: ``NUMBA_CACHE_DIR`` when set, else where this kernel is cached."""
    if numba.config.CACHE_DIR:
        return str(numba.config.CACHE_DIR)
    path = getattr(getattr(dispatcher, "_cache", None), "_cache_path", None)
    return path if isinstance(path, str) else None


def first_run_notice(location: str | None = None) -> str:
    """The text of the first-compilation notice (``location``: the cache folder, if any)."""
    where = f"cached in {location}" if CACHE and location else "on-disk cache off"
    return (
        "ami-xr: first run on this machine: compiling numeric kernels "
        f"(about {FIRST_RUN_SECONDS} s, once; {where})"
    )


def _notice(dispatcher: Any) -> None:
    """Log :func:`first_run_notice` once per process, just before the first kernel compiles."""
    if _NOTICE_GIVEN:
        return
    _NOTICE_GIVEN.append(True)
    import logging

    from ami_xr.names import COMPILE_LOGGER

    logging.getLogger(COMPILE_LOGGER).info(first_run_notice(_cache_location(dispatcher)))


class _Dispatcher(numba.core.registry.CPUDispatcher):
    """numba's CPU dispatcher with two changes, neither of which touches the generated code:

    * a call from another kernel is typed with its arguments' plain types (``int64``, not
      ``Literal[int](0)``), so a kernel called with a constant and with a variable compiles
      once, not once per constant (numba specialises jitted-to-jitted calls on literal values);
    * the first compilation of the process (a cache miss) is announced, see :func:`_notice`.
    """

    def get_call_template(self, args, kws):
        unlit = numba.core.types.unliteral
        args = tuple(unlit(a) for a in args)
        kws = {k: unlit(v) for k, v in kws.items()}
        return super().get_call_template(args, kws)

    def compile(self, sig):
        if not _NOTICE_GIVEN and self._can_compile:
            args, _ = numba.core.sigutils.normalize_signature(sig)
            if self.overloads.get(tuple(args)) is None:
                load = self._cache.load_overload
                self._cache.load_overload = lambda s, ctx: _missed(self, load(s, ctx))
                try:
                    return super().compile(sig)
                finally:
                    del self._cache.load_overload
        return super().compile(sig)


def _missed(dispatcher: Any, loaded: Any) -> Any:
    if loaded is None:
        _notice(dispatcher)
    return loaded


def jit(func=None, *, parallel: bool = False, **options):
    """``numba.njit`` with the project's policy (lazy, cached, no fastmath, one specialisation
    per argument types: see :class:`_Dispatcher`)."""
    options.setdefault("cache", CACHE)
    options.setdefault("fastmath", False)
    options.setdefault("nogil", True)

    def decorate(f):
        _POLICY_FUNCTIONS.add(f)
        disp = numba.njit(parallel=parallel, **options)(f)
        if type(disp) is numba.core.registry.CPUDispatcher:  # not under NUMBA_DISABLE_JIT
            disp.__class__ = _Dispatcher
        return disp

    return decorate if func is None else decorate(func)


def guvectorize(signatures, layout: str, **options):
    """``numba.guvectorize`` with the project's policy (cached, no fastmath).

    Note that gufuncs need explicit signatures; they are compiled on first call only when
    ``signatures`` is empty (dynamic gufunc), which is what we use to keep imports cheap.
    """
    options.setdefault("cache", CACHE)
    options.setdefault("fastmath", False)
    options.setdefault("nopython", True)
    if signatures:
        decorator = numba.guvectorize(signatures, layout, **options)
    else:
        decorator = numba.guvectorize(layout, **options)

    def decorate(f):
        _POLICY_FUNCTIONS.add(f)
        return decorator(f)

    return decorate


prange = numba.prange


# --- dependency-aware cache stamps ------------------------------------------------------------


@functools.cache
def _file_hash(path: str, mtime_ns: int, size: int) -> str:
    """sha256 of a file's bytes (memoised on its mtime and size, like numba's own stamp)."""
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


@functools.cache
def _imports(path: str, mtime_ns: int, size: int) -> tuple[tuple[int, str, tuple[str, ...]], ...]:
    """``(level, module, names)`` of every import statement in a source file."""
    with open(path, "rb") as f:
        tree = ast.parse(f.read(), filename=path)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.extend((0, alias.name, ()) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            out.append((node.level, node.module or "", tuple(a.name for a in node.names)))
    return tuple(out)


def _source_file(module: Any) -> str | None:
    path = getattr(module, "__file__", None)
    if isinstance(path, str) and path.endswith(".py") and os.path.isfile(path):
        return path
    return None


def _is_kernel_module(module: Any) -> bool:
    """Whether ``module`` compiles kernels with this policy (it holds ``jit``, ``guvectorize``
    or this module), or is this policy module itself."""
    if module is sys.modules.get(__name__):
        return True
    try:
        values = list(vars(module).values())
    except TypeError:
        return False
    policy = sys.modules.get(__name__)
    return any(v is jit or v is guvectorize or (policy is not None and v is policy) for v in values)


def _imported_modules(name: str) -> set[str]:
    """Names of the already imported modules that module ``name`` imports, including the
    modules of jitted functions it imports by name (so re-exports are followed)."""
    module = sys.modules.get(name)
    path = _source_file(module)
    if path is None:
        return set()
    st = os.stat(path)
    package = getattr(module, "__package__", None) or ""
    found: set[str] = set()
    for level, target, names in _imports(path, st.st_mtime_ns, st.st_size):
        if level:
            try:
                target = importlib.util.resolve_name("." * level + target, package)
            except (ImportError, ValueError):
                continue
        found.add(target)
        parent = sys.modules.get(target)
        for n in names:
            found.add(f"{target}.{n}")
            py_func = getattr(getattr(parent, n, None), "py_func", None)
            owner = getattr(py_func, "__module__", None)
            if isinstance(owner, str):
                found.add(owner)
    found.discard(name)
    return {m for m in found if m in sys.modules}


@functools.cache
def _dependency_stamp(name: str) -> tuple[tuple[str, str], ...]:
    """``(module, sha256)`` of every kernel module that module ``name`` imports, transitively,
    sorted by name (``name`` itself left out: numba's own stamp covers it).

    Memoised per module for the life of the process, like the imported code it describes.
    """
    seen: set[str] = set()
    todo = [name]
    while todo:
        for dep in _imported_modules(todo.pop()):
            if dep not in seen and _is_kernel_module(sys.modules[dep]):
                seen.add(dep)
                todo.append(dep)
    seen.discard(name)
    stamp = []
    for dep in sorted(seen):
        path = _source_file(sys.modules[dep])
        if path is not None:
            st = os.stat(path)
            stamp.append((dep, _file_hash(path, st.st_mtime_ns, st.st_size)))
    return tuple(stamp)


class _DependencyStampLocator:
    """Entry of numba's locator list for the functions compiled here: it takes the locator
    numba would have chosen and widens that locator's source stamp with
    :func:`_dependency_stamp`. For any other function, or on any failure, it returns ``None``
    and numba goes on to its own locators unchanged."""

    @classmethod
    def from_function(cls, py_func: Callable, py_file: str) -> Any:
        try:
            if py_func not in _POLICY_FUNCTIONS:
                return None
            from numba.core import caching

            for other in list(caching.CacheImpl._locator_classes):
                if other is cls:
                    continue
                locator = other.from_function(py_func, py_file)
                if locator is not None:
                    break
            else:
                return None
            own_stamp = locator.get_source_stamp
            deps = _dependency_stamp(py_func.__module__)
        except Exception:  # numba's internals differ: keep its default behaviour
            return None
        if not deps:
            return locator
        locator.get_source_stamp = lambda: (own_stamp(), deps)
        return locator


def _install_dependency_stamps() -> bool:
    """Put :class:`_DependencyStampLocator` first in numba's locator list; ``False`` (and numba's
    default per-file stamps) where that list is not there."""
    try:
        from numba.core import caching

        classes = caching.CacheImpl._locator_classes
        if not isinstance(classes, list):
            return False
        if _DependencyStampLocator not in classes:
            classes.insert(0, _DependencyStampLocator)
        return True
    except Exception:
        return False


DEPENDENCY_STAMPS = CACHE and _install_dependency_stamps()
