"""Mode count and accuracy of identification on a fixed catalogue of random systems (issue 10).

    python scripts/benchmark_catalogue.py                 # the 32-case catalogue, identify()
    python scripts/benchmark_catalogue.py --quick         # 4 small cases (a smoke test)
    python scripts/benchmark_catalogue.py --cases 64 --seed 1 --method per_frf
    python scripts/benchmark_catalogue.py --cluster-cases 64 --no-lscf

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

**Overlap cases (issue 20).** Then ``--cluster-cases`` (default 32) systems of
:func:`ami_xr.simulate.cluster_catalogue`: clusters of three and four modes at target overlap
0.15, 0.35, 0.7 and 1.4 (damping up to 8 %, non-proportional), analytic and FFT'd
impulse-response FRFs (``frf_source="impulse_response"``, the paper's form: eq. 15 noise on the
impulse responses), noise 0, 1, 5, 15 %; one line per case with the same columns. Every true
mode of every case (both catalogues) has an overlap factor (:func:`ami_xr.simulate.
overlap_factor`: half-power bandwidth ``2 |Re lam|`` over the distance to the nearest mode) and
falls in a bin <0.25, 0.25-0.5, 0.5-1, 1-2, >2; a spurious mode counts in the bin of the true
mode nearest to it. Per bin, noise-free and noisy, analytic and impulse response: modes found
(noisy: identifiable modes found), spurious modes, the largest relative errors (noise-free)
or the errors over the Cramér-Rao bound (noisy; analytic FRFs: the line noise above; impulse
responses: eq. 15 on the responses, :func:`ami_xr.cramer_rao_bound` from the FRF's
attributes). Then one line per target of issue 20.

**LSCF column.** With the optional ``bench`` extra (sdypy-EMA), the same cases also go through
sdypy-EMA's LSCF (order 30) with automatic stable-pole picking and LSFD, exactly as in
``scripts/bench_peers.py`` (its ``stable_poles``: a pole of the highest order kept when stable
in frequency (0.1 %) and damping (5 %) against the 5 orders below it), scored the same way and
printed beside each bin (``--no-lscf`` skips it; without sdypy-EMA it is skipped and said so).
Written against the public API only.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import runpy
import time
import warnings
from pathlib import Path

import numpy as np

import ami_xr
from ami_xr.simulate.catalogue import identifiable, line_noise_std

QUICK_CASES, QUICK_LINES = 4, 1024
QUICK_CLUSTER_CASES = 4
BIN_EDGES = (0.25, 0.5, 1.0, 2.0)
BIN_LABELS = ("<0.25", "0.25-0.5", "0.5-1", "1-2", ">2")
TARGET_FOUND_HIGH = 0.90  # noisy, overlap above 1 (issue 20)
REL_TOL = 1e-6  # noise-free relative error target (issue 10, item 4)
TARGET_FOUND = 0.95  # noisy: share of identifiable modes found
TARGET_SPURIOUS = 1.0  # noisy: spurious modes per 100 true modes
TARGET_MEDIAN, TARGET_MAX = 1.0, 3.0  # noisy: error over the bound

HEADER = (
    f"{'case':<23}{'pts':>4}{'modes':>6}{'ident':>6}{'found':>6}{'f/id':>5}{'spur':>5}"
    f"{'fn med':>9}{'fn max':>9}{'zeta med':>9}{'zeta max':>9}{'warn':>5}{'s':>6}"
)


def _crb(case, frf, truth, sigma):
    """The bound of the truth on this case's data, or None without noise."""
    if case.noise == 0:
        return None
    if frf.attrs.get("frf_source") == "impulse_response":  # eq. 15 on the responses
        return ami_xr.cramer_rao_bound(truth, frf)
    return ami_xr.cramer_rao_bound(truth, frf, frf_noise_std=sigma)


def _per_mode(score, n_true: int, crb) -> tuple[np.ndarray, np.ndarray]:
    """Errors of each TRUE mode (NaN where not found): relative, or over the bound."""
    fn, zeta = np.full(n_true, np.nan), np.full(n_true, np.nan)
    if crb is None:
        fn[score.true_index], zeta[score.true_index] = score.frequency_error, score.damping_error
    else:
        fn[score.true_index] = score.frequency_over_crb
        zeta[score.true_index] = score.damping_over_crb
    return fn, zeta


