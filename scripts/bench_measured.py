"""Measured FRF sets: ``identify`` against sdypy-EMA's LSCF on the same band, idle and loaded.

    pip install ami_xr[bench]                     # sdypy-EMA, only for this script
    python scripts/bench_measured.py              # every set found, idle and loaded
    python scripts/bench_measured.py --no-peer    # ami_xr alone
    python scripts/bench_measured.py --quick      # the shipped set only (a smoke test)

The sets (a set whose file is missing is skipped with a line saying so):

* ``measurement.uff`` (shipped in ``sample_data/``, from pyuff, MIT): three measured accelerance
  FRFs of one structure, 0-1000 Hz, 1001 lines.
* ``impact_hammer.lvm`` (``--data``, default ``../shared/data``; from the PyPI sdist
  ``pyfrf==1.1.4``, path ``data/impact2_response0.lvm``, MIT): a measured hammer test, turned
  into an FRF by ``ami_xr.read_lvm`` and ``ami_xr.impact_frf`` (the double and the clipped hit
  rejected), identified on the tool's default band (force and coherence valid).
* ``mass-loaded beam`` (simulated, measured-like): five modes of a free-free beam at 12 points
  and 15 000 lines, each FRF seeing every mode shifted by its own amount up to +-0.05 %
  (a roving accelerometer's mass, drift between measurements) and 0.1 % noise -- what makes a
  measured peak no single pole's. Every mode is single: two identified modes within 1 % of one
  true mode are a phantom split.

Each set is identified with ``ami_xr.identify`` (defaults; numba kernels compiled and cached
before any clock starts) and with sdypy-EMA's LSCF (``pol_order_high=30``, 60 roots, the
stable poles of the chart picked automatically as in ``scripts/bench_peers.py``) + LSFD on the
band ``identify`` analysed. Both are timed with ``time.perf_counter``, best of ``--repeats``
runs, first idle, then with one competing CPU-bound process that the script starts (a busy
loop in another interpreter) and stops. Printed per set and condition: lines, points, seconds
of each, the ratio ami_xr / LSCF, modes found by each, ami_xr's fits on all lines
(``refine_full_fits``) and the pairs of ami_xr modes closer than 1 % in frequency.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import subprocess
import sys
import time
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

import ami_xr
from ami_xr import names

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_peers  # noqa: E402  (the LSCF pole picking shared with the peer benchmark)

PAIR_REL = 0.01
BEAM_FN = np.array([176.0, 476.0, 932.0, 1535.0, 2286.0])  # Hz
BEAM_ZETA, BEAM_SHIFT, BEAM_NOISE = 0.002, 5e-4, 1e-3


class MeasuredSet(NamedTuple):
    name: str
    frf: object  # xarray.Dataset
    true_fn: np.ndarray | None  # Hz, known only for the simulated set


def mass_loaded_beam(n_point: int = 12, n_line: int = 15_000, seed: int = 0):
    """The simulated measured-like set of the module docstring: ``(frf Dataset, true fn)``."""
    rng = np.random.default_rng(seed)
    freq = np.linspace(50.0, 2600.0, n_line)
    s = 2j * np.pi * freq
    phi = rng.standard_normal((n_point, BEAM_FN.size))
    frf = np.zeros((n_point, n_line), complex)
    for j in range(n_point):
        wn = 2 * np.pi * BEAM_FN * (1 + BEAM_SHIFT * rng.uniform(-1, 1))
        lam = -BEAM_ZETA * wn + 1j * wn * np.sqrt(1 - BEAM_ZETA**2)
        res = lam * phi[j] * phi[0]
        frf[j] = np.sum(res / (s[:, None] - lam) + res.conj() / (s[:, None] - lam.conj()), 1)
    level = BEAM_NOISE * np.abs(frf).max(axis=1, keepdims=True)
    frf += level * (rng.standard_normal(frf.shape) + 1j * rng.standard_normal(frf.shape))
    ds = ami_xr.make_frf_dataset(frf, freq, drive_point=0, response_quantity="displacement")
    return ds, BEAM_FN


def hammer_frf(path: Path):
    """The hammer test's FRF as ``ami-xr frf`` makes it (warnings about rejected hits muted)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ami_xr.impact_frf(ami_xr.read_lvm(path))


def measured_sets(data: Path, quick: bool) -> list[MeasuredSet]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = [
            MeasuredSet(
                "measurement.uff", ami_xr.read_uff(REPO / "sample_data" / "measurement.uff"), None
            )
        ]
    if quick:
        return out
    lvm = data / "impact_hammer.lvm"
    if lvm.is_file():
        out.append(MeasuredSet("impact_hammer.lvm", hammer_frf(lvm), None))
    else:
        print(f"(skipped impact_hammer.lvm: not found in {data})")
    beam, fn = mass_loaded_beam()
    out.append(MeasuredSet("mass-loaded beam (sim.)", beam, fn))
    return out


