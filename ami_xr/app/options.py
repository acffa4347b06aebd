"""Options of the ``ami-xr`` command line that several subcommands share.

The options of :func:`ami_xr.identify` (identify, batch, demo) and of :func:`ami_xr.frf` /
:func:`ami_xr.impact_frf` (frf, batch) are declared once, as tables, and read back from the
parsed arguments as keyword dictionaries. An option's default is that of the function's
parameter (:class:`Default`): nothing is restated here, and nothing is imported until a help
text shows a default or a given value is compared with it. Options left at their default are
not passed on (:func:`non_default`), so the library applies its own.
"""

from __future__ import annotations

import argparse
import math
import re
from functools import cached_property
from typing import Any

__all__ = [
    "BENCHMARK",
    "SCHEDULER_SCHEMES",
    "Default",
    "RANDOM_SYSTEM",
    "add_frf_options",
    "add_report_options",
    "add_identify_options",
    "add_stability_option",
    "frf_options",
    "identify_options",
    "memory_size",
    "scheduler_address",
    "stability_table",
    "non_default",
    "value",
]


class Default:
    """The default of ``parameter`` of the public function ``target`` ("module:name").

    Looked up (by importing the module) only when a help text shows it or a value is compared
    with it, so building the parser imports no library module and each number is typed only in
    the function's signature.
    """

    def __init__(self, target: str, parameter: str):
        self.target, self.parameter = target, parameter

    @cached_property
    def value(self) -> Any:
        import importlib
        import inspect

        module, name = self.target.split(":")
        function = getattr(importlib.import_module(module), name)
        return inspect.signature(function).parameters[self.parameter].default

    def __str__(self) -> str:
        return str(self.value)

    def __eq__(self, other: object) -> bool:
        return self.value == (other.value if isinstance(other, Default) else other)

    __hash__ = None  # type: ignore[assignment]  # compared by value, never a dict key


IDENTIFY = "ami_xr:identify"
FRF = "ami_xr:frf"
IMPACT = "ami_xr:impact_frf"
BENCHMARK = "ami_xr.simulate:benchmark"
RANDOM_SYSTEM = "ami_xr.simulate:random_system"


def value(v: Any) -> Any:
    """An option's value, with a lazy default looked up."""
    return v.value if isinstance(v, Default) else v


def non_default(args: argparse.Namespace, options: dict[str, Any]) -> dict[str, Any]:
    """Only the options the user changed: the library applies its own defaults (which the help
    shows), and batch parameter hashes match a Python call with the same settings."""
    parser: argparse.ArgumentParser = args.subcommand_parser
    return {
        k: v
        for k, v in options.items()
        if v is not None and not isinstance(v, Default) and v != parser.get_default(k)
    }


def ranged(
    kind: type,
    low: float | None = None,
    high: float | None = None,
    *,
    low_open: bool = False,
    high_open: bool = False,
):
    """An argparse ``type`` for a finite number of ``kind`` (int or float) within
    ``[low, high]`` (``low_open``/``high_open``: the bound itself excluded); argparse names the
    option in its message and exits 2 (a value out of range would fail deep in the work, or
    silently change what it means: ``--overload-samples -1`` rejects every hit)."""
    import math

    def parse(text: str):
        try:
            number = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected {'an integer' if kind is int else 'a number'}, got {text!r}"
            ) from None
        bad = not math.isfinite(number)
        bad = bad or (low is not None and (number <= low if low_open else number < low))
        bad = bad or (high is not None and (number >= high if high_open else number > high))
        if bad:
            raise argparse.ArgumentTypeError(
                f"expected {_range_text(kind, low, high, low_open, high_open)}, got {text!r}"
            )
        return number

    parse.__name__ = kind.__name__
    return parse


def _range_text(kind, low, high, low_open, high_open) -> str:
    what = "an integer" if kind is int else "a finite number"

    def num(x):
        return f"{x:g}" if isinstance(x, float) else str(x)

    if low is not None and high is not None:
        left, right = "(" if low_open else "[", ")" if high_open else "]"
        return f"{what} in {left}{num(low)}, {num(high)}{right}"
    if low is not None:
        return f"{what} {'>' if low_open else '>='} {num(low)}"
    if high is not None:
        return f"{what} {'<' if high_open else '<='} {num(high)}"
    return what


