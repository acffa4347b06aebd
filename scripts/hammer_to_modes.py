"""From a LabVIEW hammer-test file to a modal table: LVM -> time Dataset -> FRF -> modes.

    python scripts/hammer_to_modes.py ../shared/data/impact_hammer.lvm
    python scripts/hammer_to_modes.py hits.lvm --end-value 0.05 --fmin 50 --fmax 3000 --out frf.nc

1. :func:`ami_xr.read_lvm` reads every segment of the file as one hit (``record``).
2. :func:`ami_xr.frf` (``excitation="impact"``) checks every hit (overload, double impact, weak
   force), prints why a hit is left out, and averages the good ones (H1 by default) with a force
   window on the force and an exponential window on both channels; the window's decay rate is
   kept as ``exponential_window_decay``.
3. :func:`ami_xr.identify` (the AMI phases) identifies the modes in the band and removes the
   window's damping. Where it is not available, a half-power peak pick with the same decay
   correction is printed instead (clearly labelled).
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

import ami_xr
from ami_xr import names


def _peak_pick(est, min_coherence: float = 0.8) -> list[tuple[float, float, float]]:
    """(f_n Hz, zeta measured, zeta corrected) of |H| peaks by the half-power bandwidth."""
    import scipy.signal

    f = est[names.FREQUENCY].values
    h = np.abs(est[names.FRF].isel({names.POINT: 0}).values)
    coh = est[names.COHERENCE].isel({names.POINT: 0}).values
    beta = float(est.attrs.get(names.ATTR_EXP_DECAY, 0.0))
    peaks, _ = scipy.signal.find_peaks(h, prominence=0.1 * h.max())
    rows = []
    for k in peaks:
        if coh[k] < min_coherence:
            continue
        half = h[k] / math.sqrt(2)
        lo, hi = k, k
        while lo > 0 and h[lo] > half:
            lo -= 1
        while hi < h.size - 1 and h[hi] > half:
            hi += 1
        # linear interpolation of the half-power crossings
        f_lo = np.interp(half, [h[lo], h[lo + 1]], [f[lo], f[lo + 1]])
        f_hi = np.interp(half, [h[hi], h[hi - 1]], [f[hi], f[hi - 1]])
        zeta = (f_hi - f_lo) / (2 * f[k])
        rows.append((f[k], zeta, zeta - beta / (2 * np.pi * f[k])))
    return rows


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
    args = ap.parse_args(argv)
    try:
        ts = ami_xr.read_lvm(args.path)
        fs = 1.0 / float(ts[names.TIME][1] - ts[names.TIME][0])
        n_hits = ts.sizes.get(names.RECORD, 1)
        print(
            f"{args.path}: {n_hits} hit(s) of {ts.sizes[names.TIME]} samples at {fs:g} Hz, "
            f"points {ts[names.POINT].values.tolist()}"
        )
        est = ami_xr.frf(
            ts,
            args.estimator,
            excitation="impact",
            exponential_end_value=args.end_value,
            path=args.out,
        )
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
    identify = getattr(ami_xr, "identify", None)
    if identify is not None:
        try:
            modes = identify(band)
            print(
                f"\nmodes identified by ami_xr.identify ({args.fmin:g}-{args.fmax:g} Hz; "
                "window damping removed):"
            )
            print(ami_xr.format_modal_table(modes))
            return 0
        except ami_xr.AmiXrError as err:
            print(f"\nami_xr.identify failed: {err}; falling back to peak picking")
    else:
        print("\nami_xr.identify is not available in this version; half-power peak picking:")
    print(f"{'f [Hz]':>10}  {'zeta meas. [%]':>14}  {'zeta corr. [%]':>14}")
    for fn, z_meas, z_corr in _peak_pick(band):
        print(f"{fn:10.2f}  {100 * z_meas:14.3f}  {100 * z_corr:14.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
