"""A test campaign in one command: a folder of FRF files -> batch identification -> summary.

Usage::

    python scripts/batch_campaign.py CAMPAIGN_DIR -o RESULTS_DIR [--workers 2] [--report]
    python scripts/batch_campaign.py --example 6 -o RESULTS_DIR     # simulated campaign

``CAMPAIGN_DIR`` is searched recursively for netCDF, UFF and LVM files (see ``ami-xr batch``).
With ``--example N`` the script first writes N simulated test articles (random lumped-mass
chains with 1 % noise, half as netCDF and half as UFF, in ``RESULTS_DIR/campaign``) and, after
the batch, compares every identified natural frequency with the simulator's exact one.

Run it twice: the second run finds every output up to date and does no work. Written against
the public API only (``ami_xr.batch``, ``ami_xr.open_dataset``, ``ami_xr.simulate``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import ami_xr


def make_example_campaign(folder: Path, n_articles: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Write ``n_articles`` simulated FRF files; return exact natural frequencies by file."""
    exact = {}
    for i in range(n_articles):
        g, truth = ami_xr.simulate.random_system(
            n_points=5, n_modes=5, noise=0.01, seed=seed + i, n_frequencies=1024
        )
        day = folder / f"day{i % 2 + 1}"
        day.mkdir(parents=True, exist_ok=True)
        if i % 2:
            path = day / f"article{i:02d}.uff"
            ami_xr.write_uff(g, path, binary=True)
        else:
            path = day / f"article{i:02d}.nc"
            ami_xr.to_netcdf(g, path)
        exact[path.relative_to(folder).as_posix()] = np.sort(truth["natural_frequency"].values)
    return exact


def compare_with_truth(summary, exact: dict[str, np.ndarray]) -> str:
    """Per file: modes found vs exact, and the largest natural-frequency error in %."""
    lines = ["file                    found/exact  max |f error| [%]"]
    for row in summary.rows:
        if row["file"] not in exact or row["status"] == "failed":
            continue
        fn = np.array([float(f) for f in str(row["frequencies_hz"]).split()])
        ex = exact[row["file"]]
        err = max((100 * np.min(np.abs(ex - f)) / f for f in fn), default=float("nan"))
        lines.append(f"{row['file']:<24}{fn.size:>5}/{ex.size:<6} {err:10.4f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("campaign", nargs="?", help="folder of measurement files")
    parser.add_argument("-o", "--output", required=True, help="results folder")
    parser.add_argument(
        "--example",
        type=int,
        default=0,
        metavar="N",
        help="simulate N test articles into OUTPUT/campaign first",
    )
    parser.add_argument("--workers", type=int, default=1, help="files in parallel")
    parser.add_argument("--report", action="store_true", help="also write report folders")
    args = parser.parse_args(argv)
    out = Path(args.output)
    exact = {}
    if args.example:
        campaign = out / "campaign"
        if not campaign.exists():
            exact = make_example_campaign(campaign, args.example)
        else:  # re-run: the files are already there
            exact = {p.relative_to(campaign).as_posix(): None for p in campaign.rglob("*.*")}
    elif args.campaign:
        campaign = Path(args.campaign)
    else:
        parser.error("give a CAMPAIGN folder or --example N")
    summary = ami_xr.batch(campaign, out / "results", workers=args.workers, report=args.report)
    print(summary.format())
    print(f"summary CSV: {summary.csv_path}")
    if exact and all(v is not None for v in exact.values()):
        print()
        print(compare_with_truth(summary, exact))
    return 0 if summary.ok else 3


if __name__ == "__main__":
    sys.exit(main())