def _band(text: str) -> float | str:
    if text == "all":
        return text
    try:
        return ranged(float, 0.0, low_open=True)(text)
    except argparse.ArgumentTypeError as err:
        raise argparse.ArgumentTypeError(f"{err} (or 'all')") from None


#: Schemes of a dask.distributed scheduler address that another process can reach (``inproc``
#: lives inside one process).
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")
_HOST = re.compile(r"^(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_]([A-Za-z0-9_.-]*[A-Za-z0-9_])?)$")


def scheduler_address(text: str) -> str:
    """An argparse ``type`` for ``--scheduler``: ``[SCHEME://]HOST:PORT``, checked before any
    work (dask.distributed would take ``not-an-address`` for a host and fail deep in the run, or
    wait for a connection that cannot come). Returns ``text`` unchanged."""
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    host, colon, port = rest.rpartition(":")
    why = ""
    if scheme not in SCHEDULER_SCHEMES:
        why = f"unknown scheme {scheme!r}"
    elif not colon or not host:
        why = "no HOST:PORT"
    elif not _HOST.match(host):
        why = f"{host!r} is not a host name or address"
    elif not (port.isdigit() and 1 <= int(port) <= 65535):
        why = f"port {port!r} is not an integer in 1..65535"
    if why:
        raise argparse.ArgumentTypeError(
            f"expected a scheduler address [SCHEME://]HOST:PORT (SCHEME one of "
            f"{', '.join(SCHEDULER_SCHEMES)}; default tcp), e.g. tcp://localhost:8786, "
            f"got {text!r} ({why})"
        )
    return text


def memory_size(text: str) -> str:
    """An argparse ``type`` for ``--worker-memory``: a size dask understands (``2GB``,
    ``512MiB``, ``4e9`` bytes), a fraction in (0, 1] of this machine's memory, or ``auto``;
    checked before any work (``abc`` failed deep in the cluster's start). Returns ``text``
    unchanged (dask.distributed reads it)."""
    if text.strip() == "auto":
        return text
    try:
        from dask.utils import parse_bytes
    except ImportError:  # the command says that --workers needs dask.distributed
        return text
    try:
        number = float(text)
    except ValueError:
        number = None
    try:
        size = number if number is not None else parse_bytes(text)
        good = math.isfinite(size) and size > 0
    except (ValueError, OverflowError, TypeError):
        good = False
    if not good:
        raise argparse.ArgumentTypeError(
            "expected a memory size > 0 such as 2GB, 512MiB or 4e9 (bytes), a fraction in "
            f"(0, 1] of this machine's memory, or 'auto', got {text!r}"
        )
    return text


#: Largest --max-modes (the kernels count modes in int64 arrays sized by it).
MAX_MODES_LIMIT = 10_000
#: Largest --exponential-decay [1/s]: beyond, the window underflows to zero within a millisecond.
MAX_DECAY = 1e5

