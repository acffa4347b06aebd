"""Time to draw the report: per figure and in all, on the demo's data set; and ``ami-xr demo``.

The demo's data set is simulated with the project's own functions, as ``ami-xr demo --simulate``
does (:func:`ami_xr.simulate.benchmark` with its defaults, then :func:`ami_xr.identify`). Each
figure is timed as ``ami_xr.report(ds, folder, figures=(name,))`` (draw, PNG, index.html), the
total as ``ami_xr.report(ds, folder)`` with every figure: warm (after one untimed call), median
of ``--repeat``. Then the wall time of the whole ``ami-xr demo`` in a subprocess, in a temporary
folder: run twice, the second (warm: numba cache and OS file cache filled) is reported. Wall
and CPU time are printed (on a shared, busy machine the CPU time is the steadier figure).
Target (issue 12): the report's figures <= 1.5 s warm.

    python scripts/bench_report.py [--repeat 3] [--no-demo]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_S = 1.5


def _median_seconds(call, repeat: int) -> tuple[float, float]:
    """Median wall time and median CPU time of this process (the CPU time is what a busy,
    shared machine leaves unchanged)."""
    call()  # warm: imports, fonts, numba
    wall, cpu = [], []
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        call()
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return statistics.median(wall), statistics.median(cpu)


def _demo_dataset():
    import ami_xr

    _, g, _ = ami_xr.simulate.benchmark()
    return ami_xr.identify(g)


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _demo_seconds(folder: Path) -> tuple[float, float]:
    """Wall and CPU time of the second of two ``ami-xr demo`` runs in ``folder``."""
    command = [sys.executable, "-m", "ami_xr", "demo", "-o", str(folder / "demo")]
    for _ in range(2):
        start, start_cpu = time.perf_counter(), _children_cpu()
        subprocess.run(command, cwd=folder, capture_output=True, check=True)
        wall, cpu = time.perf_counter() - start, _children_cpu() - start_cpu
    return wall, cpu


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="timed calls per figure (median)")
    parser.add_argument("--no-demo", action="store_true", help="skip the 'ami-xr demo' timing")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f"--repeat must be >= 1, got {args.repeat}")
    from ami_xr.app.report import FIGURES, MEASUREMENT_FIGURES, report

    ds = _demo_dataset()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        stems = [s for s, v in MEASUREMENT_FIGURES.items() if v[2] in ds] + list(FIGURES)
        print(f"report figures of the demo data set, warm, median of {args.repeat}:")
        print(f"  {'figure':16s} {'wall':>9s} {'cpu':>9s}")
        for stem in stems:
            wall, cpu = _median_seconds(
                lambda s=stem: report(ds, folder / "one", figures=(s,)), args.repeat
            )
            print(f"  {stem:16s} {wall:7.3f} s {cpu:7.3f} s")
        wall, cpu = _median_seconds(lambda: report(ds, folder / "all"), args.repeat)
        verdict = "met" if wall <= TARGET_S else "NOT met"
        print(
            f"  {'all (report())':16s} {wall:7.3f} s {cpu:7.3f} s   "
            f"target <= {TARGET_S} s wall: {verdict}"
        )
        if not args.no_demo:
            wall, cpu = _demo_seconds(folder)
            print(
                f"ami-xr demo, whole command, warm (second run): {wall:.3f} s wall, {cpu:.3f} s cpu"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
