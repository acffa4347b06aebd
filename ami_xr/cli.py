"""The ``ami-xr`` command line: a thin shell over the public functions.

Each subcommand parses its options, calls one public function (heavy imports happen inside the
subcommand, so ``ami-xr --help`` is fast and compiles nothing), and maps errors to exit codes:

* Warnings of ami_xr (e.g. no modes found, iteration cap reached) print as one line each;
  other packages' warnings only with ``-v``.
* 0 success; 1 a library error (bad input file, bad option value, failed identification): one
  line ``ami-xr <command>: error: ...`` on stderr, no traceback (``-v`` shows it); 2 a usage error
  (argparse); 3 ``batch`` finished but some files failed; 130 interrupted (Ctrl-C).
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import traceback
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ami_xr.errors import AmiXrError, AmiXrWarning

EXIT_OK = 0
EXIT_ERROR = 1
EXIT_USAGE = 2
EXIT_BATCH_FAILURES = 3
EXIT_INTERRUPTED = 130

#: The paper's AMI results (average eigenvalues of Tables 1-2, rad/s) for the demo comparison.
PAPER_AMI_EIGENVALUES = (
    -0.46025 + 30.555j,
    -0.71644 + 48.041j,
    -0.39394 + 65.057j,
    -0.54413 + 65.836j,
)
DEFAULT_DEMO_DIR = "ami_xr_demo"


class _Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Show defaults (unless the help states its own) and keep the description's line breaks."""

    def _get_help_string(self, action):
        if "(default:" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


# --- helpers -------------------------------------------------------------------------------------
def _one_line(err: BaseException) -> str:
    # SchemaError lists its problems as "  - ..." bullets: join them into one line.
    lines = [re.sub(r"^\s*-\s+", "", s).strip() for s in str(err).strip().splitlines() if s.strip()]
    text = "; ".join(lines) if lines else type(err).__name__
    if not isinstance(err, AmiXrError):
        text = f"{type(err).__name__}: {text}"
    return text


def _say(*parts: Any) -> None:
    print(*parts, flush=True)


def _open_any(path: str | os.PathLike):
    """Read a netCDF, UFF or LVM file into a Dataset (by suffix)."""
    from ami_xr.batch import read_input

    return read_input(path)


def _write_any(
    ds,
    path: str | os.PathLike,
    *,
    binary: bool = False,
    function: str,
    parameters: dict | None = None,
) -> Path:
    path = Path(path)
    if path.suffix.lower() in (".uff", ".unv"):
        from ami_xr.io.uff import write_uff

        return write_uff(ds, path, binary=binary)
    if path.suffix.lower() != ".nc":
        from ami_xr.errors import AmiXrValueError

        raise AmiXrValueError(f"output {str(path)!r}: expected a .nc, .uff or .unv file name")
    import ami_xr

    return ami_xr.to_netcdf(ds, path, function=function, parameters=parameters)


def _non_default(
    args: argparse.Namespace, options: dict[str, Any], dests: dict[str, str]
) -> dict[str, Any]:
    """Only the options the user changed: the library applies its own defaults (which the help
    shows), and batch parameter hashes match a Python call with the same settings."""
    parser: argparse.ArgumentParser = args._parser
    return {
        k: v
        for k, v in options.items()
        if v is not None and v != parser.get_default(dests.get(k, k))
    }


def _add_output(
    p: argparse.ArgumentParser, what: str, required: bool = True, default: str | None = None
) -> None:
    p.add_argument("-o", "--output", required=required, default=default, metavar="PATH", help=what)


# --- identify options (shared by identify, batch and demo) ------------------------------------
def _band(text: str) -> float | str:
    if text == "all":
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or 'all', got {text!r}") from None