# --- options of ami_xr.identify and ami_xr.frf -------------------------------------------------
# (flag, function, type or choices, help[, metavar]): the option's default is that of the
# function's parameter of the flag's name; function None: default None (ami_xr.frf and
# ami_xr.impact_frf differ, the excitation decides).
IDENTIFY_OPTIONS = (
    (
        "--method",
        IDENTIFY,
        ("simo", "per_frf", "paper"),
        "simo: one eigenvalue fit over all FRFs per mode; per_frf: the paper's per-FRF fits "
        "averaged with SNR weights; paper: the paper's AMI exactly (plain mean, eq. 9 over "
        "bands, continuous basis, no refinement)",
    ),
    (
        "--delta",
        IDENTIFY,
        ranged(float, 0.0, 1.0, low_open=True, high_open=True),
        "subtraction: fit the lines with |G| >= delta * peak, in (0, 1)",
    ),
    (
        "--pfa",
        IDENTIFY,
        ranged(float, 0.0, 1.0, low_open=True, high_open=True),
        "subtraction: false-alarm probability of the automatic stop (a noise peak is taken "
        "for a mode with this probability)",
    ),
    ("--max-modes", IDENTIFY, ranged(int, 1, MAX_MODES_LIMIT), "subtraction: most modes per FRF"),
    (
        "--fmin",
        IDENTIFY,
        ranged(float, 0.0),
        "analysis band: lowest frequency [Hz] (default: where the excitation is valid for an "
        "FRF from ami-xr frf (force within 20 dB of its low-frequency level, coherence >= 0.8), "
        "else the first line)",
        "HZ",
    ),
    (
        "--fmax",
        IDENTIFY,
        ranged(float, 0.0),
        "analysis band: highest frequency [Hz] (default: as --fmin, the last line)",
        "HZ",
    ),
    (
        "--tol",
        IDENTIFY,
        ranged(float, 0.0, low_open=True),
        "isolation: relative change of Re and Im of every eigenvalue that ends the iteration "
        "(1e-4 = 0.01 %%)",
    ),
    ("--max-iter", IDENTIFY, ranged(int, 1, 10**6), "isolation: iteration cap"),
    (
        "--band",
        IDENTIFY,
        _band,
        "global fit: half-width of the band around each mode in half-power bandwidths "
        "2|Re lambda| [rad/s], or 'all' for every line",
    ),
)
FRF_OPTIONS = (
    (
        "--estimator",
        FRF,
        ("H1", "H2", "Hv"),
        "FRF estimator: H1 = Gfy/Gff (output noise), H2 = Gyy/Gyf (input noise), Hv (total "
        "least squares)",
    ),
    (
        "--window",
        None,
        str,
        "Welch window for random excitation (hann, boxcar, flattop, ...) (default: hann)",
    ),
    (
        "--nperseg",
        None,
        ranged(int, 1),
        "segment length [samples] (default: that of ami_xr.frf (random), the whole record "
        "(impact))",
    ),
    (
        "--noverlap",
        None,
        ranged(int, 0),
        "segment overlap [samples] (default: nperseg // 2 (random), 0 (impact))",
    ),
    ("--nfft", None, ranged(int, 1), "FFT length [samples] (default: nperseg)"),
    (
        "--detrend",
        None,
        ("constant", "linear", "none"),
        "detrend of each segment (default: constant (random), none (impact))",
    ),
    (
        "--average",
        FRF,
        ("linear", "exponential"),
        "averaging over segments or hits: linear (plain mean) or exponential (running, time "
        "constant --n-average); not scipy.signal.csd's average, which means mean or median",
    ),
    ("--n-average", FRF, ranged(int, 1), "time constant of exponential averaging [segments]"),
    (
        "--force-window",
        IMPACT,
        ranged(float, 0.0, low_open=True),
        "impact: force window width [s] (default: from the force pulse)",
        "SECONDS",
    ),
    (
        "--exponential-decay",
        IMPACT,
        ranged(float, 0.0, MAX_DECAY, low_open=True),
        "impact: exponential window decay rate [1/s] (its damping is removed again by "
        "identification) (default: none)",
        "PER_SECOND",
    ),
    (
        "--exponential-end-value",
        IMPACT,
        ranged(float, 0.0, 1.0, low_open=True, high_open=True),
        "impact: exponential window by its value at the record end [0-1], instead of "
        "--exponential-decay (default: none)",
        "FRACTION",
    ),
    (
        "--double-impact-threshold",
        IMPACT,
        ranged(float, 0.0, 1.0, low_open=True),
        "impact: second force pulse above this fraction of the peak = double impact",
        "FRACTION",
    ),
    (
        "--overload-samples",
        IMPACT,
        ranged(int, 1),
        "impact: this many samples at the channel's extreme = overload",
    ),
    (
        "--min-force",
        IMPACT,
        ranged(float, 0.0),
        "impact: reject hits whose peak force is below this [force units] (default: no minimum)",
        "NEWTON",
    ),
    (
        "--weak-force-ratio",
        IMPACT,
        ranged(float, 0.0, 1.0, high_open=True),
        "impact: reject hits weaker than this fraction of the median peak",
        "FRACTION",
    ),
)


def _dest(flag: str) -> str:
    return flag.lstrip("-").replace("-", "_")


