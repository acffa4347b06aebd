"""First-run cost of ``ami-xr demo``: cold (empty numba cache) and warm, and what compiles.

Each run is a subprocess with its own temporary numba cache (``NUMBA_CACHE_DIR``) and output
folder, so the machine's own cache is neither used nor touched:

1. cold: ``python -m ami_xr demo`` with the empty cache - wall and CPU time (what a new user
   waits for after ``pip install``);
2. warm: the same command again on the cache the first run filled;
3. a probe: the demo run in-process (again with an empty cache), with numba's dispatcher
   ``compile`` timed (CPU time of the compiling thread), then every numba dispatcher of
   ``ami_xr.kernels.*`` listed with its number of compiled specialisations and the CPU seconds
   spent compiling it (its callees' compilation excluded) - the top ``--top`` are printed -
   and the largest of numba's own implementations compiled for them (``np.roots``, ``np.empty``,
   a sort, the formatted error of an array-to-array slice assignment: costs a kernel's source
   decides). A kernel inlined into its caller (``inline="always"``) compiles as part of it.

Wall and CPU time are printed (on a shared, busy machine the CPU time is the steadier figure).
Target (issue 11 item 1): cold demo <= 20 s.

    python scripts/bench_first_run.py [--top 15] [--no-report] [--probe-only] [--repeat N]

``--repeat N`` runs the cold demo N times, each on a new empty cache, and prints the least and
the median CPU time: on a machine shared with other work, contention inflates CPU time too
(caches, hyper-threads), and the least of a few runs is the steadier figure to compare.

``--base DIR`` (a checkout of the base, e.g. ``git worktree add ../base main --detach``) runs
every cold and warm demo and the probe for the base too, the base's run and this tree's run
back to back (``PYTHONPATH`` set to each tree), and prints both with their ratio: timings on a
shared machine compare only within one run.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_COLD_S = 20.0


def _child_times() -> float:
    t = os.times()
    return t.children_user + t.children_system


def _env(cache: str, tree: str | None) -> dict[str, str]:
    """The environment of a child: its own numba cache, and ``tree`` first on the path."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, AMI_XR_NUMBA_CACHE="1")
    if tree is not None:
        env["PYTHONPATH"] = os.pathsep.join([tree] + [p for p in [env.get("PYTHONPATH")] if p])
    return env