def _add_identify_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("identification options (ami_xr.identify)")
    g.add_argument(
        "--method",
        default="simo",
        choices=("simo", "per_frf", "paper"),
        help="simo: one eigenvalue fit over all FRFs per mode; per_frf: the paper's "
        "per-FRF fits averaged with SNR weights; paper: the paper's AMI exactly "
        "(plain mean, eq. 9 over bands, continuous basis, no refinement)",
    )
    g.add_argument(
        "--refine",
        dest="refine",
        action="store_const",
        const=True,
        default=None,
        help="force the joint maximum-likelihood refinement (default: on unless --method paper)",
    )
    g.add_argument(
        "--no-refine",
        dest="refine",
        action="store_const",
        const=False,
        help="skip the joint refinement (default: refine unless --method paper)",
    )
    g.add_argument(
        "--delta",
        type=float,
        default=0.5,
        help="subtraction: fit the lines with |G| >= delta * peak, in (0, 1)",
    )
    g.add_argument(
        "--pfa",
        type=float,
        default=1e-3,
        help="subtraction: false-alarm probability of the automatic stop (a noise "
        "peak is taken for a mode with this probability)",
    )
    g.add_argument("--max-modes", type=int, default=20, help="subtraction: most modes per FRF")
    g.add_argument(
        "--tol",
        type=float,
        default=1e-4,
        help="isolation: relative change of Re and Im of every eigenvalue that "
        "ends the iteration (1e-4 = 0.01 %%)",
    )
    g.add_argument("--max-iter", type=int, default=100, help="isolation: iteration cap")
    g.add_argument(
        "--band",
        type=_band,
        default=1.0,
        help="global fit: half-width of the band around each mode in half-power "
        "bandwidths 2|Re lambda| [rad/s], or 'all' for every line",
    )
    g.add_argument(
        "--residual-terms",
        action="store_true",
        help="global fit: add lower and upper residual terms for out-of-band modes (measured FRFs)",
    )


def _identify_options(args: argparse.Namespace) -> dict[str, Any]:
    return _non_default(
        args,
        {
            "method": args.method,
            "refine": args.refine,
            "delta": args.delta,
            "pfa": args.pfa,
            "max_modes": args.max_modes,
            "tol": args.tol,
            "max_iter": args.max_iter,
            "band": args.band,
            "residual_terms": args.residual_terms,
        },
        {},
    )


# --- subcommands ---------------------------------------------------------------------------------
def _cmd_simulate(args: argparse.Namespace) -> int:
    import ami_xr

    if args.time_output and args.system != "beam-absorbers":
        from ami_xr.errors import AmiXrValueError

        raise AmiXrValueError("--time-output: only the beam-absorbers system has impulse responses")
    ts = None
    if args.system == "beam-absorbers":
        params = {
            "system": args.system,
            "noise": args.noise,
            "seed": args.seed,
            "duration": args.duration,
            "n_samples": args.samples,
        }
        ts, g, truth = ami_xr.simulate.benchmark(
            noise=args.noise, seed=args.seed, duration=args.duration, n_samples=args.samples
        )
        function = "ami_xr.simulate.benchmark"
    else:
        params = {
            "system": args.system,
            "n_points": args.points,
            "topology": args.topology,
            "noise": args.noise,
            "seed": args.seed,
            "closely_spaced": args.closely_spaced,
            "weak_mode": args.weak_mode,
            "max_frequency_hz": args.max_frequency,
        }
        g, truth = ami_xr.simulate.random_system(
            args.points,
            args.topology,
            noise=args.noise,
            seed=args.seed,
            closely_spaced=args.closely_spaced,
            weak_mode=args.weak_mode,
            max_frequency_hz=args.max_frequency,
        )
        function = "ami_xr.simulate.random_system"
    ami_xr.to_netcdf(g, args.output, function=function, parameters=params)
    _say(f"wrote FRFs ({g.sizes['point']} points x {g.sizes['frequency']} lines) to {args.output}")
    if args.time_output:
        ami_xr.to_netcdf(ts, args.time_output, function=function, parameters=params)
        _say(f"wrote impulse responses to {args.time_output}")
    if args.truth_output:
        ami_xr.to_netcdf(truth, args.truth_output, function=function, parameters=params)
        _say(f"wrote exact modal parameters to {args.truth_output}")
    return EXIT_OK