def _add_options(group, spec: tuple) -> None:
    """One option per entry of ``spec`` (see IDENTIFY_OPTIONS)."""
    for flag, target, kind, help_text, *metavar in spec:
        kind = {"choices": kind} if isinstance(kind, tuple) else {"type": kind}
        default = None if target is None else Default(target, _dest(flag))
        group.add_argument(
            flag, default=default, help=help_text, metavar=metavar[0] if metavar else None, **kind
        )


def add_identify_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("identification options (ami_xr.identify)")
    _add_options(g, IDENTIFY_OPTIONS[:1])
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
    _add_options(g, IDENTIFY_OPTIONS[1:])
    g.add_argument(
        "--residual-terms",
        action="store_true",
        help="global fit: add lower and upper residual terms for out-of-band modes (measured FRFs)",
    )


def add_stability_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--stability",
        action="store_true",
        help="after identifying, re-run identify for pfa 1e-2..1e-5 on the band and on the band "
        "trimmed by 10%% at each end, and record how each mode holds (ami_xr.stability: "
        "stability_fraction, 1 = found in every variant; a figure in the report)",
    )


def stability_table(result) -> str:
    """Per mode: frequency, stability fraction and spread of the matched frequencies."""
    from ami_xr import names

    lines = ["mode  f [Hz]      stability  spread [Hz]  variants found/in band"]
    found = result[names.STABILITY_FOUND].transpose(names.MODE, ...).values
    in_band = result[names.STABILITY_IN_BAND].transpose(names.MODE, ...).values
    for k, mode in enumerate(result[names.MODE].values.tolist()):
        fn = float(result[names.NATURAL_FREQUENCY].values[k])
        frac = float(result[names.STABILITY_FRACTION].values[k])
        spread = float(result[names.STABILITY_FREQUENCY_SPREAD].values[k])
        lines.append(
            f"{mode!s:<5} {fn:<11.6g} {frac:<10.3g} {spread:<12.3g} "
            f"{int(found[k].sum())}/{int(in_band[k].sum())}"
        )
    return "\n".join(lines)


def identify_options(args: argparse.Namespace) -> dict[str, Any]:
    first, *rest = (_dest(spec[0]) for spec in IDENTIFY_OPTIONS)
    keys = (first, "refine", *rest, "residual_terms")
    return non_default(args, {k: getattr(args, k) for k in keys})


def add_frf_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("FRF estimation options (ami_xr.frf; time-history input only)")
    _add_options(g, FRF_OPTIONS[:1])
    g.add_argument(
        "--excitation",
        default="auto",
        choices=("auto", "random", "impact"),
        help="impact: every record is a hammer hit (checked, windowed, averaged; "
        "ami_xr.impact_frf); random: Welch segments (ami_xr.frf); auto: impact when the force "
        "is a short pulse, else random (the rule of ami_xr.dsp.timeseries.excitation_of, "
        "which ami_xr.frf also applies to warn about hammer data)",
    )
    split = [spec[0] for spec in FRF_OPTIONS].index("--double-impact-threshold")
    _add_options(g, FRF_OPTIONS[1:split])
    g.add_argument(
        "--no-hit-checks",
        action="store_true",
        help="impact: use every hit (no overload/double-impact/weak-force checks)",
    )
    _add_options(g, FRF_OPTIONS[split:])


def frf_options(args: argparse.Namespace) -> dict[str, Any]:
    keys = [_dest(spec[0]) for spec in FRF_OPTIONS]
    options = non_default(args, {k: getattr(args, k) for k in keys})
    if args.no_hit_checks:
        options["hit_checks"] = False
    if args.excitation != "auto":
        options["excitation"] = args.excitation
    return options


# --- options of ami_xr.report ------------------------------------------------------------------
class ReportFigures:
    """The figure names :func:`ami_xr.report` accepts, as argparse ``choices``: looked up (by
    importing ami_xr.report) only when a help text lists them or a given name is checked, so
    building the parser imports nothing and the list is never restated here."""

    @cached_property
    def names(self) -> tuple[str, ...]:
        from ami_xr.app.report import FIGURES, GEOMETRY_FIGURES, MEASUREMENT_FIGURES

        return (*MEASUREMENT_FIGURES, *FIGURES, *GEOMETRY_FIGURES)

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def __iter__(self):
        return iter(self.names)