def _spurious_nearest(lam_id: np.ndarray, spurious: np.ndarray, truth) -> np.ndarray:
    """For each spurious identified mode, the true mode nearest to it (in units of |Re lam|)."""
    lam_t = truth["eigenvalue"].values
    lam = np.asarray(lam_id, dtype=complex)[spurious]
    lam = np.where(lam.imag < 0, lam.conj(), lam)
    if lam.size == 0:
        return np.array([], dtype=int)
    with np.errstate(invalid="ignore"):
        d = np.abs(lam[:, None] - lam_t[None, :]) / np.abs(lam_t.real)[None, :]
    return np.argmin(np.where(np.isfinite(d), d, np.inf), axis=1)


def run_case(case, method_kwargs: dict, n_frequencies: int | None, peer=None) -> dict:
    """Simulate, identify and score one catalogue case; a dict of counts and error arrays, and
    per true mode its overlap factor, found flags and errors (of identify and, with ``peer``,
    of LSCF)."""
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
    try:
        crb = _crb(case, frf, truth, sigma)
    except ami_xr.AmiXrValueError as err:  # pragma: no cover - singular truth
        failed = failed or f"no bound: {err}"
    score = ami_xr.simulate.score_modes(modes, truth, crb=crb)
    if crb is None:
        fn_err, z_err = score.frequency_error, score.damping_error
    else:
        fn_err, z_err = score.frequency_over_crb, score.damping_over_crb
    lam_id = modes["eigenvalue"].values if hasattr(modes, "data_vars") else modes
    mode_fn, mode_zeta = _per_mode(score, score.n_true, crb)
    row = {
        "case": case,
        "source": frf.attrs.get("frf_source"),
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
        "overlap": np.asarray(ami_xr.simulate.overlap_factor(truth["eigenvalue"].values)),
        "ident_mask": ident,
        "found_mask": score.found,
        "mode_fn": mode_fn,
        "mode_zeta": mode_zeta,
        "spurious_at": _spurious_nearest(lam_id, score.spurious, truth),
    }
    if peer is not None:
        lam_lscf, row["lscf_failed"] = peer(frf)
        s2 = ami_xr.simulate.score_modes(lam_lscf, truth, crb=crb)
        row["lscf_found_mask"] = s2.found
        row["lscf_fn"], row["lscf_zeta"] = _per_mode(s2, s2.n_true, crb)
        row["lscf_spurious_at"] = _spurious_nearest(lam_lscf, s2.spurious, truth)
    return row


def lscf_runner(quiet: bool = True):
    """sdypy-EMA's LSCF + automatic stable poles + LSFD, as ``scripts/bench_peers.py`` runs it
    (its functions reused): a function ``frf -> (eigenvalues, failure text)``, or None when
    sdypy-EMA is not installed."""
    peers = runpy.run_path(str(Path(__file__).with_name("bench_peers.py")), run_name="bench_peers")
    ema = peers["import_peer"]()
    if ema is None:
        return None

    def run(frf):
        h = np.ascontiguousarray(frf["frf"].transpose("point", "frequency").values)
        f = frf["frequency"].values
        lower, upper = float(f[1]), float(f[-1])
        with warnings.catch_warnings(), contextlib.redirect_stderr(io.StringIO()):
            warnings.simplefilter("ignore")
            try:
                with contextlib.redirect_stdout(io.StringIO()):
                    model = ema.Model(
                        h,
                        f,
                        lower=lower,
                        upper=upper,
                        pol_order_high=peers["LSCF_ORDER"],
                        frf_form="receptance",
                    )
                    model.get_poles(method="lscf", show_progress=False)
                    last = len(model.all_poles) - 1
                    keep = peers["stable_poles"](model.all_poles, lower, upper)
                    lam = peers["_lsfd"](model, keep, last)
            except Exception as err:  # noqa: BLE001 - a peer's failure is a result
                return np.array([], dtype=complex), f"{type(err).__name__}: {err}"
        return np.asarray(lam, dtype=complex), ""

    return run


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


def _bin(overlap: np.ndarray) -> np.ndarray:
    return np.searchsorted(np.asarray(BIN_EDGES), overlap, side="right")


