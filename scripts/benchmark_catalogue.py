"""Mode count and accuracy of identification on a fixed catalogue of random systems (issue 10).

    python scripts/benchmark_catalogue.py                 # the 32-case catalogue, identify()
    python scripts/benchmark_catalogue.py --quick         # 4 small cases (a smoke test)
    python scripts/benchmark_catalogue.py --cases 64 --seed 1 --method per_frf

The catalogue is :func:`ami_xr.simulate.catalogue`: random chains and grids with and without a
closely spaced pair (separation below the half-power bandwidth) and a weakly excited mode, at
noise 0, 1, 5 and 15 % (eq. 15 on the real and imaginary parts of analytic FRFs). One line per
case as it finishes:

* ``modes``: true modes. ``ident``: identifiable modes -- peak SNR >= 6 dB at one measured point
  at least, the SNR of mode k at point j being ``|A_jk| / |Re lam_k|`` (the peak of the mode's
  own contribution) over ``sigma_j = sqrt(E |noise|^2)`` of one line of FRF j (see
  :mod:`ami_xr.simulate.catalogue`); without noise every mode is identifiable.
* ``found``: identified modes matched to true ones (``|lam_id - lam| < |Re lam|``, half the
  half-power bandwidth; one-to-one, nearest first; :func:`ami_xr.simulate.score_modes`);
  ``f/id``: of them, identifiable ones. ``spur``: identified modes matched to none.
* Errors of the found modes: natural frequency ``fn`` and damping ratio ``zeta``, each divided by
  its Cramér-Rao standard deviation (:func:`ami_xr.cramer_rao_bound` with the line noise above),
  median and max over the case's found modes. Noise-free cases print the relative errors instead.

Totals per noise level and overall, then one line per target of issue 10 with met/NOT met.
Written against the public API only.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import ami_xr
from ami_xr.simulate.catalogue import identifiable, line_noise_std

QUICK_CASES, QUICK_LINES = 4, 1024
REL_TOL = 1e-6  # noise-free relative error target (issue 10, item 4)
TARGET_FOUND = 0.95  # noisy: share of identifiable modes found
TARGET_SPURIOUS = 1.0  # noisy: spurious modes per 100 true modes
TARGET_MEDIAN, TARGET_MAX = 1.0, 3.0  # noisy: error over the bound

HEADER = (
    f"{'case':<23}{'pts':>4}{'modes':>6}{'ident':>6}{'found':>6}{'f/id':>5}{'spur':>5}"
    f"{'fn med':>9}{'fn max':>9}{'zeta med':>9}{'zeta max':>9}{'warn':>5}{'s':>6}"
)


def run_case(case, method_kwargs: dict, n_frequencies: int | None) -> dict:
    """Simulate, identify and score one catalogue case; a dict of counts and error arrays."""
    frf, truth = case.build(**({"n_frequencies": n_frequencies} if n_frequencies else {}))
    sigma = line_noise_std(frf, truth)
    ident = identifiable(truth, sigma)
    t0 = time.perf_counter()
    failed = ""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            modes = ami_xr.identify(frf, **method_kwargs)
        except ami_xr.AmiXrError as err:
            modes, failed = np.array([], dtype=complex), str(err).splitlines()[0]
    seconds = time.perf_counter() - t0
    crb = None
    if case.noise > 0:
        try:
            crb = ami_xr.cramer_rao_bound(truth, frf, frf_noise_std=sigma)
        except ami_xr.AmiXrValueError as err:  # pragma: no cover - singular truth
            failed = failed or f"no bound: {err}"
    score = ami_xr.simulate.score_modes(modes, truth, crb=crb)
    if crb is None:
        fn_err, z_err = score.frequency_error, score.damping_error
    else:
        fn_err, z_err = score.frequency_over_crb, score.damping_over_crb
    return {
        "case": case,
        "modes": score.n_true,
        "ident": int(ident.sum()),
        "found": score.n_found,
        "found_ident": int((score.found & ident).sum()),
        "spurious": score.n_spurious,
        "fn": fn_err,
        "zeta": z_err,
        "warnings": len(caught),
        "seconds": seconds,
        "failed": failed,
    }


def _stat(values: np.ndarray, noisy: bool) -> tuple[str, str]:
    if values.size == 0:
        return "-", "-"
    med, mx = np.median(values), np.max(values)
    return (f"{med:.2f}", f"{mx:.2f}") if noisy else (f"{med:.0e}", f"{mx:.0e}")


def format_row(r: dict) -> str:
    c, noisy = r["case"], r["case"].noise > 0
    fn, zeta = _stat(r["fn"], noisy), _stat(r["zeta"], noisy)
    line = (
        f"{c.name:<23}{c.n_points:>4}{r['modes']:>6}{r['ident']:>6}{r['found']:>6}"
        f"{r['found_ident']:>5}{r['spurious']:>5}{fn[0]:>9}{fn[1]:>9}{zeta[0]:>9}{zeta[1]:>9}"
        f"{r['warnings']:>5}{r['seconds']:>6.1f}"
    )
    return line + (f"  FAILED: {r['failed']}" if r["failed"] else "")


def totals(rows: list[dict]) -> dict:
    """Sums and pooled error statistics of some case rows."""
    fn = np.concatenate([r["fn"] for r in rows]) if rows else np.array([])
    zeta = np.concatenate([r["zeta"] for r in rows]) if rows else np.array([])
    t = {k: sum(r[k] for r in rows) for k in ("modes", "ident", "found", "found_ident")}
    t["spurious"] = sum(r["spurious"] for r in rows)
    t["cases"], t["fn"], t["zeta"] = len(rows), fn, zeta
    return t


def _pct(a: int, b: int) -> float:
    return 100.0 * a / b if b else float("nan")


def format_totals(label: str, t: dict, errors: str | None) -> str:
    """One totals line; ``errors``: "crb" (noisy), "relative" (noise-free) or None."""
    line = (
        f"{label:<12} cases {t['cases']:3d}  modes {t['modes']:4d}  identifiable {t['ident']:4d}  "
        f"found {t['found']:4d} ({_pct(t['found'], t['modes']):5.1f} % of modes)  "
        f"found identifiable {t['found_ident']:4d} ({_pct(t['found_ident'], t['ident']):5.1f} %)  "
        f"spurious {t['spurious']:3d} ({_pct(t['spurious'], t['modes']):.1f} per 100 modes)"
    )
    if errors is None or t["fn"].size == 0:
        return line
    if errors == "crb":
        return line + (
            f"  error/CRB fn median {np.median(t['fn']):.2f} max {np.max(t['fn']):.2f}, "
            f"zeta median {np.median(t['zeta']):.2f} max {np.max(t['zeta']):.2f}"
        )
    return line + f"  relative error max fn {np.max(t['fn']):.1e}, zeta {np.max(t['zeta']):.1e}"


def target_lines(clean: dict, noisy: dict) -> list[str]:
    """One line per issue-10 target: the measured value and met / NOT met."""

    def line(text, value, ok):
        return f"  {text:<58} {value:<34} {'met' if ok else 'NOT met'}"

    out = []
    if clean["cases"]:
        both = np.concatenate([clean["fn"], clean["zeta"]])
        worst = float(np.max(both)) if both.size else float("nan")
        out.append(
            line(
                "noise-free: 100 % of modes found",
                f"{clean['found']}/{clean['modes']} ({_pct(clean['found'], clean['modes']):.1f} %)",
                clean["found"] == clean["modes"],
            )
        )
        out.append(
            line(
                f"noise-free: relative error of fn and zeta <= {REL_TOL:g}",
                f"max {worst:.1e}",
                both.size > 0 and worst <= REL_TOL,
            )
        )
    if noisy["cases"]:
        share = noisy["found_ident"] / noisy["ident"] if noisy["ident"] else float("nan")
        per100 = _pct(noisy["spurious"], noisy["modes"])
        med = max((np.median(noisy[k]) for k in ("fn", "zeta") if noisy[k].size), default=np.nan)
        mx = max((np.max(noisy[k]) for k in ("fn", "zeta") if noisy[k].size), default=np.nan)
        out += [
            line(
                f"noisy: >= {100 * TARGET_FOUND:.0f} % of identifiable modes found",
                f"{noisy['found_ident']}/{noisy['ident']} ({100 * share:.1f} %)",
                share >= TARGET_FOUND,
            ),
            line(
                f"noisy: <= {TARGET_SPURIOUS:g} spurious mode per 100 true modes",
                f"{noisy['spurious']} per {noisy['modes']} ({per100:.1f} per 100)",
                per100 <= TARGET_SPURIOUS,
            ),
            line(
                f"noisy: error/CRB median <= {TARGET_MEDIAN:g} (worse of fn, zeta)",
                f"{med:.2f}",
                bool(med <= TARGET_MEDIAN),
            ),
            line(
                f"noisy: error/CRB max <= {TARGET_MAX:g} (fn and zeta)",
                f"{mx:.2f}",
                bool(mx <= TARGET_MAX),
            ),
        ]
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"{QUICK_CASES} cases (unless --cases) on {QUICK_LINES} frequency lines",
    )
    parser.add_argument("--cases", type=int, default=None, help="number of cases (default 32)")
    parser.add_argument("--seed", type=int, default=0, help="catalogue seed")
    parser.add_argument(
        "--method",
        choices=("simo", "per_frf", "paper"),
        default=None,
        help="method of ami_xr.identify (default: identify's own default, nothing passed)",
    )
    args = parser.parse_args(argv)
    n_cases = args.cases if args.cases is not None else (QUICK_CASES if args.quick else 32)
    cases = ami_xr.simulate.catalogue(n_cases, args.seed)
    method_kwargs = {} if args.method is None else {"method": args.method}
    call = "identify(frf" + "".join(f", {k}={v!r}" for k, v in method_kwargs.items()) + ")"
    lines = QUICK_LINES if args.quick else None
    print(
        f"Catalogue: {n_cases} cases, seed {args.seed}, ami_xr.{call}"
        + (f", {QUICK_LINES} lines (quick)" if args.quick else "")
    )
    print("errors: found modes' |error| / Cramér-Rao std (median, max); noise 0 %: relative errors")
    print(HEADER, flush=True)
    rows = []
    for case in cases:
        row = run_case(case, method_kwargs, lines)
        rows.append(row)
        print(format_row(row), flush=True)

    print("\nTotals")
    for noise in sorted({c.noise for c in cases}):
        sub = [r for r in rows if r["case"].noise == noise]
        kind = "crb" if noise > 0 else "relative"
        print(format_totals(f"noise {100 * noise:g} %", totals(sub), kind))
    noisy = totals([r for r in rows if r["case"].noise > 0])
    clean = totals([r for r in rows if r["case"].noise == 0])
    if noisy["cases"]:
        print(format_totals("all noisy", noisy, "crb"))
    print(format_totals("all", totals(rows), None))
    print("\nTargets (issue 10)")
    for text in target_lines(clean, noisy):
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