def _cmd_frf(args: argparse.Namespace) -> int:
    import ami_xr
    from ami_xr.batch import estimate_frf

    ts = _open_any(args.input)
    options = _frf_options(args)
    g = estimate_frf(ts, options)
    if "hit_rejected" in g:  # impact test: say which hits were left out and why
        rejected = g["hit_rejected"].values.astype(bool)
        reasons = (
            g["hit_reject_reason"].values if "hit_reject_reason" in g else [""] * rejected.size
        )
        _say(f"hits: {rejected.size}, used {int((~rejected).sum())}")
        for i in range(rejected.size):
            if rejected[i]:
                _say(f"  hit {i} rejected: {reasons[i]}")
    ami_xr.to_netcdf(g, args.output, function="ami_xr.frf", parameters=options)
    _say(f"wrote FRFs ({g.sizes['point']} points x {g.sizes['frequency']} lines) to {args.output}")
    return EXIT_OK


def _add_frf_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("FRF estimation options (ami_xr.frf; time-history input only)")
    g.add_argument(
        "--estimator",
        default="H1",
        choices=("H1", "H2", "Hv"),
        help="FRF estimator: H1 = Gfy/Gff (output noise), H2 = Gyy/Gyf (input "
        "noise), Hv (total least squares)",
    )
    g.add_argument(
        "--excitation",
        default="auto",
        choices=("auto", "random", "impact"),
        help="impact: every record is a hammer hit (checked, windowed, averaged); "
        "random: Welch segments; auto: impact when the data have a 'record' "
        "dim, else random",
    )
    g.add_argument(
        "--window",
        default=None,
        help="Welch window for random excitation (hann, boxcar, flattop, ...); default hann",
    )
    g.add_argument(
        "--nperseg",
        type=int,
        default=None,
        help="segment length [samples]; default 256 (random) or the whole record (impact)",
    )
    g.add_argument(
        "--noverlap",
        type=int,
        default=None,
        help="segment overlap [samples]; default nperseg // 2 (random), 0 (impact)",
    )
    g.add_argument("--nfft", type=int, default=None, help="FFT length [samples]; default nperseg")
    g.add_argument(
        "--detrend",
        default=None,
        choices=("constant", "linear", "none"),
        help="detrend of each segment; default constant (random), none (impact)",
    )
    g.add_argument(
        "--average",
        default="linear",
        choices=("linear", "exponential"),
        help="averaging over segments or hits",
    )
    g.add_argument(
        "--n-average", type=int, default=8, help="time constant of exponential averaging [segments]"
    )
    g.add_argument(
        "--force-window",
        type=float,
        default=None,
        metavar="SECONDS",
        help="impact: force window width [s]; default from the force pulse",
    )
    g.add_argument(
        "--exponential-decay",
        type=float,
        default=None,
        metavar="PER_SECOND",
        help="impact: exponential window decay rate [1/s] (its damping is removed "
        "again by identification); default none",
    )
    g.add_argument(
        "--exponential-end-value",
        type=float,
        default=None,
        metavar="FRACTION",
        help="impact: exponential window by its value at the record end [0-1], "
        "instead of --exponential-decay",
    )
    g.add_argument(
        "--no-hit-checks",
        action="store_true",
        help="impact: use every hit (no overload/double-impact/weak-force checks)",
    )
    g.add_argument(
        "--double-impact-threshold",
        type=float,
        default=0.1,
        metavar="FRACTION",
        help="impact: second force pulse above this fraction of the peak = double impact",
    )
    g.add_argument(
        "--overload-samples",
        type=int,
        default=3,
        help="impact: this many samples at the channel's extreme = overload",
    )
    g.add_argument(
        "--min-force",
        type=float,
        default=None,
        metavar="NEWTON",
        help="impact: reject hits whose peak force is below this [force units]",
    )
    g.add_argument(
        "--weak-force-ratio",
        type=float,
        default=0.1,
        metavar="FRACTION",
        help="impact: reject hits weaker than this fraction of the median peak",
    )


def _frf_options(args: argparse.Namespace) -> dict[str, Any]:
    options = {
        "estimator": args.estimator,
        "window": args.window,
        "nperseg": args.nperseg,
        "noverlap": args.noverlap,
        "nfft": args.nfft,
        "detrend": args.detrend,
        "average": args.average,
        "n_average": args.n_average,
        "force_window": args.force_window,
        "exponential_decay": args.exponential_decay,
        "exponential_end_value": args.exponential_end_value,
        "double_impact_threshold": args.double_impact_threshold,
        "overload_samples": args.overload_samples,
        "min_force": args.min_force,
        "weak_force_ratio": args.weak_force_ratio,
    }
    options = _non_default(args, options, {})
    if args.no_hit_checks:
        options["hit_checks"] = False
    if args.excitation != "auto":
        options["excitation"] = args.excitation
    return options


