"""ami_xr against a peer: ``identify`` and sdypy-EMA's LSCF + LSFD on the same data, one run.

    pip install ami_xr[bench]                    # sdypy-EMA, only for this script
    python scripts/bench_peers.py                # 32 random systems, both methods
    python scripts/bench_peers.py --quick --no-peer   # 2 tiny systems, ami_xr only (smoke test)
    python scripts/bench_peers.py --large        # 1000 points x 2048 lines, 12 modes (issue 21)

The data: a fixed set of ``--systems`` (default 32) random lumped-mass systems from
:func:`ami_xr.simulate.random_system`, the same for the same ``--seed`` (drawn from
``numpy.random.default_rng(seed)``): chains and grids alternately, 5-50 measured points,
3000-6000 frequency lines, 4-12 true modes in the band, noise 1, 2, 3 or 5 % (eq. 15 on the
real and imaginary parts of the analytic receptances). ``random_system`` has as many modes as
measured points, so the band is cut instead: the lines run from 0 Hz to midway between the
n-th and the (n+1)-th natural frequency (to ``max_frequency_hz`` when n is every mode), and the
true modes are the n inside it; the modes above leave their residual in the band, as in a
measurement. The structures are scaled to a highest natural frequency of 800 Hz
(``max_frequency_hz=1000``), because sdypy-EMA's ``select_closest_poles`` narrows its search
window down to an absolute 2 Hz.

The methods, each warmed once on a small system before anything is timed (numba compilation of
ami_xr excluded), then timed with ``time.perf_counter`` on one run per system:

* **ami_xr**: ``ami_xr.identify(frf)`` with its defaults, on the Dataset.
* **sdypy-EMA** (LSCF order 30 + LSFD): ``sdypy.EMA.Model(H, f, lower=f[1], upper=f[-1],
  pol_order_high=30, frf_form="receptance")``, ``get_poles(method="lscf")``, pole selection,
  ``get_constants(method="lsfd")``; ``H`` (points x lines) is taken from the Dataset before the
  clock starts. sdypy-EMA (0.31) has no automatic pole selection: ``select_poles`` opens the
  interactive stabilization chart and ``select_closest_poles`` needs approximate natural
  frequencies. So two selections are timed and printed:

  - ``auto`` (the fair one, used for the ratio): the stable poles of the chart, automated. A
    pole of the highest order (60 roots) is kept when its frequency lies inside the band, its
    damping ratio is in (0, 0.2), and it is "stable frequency, stable damping" by the chart's
    own default tolerances (0.1 % in frequency, 5 % in damping ratio, relative to the lower
    order) against the nearest pole of each of the 5 orders below it, followed down order by
    order. The rule matters little: asking stability against one order only instead of five
    finds 39 instead of 34 of the 52 true modes of the first 8 systems (seed 0); the order-30
    fit itself misses the rest.
  - ``oracle``: ``select_closest_poles`` given the TRUE natural frequencies in the band. This
    favours sdypy-EMA (it is told how many modes there are and where); its time includes the
    same pole computation and LSFD.

Scoring (:func:`ami_xr.simulate.score_modes`): an identified mode matches a true one when
``|lam_id - lam_true| < |Re lam_true|`` (half the half-power bandwidth), one-to-one, nearest
first. Per system: points, lines, true modes, noise, seconds of each method, modes found by
each, and the largest relative error of natural frequency and damping ratio over the matched
modes. Totals: the sums of times, the ratio ami_xr / sdypy-EMA, found / true for each and the
spurious (unmatched identified) modes. Written against ami_xr's public API only.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import os
import sys
import time
import warnings
from typing import NamedTuple

import numpy as np

import ami_xr
from ami_xr.simulate import random_system, score_modes

N_SYSTEMS = 32
POINTS, LINES, MODES = (5, 50), (3000, 6000), (4, 12)  # inclusive ranges
NOISE_LEVELS = (0.01, 0.02, 0.03, 0.05)
QUICK_POINTS, QUICK_LINES, QUICK_MODES = (5, 8), (600, 800), (4, 4)
MAX_FREQUENCY_HZ = 1000.0
LSCF_ORDER = 30  # sdypy's pol_order_high: orders 2, 4, ..., 60 roots
STABLE_ORDERS = 5  # auto selection: stable against each of this many lower orders
FN_TOL, XI_TOL = 0.001, 0.05  # sdypy's stabilization-chart defaults
XI_MAX = 0.2
PEER_MISSING = (
    "bench_peers.py: sdypy-EMA is not installed; pip install ami_xr[bench] "
    "(or run with --no-peer for ami_xr alone)"
)


class System(NamedTuple):
    """One benchmark system: the arguments of ``random_system`` and the band's mode count."""

    index: int
    topology: str
    n_points: int
    n_lines: int
    n_modes: int  # true modes in the band
    noise: float
    seed: int

    def build(self) -> tuple[object, np.ndarray]:
        """``(frf Dataset, true eigenvalues in the band)``."""
        common = {"seed": self.seed, "max_frequency_hz": MAX_FREQUENCY_HZ}
        _, truth = random_system(self.n_points, self.topology, n_frequencies=2, **common)
        fn = np.sort(truth["natural_frequency"].values)
        k = self.n_modes
        edge = MAX_FREQUENCY_HZ if k == fn.size else 0.5 * (fn[k - 1] + fn[k])
        frf, truth = random_system(
            self.n_points,
            self.topology,
            noise=self.noise,
            frequency=np.linspace(0.0, edge, self.n_lines),
            **common,
        )
        lam = truth["eigenvalue"].values
        lam = lam[np.abs(lam) / (2 * np.pi) < edge]
        assert lam.size == k, (lam.size, k)
        return frf, lam


