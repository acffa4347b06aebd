"""From a LabVIEW hammer-test file to a modal table: LVM -> time Dataset -> FRF -> modes.

    python scripts/hammer_to_modes.py ../shared/data/impact_hammer.lvm
    python scripts/hammer_to_modes.py hits.lvm --end-value 0.05 --fmin 50 --fmax 3000 --out frf.nc \
        --modes modes.nc --report report/

1. :func:`ami_xr.read_lvm` reads every segment of the file as one hit (``record``).
2. :func:`ami_xr.impact_frf` checks every hit (overload, double impact, weak
   force), prints why a hit is left out, and averages the good ones (H1 by default) with a force
   window on the force and an exponential window on both channels; the window's decay rate is
   kept as ``exponential_window_decay``.
3. :func:`ami_xr.identify` (the AMI phases) identifies the modes in the band and removes the
   window's damping.
4. :func:`ami_xr.report` (optional, ``--report DIR``) draws the figures and the HTML page.
"""

from __future__ import annotations

import argparse
import sys

import ami_xr
from ami_xr import names


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("path", help="LabVIEW .lvm file, one segment per hit")
    ap.add_argument("--estimator", default="H1", choices=("H1", "H2", "Hv"))
    ap.add_argument(
        "--end-value",
        type=float,
        default=0.01,
        help="exponential window value at the record end (default 0.01)",
    )
    ap.add_argument("--fmin", type=float, default=50.0, help="band start [Hz] (default 50)")
    ap.add_argument("--fmax", type=float, default=3000.0, help="band end [Hz] (default 3000)")
    ap.add_argument("--out", default=None, help="also write the FRF Dataset (netCDF)")
    ap.add_argument("--modes", default=None, help="also write the identified modes (netCDF)")
    ap.add_argument(
        "--report", default=None, help="also write a report (PNGs + index.html) to this folder"
    )
    args = ap.parse_args(argv)
    try:
        ts = ami_xr.read_lvm(args.path)
        fs = 1.0 / float(ts[names.TIME][1] - ts[names.TIME][0])
        n_hits = ts.sizes.get(names.RECORD, 1)
        print(
            f"{args.path}: {n_hits} hit(s) of {ts.sizes[names.TIME]} samples at {fs:g} Hz, "
            f"points {ts[names.POINT].values.tolist()}"
        )
        est = ami_xr.impact_frf(
            ts,
            args.estimator,
            exponential_end_value=args.end_value,
        )
        if args.out:
            ami_xr.to_netcdf(est, args.out)
    except ami_xr.AmiXrError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    print("\nhit  peak force  used  reason")
    for r in range(est.sizes[names.RECORD]):
        peak = float(est[names.HIT_PEAK_FORCE][r])
        bad = bool(est[names.HIT_REJECTED][r])
        print(
            f"{r:>3}  {peak:10.2f}  {'no ' if bad else 'yes'}   "
            f"{est[names.HIT_REJECT_REASON].values[r]}"
        )
    beta = float(est.attrs.get(names.ATTR_EXP_DECAY, 0.0))
    band = est.sel({names.FREQUENCY: slice(args.fmin, args.fmax)})
    print(
        f"\nFRF: {args.estimator} over {est.attrs[names.ATTR_N_AVERAGES]} hit(s), "
        f"{est[names.FRF].attrs[names.ATTR_UNITS]}, {est.sizes[names.FREQUENCY]} lines; "
        f"force window {est.attrs[names.ATTR_FORCE_WINDOW_WIDTH] * 1e3:.2f} ms; exponential "
        f"window decay {beta:.4g} 1/s; median coherence {args.fmin:g}-{args.fmax:g} Hz: "
        f"{float(band[names.COHERENCE].median()):.4f}"
    )
    if args.out:
        print(f"wrote {args.out}")
    try:
        modes = ami_xr.identify(band)
        if args.modes:
            ami_xr.to_netcdf(modes, args.modes)
    except ami_xr.AmiXrError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    print(
        f"\nmodes identified by ami_xr.identify ({args.fmin:g}-{args.fmax:g} Hz; "
        "window damping removed):"
    )
    print(ami_xr.format_modal_table(modes))
    if args.modes:
        print(f"wrote {args.modes}")
    if args.report:
        print(f"wrote {ami_xr.report(modes, args.report, title=f'hammer test: {args.path}')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
