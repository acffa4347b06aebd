"""Longest stretch between two interrupt checkpoints inside ``identify`` (issue 42 item 7).

A signal that arrives while compiled code runs is held until the next
:func:`ami_xr.interrupt.checkpoint`, so the longest gap between checkpoints is how long a
Ctrl-C of the command line may wait. This runs ``identify`` on a simulated set of ``--points``
points x ``--lines`` lines (``ami_xr.simulate.spread.many_points``) inside
:func:`ami_xr.interrupt.armed`, once to compile and warm up and once measured, with every
checkpoint timed in wall and CPU seconds, and prints the longest gaps with the functions that
called the checkpoints at either end (the work in between is what ran without one).
Target: at most 1 s.

    python scripts/bench_checkpoint_gap.py [--points 1000] [--lines 4096] [--top 5]
    python scripts/bench_checkpoint_gap.py --compress off   # every phase on every point (the
                                                            # SIMO isolation kernel, the refinement)
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings


def _caller() -> str:
    """``module.function`` of the first frame outside the interrupt and progress modules."""
    frame = sys._getframe(2)
    while frame is not None:
        module = frame.f_globals.get("__name__", "")
        if module not in ("ami_xr.interrupt", "ami_xr.progress", __name__):
            return f"{module.removeprefix('ami_xr.')}.{frame.f_code.co_name}"
        frame = frame.f_back
    return "?"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, default=1000)
    parser.add_argument("--lines", type=int, default=4096)
    parser.add_argument("--top", type=int, default=5, help="gaps listed (default 5)")
    parser.add_argument(
        "--compress", default="auto", help="identify's compress: auto (default), off or an int"
    )
    args = parser.parse_args(argv)
    compress = int(args.compress) if args.compress.isdigit() else args.compress
    if compress not in ("auto", "off") and not isinstance(compress, int):
        parser.error(f"--compress: expected auto, off or an int, got {args.compress!r}")

    import ami_xr
    from ami_xr import interrupt, progress
    from ami_xr.simulate.spread import many_points

    ds, _ = many_points(args.points, args.lines, 12, noise=0.02, seed=0)
    real = interrupt.checkpoint
    gaps: list[tuple[float, float, str, str]] = []
    last = [time.perf_counter(), time.process_time(), "start"]

    def timed() -> None:
        now, cpu, where = time.perf_counter(), time.process_time(), _caller()
        gaps.append((now - last[0], cpu - last[1], last[2], where))
        last[:] = [now, cpu, where]
        real()

    # progress.detail calls the name it imported; the other modules call interrupt.checkpoint
    interrupt.checkpoint = progress.checkpoint = timed
    try:
        for _run in ("warm-up", "measured"):
            gaps.clear()
            with warnings.catch_warnings(), interrupt.armed():
                warnings.simplefilter("ignore")
                last[:] = [time.perf_counter(), time.process_time(), "start"]
                t0, c0 = time.perf_counter(), time.process_time()
                out = ami_xr.identify(ds, compress=compress)
                timed()
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        interrupt.checkpoint = progress.checkpoint = real
    print(
        f"identify {args.points} points x {args.lines} lines, compress={compress} (measured): "
        f"{out.sizes['mode']} modes, "
        f"{wall:.2f} s wall, {cpu:.2f} s CPU, {len(gaps)} checkpoints"
    )
    print(f"{'wall s':>7} {'CPU s':>7}  from -> to")
    for w, c, a, b in sorted(gaps, key=lambda g: -g[1])[: args.top]:
        print(f"{w:7.3f} {c:7.3f}  {a} -> {b}")
    longest = max(g[1] for g in gaps)
    print(f"longest gap: {longest:.3f} s CPU, {max(g[0] for g in gaps):.3f} s wall (target 1 s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