def _run_demo(
    cache: str, out: str, report: bool, tree: str | None = None
) -> tuple[float, float, str]:
    """Wall and CPU seconds of one ``python -m ami_xr demo`` (of ``tree``) and its stderr."""
    env = _env(cache, tree)
    cmd = [sys.executable, "-m", "ami_xr", "demo", "-o", out]
    if not report:
        cmd.append("--no-report")
    cpu0, t0 = _child_times(), time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    wall, cpu = time.perf_counter() - t0, _child_times() - cpu0
    if done.returncode:
        sys.exit(f"demo failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return wall, cpu, done.stderr


def _probe(report: bool) -> dict:
    """Run the demo in this process with ``Dispatcher.compile`` timed (call with an empty
    ``NUMBA_CACHE_DIR``). Returns per-dispatcher rows."""
    from numba.core import dispatcher as nd

    own: dict[int, float] = {}
    library: dict[str, float] = {}  # numba's own implementations (np.roots, argsort, ...)
    library_sigs: dict[str, list[str]] = {}  # their compiled signatures
    stack: list[float] = []  # callees' time, per open compile
    original = nd.Dispatcher.compile

    def timed(self, sig):
        stack.append(0.0)
        t0 = time.thread_time()  # CPU time of this thread: steady on a busy machine
        try:
            return original(self, sig)
        finally:
            total = time.thread_time() - t0
            inner = stack.pop()
            own[id(self)] = own.get(id(self), 0.0) + total - inner
            func = self.py_func
            if not getattr(func, "__module__", "").startswith("ami_xr"):
                key = f"{func.__module__}.{func.__qualname__}".replace(".<locals>", "")
                library[key] = library.get(key, 0.0) + total - inner
                library_sigs.setdefault(key, []).append(str(sig))
            if stack:
                stack[-1] += total

    nd.Dispatcher.compile = timed
    import ami_xr.app.demo

    with tempfile.TemporaryDirectory() as out:
        t0, cpu0 = time.perf_counter(), time.process_time()
        ami_xr.app.demo.demo(out, report=report, progress=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    rows = []
    for name, module in sorted(sys.modules.items()):
        if not name.startswith("ami_xr.kernels") or module is None:
            continue
        for attr, obj in vars(module).items():
            if isinstance(obj, nd.Dispatcher) and getattr(obj.py_func, "__module__", "") == name:
                if obj.signatures or id(obj) in own:
                    rows.append(
                        {
                            "kernel": f"{name.removeprefix('ami_xr.kernels.')}.{attr}",
                            "signatures": [str(s) for s in obj.signatures],
                            "parallel": bool(obj.targetoptions.get("parallel")),
                            "seconds": own.get(id(obj), 0.0),
                        }
                    )
    return {
        "wall": wall,
        "cpu": cpu,
        "rows": rows,
        "library": library,
        "library_sigs": library_sigs,
    }


def _message(err: str) -> str:
    message = [line for line in err.splitlines() if "compiling" in line]
    return message[0] if message else "(none)"


def _demo_times(tmp: str, trees: dict[str, str | None], repeat: int, report: bool) -> None:
    """Cold (``repeat`` times, each tree's run after the other's) and warm demo per tree."""
    cold: dict[str, list[float]] = {name: [] for name in trees}
    caches: dict[str, str] = {}
    for rep in range(max(repeat, 1)):
        for name, tree in trees.items():
            cache, out = str(Path(tmp, f"{name}-cache{rep}")), str(Path(tmp, "out"))
            wall, cpu, err = _run_demo(cache, out, report, tree)
            print(f"{name:>5} demo cold (empty numba cache): {wall:6.1f} s wall, {cpu:6.1f} s CPU")
            if rep == 0:
                print(f"        first-run message: {_message(err)}")
            cold[name].append(cpu)
            caches[name] = cache
    warm: dict[str, float] = {}
    for name, tree in trees.items():
        wall, cpu, err = _run_demo(caches[name], str(Path(tmp, "out")), report, tree)
        print(f"{name:>5} demo warm (cache filled):      {wall:6.1f} s wall, {cpu:6.1f} s CPU")
        print(f"        first-run message: {_message(err)}")
        warm[name] = cpu
    for name, cpus in cold.items():
        print(
            f"{name:>5} cold over {len(cpus)} run(s): least {min(cpus):.1f} s CPU, "
            f"median {sorted(cpus)[len(cpus) // 2]:.1f} s CPU; warm {warm[name]:.1f} s CPU"
        )
    if len(trees) > 1:
        least = {name: min(cpus) for name, cpus in cold.items()}
        print(
            f"this/base: cold {least['this'] / least['base']:.2f} (least CPU), "
            f"warm {warm['this'] / warm['base']:.2f}"
        )
    print(f"target: cold <= {TARGET_COLD_S:.0f} s")


def _run_probe(tmp: str, name: str, tree: str | None, report: bool) -> dict:
    env = _env(str(Path(tmp, f"{name}-probe")), tree)
    cmd = [sys.executable, __file__, "--_probe"] + (["--no-report"] if not report else [])
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if done.returncode:
        sys.exit(f"probe ({name}) failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _summary(name: str, probe: dict) -> float:
    rows = probe["rows"]
    total = sum(r["seconds"] for r in rows)
    n_sig = sum(len(r["signatures"]) for r in rows)
    library_sigs = probe.get("library_sigs", {})
    n_lib = sum(len(set(v)) for v in library_sigs.values())
    print(
        f"{name:>5} in-process demo, empty cache: {probe['wall']:.1f} s wall, "
        f"{probe['cpu']:.1f} s CPU; {len(rows)} kernels, {n_sig} specialisations, "
        f"{n_lib} of numba's own; {total:.1f} s CPU compiling"
    )
    return total


def _print_probe(probe: dict, top: int) -> None:
    rows = sorted(probe["rows"], key=lambda r: -r["seconds"])
    print(f"{'CPU s':>8}  {'sigs':>4}  kernel (its callees' compilation excluded)")
    for r in rows[:top]:
        flag = "  (parallel)" if r["parallel"] else ""
        print(f"{r['seconds']:8.2f}  {len(r['signatures']):4d}  {r['kernel']}{flag}")
    library = sorted(probe.get("library", {}).items(), key=lambda kv: -kv[1])
    library_sigs = probe.get("library_sigs", {})
    print(
        f"numba's own implementations compiled for them: {sum(v for _, v in library):.1f} s CPU"
        " (the largest; sigs: distinct signatures)"
    )
    for key, seconds in library[: max(top // 2, 3)]:
        print(f"{seconds:8.2f}  {len(set(library_sigs.get(key, ()))):4d}  {key}")
    for r in rows:
        if len(r["signatures"]) > 1:
            print(f"  {r['kernel']}: " + " | ".join(r["signatures"]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--top", type=int, default=15, help="kernels listed (default 15)")
    parser.add_argument("--no-report", action="store_true", help="demo without the report")
    parser.add_argument("--probe-only", action="store_true", help="only the per-kernel table")
    parser.add_argument(
        "--repeat", type=int, default=1, help="cold runs, each on a new empty cache (default 1)"
    )
    parser.add_argument(
        "--base", metavar="DIR", help="a checkout of the base, run back to back with this tree"
    )
    parser.add_argument("--_probe", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    report = not args.no_report
    if args._probe:
        print(json.dumps(_probe(report)))
        return 0
    this = str(Path(__file__).resolve().parents[1])
    trees: dict[str, str | None] = {"this": this}
    if args.base:
        base = Path(args.base).resolve()
        if not (base / "ami_xr" / "__init__.py").is_file():
            parser.error(f"--base: expected a checkout with ami_xr/__init__.py, got {base}")
        trees = {"base": str(base), "this": this}
    with tempfile.TemporaryDirectory() as tmp:
        if not args.probe_only:
            _demo_times(tmp, trees, args.repeat, report)
        print()
        probes = {name: _run_probe(tmp, name, tree, report) for name, tree in trees.items()}
    totals = {name: _summary(name, probe) for name, probe in probes.items()}
    if len(totals) > 1:
        print(f"this/base: compiling {totals['this'] / totals['base']:.2f} (CPU)")
    _print_probe(probes["this"], args.top)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