class _Activity:
    """Progress indicator while one long call runs (identification has no finer progress hook):
    a tqdm bar (or a plain line) on stderr with the elapsed time, refreshed from a thread."""

    def __init__(self, desc: str, enabled: bool):
        self.desc, self.enabled = desc, enabled

    def __enter__(self):
        if not self.enabled:
            return self
        import threading
        import time

        self._stop = threading.Event()
        self._start = time.perf_counter()
        try:
            from tqdm import tqdm

            self._bar = tqdm(
                total=None,
                desc=self.desc,
                file=sys.stderr,
                bar_format="{desc}: {elapsed}",
                leave=False,
            )
        except ImportError:
            self._bar = None

        def tick():
            while not self._stop.wait(0.25):
                if self._bar is not None:
                    self._bar.refresh()
                else:
                    sys.stderr.write(f"\r{self.desc}: {time.perf_counter() - self._start:.1f} s")
                    sys.stderr.flush()

        self._thread = threading.Thread(target=tick, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        if not self.enabled:
            return False
        self._stop.set()
        self._thread.join()
        if self._bar is not None:
            self._bar.close()
        else:
            sys.stderr.write("\n")
        return False


#: Show the progress indicator from this many FRFs on (small jobs finish in a blink).
PROGRESS_MIN_POINTS = 8


def _identify_with_progress(ds, options: dict[str, Any], show: bool):
    from ami_xr import names
    from ami_xr.ami import identify

    n = ds.sizes.get(names.POINT, 0)
    # Only on a terminal: a ticking line would clutter logs and pipes.
    tty = sys.stderr.isatty()
    with _Activity(f"identify: {n} FRFs", show and tty and n >= PROGRESS_MIN_POINTS):
        return identify(ds, **options)


def _cmd_identify(args: argparse.Namespace) -> int:
    from ami_xr.report import format_modal_table

    ds = _open_any(args.input)
    options = _identify_options(args)
    result = _identify_with_progress(ds, options, show=not args.quiet)
    _say(format_modal_table(result))
    if args.output:
        _write_any(result, args.output, function="ami_xr.identify", parameters=options)
        _say(f"wrote modes to {args.output}")
    return EXIT_OK


def _cmd_report(args: argparse.Namespace) -> int:
    from ami_xr.report import report

    ds = _open_any(args.input)
    index = report(ds, args.output, title=args.title)
    _say(f"wrote report to {index}")
    return EXIT_OK


def _cmd_convert(args: argparse.Namespace) -> int:
    src = Path(args.input)
    ds = _open_any(src)
    out = _write_any(
        ds,
        args.output,
        binary=args.binary,
        function="ami_xr.cli.convert",
        parameters={"input": str(src)},
    )
    _say(f"converted {src} -> {out}")
    return EXIT_OK


def _cmd_batch(args: argparse.Namespace) -> int:
    from ami_xr.batch import batch

    summary = batch(
        args.input,
        args.output,
        workers=args.workers,
        identify_options=_identify_options(args),
        frf_options=_frf_options(args),
        report=args.report,
        force=args.force,
        progress=not args.quiet,
        keep_tracebacks=args.verbose,
    )
    _say(summary.format())
    _say(f"summary: {summary.csv_path}")
    if args.verbose:
        for row in summary.rows:
            if row.get("traceback"):
                print(f"--- {row['file']}\n{row['traceback']}", file=sys.stderr)
    return EXIT_OK if summary.ok else EXIT_BATCH_FAILURES


# --- demo ----------------------------------------------------------------------------------------
def _sample_frf_file() -> Path | None:
    """The shipped benchmark FRF file (noisy, paper's seed), if present.

    Looked for in ``./sample_data`` (the README runs the demo from the repository root, where a
    plain ``pip install .`` leaves the package in site-packages) and then beside the package
    (an editable install or a source checkout).
    """
    for folder in (Path.cwd() / "sample_data", Path(__file__).resolve().parents[1] / "sample_data"):
        if not folder.is_dir():
            continue
        for pattern in ("*benchmark*frf*.nc", "*frf*.nc"):
            for path in sorted(folder.glob(pattern)):
                name = path.name.lower()
                if "clean" not in name and "noise_free" not in name and "noisefree" not in name:
                    return path
    return None


def _cmd_demo(args: argparse.Namespace) -> int:
    import numpy as np

    import ami_xr
    from ami_xr.report import format_modal_table

    outdir = Path(args.output)
    sample = None if args.simulate else _sample_frf_file()
    truth = ami_xr.simulate.benchmark_model()
    if sample is not None:
        g = ami_xr.open_dataset(sample)
        _say(f"benchmark FRFs: {sample}")
    else:
        _, g, _ = ami_xr.simulate.benchmark(noise=args.noise, seed=args.seed)
        _say(f"benchmark FRFs: simulated (noise {args.noise}, seed {args.seed})")
    _say(
        f"  {g.sizes['point']} points {list(map(str, g['point'].values))} x "
        f"{g.sizes['frequency']} lines, 0-{float(g['frequency'][-1]):.4g} Hz, drive point "
        f"{g.attrs.get('drive_point')}\n"
    )
    options = _identify_options(args)
    result = _identify_with_progress(g, options, show=True)
    _say(format_modal_table(result))
    lam = np.atleast_1d(result["eigenvalue"].values) if "eigenvalue" in result else np.zeros(0)
    exact = np.asarray(truth["eigenvalue"].values)
    _say("\n" + _comparison_table(lam, exact, np.asarray(PAPER_AMI_EIGENVALUES)))
    _say(
        "\nerrors: natural frequency and damping ratio vs the simulator's exact values; "
        "paper AMI = the averages of Tables 1-2 of Ginsberg & Allen (one noise seed)"
    )
    outdir.mkdir(parents=True, exist_ok=True)
    modes_path = ami_xr.to_netcdf(
        result, outdir / "modes.nc", function="ami_xr.identify", parameters=options
    )
    _say(f"\nwrote {modes_path}")
    if not args.no_report:
        import importlib.util

        if importlib.util.find_spec("matplotlib") is None:
            # the report is the one optional part of the demo: say how to get it, do not fail
            _say("no report: it needs matplotlib (pip install 'ami_xr[plot]')")
        else:
            from ami_xr.report import report

            title = "ami_xr demo: paper benchmark"
            _say(f"wrote {report(result, outdir / 'report', title=title)}")
    return EXIT_OK


def _comparison_table(lam, exact, paper) -> str:
    """Identified eigenvalues next to the paper's AMI averages and the exact values."""
    import numpy as np

    def fmt(z: complex) -> str:
        return f"{z.real:.5f}{z.imag:+.4f}i"

    def errors(z: complex, z0: complex) -> tuple[str, str]:
        wn, wn0 = abs(z), abs(z0)
        zeta, zeta0 = -z.real / wn, -z0.real / wn0
        return f"{100 * (wn - wn0) / wn0:+.3f}", f"{100 * (zeta - zeta0) / zeta0:+.1f}"

    header = (
        "mode",
        "identified [rad/s]",
        "paper AMI [rad/s]",
        "exact [rad/s]",
        "f err % (ours/paper)",
        "zeta err % (ours/paper)",
    )
    rows = []
    for i, lk in enumerate(lam):
        k = int(np.argmin(np.abs(np.abs(exact) - abs(lk))))  # nearest exact mode
        ours = errors(lk, exact[k])
        theirs = errors(paper[k], exact[k]) if k < paper.size else ("-", "-")
        rows.append(
            (
                str(i + 1),
                fmt(lk),
                fmt(paper[k]) if k < paper.size else "-",
                fmt(exact[k]),
                f"{ours[0]} / {theirs[0]}",
                f"{ours[1]} / {theirs[1]}",
            )
        )
    widths = [
        max(len(h), *(len(r[c]) for r in rows)) if rows else len(h) for c, h in enumerate(header)
    ]
    lines = [
        "  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)),
        "  ".join("-" * w for w in widths),
    ]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return "\n".join(line.rstrip() for line in lines)


# --- parser --------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    """The ``ami-xr`` argument parser (every option shows its default and units in --help)."""
    from ami_xr import __version__

    parser = argparse.ArgumentParser(
        prog="ami-xr",
        formatter_class=_Formatter,
        description="Experimental modal analysis with the Algorithm of Mode Isolation "
        "(Ginsberg & Allen) on labeled xarray data.\n\n"
        "Start with:  ami-xr demo",
        epilog="Exit codes: 0 ok, 1 error (one line on stderr; -v shows the traceback), "
        "2 usage error, 3 batch with failed files, 130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"ami_xr {__version__}")
    parser.add_argument(
        "-v", "--verbose", action="store_true", default=False, help="show tracebacks of errors"
    )
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        default=argparse.SUPPRESS,
        help="show tracebacks of errors",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def add(name: str, help_text: str, description: str) -> argparse.ArgumentParser:
        p = sub.add_parser(
            name,
            help=help_text,
            description=description,
            formatter_class=_Formatter,
            parents=[common],
        )
        p.set_defaults(_parser=p)
        return p

    p = add(
        "demo",
        "identify the paper's benchmark and compare with the paper",
        "Load the shipped benchmark FRFs (sample_data/, or simulate them when absent), run "
        "the identification, print the modal table next to the paper's AMI values and the "
        "simulator's exact values, and write modes.nc and a report/ folder.",
    )
    _add_output(p, "output folder", required=False, default=DEFAULT_DEMO_DIR)
    p.add_argument(
        "--simulate",
        action="store_true",
        help="simulate the benchmark even when sample data are present",
    )
    p.add_argument(
        "--noise",
        type=float,
        default=0.15,
        help="noise level alpha of eq. 15 (fraction of each signal's peak) when simulating",
    )
    p.add_argument("--seed", type=int, default=0, help="noise seed when simulating")
    p.add_argument("--no-report", action="store_true", help="skip the report (no matplotlib)")
    _add_identify_options(p)
    p.set_defaults(func=_cmd_demo)

    p = add(
        "simulate",
        "simulate a test system and write its FRFs",
        "Simulate a system with exactly known modes and write its FRFs (displacement "
        "receptance, m/N) as netCDF. beam-absorbers: the paper's benchmark (cantilever beam "
        "with three absorbers, unit impulse at the tip, FRFs = dt * FFT of the noisy impulse "
        "responses). random: a random lumped-mass chain or grid (analytic FRFs, noise on "
        "their real and imaginary parts).",
    )
    p.add_argument("system", choices=("beam-absorbers", "random"), help="which system")
    _add_output(p, "FRF netCDF file to write")
    p.add_argument(
        "--noise",
        type=float,
        default=0.15,
        help="noise level alpha of eq. 15 (fraction of each signal's peak; 0 = noise-free)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the noise (and of the random system) (reproducible)",
    )
    p.add_argument(
        "--truth-output",
        default=None,
        metavar="PATH",
        help="also write the exact modal parameters to this netCDF file",
    )
    g = p.add_argument_group("beam-absorbers options")
    g.add_argument("--duration", type=float, default=60.0, help="record length [s]")
    g.add_argument("--samples", type=int, default=4096, help="samples per record")
    g.add_argument(
        "--time-output",
        default=None,
        metavar="PATH",
        help="also write the impulse responses [m per N s] to this netCDF file",
    )
    g = p.add_argument_group("random options")
    g.add_argument("--points", type=int, default=8, help="measured points (5-50)")
    g.add_argument(
        "--topology",
        default="chain",
        choices=("chain", "grid"),
        help="masses in a grounded line, or on a grid clamped along one row",
    )
    g.add_argument(
        "--closely-spaced",
        action="store_true",
        help="add an absorber that makes two closely spaced modes",
    )
    g.add_argument("--weak-mode", action="store_true", help="add a weakly excited mode")
    g.add_argument(
        "--max-frequency",
        type=float,
        default=50.0,
        help="top of the frequency grid [Hz]; the highest mode is at 0.8 x this",
    )
    p.set_defaults(func=_cmd_simulate)

    p = add(
        "frf",
        "estimate FRFs from force and response time histories",
        "Read a time Dataset (netCDF, UFF dataset 58 time responses, or LabVIEW .lvm) and "
        "estimate FRFs with coherence (ami_xr.frf).",
    )
    p.add_argument("input", help="time-history file (.nc, .uff, .lvm)")
    _add_output(p, "FRF netCDF file to write")
    _add_frf_options(p)
    p.set_defaults(func=_cmd_frf)

    p = add(
        "identify",
        "identify modes from FRFs (subtraction, isolation, global fit)",
        "Run the Algorithm of Mode Isolation on an FRF file and print the modal table "
        "(mode, natural frequency in Hz and rad/s, damping ratio in %, FRFs that detected "
        "the mode, quality flags).",
    )
    p.add_argument("input", help="FRF file (.nc or .uff)")
    _add_output(
        p,
        "result file to write (.nc: FRFs + modal results; .uff: FRFs as dataset "
        "58 and mode shapes as dataset 55); omit to only print the table",
        required=False,
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    _add_identify_options(p)
    p.set_defaults(func=_cmd_identify)

    p = add(
        "report",
        "draw the figures and write an HTML report",
        "Write Bode, Nyquist, subtraction, mode-vector and MAC plots (PNG), the modal table "
        "(CSV) and an index.html showing them, from an identification result.",
    )
    p.add_argument("input", help="result file of 'ami-xr identify' (.nc)")
    _add_output(p, "report folder (created)")
    p.add_argument("--title", default=None, help="page title (default: from the source file)")
    p.set_defaults(func=_cmd_report)

    p = add(
        "convert",
        "convert between UFF and netCDF",
        "Convert a file by its suffixes: .uff/.unv (dataset 58 FRFs or time histories, 55 "
        "mode shapes) or .lvm -> .nc, and .nc -> .uff (FRFs as 58, modes as 55, time "
        "histories as 58).",
    )
    p.add_argument("input", help="input file (.uff, .unv, .lvm or .nc)")
    _add_output(p, "output file (.nc, .uff or .unv)")
    p.add_argument(
        "--binary",
        action="store_true",
        help="write UFF dataset 58 in binary (exact float64) instead of ASCII",
    )
    p.set_defaults(func=_cmd_convert)

    p = add(
        "batch",
        "identify every measurement file in a folder tree",
        "Process every .nc, .uff/.unv and .lvm file under DIR (time histories -> FRFs -> "
        "modes), writing OUTDIR/<same folders>/<stem>.modes.nc atomically. Files whose "
        "output is up to date (same input content and options) are skipped, so an "
        "interrupted run resumes. A bad file is reported and skipped. Prints and writes "
        "OUTDIR/batch_summary.csv; exits with 3 when any file failed.",
    )
    p.add_argument(
        "input", metavar="DIR", help="folder of measurement files (searched recursively)"
    )
    _add_output(p, "output folder (mirrors DIR)")
    p.add_argument("--workers", type=int, default=1, help="files processed in parallel (processes)")
    p.add_argument(
        "--report", action="store_true", help="also write <stem>.report/ folders (needs matplotlib)"
    )
    p.add_argument("--force", action="store_true", help="redo files whose outputs are up to date")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    _add_identify_options(p)
    _add_frf_options(p)
    p.set_defaults(func=_cmd_batch)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ami-xr``; returns the exit code (see the module docstring)."""
    parser = build_parser()
    args = parser.parse_args(argv)

    def show_warning(message, category, filename, lineno, file=None, line=None):
        # ami_xr's own warnings (no modes, no convergence) as one line each; warnings from
        # other packages (numpy internals) only with -v, with their source location.
        if issubclass(category, AmiXrWarning):
            text = " ".join(str(message).split())
            print(f"ami-xr {args.command}: warning: {category.__name__}: {text}", file=sys.stderr)
        elif args.verbose:
            print(
                warnings.formatwarning(message, category, filename, lineno, line).rstrip(),
                file=sys.stderr,
            )

    try:
        with warnings.catch_warnings():
            warnings.showwarning = show_warning
            return int(args.func(args) or EXIT_OK)
    except KeyboardInterrupt:
        print("ami-xr: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (AmiXrError, ValueError, OSError, ImportError) as err:
        if args.verbose:
            traceback.print_exc()
        print(f"ami-xr {args.command}: error: {_one_line(err)}", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
