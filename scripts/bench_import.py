"""Start-up cost: ``import ami_xr`` and ``ami-xr --help`` in fresh interpreters.

Prints the median over ``--repeat`` fresh processes of: ``import ami_xr`` (timed inside the
interpreter), ``import xarray`` for comparison (the baseline of any xarray tool), and the wall
time of ``python -m ami_xr --help`` (interpreter start included). Target (issue 8): both ami_xr
figures <= 0.3 s.

    python scripts/bench_import.py [--repeat 7]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

TIMED_IMPORT = "import time; t = time.perf_counter(); import {0}; print(time.perf_counter() - t)"


def _import_seconds(module: str) -> float:
    done = subprocess.run(
        [sys.executable, "-c", TIMED_IMPORT.format(module)],
        capture_output=True,
        text=True,
        check=True,
    )
    return float(done.stdout.strip().splitlines()[-1])


def _help_seconds() -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "ami_xr", "--help"], capture_output=True, check=True)
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="fresh processes per figure")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f"--repeat must be >= 1, got {args.repeat}")
    _import_seconds("ami_xr")  # warm the OS file cache once
    rows = {
        "import ami_xr": [_import_seconds("ami_xr") for _ in range(args.repeat)],
        "import xarray (baseline)": [_import_seconds("xarray") for _ in range(args.repeat)],
        "python -m ami_xr --help (wall)": [_help_seconds() for _ in range(args.repeat)],
    }
    print(f"median of {args.repeat} fresh interpreters, Python {sys.version.split()[0]}")
    for name, times in rows.items():
        print(f"  {name:32s} {statistics.median(times):7.3f} s   (min {min(times):.3f} s)")
    ours = max(
        statistics.median(rows["import ami_xr"]),
        statistics.median(rows["python -m ami_xr --help (wall)"]),
    )
    print(f"target <= 0.3 s: {'met' if ours <= 0.3 else 'NOT met'} ({ours:.3f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