def systems(n: int = N_SYSTEMS, seed: int = 0, quick: bool = False) -> list[System]:
    """The fixed benchmark set: ``n`` systems, the same for the same ``seed``."""
    rng = np.random.default_rng(seed)
    points, lines, modes = (
        (QUICK_POINTS, QUICK_LINES, QUICK_MODES)
        if quick
        else (
            POINTS,
            LINES,
            MODES,
        )
    )
    out = []
    for i in range(n):
        n_points = int(rng.integers(points[0], points[1] + 1))
        n_lines = int(rng.integers(lines[0], lines[1] + 1))
        n_modes = int(rng.integers(modes[0], min(modes[1], n_points) + 1))
        noise = float(rng.choice(NOISE_LEVELS))
        topology = ("chain", "grid")[i % 2]
        out.append(System(i, topology, n_points, n_lines, n_modes, noise, int(rng.integers(2**31))))
    return out


class Result(NamedTuple):
    seconds: float
    found: int
    spurious: int
    fn_error: float  # max relative error over matched modes (NaN when none)
    zeta_error: float
    failed: str = ""


def score(lam_identified, lam_true: np.ndarray, seconds: float, failed: str = "") -> Result:
    """Match and measure (one-to-one, ``|lam_id - lam| < |Re lam|``)."""
    s = score_modes(np.asarray(lam_identified, dtype=complex), lam_true)
    fn = float(s.frequency_error.max()) if s.n_found else float("nan")
    zeta = float(s.damping_error.max()) if s.n_found else float("nan")
    return Result(seconds, s.n_found, s.n_spurious, fn, zeta, failed)


def run_ami(frf, lam_true: np.ndarray) -> Result:
    failed = ""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        try:
            lam = ami_xr.identify(frf)["eigenvalue"].values
        except ami_xr.AmiXrError as err:
            lam, failed = np.array([], dtype=complex), str(err).splitlines()[0]
        seconds = time.perf_counter() - t0
    return score(lam, lam_true, seconds, failed)