def run_ami(frf) -> tuple[float, object]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        modes = ami_xr.identify(frf)
        return time.perf_counter() - t0, modes


def run_lscf(ema, frf, band: tuple[float, float]) -> tuple[float, np.ndarray]:
    """sdypy-EMA LSCF (60 roots) + automatic stable-pole pick + LSFD on ``band`` (Hz)."""
    sel = frf[names.FRF].sel({names.FREQUENCY: slice(*band)})
    h = np.ascontiguousarray(sel.transpose(names.POINT, names.FREQUENCY).values)
    f = sel[names.FREQUENCY].values
    lower, upper = float(f[1]), float(f[-1])
    form = {"displacement": "receptance", "velocity": "mobility", "acceleration": "accelerance"}
    kind = form.get(str(frf.attrs.get(names.ATTR_QUANTITY, "displacement")), "receptance")
    with warnings.catch_warnings(), contextlib.redirect_stderr(io.StringIO()):
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        model = ema.Model(
            h, f, lower=lower, upper=upper, pol_order_high=bench_peers.LSCF_ORDER, frf_form=kind
        )
        model.get_poles(method="lscf", show_progress=False)
        last = len(model.all_poles) - 1
        lam = bench_peers._lsfd(
            model, bench_peers.stable_poles(model.all_poles, lower, upper), last
        )
        return time.perf_counter() - t0, np.sort(np.abs(lam)) / (2 * np.pi)


def close_pairs(fn: np.ndarray) -> int:
    fn = np.sort(fn)
    return int(np.sum(np.diff(fn) < PAIR_REL * fn[:-1]))


@contextlib.contextmanager
def competing_process():
    """One CPU-bound process beside the benchmark (a busy loop in another interpreter)."""
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.5)  # let it start spinning
        yield
    finally:
        proc.kill()
        proc.wait()


def measure(sets, ema, repeats: int, label: str) -> list[float]:
    ratios = []
    for s in sets:
        t_ami, modes = min((run_ami(s.frf) for _ in range(repeats)), key=lambda r: r[0])
        fn = np.sort(modes[names.NATURAL_FREQUENCY].values)
        band = (float(modes.attrs[names.ATTR_BAND_FMIN]), float(modes.attrs[names.ATTR_BAND_FMAX]))
        n_line = int(modes.sizes[names.FREQUENCY]) if names.FREQUENCY in modes.sizes else 0
        full = modes.attrs.get("refine_full_fits", "-")  # (absent before it was recorded)
        line = (
            f"{label:7s} {s.name:26s} {s.frf.sizes[names.POINT]:3d} x {n_line:6d} "
            f"{band[0]:7.1f}-{band[1]:7.1f} Hz  ami_xr {t_ami:7.2f} s {fn.size:3d} modes "
            f"{full!s:>3} full fits {close_pairs(fn):2d} pairs<1%"
        )
        if s.true_fn is not None:
            split = sum(int(np.sum(np.abs(fn - f) < PAIR_REL * f) > 1) for f in s.true_fn)
            line += f" phantom splits {split}"
        if ema is not None:
            t_lscf, fn_lscf = min(
                (run_lscf(ema, s.frf, band) for _ in range(repeats)), key=lambda r: r[0]
            )
            ratios.append(t_ami / t_lscf)
            line += f" | LSCF {t_lscf:6.2f} s {fn_lscf.size:3d} modes | ratio {t_ami / t_lscf:6.1f}"
        print(line, flush=True)
    return ratios


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(REPO.parent / "shared" / "data"))
    ap.add_argument("--no-peer", action="store_true", help="ami_xr alone (no sdypy-EMA)")
    ap.add_argument("--quick", action="store_true", help="the shipped set only, idle only")
    ap.add_argument("--repeats", type=int, default=2, help="best of this many runs (default 2)")
    args = ap.parse_args(argv)
    ema = None if args.no_peer else bench_peers.import_peer()
    sets = measured_sets(Path(args.data), args.quick)
    # compile and cache the kernels before any clock starts
    run_ami(ami_xr.simulate.benchmark(noise=0.15, seed=0)[1])
    print(
        f"ami_xr {getattr(ami_xr, '__version__', '')}; best of {args.repeats}; 1 competing "
        "process when 'loaded'"
    )
    idle = measure(sets, ema, args.repeats, "idle")
    loaded = []
    if not args.quick:
        with competing_process():
            loaded = measure(sets, ema, args.repeats, "loaded")
    for label, r in (("idle", idle), ("loaded", loaded)):
        if r:
            print(f"time ratio ami_xr / LSCF, {label}: max {max(r):.1f}, median {np.median(r):.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