class FrequencyRange(argparse.Action):
    """``--frequency-range FMIN FMAX``: two finite frequencies in Hz, 0 <= FMIN < FMAX; else a
    usage error (exit 2) naming the option."""

    def __call__(self, parser, namespace, values, option_string=None):
        import math

        f0, f1 = values
        if not (math.isfinite(f0) and math.isfinite(f1) and 0 <= f0 < f1):
            parser.error(
                f"argument {option_string}: expected 0 <= FMIN < FMAX (finite, Hz), "
                f"got {f0:g} {f1:g}"
            )
        setattr(namespace, self.dest, (f0, f1))


def add_report_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("figures (ami_xr.report)")
    g.add_argument(
        "--frequency-range",
        nargs=2,
        type=float,
        action=FrequencyRange,
        metavar=("FMIN", "FMAX"),
        help="band of the figures with a frequency axis (Bode, subtraction, coherence, force "
        "spectrum) [Hz] (default: the whole band)",
    )
    g.add_argument(
        "--figures",
        nargs="+",
        choices=ReportFigures(),
        metavar="NAME",
        help="draw only these figures, from: %(choices)s (default: every figure whose inputs "
        "are in the file)",
    )


#: What each subcommand reads and writes, for :func:`check_paths`: the argument names of its
#: inputs, and of its outputs with their kind (see :func:`ami_xr.io.formats.check_output`).
#: Every subcommand is listed (a test checks it), so a new one cannot skip the rule.
PATHS: dict[str, tuple[tuple[str, ...], tuple[tuple[str, str], ...]]] = {
    "demo": ((), (("output", "folder"),)),
    "simulate": (
        (),
        (("output", "netcdf"), ("time_output", "netcdf"), ("truth_output", "netcdf")),
    ),
    "frf": (("input",), (("output", "netcdf"),)),
    "identify": (("input",), (("output", "file"),)),
    "report": (("input",), (("output", "folder"),)),
    "convert": (("input",), (("output", "file"),)),
    # several inputs: _cmd_combine checks each, and the output against them
    "combine": ((), (("output", "netcdf"),)),
    "batch": (("input",), (("output", "folder"),)),
}


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Show defaults (unless the help states its own) and keep the description's line breaks.

    No "(default: None)": a required option has no default, and an option whose default is None
    (unset: the library or the excitation decides) says in its help what happens.
    """

    def _get_help_string(self, action):
        if "(default:" in (action.help or ""):
            return action.help
        if action.required or value(action.default) is None:
            return action.help
        return super()._get_help_string(action)


def check_paths(args: argparse.Namespace) -> None:
    """Apply the output rule (module docstring) to the paths of ``args.command``, before any work.

    Raises
    ------
    DataFileError
        Naming the option, the output and, where it clashes with one, the input; or an input
        that is missing or not a regular file (a folder for ``batch``).
    SystemExit
        Code 2 (a usage error, one line): ``batch DIR -o DIR``, the same folder.
    """
    from ami_xr.app.batch_files import BATCH_SAME_FOLDER, same_folder
    from ami_xr.io.formats import check_input, check_output

    reads, writes = PATHS[args.command]
    inputs = [value(getattr(args, a)) for a in reads]
    for path in inputs:  # a FIFO or device would block or never end the reader: refuse it now
        if path is not None:
            check_input(path, folder=args.command == "batch")
    if args.command == "batch" and same_folder(value(args.input), value(args.output)):
        parser: argparse.ArgumentParser = args.subcommand_parser  # a usage error: exit 2
        why = BATCH_SAME_FOLDER.format(path=str(value(args.output)))
        parser.exit(2, f"{parser.prog}: error: argument -o/--output: {why}\n")
    done: list[str] = []
    for attr, kind in writes:
        path = value(getattr(args, attr))
        if path is None:
            continue
        flag = "-o" if attr == "output" else "--" + attr.replace("_", "-")
        check_output(
            path, kind, inputs=inputs, outputs=done, name=flag, writer=f"ami-xr {args.command}"
        )
        done.append(str(path))