def _freq_damp(poles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sdypy's convention (``tools.complex_freq_to_freq_and_damp``): Hz signed by Im, zeta."""
    fr = np.sign(poles.imag) * np.abs(poles)
    fr[fr == 0] = -1e-10
    return fr / (2 * np.pi), -poles.real / fr


def stable_poles(all_poles, lower: float, upper: float) -> np.ndarray:
    """Indices into ``all_poles[-1]`` of the poles the ``auto`` rule keeps (module docstring)."""
    sets = []
    for poles in all_poles[-(STABLE_ORDERS + 1) :]:
        fr, xi = _freq_damp(np.asarray(poles))
        sets.append((fr, xi, (fr > lower) & (fr < upper) & (xi > 0) & (xi < XI_MAX)))
    fr, xi, keep = sets[-1]
    index = np.flatnonzero(keep)
    cur_f, cur_x = fr[index], xi[index]
    ok = np.ones(index.size, bool)
    for pf, px, pk in reversed(sets[:-1]):
        pf, px = pf[pk], px[pk]
        if pf.size == 0 or index.size == 0:
            return np.array([], dtype=int)
        j = np.argmin(np.abs(cur_f[:, None] - pf[None, :]), axis=1)
        ok &= (np.abs(cur_f - pf[j]) < FN_TOL * pf[j]) & (np.abs(cur_x - px[j]) < XI_TOL * px[j])
        cur_f, cur_x = pf[j], px[j]
    return index[ok]


def _lsfd(model, pole_index: np.ndarray, order: int) -> np.ndarray:
    """LSFD on the chosen poles of ``model.all_poles[order]``; their eigenvalues."""
    if pole_index.size == 0:
        return np.array([], dtype=complex)
    model.pole_ind = np.column_stack([np.full(pole_index.size, order), pole_index])
    model.get_constants(method="lsfd")
    lam = np.asarray(model.all_poles[order])[pole_index]
    return np.where(lam.imag < 0, lam.conj(), lam)


def run_sdypy(ema, frf, lam_true: np.ndarray) -> tuple[Result, Result]:
    """(auto, oracle) results of sdypy-EMA's LSCF + LSFD on ``frf``."""
    h = np.ascontiguousarray(frf["frf"].transpose("point", "frequency").values)
    f = frf["frequency"].values
    lower, upper = float(f[1]), float(f[-1])
    with warnings.catch_warnings(), contextlib.redirect_stderr(io.StringIO()):
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        model = ema.Model(
            h, f, lower=lower, upper=upper, pol_order_high=LSCF_ORDER, frf_form="receptance"
        )
        model.get_poles(method="lscf", show_progress=False)
        t_poles = time.perf_counter() - t0
        last = len(model.all_poles) - 1

        t0 = time.perf_counter()
        lam_auto = _lsfd(model, stable_poles(model.all_poles, lower, upper), last)
        t_auto = time.perf_counter() - t0

        t0 = time.perf_counter()
        failed = ""
        try:
            model.select_closest_poles(np.abs(lam_true) / (2 * np.pi))
            model.get_constants(method="lsfd")
            idx = np.asarray(model.pole_ind, dtype=int)
            lam_oracle = np.array([model.all_poles[i][j] for i, j in idx])
            lam_oracle = np.where(lam_oracle.imag < 0, lam_oracle.conj(), lam_oracle)
        except Exception as err:  # noqa: BLE001 - a peer's failure is a result, not a crash
            lam_oracle, failed = np.array([], dtype=complex), f"{type(err).__name__}: {err}"
        t_oracle = time.perf_counter() - t0
    return (
        score(lam_auto, lam_true, t_poles + t_auto),
        score(lam_oracle, lam_true, t_poles + t_oracle, failed),
    )


def import_peer():
    """``sdypy.EMA``, or None when it is not installed."""
    try:
        return importlib.import_module("sdypy.EMA")
    except ImportError:
        return None


def _err(x: float) -> str:
    return "-" if not np.isfinite(x) else f"{x:.0e}"


def header(peer: bool) -> str:
    line = (
        f"{'system':<10}{'pts':>4}{'lines':>6}{'modes':>6}{'noise':>6}"
        f"{'t ami':>8}{'found':>6}{'fn err':>8}{'zeta err':>9}"
    )
    if peer:
        line += (
            f" |{'t sdypy':>8}{'found':>6}{'fn err':>8}{'zeta err':>9}"
            f" |{'t oracle':>9}{'found':>6}{'fn err':>8}{'zeta err':>9}"
        )
    return line


def row(system: System, ami: Result, auto: Result | None, oracle: Result | None) -> str:
    name = f"{system.index:02d}-{system.topology}"
    line = (
        f"{name:<10}{system.n_points:>4}{system.n_lines:>6}{system.n_modes:>6}"
        f"{100 * system.noise:>5.0f}%{ami.seconds:>8.2f}{ami.found:>6}"
        f"{_err(ami.fn_error):>8}{_err(ami.zeta_error):>9}"
    )
    if auto is not None and oracle is not None:
        line += (
            f" |{auto.seconds:>8.2f}{auto.found:>6}{_err(auto.fn_error):>8}"
            f"{_err(auto.zeta_error):>9}"
            f" |{oracle.seconds:>9.2f}{oracle.found:>6}{_err(oracle.fn_error):>8}"
            f"{_err(oracle.zeta_error):>9}"
        )
    failed = [r.failed for r in (ami, auto, oracle) if r is not None and r.failed]
    return line + (f"  FAILED: {failed[0]}" if failed else "")


def total_line(label: str, results: list[Result], n_true: int) -> str:
    seconds = sum(r.seconds for r in results)
    found = sum(r.found for r in results)
    spurious = sum(r.spurious for r in results)
    fn = max((r.fn_error for r in results if np.isfinite(r.fn_error)), default=float("nan"))
    zeta = max((r.zeta_error for r in results if np.isfinite(r.zeta_error)), default=float("nan"))
    return (
        f"  {label:<26} time {seconds:8.2f} s   found {found:4d}/{n_true} "
        f"({100 * found / n_true:5.1f} %)   spurious {spurious:4d}   "
        f"max rel. error fn {_err(fn)}, zeta {_err(zeta)}"
    )


def _warm(ema) -> None:
    """One throw-away call of each method on a small system (numba compiles here)."""
    frf, lam = systems(1, seed=12345, quick=True)[0].build()
    run_ami(frf, lam)
    if ema is not None:
        run_sdypy(ema, frf, lam)


LARGE = (1000, 2048, 12)  # points, lines, modes of the issue-21 case


def large_case(ema, n_points: int, n_lines: int, n_modes: int, repeats: int = 3) -> int:
    """The many-points case of issue 21: ``n_points`` x ``n_lines``, ``n_modes`` modes
    (:func:`ami_xr.simulate.spread.many_points`, 2 % noise), both methods on the same data in
    this run; the best of ``repeats`` timings of each (the machine may be shared), the ratio."""
    from ami_xr.simulate.spread import many_points

    frf, truth = many_points(n_points, n_lines, n_modes, noise=0.02, seed=0)
    lam = truth["eigenvalue"].values
    small, small_truth = many_points(250, 256, 5, noise=0.02, seed=1)
    run_ami(small, small_truth["eigenvalue"].values)  # warm: compile the compressed path
    amis = [run_ami(frf, lam) for _ in range(repeats)]
    ami = min(amis, key=lambda r: r.seconds)
    print(
        f"large case: {n_points} points x {n_lines} lines, {n_modes} true modes, 2 % noise "
        f"(best of {repeats})"
    )
    print(header(ema is not None), flush=True)
    system = System(0, "spread", n_points, n_lines, n_modes, 0.02, 0)
    auto = oracle = None
    if ema is not None:
        runs = [run_sdypy(ema, frf, lam) for _ in range(repeats)]
        auto = min((r[0] for r in runs), key=lambda r: r.seconds)
        oracle = min((r[1] for r in runs), key=lambda r: r.seconds)
    print(row(system, ami, auto, oracle))
    if auto is not None:
        print(
            f"  time ami_xr {ami.seconds:.2f} s, sdypy-EMA (auto) {auto.seconds:.2f} s, "
            f"ratio {ami.seconds / auto.seconds:.2f}"
        )
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--systems", type=int, default=None, help="number of systems (32)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the system set")
    parser.add_argument("--quick", action="store_true", help="2 tiny systems (unless --systems)")
    parser.add_argument("--no-peer", action="store_true", help="ami_xr only (no sdypy-EMA)")
    parser.add_argument(
        "--large",
        action="store_true",
        help="only the issue-21 case: 1000 points x 2048 lines, 12 modes (--points etc.)",
    )
    parser.add_argument("--points", type=int, default=LARGE[0], help="points of --large")
    parser.add_argument("--lines", type=int, default=LARGE[1], help="lines of --large")
    parser.add_argument("--modes", type=int, default=LARGE[2], help="modes of --large")
    args = parser.parse_args(argv)
    ema = None
    if not args.no_peer:
        ema = import_peer()
        if ema is None:
            print(PEER_MISSING, file=sys.stderr)
            return 2
    if args.large:
        return large_case(ema, args.points, args.lines, args.modes)
    n = args.systems if args.systems is not None else (2 if args.quick else N_SYSTEMS)
    if n < 1:
        parser.error(f"--systems: expected an integer >= 1, got {n}")
    bench = systems(n, args.seed, quick=args.quick)
    cpus = os.cpu_count()
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else cpus
    from importlib.metadata import PackageNotFoundError, version

    def _version(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "?"

    print(
        f"bench_peers: {n} random systems (seed {args.seed}{', quick' if args.quick else ''}); "
        f"cpu_count {cpus} (usable {usable}); ami_xr {_version('ami_xr')}"
        + ("" if ema is None else f", sdypy-EMA {_version('sdypy-EMA')} LSCF order {LSCF_ORDER}")
    )
    _warm(ema)
    print("errors: max relative error of matched modes; found: matched one-to-one to true modes")
    print(header(ema is not None), flush=True)
    n_true, amis, autos, oracles = 0, [], [], []
    for system in bench:
        frf, lam = system.build()
        n_true += lam.size
        amis.append(run_ami(frf, lam))
        auto = oracle = None
        if ema is not None:
            auto, oracle = run_sdypy(ema, frf, lam)
            autos.append(auto)
            oracles.append(oracle)
        print(row(system, amis[-1], auto, oracle), flush=True)

    print(f"\nTotals over {n} systems, {n_true} true modes")
    print(total_line("ami_xr.identify", amis, n_true))
    if ema is not None:
        print(total_line("sdypy-EMA LSCF+LSFD, auto", autos, n_true))
        print(total_line("sdypy-EMA, oracle poles", oracles, n_true))
        t_ami = sum(r.seconds for r in amis)
        t_auto = sum(r.seconds for r in autos)
        t_oracle = sum(r.seconds for r in oracles)
        print(f"  time ratio ami_xr / sdypy-EMA (auto):   {t_ami / t_auto:.2f}")
        print(f"  time ratio ami_xr / sdypy-EMA (oracle): {t_ami / t_oracle:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
