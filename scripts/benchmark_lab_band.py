"""The default analysis band on simulated lab tests (issue 37, item 2): a shaker whose force
rolls off at low frequency, a sweep that ends below Nyquist, coherence dips at antiresonances.

    python scripts/benchmark_lab_band.py            # 3 systems per case
    python scripts/benchmark_lab_band.py --systems 1
    python scripts/benchmark_lab_band.py --quantity velocity   # mobility (or acceleration, all)

Each system is a random chain of :func:`ami_xr.simulate.random_system` (6 points, modes from a
few Hz to 32 Hz). Its force and response histories are simulated at 128 Hz for 1024 s (the
response is the force filtered by the exact receptances, circularly; sensor noise 0.5 % of each
channel's RMS on the responses, 0.1 % on the force; the responses measured as displacement, or
with ``--quantity`` as velocity or acceleration, the sensor noise white in that quantity),
turned into H1 FRFs by ``ami_xr.frf`` (Hann, 16384 samples: 0.0078 Hz lines, 15 averages: the
lightest mode, 0.8 % at 2.3 Hz, spans 4.6 lines) and identified with every default. Cases:

* ``rolloff``: random force high-passed (amplitude (f/fc)^1.5 below fc = 10x the lowest mode): the
  force at the lowest mode is 30 dB below its peak, the response there clean;
* ``sweep``: a linear chirp from 0.5 Hz to 24 Hz repeated every 128 s (one per segment), a 2nd harmonic at
  -40 dB (a shaker's distortion): above 24 Hz the structure answers only the harmonic;
* ``random``: flat random force (coherence dips only at antiresonances).

Per case: the analysis band chosen, the modes with a clean peak inside the excitation (true
modes whose frequency lies within the excited range and whose peak stands sqrt(12) = 3.5
times above the noise of the H1 estimate at one point: a random error of at most 29 %) found, modes reported past the excitation (above 24 Hz for the sweep), and spurious
modes (matched to no true mode). Target (issue 37): every clean mode found, none past the
excitation. Time per identification is printed. Written against the public API only.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import ami_xr
from ami_xr.simulate import random_system, score_modes

FS, SECONDS, NPERSEG = 128.0, 1024.0, 16384
SWEEP_END = 24.0
SWEEP_PERIOD = NPERSEG / FS  # one sweep per Welch segment (a repeated sweep fills every line)
CASES = ("rolloff", "sweep", "random")
CLEAN_SNR = 12.0**0.5  # a clean peak: |H1|'s random error at most 29 % (the band's own limit)


def _force(case: str, t: np.ndarray, f_low: float, rng) -> tuple[np.ndarray, float, float]:
    """The force history and the excited range (lo, hi) in Hz."""
    n = t.size
    if case == "sweep":
        tau = np.mod(t, SWEEP_PERIOD)
        k = (SWEEP_END - 0.5) / SWEEP_PERIOD
        phase = 2 * np.pi * (0.5 * tau + 0.5 * k * tau**2)
        return np.sin(phase) + 0.01 * np.sin(2 * phase), 0.5, SWEEP_END
    x = rng.standard_normal(n)
    if case == "rolloff":
        f = np.fft.rfftfreq(n, 1 / FS)
        fc = 10.0 * f_low
        hp = (f / fc) ** 1.5 / np.sqrt(1 + (f / fc) ** 3)  # -30 dB (power) at fc / 10
        x = np.fft.irfft(np.fft.rfft(x) * hp, n)
    return x, 0.0, FS / 2


QUANTITIES = ("displacement", "velocity", "acceleration")


def _case(seed: int, case: str, quantity: str = "displacement"):
    rng = np.random.default_rng([seed, CASES.index(case)])
    n = int(FS * SECONDS)
    f = np.fft.rfftfreq(n, 1 / FS)
    frf, truth = random_system(6, "chain", seed=seed, frequency=f, max_frequency_hz=40.0)
    fn = truth["natural_frequency"].values
    t = np.arange(n) / FS
    x, lo, hi = _force(case, t, float(fn.min()), rng)
    h = frf["frf"].transpose("point", "frequency").values
    h = np.where(np.isfinite(h), h, 0.0)
    k = QUANTITIES.index(quantity)  # the response measured as the k-th derivative
    h = h * (2j * np.pi * f)[None, :] ** k
    y = np.fft.irfft(np.fft.rfft(x)[None, :] * h, n, axis=1)
    y += 0.005 * y.std(axis=1, keepdims=True) * rng.standard_normal(y.shape)
    x = x + 0.001 * x.std() * rng.standard_normal(n)
    ts = ami_xr.make_time_dataset(
        y,
        fs=FS,
        force=x,
        points=frf["point"].values,
        drive_point=frf.attrs["drive_point"],
        response_quantity=quantity,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est = ami_xr.frf(ts, nperseg=NPERSEG)
    return est, truth, (lo, hi)


def _clean(truth, est, lo, hi, quantity: str = "displacement") -> np.ndarray:
    """True modes inside the excited range whose peak stands ``CLEAN_SNR`` above the FRF's
    noise (``frf_line_noise_std`` at the mode's line) at one point at least."""
    fn = truth["natural_frequency"].values
    noise = est["frf_line_noise_std"].transpose("point", "frequency").values
    f = est["frequency"].values
    lam = truth["eigenvalue"].values
    res = truth["residue"].sel(point=est["point"].values).transpose("point", "mode").values
    peak = np.abs(res) / np.abs(lam.real)[None] * np.abs(lam)[None] ** QUANTITIES.index(quantity)
    at = np.array([np.argmin(np.abs(f - x)) for x in fn])
    snr = peak / noise[:, at]
    return (fn > lo) & (fn < hi) & ((snr >= CLEAN_SNR).any(axis=0))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--systems", type=int, default=3)
    p.add_argument("--quantity", choices=(*QUANTITIES, "all"), default="displacement")
    a = p.parse_args(argv)
    quantities = QUANTITIES if a.quantity == "all" else (a.quantity,)
    ok = True
    for quantity in quantities:
        if len(quantities) > 1:
            print(f"== responses measured as {quantity}")
        ok &= _run(a.systems, quantity)
        print()
    if len(quantities) > 1:
        print(f"every quantity: every clean mode found, none past the excitation -> "
              f"{'met' if ok else 'NOT met'}")
    return 0


def _run(systems: int, quantity: str) -> bool:
    total = {c: [0, 0, 0, 0, 0.0] for c in CASES}  # clean, found, past, spurious, seconds
    print(f"{'case':<9}{'seed':>5}{'band [Hz]':>16}{'clean':>7}{'found':>7}{'past':>6}"
          f"{'spur':>6}{'s':>7}")
    for seed in range(systems):
        for case in CASES:
            est, truth, (lo, hi) = _case(seed, case, quantity)
            clean = _clean(truth, est, lo, hi, quantity)
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out = ami_xr.identify(est)
            dt = time.perf_counter() - t0
            s = score_modes(out, truth)
            found = int((s.found & clean).sum())
            fn_out = out["natural_frequency"].values
            past = int(np.sum(fn_out > hi * 1.02)) if hi < FS / 2 else 0
            band = f"{out.attrs['analysis_band_fmin']:.2f}-{out.attrs['analysis_band_fmax']:.1f}"
            print(f"{case:<9}{seed:>5}{band:>16}{int(clean.sum()):>7}{found:>7}{past:>6}"
                  f"{s.n_spurious:>6}{dt:>7.1f}", flush=True)
            for i, v in enumerate((int(clean.sum()), found, past, s.n_spurious, dt)):
                total[case][i] += v
    print()
    ok = True
    for case in CASES:
        c, f, past, spur, secs = total[case]
        good = f == c and past == 0
        ok &= good
        print(f"{case:<9} clean modes found {f}/{c}, past the excitation {past}, spurious {spur}, "
              f"{secs:.1f} s -> {'met' if good else 'NOT met'}")
    print(f"target: every clean mode found, none past the excitation -> {'met' if ok else 'NOT met'}")
    return ok


if __name__ == "__main__":
    raise SystemExit(main())
