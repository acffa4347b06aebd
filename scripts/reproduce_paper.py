"""Reproduce Ginsberg & Allen's benchmark (Tables 1-6, the 15 % noise study) and beat it.

    python scripts/reproduce_paper.py                 # 50 seeds, noise 15 % and 5 %, noise-free
    python scripts/reproduce_paper.py --quick         # 10 seeds, no speed section
    python scripts/reproduce_paper.py --seeds 200 --noise 0.15

Prints, side by side with the paper's numbers:

1. Tables 1-6 for one noise seed: per-FRF eigenvalues with x marks, averages, analytical values
   and errors (the paper's AMI, ``method="paper"``), then the refined eigenvalues; mode vectors
   identified vs exact (the tip displacement; the paper's row q1 is a Ritz coordinate, 0.41345
   times smaller at the tip -- see ami_xr.simulate.beam).
2. A Monte Carlo over noise seeds for each noise level: the fraction of seeds in which all four
   modes were found with no spurious mode; mean, median and signed mean errors per mode of
   natural frequency (%) and damping ratio (%), and the mode-vector error
   ``|phi - phi_true| / |phi_true|`` (up to the sign of eq. 8's square root), for the paper's AMI,
   SIMO AMI without refinement and the default (refined) method; the Cramér-Rao bound and the
   paper's figures next to them; time per identification.
3. Speed: compile time (fresh numba cache, in a subprocess), one benchmark identification after
   compilation, and 1000 points x 2048 lines of a simulated system with 6-12 modes.

Uses the public API only.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np
from scipy.optimize import linear_sum_assignment

import ami_xr
import ami_xr.ami as ami_xr_ami
from ami_xr.simulate import paper as published

# The Cramér-Rao bound stated in issue 3 (%, expected absolute error) -- recomputed below.
ISSUE_CRB = {
    "fn": [0.045, 0.067, 0.012, 0.024],
    "zeta": [3.0, 4.5, 2.0, 2.7],
    "mv": [np.nan, np.nan, 3.5, 4.7],
}
METHODS = {  # label -> identify keyword arguments
    "paper": {"method": "paper"},
    "simo": {"method": "simo", "refine": False},
    "refined": {},
}
TARGET_FACTOR = 1.3
# ami_xr.identify (the package export) is ami_xr.ami.identify
IDENTIFY = getattr(ami_xr, "identify", None) or ami_xr_ami.identify


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------
def fmt_c(z, digits=5):
    if z is None or not np.isfinite(z):
        return "x".center(20)
    return f"{z.real:.{digits}f}{z.imag:+.{digits - 1}f}i".rjust(20)


def match_modes(lam_id, lam_true):
    """Pair identified and true modes (one-to-one); a pair counts within one bandwidth."""
    if lam_id.size == 0:
        return {}
    cost = np.abs(lam_id[:, None] - lam_true[None, :]) / np.abs(lam_true.real)[None, :]
    rows, cols = linear_sum_assignment(cost)
    return {int(c): int(r) for r, c in zip(rows, cols, strict=True) if cost[r, c] < 2.0}


def mode_vector_error(phi, phi_true):
    n = np.linalg.norm(phi_true)
    return min(np.linalg.norm(phi - phi_true), np.linalg.norm(phi + phi_true)) / n


def identify(frf, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ami_xr.ConvergenceWarning)
        warnings.simplefilter("ignore", ami_xr.NoModesWarning)
        warnings.simplefilter("ignore", RuntimeWarning)  # nan-statistics of undetected modes
        return IDENTIFY(frf, **kwargs)


def per_frf_eigenvalues(result):
    """The per-FRF eigenvalues (point, mode) of the Isolation Phase, NaN where not detected."""
    for name, var in result.data_vars.items():
        if (
            set(var.dims) == {"point", "mode"}
            and np.iscomplexobj(var.values)
            and "eigenvalue" in name
        ):
            return var.transpose("point", "mode").values
    return None


# ------------------------------------------------------------------------------------------
# 1. Tables 1-6 for one seed
# ------------------------------------------------------------------------------------------
def tables(seed: int) -> None:
    _, frf, truth = ami_xr.simulate.benchmark(noise=0.15, seed=seed)
    lam_t = truth["eigenvalue"].values
    print(f"== Tables 1-2 equivalent: eigenvalues (rad/s) per FRF, 15 % noise, seed {seed} ==")
    for label, kwargs in (
        ("paper AMI (method='paper')", METHODS["paper"]),
        ("refined (default)", METHODS["refined"]),
    ):
        res = identify(frf, **kwargs)
        lam = res["eigenvalue"].values
        pairs = match_modes(lam, lam_t)
        print(f"-- {label}: {lam.size} modes identified")
        print(
            " " * 12
            + "".join(f"{'mode ' + str(k + 1):>20s}" for k in range(4))
            + "   | paper "
            + "".join(f"{'mode ' + str(k + 1):>20s}" for k in range(4))
        )
        per = per_frf_eigenvalues(res) if kwargs.get("method") == "paper" else None
        points = list(frf["point"].values)
        if per is not None:
            for j, p in enumerate(points):
                row = [
                    per[j, pairs[k]] if k in pairs and np.isfinite(per[j, pairs[k]]) else None
                    for k in range(4)
                ]
                print(
                    f"  G_{p:<8s}"
                    + "".join(fmt_c(z) for z in row)
                    + "   |       "
                    + "".join(fmt_c(z) for z in published.AMI_PER_FRF_EIGENVALUES[j])
                )
        ours = [lam[pairs[k]] if k in pairs else None for k in range(4)]
        print(
            "  result    "
            + "".join(fmt_c(z) for z in ours)
            + "   |       "
            + "".join(fmt_c(z) for z in published.AMI_EIGENVALUES)
        )
        print(
            "  analytic  "
            + "".join(fmt_c(z) for z in lam_t)
            + "   |       "
            + "".join(fmt_c(z) for z in published.ANALYTICAL_EIGENVALUES)
        )
        err = [
            "x"
            if z is None
            else f"{100 * (z.real - t.real) / t.real:.2f}{100 * (z.imag - t.imag) / t.imag:+.4f}i"
            for z, t in zip(ours, lam_t, strict=True)
        ]
        print(
            "  error (%) "
            + "".join(f"{e:>20s}" for e in err)
            + "   |       "
            + "".join(f"{e:>20s}" for e in published.AMI_EIGENVALUE_ERRORS)
        )
        if "eigenvalue_std" in res:
            std = res["eigenvalue_std"].values
            print(
                "  std       "
                + "".join(fmt_c(std[pairs[k]]) if k in pairs else fmt_c(None) for k in range(4))
                + "   | (Gauss-Newton standard errors of the real and imaginary parts)"
            )
        if "quality_flags" in res:
            flags = ami_xr.flag_text(res["quality_flags"].values)
            print(
                "  flags: "
                + "; ".join(
                    f"mode {k + 1}: {str(flags[pairs[k]]) or '-'}" for k in range(4) if k in pairs
                )
            )
        print(
            "== Tables 3-6 equivalent: mode vectors x 1e6 (identified | exact | paper's AMI, "
            f"row q1 converted to the tip), {label} =="
        )
        phi_t = truth["mode_vector"].transpose("point", "mode").values
        phi = res["mode_vector"].transpose("point", "mode").values
        # The paper's row q1 is the first Ritz coordinate; the tip displacement is output[0, 0] q1.
        paper_ami = published.AMI_MODE_VECTORS.copy()
        paper_ami[0] *= ami_xr.simulate.beam_absorbers(1, basis="mass")[3][0, 0]
        for k in range(4):
            if k not in pairs:
                print(f"  mode {k + 1}: not found")
                continue
            ph = phi[:, pairs[k]]
            closer = np.linalg.norm(ph - phi_t[:, k]) <= np.linalg.norm(ph + phi_t[:, k])
            sign = 1.0 if closer else -1.0
            e = mode_vector_error(ph, phi_t[:, k])
            print(
                f"  mode {k + 1}: error {100 * e:.1f} %   (paper: "
                + (f"{published.AMI_MODE_VECTOR_ERRORS[k - 2]} %" if k >= 2 else "> 1000 %")
                + ")"
            )
            for j, p in enumerate(points):
                print(
                    f"    {p:>4s} {fmt_c(1e6 * sign * ph[j], 2)} | {fmt_c(1e6 * phi_t[j, k], 2)}"
                    f"   paper AMI {fmt_c(1e6 * paper_ami[j, k], 2)}"
                )
    print()


# ------------------------------------------------------------------------------------------
# 2. Monte Carlo
# ------------------------------------------------------------------------------------------
def monte_carlo(noise: float, seeds: int) -> dict:
    _, frf0, truth = ami_xr.simulate.benchmark(noise=max(noise, 0.15), seed=0)
    lam_t = truth["eigenvalue"].values
    fn_t = np.abs(lam_t)
    zeta_t = -lam_t.real / fn_t
    phi_t = truth["mode_vector"].transpose("point", "mode").values
    crb = ami_xr.cramer_rao_bound(truth, frf0, noise_level=noise) if noise > 0 else None
    stats = {
        m: {
            "ok": 0,
            "fn": [],
            "zeta": [],
            "mv": [],
            "t": [],
            "found": np.zeros(4),
            "flag_dp": np.zeros(4),
        }
        for m in METHODS
    }
    n_seeds = seeds if noise > 0 else 1
    for seed in range(n_seeds):
        _, frf, _ = ami_xr.simulate.benchmark(noise=noise, seed=1000 + seed)
        for m, kwargs in METHODS.items():
            t0 = time.perf_counter()
            res = identify(frf, **kwargs)
            stats[m]["t"].append(time.perf_counter() - t0)
            lam = res["eigenvalue"].values
            pairs = match_modes(lam, lam_t)
            phi = res["mode_vector"].transpose("point", "mode").values
            if len(pairs) == 4 and lam.size == 4:
                stats[m]["ok"] += 1
            fn = np.full(4, np.nan)
            ze = np.full(4, np.nan)
            mv = np.full(4, np.nan)
            for k, i in pairs.items():
                stats[m]["found"][k] += 1
                fn[k] = 100 * (np.abs(lam[i]) - fn_t[k]) / fn_t[k]
                ze[k] = 100 * (-lam[i].real / np.abs(lam[i]) - zeta_t[k]) / zeta_t[k]
                mv[k] = 100 * mode_vector_error(phi[:, i], phi_t[:, k])
                if "quality_flags" in res and "drive" in str(
                    ami_xr.flag_text(res["quality_flags"].values)[i]
                ):
                    stats[m]["flag_dp"][k] += 1
            stats[m]["fn"].append(fn)
            stats[m]["zeta"].append(ze)
            stats[m]["mv"].append(mv)
    report(noise, n_seeds, stats, crb)
    return stats


def report(noise, n_seeds, stats, crb):
    head = "noise-free" if noise == 0 else f"{100 * noise:g} % noise (eq. 15), {n_seeds} seeds"
    print(f"== Monte Carlo: {head} ==")
    if crb is not None:
        c_fn = 100 * crb["natural_frequency_error"].values
        c_z = 100 * crb["damping_ratio_error"].values
        c_mv = 100 * crb["mode_vector_error"].values
        print("  Cramér-Rao bound (expected |error|, %):")
        print(
            "    natural frequency "
            + " ".join(f"{v:8.4f}" for v in c_fn)
            + "   (issue: "
            + ", ".join(f"{v:g}" for v in ISSUE_CRB["fn"])
            + ")"
        )
        print(
            "    damping ratio     "
            + " ".join(f"{v:8.3f}" for v in c_z)
            + "   (issue: "
            + ", ".join(f"{v:g}" for v in ISSUE_CRB["zeta"])
            + ")"
        )
        print(
            "    mode vector       "
            + " ".join(f"{v:8.3g}" for v in c_mv)
            + "   (issue: modes 3, 4: 3.5, 4.7; modes 1, 2: linearised bound meaningless, "
            "drive-point residue below noise)"
        )
    for m, s in stats.items():
        fn, ze, mv = (np.array(s[key]) for key in ("fn", "zeta", "mv"))
        print(
            f"  -- {m}: all 4 modes and no spurious mode in {s['ok']}/{n_seeds} seeds "
            f"({100 * s['ok'] / n_seeds:.0f} %); found per mode "
            + "/".join(str(int(v)) for v in s["found"])
            + f"; median time per identification {1e3 * np.median(s['t']):.0f} ms"
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            rows = [
                ("f_n mean |err| %", np.nanmean(np.abs(fn), 0), "{:9.4f}"),
                ("f_n median |err| %", np.nanmedian(np.abs(fn), 0), "{:9.4f}"),
                ("f_n signed mean %", np.nanmean(fn, 0), "{:+9.4f}"),
                ("zeta mean |err| %", np.nanmean(np.abs(ze), 0), "{:9.3f}"),
                ("zeta median |err| %", np.nanmedian(np.abs(ze), 0), "{:9.3f}"),
                ("zeta signed mean %", np.nanmean(ze, 0), "{:+9.3f}"),
                ("mode vector mean %", np.nanmean(mv, 0), "{:9.3g}"),
                ("mode vector median %", np.nanmedian(mv, 0), "{:9.3g}"),
            ]
        for name, vals, f in rows:
            extra = ""
            if crb is not None and name.endswith("mean |err| %"):
                ref = c_fn if name.startswith("f_n") else c_z
                extra = "   ratio to CRB " + " ".join(f"{v:5.2f}" for v in vals / ref)
            if crb is not None and name == "mode vector mean %":
                extra = "   ratio to CRB (3, 4) " + " ".join(
                    f"{v:5.2f}" for v in vals[2:] / c_mv[2:]
                )
            print(
                f"    {name:22s}"
                + " ".join(f.format(v) for v in vals)
                + f"   avg {np.nanmean(vals):8.4g}"
                + extra
            )
        if noise == 0:
            worst = np.nanmax(np.abs(np.concatenate([fn, ze, mv], axis=None))) / 100
            print(
                f"    largest relative error (f_n, zeta, mode vectors 1-4): {worst:.1e}"
                + ("  < 1e-6" if worst < 1e-6 else "  NOT < 1e-6")
            )
        elif s["flag_dp"].any():
            print(
                "    drive-point flag per mode (seeds): "
                + "/".join(str(int(v)) for v in s["flag_dp"])
            )
        if crb is not None and m == "refined":
            ok_fn = np.nanmean(np.abs(fn), 0) <= TARGET_FACTOR * c_fn
            ok_z = np.nanmean(np.abs(ze), 0) <= TARGET_FACTOR * c_z
            ok_mv = np.nanmean(mv, 0)[2:] <= TARGET_FACTOR * c_mv[2:]
            ok_found = s["ok"] >= 0.95 * n_seeds
            print(
                f"    targets (mean |err| <= {TARGET_FACTOR} x CRB; >= 95 % seeds complete): "
                f"f_n {'met' if ok_fn.all() else 'NOT met ' + str(ok_fn)}, "
                f"zeta {'met' if ok_z.all() else 'NOT met ' + str(ok_z)}, "
                f"mode vectors 3-4 {'met' if ok_mv.all() else 'NOT met ' + str(ok_mv)}, "
                f"modes found {'met' if ok_found else 'NOT met'}"
            )
    if noise == 0.15:
        print(
            f"  paper (one seed): f_n average {published.AMI_MEAN_FREQUENCY_ERROR} %, damping "
            f"average {published.AMI_MEAN_DAMPING_ERROR} %, mode vectors 3, 4: "
            f"{published.AMI_MODE_VECTOR_ERRORS[0]} %, {published.AMI_MODE_VECTOR_ERRORS[1]} %; "
            "modes 1, 2 off by more than an order of magnitude"
        )
    print()


# ------------------------------------------------------------------------------------------
# 3. speed
# ------------------------------------------------------------------------------------------
_COMPILE_SNIPPET = """
import time, warnings
t0 = time.perf_counter()
import ami_xr
import ami_xr.ami
t1 = time.perf_counter()
_, frf, _ = ami_xr.simulate.benchmark(noise=0.15, seed=1)
t2 = time.perf_counter()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    ami_xr.ami.identify(frf)
t3 = time.perf_counter()
print(f"{t1 - t0:.3f} {t3 - t2:.3f}")
"""


_REFINE_SNIPPET = """
import time, warnings
import ami_xr
_, frf, truth = ami_xr.simulate.benchmark(noise=0.15, seed=1)
start = frf.assign(eigenvalue=truth["eigenvalue"] * 1.001)
t0 = time.perf_counter()
ami_xr.refine(start)
print(f"0 {time.perf_counter() - t0:.3f}")
"""


def first_call_seconds(cache_dir: str, snippet: str = _COMPILE_SNIPPET) -> tuple[float, float]:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    out = subprocess.run(
        [sys.executable, "-c", snippet], env=env, check=True, capture_output=True, text=True
    ).stdout.split()
    return float(out[0]), float(out[1])


def big_system(n_points=1000, n_lines=2048, seed=7, noise=0.02):
    """A 6-12 mode random system seen at ``n_points`` points (mixtures of its measured points)."""
    rng = np.random.default_rng(seed)
    n_modes = int(rng.integers(6, 13))
    frf_small, truth = ami_xr.simulate.random_system(
        n_points=min(n_modes, 12), n_modes=n_modes, seed=seed, n_frequencies=n_lines
    )
    phi = truth["mode_vector"].transpose("point", "mode").values
    drive = list(truth["point"].values).index(truth.attrs["drive_point"])
    mix = rng.standard_normal((n_points, phi.shape[0]))
    mix[0] = 0.0
    mix[0, drive] = 1.0  # point 0 is the drive point
    big = (
        truth[["eigenvalue"]]
        .assign(mode_vector=(("point", "mode"), mix @ phi))
        .assign_coords(point=np.arange(n_points))
    )
    big.attrs["drive_point"] = 0
    frf = ami_xr.simulate.frf(big, frf_small["frequency"].values)
    g = frf["frf"].values
    scale = noise * np.abs(g).max(axis=1, keepdims=True)
    g = g + scale * (rng.uniform(-1, 1, g.shape) + 1j * rng.uniform(-1, 1, g.shape))
    return frf.assign(frf=(("point", "frequency"), g, frf["frf"].attrs)), big


def speed(repeats: int = 5) -> None:
    print("== Speed ==")
    with tempfile.TemporaryDirectory() as cache:
        imp, cold = first_call_seconds(cache)
        _, warm = first_call_seconds(cache)
    with tempfile.TemporaryDirectory() as cache:
        _, r_cold = first_call_seconds(cache, _REFINE_SNIPPET)
        _, r_warm = first_call_seconds(cache, _REFINE_SNIPPET)
    print(
        f"  import ami_xr and ami_xr.ami (xarray, numba) {imp:.2f} s; first identification "
        "in a fresh process: "
        f"{cold:.2f} s with an empty numba cache (compilation), {warm:.2f} s with the cache "
        "filled by the previous process"
    )
    print(
        f"  first ami_xr.refine in a fresh process: {r_cold:.2f} s with an empty cache, "
        f"{r_warm:.2f} s with the cache filled"
    )
    _, frf, _ = ami_xr.simulate.benchmark(noise=0.15, seed=1)
    for m, kwargs in METHODS.items():
        identify(frf, **kwargs)
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            identify(frf, **kwargs)
            ts.append(time.perf_counter() - t0)
        print(
            f"  benchmark 4 x {frf.sizes['frequency']} lines, {m}: "
            f"median {1e3 * np.median(ts):.0f} ms, best {1e3 * min(ts):.0f} ms over "
            f"{repeats} runs (target < 200 ms)"
        )
    ami_only = identify(frf, **METHODS["simo"])
    ami_xr.refine(ami_only)
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        ami_xr.refine(ami_only)
        ts.append(time.perf_counter() - t0)
    print(
        f"  of which ami_xr.refine alone: median {1e3 * np.median(ts):.0f} ms, best "
        f"{1e3 * min(ts):.0f} ms"
    )
    frf_big, truth_big = big_system()
    identify(frf_big.isel(point=slice(0, 20)))  # compile any size-dependent path
    t0 = time.perf_counter()
    ami_big = identify(frf_big, **METHODS["simo"])
    t1 = time.perf_counter()
    res = ami_xr.refine(ami_big)
    dt = time.perf_counter() - t0
    pairs = match_modes(res["eigenvalue"].values, truth_big["eigenvalue"].values)
    print(
        f"  {frf_big.sizes['point']} points x {frf_big.sizes['frequency']} lines, "
        f"{truth_big.sizes['mode']} modes (2 % noise): {dt:.2f} s (AMI {t1 - t0:.2f} s, "
        f"refine {dt - (t1 - t0):.2f} s), {res.sizes['mode']} modes identified, "
        f"{len(pairs)} matched (target < 10 s)"
    )
    print()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=50, help="noise seeds per level (default 50)")
    p.add_argument(
        "--noise",
        type=float,
        nargs="+",
        default=[0.15, 0.05, 0.0],
        help="eq. 15 noise levels alpha (default 0.15 0.05 0)",
    )
    p.add_argument("--table-seed", type=int, default=0, help="seed of Tables 1-6 (default 0)")
    p.add_argument("--quick", action="store_true", help="10 seeds and no speed section")
    p.add_argument("--no-speed", action="store_true", help="skip the speed section")
    p.add_argument("--speed-only", action="store_true", help="only the speed section")
    args = p.parse_args(argv)
    seeds = min(args.seeds, 10) if args.quick else args.seeds
    if seeds < 1:
        p.error("--seeds: expected a positive number")
    print(
        f"ami_xr {ami_xr.__version__}: the benchmark of Ginsberg & Allen (4 FRFs x 2049 lines, "
        "60 s at 2^12 samples, tip impulse)\n"
    )
    if args.speed_only:
        speed()
        return 0
    tables(args.table_seed)
    for noise in args.noise:
        monte_carlo(noise, seeds)
    if not (args.quick or args.no_speed):
        speed()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