def bin_stats(rows: list[dict], lscf: bool) -> dict:
    """Pooled per-bin figures of some rows: keyed by bin index, each a dict of counts and error
    arrays (identify and, with ``lscf``, LSCF)."""
    out = {}
    for b in range(len(BIN_LABELS)):
        d = {"modes": 0, "ident": 0, "found": 0, "found_ident": 0, "spurious": 0}
        d.update({"fn": [], "zeta": [], "l_found": 0, "l_found_ident": 0, "l_spurious": 0})
        d.update({"l_fn": [], "l_zeta": []})
        for r in rows:
            inb = _bin(r["overlap"]) == b
            ident = r["ident_mask"] & inb
            d["modes"] += int(inb.sum())
            d["ident"] += int(ident.sum())
            d["found"] += int((r["found_mask"] & inb).sum())
            d["found_ident"] += int((r["found_mask"] & ident).sum())
            d["spurious"] += int(np.sum(_bin(r["overlap"][r["spurious_at"]]) == b))
            d["fn"].append(r["mode_fn"][inb & r["found_mask"]])
            d["zeta"].append(r["mode_zeta"][inb & r["found_mask"]])
            if lscf and "lscf_found_mask" in r:
                m = r["lscf_found_mask"]
                d["l_found"] += int((m & inb).sum())
                d["l_found_ident"] += int((m & ident).sum())
                d["l_spurious"] += int(np.sum(_bin(r["overlap"][r["lscf_spurious_at"]]) == b))
                d["l_fn"].append(r["lscf_fn"][inb & m])
                d["l_zeta"].append(r["lscf_zeta"][inb & m])
        for k in ("fn", "zeta", "l_fn", "l_zeta"):
            d[k] = np.concatenate(d[k]) if d[k] else np.array([])
            d[k] = d[k][np.isfinite(d[k])]
        out[b] = d
    return out


def _errs(fn: np.ndarray, zeta: np.ndarray, noisy: bool) -> str:
    if fn.size == 0:
        return "-"
    if noisy:
        return (
            f"fn {np.median(fn):.2f}/{np.max(fn):.2f}, zeta {np.median(zeta):.2f}/"
            f"{np.max(zeta):.2f}"
        )
    return f"fn {np.max(fn):.0e}, zeta {np.max(zeta):.0e}"


def bin_lines(label: str, stats: dict, noisy: bool, lscf: bool) -> list[str]:
    """One line per non-empty bin, phrased as the issue's targets."""
    out = []
    for b, d in stats.items():
        if d["modes"] == 0:
            continue
        num, den = ("found_ident", "ident") if noisy else ("found", "modes")
        what = "identifiable found" if noisy else "found"
        line = f"  {label + ',':<20} overlap {BIN_LABELS[b]:<8}: {d[num]:3d}/{d[den]:<3d} {what}"
        if lscf:
            line += f" (LSCF {d['l_' + num]}/{d[den]})"
        line += f", spurious {d['spurious']}" + (f" (LSCF {d['l_spurious']})" if lscf else "")
        kind = "error/CRB med/max" if noisy else "max rel err"
        line += f", {kind} {_errs(d['fn'], d['zeta'], noisy)}"
        if lscf:
            line += f" (LSCF {_errs(d['l_fn'], d['l_zeta'], noisy)})"
        out.append(line)
    return out


