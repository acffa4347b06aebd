"""Impact hit checks: overload (clipping), double impact and weak force, per hammer hit.

Used by :func:`ami_xr.dsp.frf.impact_frf` before averaging; public so that a test campaign can
screen hits without estimating FRFs.
"""

from __future__ import annotations

import numpy as np

from ami_xr.kernels import impact as _ki


def check_hits(
    force: np.ndarray,
    response: np.ndarray,
    *,
    overload_samples: int = 3,
    double_impact_threshold: float = 0.1,
    min_force: float | None = None,
    weak_force_ratio: float = 0.1,
    min_snr: float = 10.0,
    point_labels: list | None = None,
) -> tuple[np.ndarray, list[str], np.ndarray, np.ndarray]:
    """Check impact hits; return (rejected, reasons, peak force, pulse (start, end) samples).

    ``force`` (hit, reference, time) and ``response`` (hit, point, time). A hit is rejected for

    * overload: some channel has ``overload_samples`` or more consecutive samples equal to its
      maximum or minimum (the converter's limit code, i.e. clipping);
    * double impact: a second force pulse, i.e. ``|f|`` above ``double_impact_threshold`` times
      the peak again after the first pulse has ended (quiet for at least the pulse's length);
    * no force: the force is constant (zero included) throughout the hit;
    * weak force: peak ``|f|`` below ``min_force``, or below ``weak_force_ratio`` times the median
      peak of the hits, or below ``min_snr`` times the force noise (1.4826 * MAD of the hit).
    """
    nrec, nref, nt = force.shape
    labels = point_labels if point_labels is not None else list(range(response.shape[1]))
    reasons: list[list[str]] = [[] for _ in range(nrec)]
    # overload, per channel
    runs_f = _ki.extreme_run(force.reshape(nrec * nref, nt)).reshape(nrec, nref)
    runs_y = _ki.extreme_run(response.reshape(-1, nt)).reshape(nrec, -1)
    for r in range(nrec):
        for i in np.flatnonzero(runs_f[r] >= overload_samples):
            peak = force[r, i][np.argmax(np.abs(force[r, i]))]
            reasons[r].append(
                f"overload: force{'' if nref == 1 else f' {i}'} clipped at {peak:.6g} "
                f"({runs_f[r, i]} equal samples at its extreme)"
            )
        for p in np.flatnonzero(runs_y[r] >= overload_samples):
            peak = response[r, p][np.argmax(np.abs(response[r, p]))]
            reasons[r].append(
                f"overload: response at point {labels[p]!r} clipped at {peak:.6g} "
                f"({runs_y[r, p]} equal samples at its extreme)"
            )
    # force pulses (first force channel: the hammer)
    f0 = np.ascontiguousarray(force[:, 0, :])
    peak = np.max(np.abs(f0), axis=1)
    thr = double_impact_threshold * peak
    # quiet gap needed to call a new pulse: the first pulse's own length (at least 3 samples)
    first = _ki.force_pulses(f0, thr, 3)
    pulses = np.empty_like(first)
    for r in range(nrec):
        gap = max(3, int(first[r, 2] - first[r, 1] + 1))
        pulses[r] = _ki.force_pulses(f0[r : r + 1], thr[r : r + 1], gap)[0]
    overloaded = np.array([any(s.startswith("overload") for s in reasons[r]) for r in range(nrec)])
    clean_peaks = peak[~overloaded] if np.any(~overloaded) else peak
    median_peak = float(np.median(clean_peaks))
    noise = 1.4826 * np.median(np.abs(f0 - np.median(f0, axis=1, keepdims=True)), axis=1)
    for r in range(nrec):
        if pulses[r, 0] >= 2:
            delay = pulses[r, 3] - pulses[r, 1]
            reasons[r].append(
                f"double impact: a second force pulse {delay} samples after the first "
                f"(|force| > {double_impact_threshold:g} x peak again)"
            )
        if not np.ptp(f0[r]) > 0:
            # no pulse at all: with one hit there is no median to compare with, and a zero
            # noise skips the SNR test below, so this must be caught on its own
            reasons[r].append(
                f"no force: the force is {f0[r, 0]:.6g} in every sample of the hit (no impact "
                "recorded: dead sensor or unplugged?)"
            )
        elif min_force is not None and peak[r] < min_force:
            reasons[r].append(f"force too weak: peak {peak[r]:.4g} < min_force={min_force:g}")
        elif nrec > 1 and peak[r] < weak_force_ratio * median_peak:
            reasons[r].append(
                f"force too weak: peak {peak[r]:.4g} < {weak_force_ratio:g} x the median peak "
                f"{median_peak:.4g} of the hits"
            )
        elif noise[r] > 0 and peak[r] < min_snr * noise[r]:
            reasons[r].append(
                f"force too weak: peak {peak[r]:.4g} < {min_snr:g} x the force noise {noise[r]:.3g}"
            )
    rejected = np.array([bool(x) for x in reasons])
    return rejected, ["; ".join(x) for x in reasons], peak, pulses[:, 1:3]