def issue20_targets(groups: dict, lscf: bool) -> list[str]:
    """One line per target of issue 20 from the per-bin figures of each (noisy, source) group."""

    def line(text, value, ok):
        return f"  {text:<62} {value:<30} {'met' if ok else 'NOT met'}"

    out = []
    clean = [(src, b, d) for (noisy, src), st in groups.items() if not noisy for b, d in st.items()]
    noisy = [(src, b, d) for (nz, src), st in groups.items() if nz for b, d in st.items()]
    clean = [x for x in clean if x[2]["modes"]]
    noisy = [x for x in noisy if x[2]["modes"]]
    if clean:
        worst = min(clean, key=lambda x: x[2]["found"] / x[2]["modes"])
        share = worst[2]["found"] / worst[2]["modes"]
        out.append(
            line(
                "noise-free: 100 % of modes in every overlap bin and source",
                f"worst {worst[2]['found']}/{worst[2]['modes']} ({worst[0][:3]} "
                f"{BIN_LABELS[worst[1]]})",
                share == 1.0,
            )
        )
        errs = [np.max(np.r_[d["fn"], d["zeta"]]) for _, _, d in clean if d["fn"].size]
        mx = max(errs, default=float("nan"))
        out.append(
            line(
                f"noise-free: relative error <= {REL_TOL:g} in every bin",
                f"max {mx:.1e}",
                bool(mx <= REL_TOL),
            )
        )
    if noisy:
        for high in (False, True):
            sel = [(s, b, d) for s, b, d in noisy if (b >= 3) == high and d["ident"]]
            if not sel:
                continue
            need = TARGET_FOUND_HIGH if high else TARGET_FOUND
            s, b, d = min(sel, key=lambda x: x[2]["found_ident"] / x[2]["ident"])
            share = d["found_ident"] / d["ident"]
            out.append(
                line(
                    f"noisy: >= {100 * need:.0f} % of identifiable modes, overlap "
                    + ("above 1" if high else "up to 1"),
                    f"worst {d['found_ident']}/{d['ident']} ({s[:3]} {BIN_LABELS[b]})",
                    share >= need,
                )
            )
        n_modes = sum(d["modes"] for _, _, d in noisy)
        n_spur = sum(d["spurious"] for _, _, d in noisy)
        out.append(
            line(
                f"noisy: <= {TARGET_SPURIOUS:g} spurious mode per 100 true modes",
                f"{n_spur} per {n_modes}",
                100 * n_spur / n_modes <= TARGET_SPURIOUS,
            )
        )
        fn = np.concatenate([d["fn"] for _, _, d in noisy])
        zeta = np.concatenate([d["zeta"] for _, _, d in noisy])
        if fn.size:
            med = max(np.median(fn), np.median(zeta))
            mx = max(np.max(fn), np.max(zeta))
            out.append(
                line("noisy: error/CRB median <= 1 (worse of fn, zeta)", f"{med:.2f}", med <= 1)
            )
            out.append(line("noisy: error/CRB max <= 3 (fn and zeta)", f"{mx:.2f}", mx <= 3))
    if lscf:
        worse = []
        for (nz, src), st in groups.items():
            for b, d in st.items():
                k = "found_ident" if nz else "found"
                if d[k] < d["l_" + k]:
                    worse.append(f"{'noisy' if nz else 'clean'} {src[:3]} {BIN_LABELS[b]}")
        out.append(
            line(
                "at least as many modes as LSCF in every bin",
                f"fewer in {len(worse)} bin(s)" + (f": {', '.join(worse[:2])}" if worse else ""),
                not worse,
            )
        )
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
    parser.add_argument(
        "--cluster-cases",
        type=int,
        default=None,
        help=f"overlap cases of issue 20 (default 32, {QUICK_CLUSTER_CASES} with --quick; 0: none)",
    )
    parser.add_argument("--no-lscf", action="store_true", help="skip the sdypy-EMA LSCF column")
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
    peer = None if args.no_lscf else lscf_runner()
    n_cluster = (
        args.cluster_cases
        if args.cluster_cases is not None
        else (QUICK_CLUSTER_CASES if args.quick else 32)
    )
    print(HEADER, flush=True)
    rows = []
    for case in cases:
        row = run_case(case, method_kwargs, lines, peer)
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
    if n_cluster > 0:
        overlap_section(rows, n_cluster, args, method_kwargs, lines, peer)
    return 0


def overlap_section(rows, n_cluster, args, method_kwargs, lines, peer) -> None:
    """The overlap cases of issue 20, then the per-bin figures of every case and the targets."""
    ccases = ami_xr.simulate.cluster_catalogue(n_cluster, args.seed)
    print(
        f"\nOverlap cases (issue 20): {n_cluster} clustered systems, seed {args.seed}; "
        + (
            "LSCF column: sdypy-EMA LSCF order 30, automatic stable poles, LSFD"
            if peer is not None
            else "no LSCF column ("
            + (
                "--no-lscf"
                if args.no_lscf
                else "sdypy-EMA not installed: pip install ami_xr[bench]"
            )
            + ")"
        )
    )
    print(HEADER, flush=True)
    crows = []
    for case in ccases:
        row = run_case(case, method_kwargs, lines, peer)
        crows.append(row)
        print(format_row(row), flush=True)
    print("\nTotals of the overlap cases")
    for noise in sorted({c.noise for c in ccases}):
        sub = [r for r in crows if r["case"].noise == noise]
        print(
            format_totals(f"noise {100 * noise:g} %", totals(sub), "crb" if noise else "relative")
        )
    every = rows + crows
    lscf = peer is not None
    print(
        f"\nPer overlap bin, all {len(every)} cases (overlap = half-power bandwidth / spacing; "
        "errors: noise-free max relative, noisy median/max over the bound)"
    )
    groups = {}
    for noisy in (False, True):
        for src in ("analytic", "impulse_response"):
            sub = [r for r in every if (r["case"].noise > 0) == noisy and r["source"] == src]
            if not sub:
                continue
            groups[(noisy, src)] = bin_stats(sub, lscf)
            kind = "impulse" if src != "analytic" else "analytic"
            label = f"{'noisy' if noisy else 'noise-free'} {kind}"
            for text in bin_lines(label, groups[(noisy, src)], noisy, lscf):
                print(text)
    print("\nTargets (issue 20)")
    for text in issue20_targets(groups, lscf):
        print(text)


if __name__ == "__main__":
    raise SystemExit(main())
