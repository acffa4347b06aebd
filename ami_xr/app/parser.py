"""The ``ami-xr`` argument parser: the subcommands, their options and help texts (every option
shows its default and units in --help); each subcommand runs a function of
:mod:`ami_xr.app.commands`."""

from __future__ import annotations

import argparse
from typing import Any

from ami_xr.app.cluster import add_cluster_options
from ami_xr.app.commands import (
    cmd_batch,
    cmd_combine,
    cmd_convert,
    cmd_demo,
    cmd_frf,
    cmd_identify,
    cmd_report,
    cmd_simulate,
)
from ami_xr.app.options import (
    BENCHMARK,
    RANDOM_SYSTEM,
    Default,
    HelpFormatter,
    add_frf_options,
    add_identify_options,
    add_report_options,
    add_stability_option,
    ranged,
)
from ami_xr.progress import DELAY_SECONDS


def _add_output(
    p: argparse.ArgumentParser, what: str, required: bool = True, default: Any = None
) -> None:
    if required:  # no default to show: argparse refuses the command without it
        default = argparse.SUPPRESS
    p.add_argument("-o", "--output", required=required, default=default, metavar="PATH", help=what)


def _add_demo(add) -> None:
    p = add(
        "demo",
        "identify the paper's benchmark and compare with the paper",
        "Load the shipped benchmark FRFs (sample_data/, or simulate them when absent), run "
        "the identification, print the modal table next to the paper's AMI values and the "
        "simulator's exact values, and write modes.nc and a report/ folder.",
    )
    _add_output(
        p, "output folder", required=False, default=Default("ami_xr.app.demo:demo", "output_dir")
    )
    p.add_argument(
        "--simulate",
        action="store_true",
        help="simulate the benchmark even when sample data are present",
    )
    _add_noise_seed(
        p,
        "noise level alpha of eq. 15 (fraction of each signal's peak) when simulating",
        "noise seed when simulating",
    )
    p.add_argument("--no-report", action="store_true", help="skip the report (no matplotlib)")
    add_identify_options(p)
    p.set_defaults(func=cmd_demo)


def _add_noise_seed(p, noise_help: str, seed_help: str) -> None:
    """``--noise`` and ``--seed`` of the simulated benchmark (defaults from ``benchmark``)."""
    p.add_argument(
        "--noise", type=ranged(float, 0.0), default=Default(BENCHMARK, "noise"), help=noise_help
    )
    p.add_argument(
        "--seed",
        type=ranged(int, 0, 2**32 - 1),
        default=Default(BENCHMARK, "seed"),
        help=seed_help,
    )


def _add_simulate(add) -> None:
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
    _add_noise_seed(
        p,
        "noise level alpha of eq. 15 (fraction of each signal's peak; 0 = noise-free)",
        "seed of the noise (and of the random system) (reproducible)",
    )
    p.add_argument(
        "--truth-output",
        default=None,
        metavar="PATH",
        help="also write the exact modal parameters to this netCDF file (default: not written)",
    )
    g = p.add_argument_group("beam-absorbers options")
    g.add_argument(
        "--duration",
        type=ranged(float, 0.0, low_open=True),
        default=Default(BENCHMARK, "duration"),
        help="record length [s]",
    )
    g.add_argument(
        "--samples",
        type=ranged(int, 2),
        default=Default(BENCHMARK, "n_samples"),
        help="samples per record",
    )
    g.add_argument(
        "--time-output",
        default=None,
        metavar="PATH",
        help="also write the impulse responses [m per N s] to this netCDF file (default: not "
        "written)",
    )
    g = p.add_argument_group("random options")
    g.add_argument(
        "--points",
        type=ranged(int, 5, 50),
        default=Default(RANDOM_SYSTEM, "n_points"),
        help="measured points (5-50)",
    )
    g.add_argument(
        "--topology",
        default=Default(RANDOM_SYSTEM, "topology"),
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
        type=ranged(float, 0.0, low_open=True),
        default=Default(RANDOM_SYSTEM, "max_frequency_hz"),
        help="top of the frequency grid [Hz]; the highest mode is at 0.8 x this",
    )
    p.set_defaults(func=cmd_simulate)


def _add_file_commands(add) -> None:
    """frf, identify, report and convert: one input file each."""
    p = add(
        "frf",
        "estimate FRFs from force and response time histories",
        "Read a time Dataset (netCDF, UFF dataset 58 time responses, LabVIEW .lvm, or MATLAB "
        ".mat channels with a sampling rate: see ami_xr.io.time_mat) and "
        "estimate FRFs with coherence (ami_xr.frf).",
    )
    p.add_argument("input", help="time-history file (.nc, .uff, .lvm, .mat)")
    _add_output(p, "FRF netCDF file to write")
    g = p.add_argument_group("channels (what the file does not say)")
    g.add_argument(
        "--force-channel",
        metavar="INDEX_OR_TITLE",
        help=".lvm, .mat: the force channel, by column index (0 = first) or title (default: "
        "the channel with a force unit (N, kN, lbf) or 'force' in its title)",
    )
    g.add_argument(
        "--points",
        metavar="LABELS",
        help=".lvm, .mat: comma-separated labels of the response channels, in file order "
        "(default: their column titles)",
    )
    g.add_argument(
        "--drive-point",
        metavar="LABEL",
        help="label of the response point where the force acts (default: the file's; for .lvm "
        "the single response channel, reported as an assumption and recorded as "
        "drive_point_assumed)",
    )
    add_frf_options(p)
    p.set_defaults(func=cmd_frf)

    p = add(
        "identify",
        "identify modes from FRFs (subtraction, isolation, global fit)",
        "Run the Algorithm of Mode Isolation on an FRF file and print the modal table "
        "(mode, natural frequency in Hz and rad/s, damping ratio in %, FRFs that detected "
        "the mode, quality flags).",
    )
    p.add_argument("input", help="FRF file (.nc, .uff/.unv, or an FRF table: .csv/.txt/.dat, .mat)")
    _add_output(
        p,
        "result file to write (.nc: FRFs + modal results; .uff: FRFs as dataset "
        "58 and mode shapes as dataset 55) (default: none, only print the table)",
        required=False,
    )
    add_stability_option(p)
    p.add_argument(
        "--conjugate",
        action="store_true",
        help="use the complex conjugate of the FRFs read (data exported with the e^{-iwt} sign "
        "convention; ami_xr's is e^{+iwt}, see ami_xr.dsp.convention)",
    )
    p.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="no progress bar (otherwise drawn on stderr, on a terminal, once identification "
        f"has run {DELAY_SECONDS:g} s: phases done, and inside the running phase the FRFs "
        "done or the refinement's modes and iterations)",
    )
    add_identify_options(p)
    add_cluster_options(p)
    p.set_defaults(func=cmd_identify)

    p = add(
        "report",
        "draw the figures and write an HTML report",
        "Write Bode, Nyquist, subtraction, mode-vector and MAC plots (PNG), the modal table "
        "(CSV) and an index.html showing them, from an identification result.",
    )
    p.add_argument("input", help="result file of 'ami-xr identify' (.nc)")
    _add_output(p, "report folder (created)")
    p.add_argument("--title", default=None, help="page title (default: from the source file)")
    p.add_argument(
        "--reference",
        metavar="LABEL",
        default=None,
        help="multi-reference result: draw the FRFs of this reference only (default: every "
        "reference, FRF figures once per reference; both show the participation per reference, "
        "drive-point consistency and the MAC within close pairs)",
    )
    add_report_options(p)
    p.set_defaults(func=cmd_report)

    p = add(
        "convert",
        "convert between UFF and netCDF",
        "Convert a file by its suffixes: .uff/.unv (dataset 58 FRFs or time histories, 55 "
        "mode shapes), .lvm or an FRF table (.csv/.txt/.dat, .mat) -> .nc, and .nc -> .uff "
        "(FRFs as 58, modes as 55, time histories as 58).",
    )
    p.add_argument("input", help="input file (.uff, .unv, .lvm, .csv, .txt, .dat, .mat or .nc)")
    _add_output(p, "output file (.nc, .uff or .unv)")
    p.add_argument(
        "--binary",
        action="store_true",
        help="write UFF dataset 58 in binary (exact float64) instead of ASCII",
    )
    p.set_defaults(func=cmd_convert)


def _add_combine(add) -> None:
    p = add(
        "combine",
        "one FRF set from the runs of a roving test",
        "Combine FRF files measured in runs (ami_xr.combine_runs): a roving response (the runs "
        "share the excitation, each measured other points) or a roving hammer (the runs share "
        "one response point; by reciprocity the hammer positions become the points). Points are "
        "concatenated; each run's force autospectrum, coherence and noise are kept, the run of "
        "each point is recorded (point_run), and the frequency lines, units and drive point are "
        "checked to agree (an error names the run that differs).",
    )
    p.add_argument("input", nargs="+", help="FRF files of the runs (.nc, .uff/.unv, tables)")
    _add_output(p, "FRF netCDF file to write")
    p.add_argument(
        "--drive-point",
        metavar="LABEL",
        type=_label,
        default=None,
        help="roving response: where the shaker acts, for runs that do not state it; roving "
        "hammer: the response point (default: what the runs state)",
    )
    p.add_argument(
        "--layout",
        choices=("auto", "roving_response", "roving_hammer"),
        default="auto",
        help="auto: a roving hammer when every run has the same one response point and its own "
        "drive point, else a roving response",
    )
    p.set_defaults(func=cmd_combine)


def _label(text: str) -> int | str:
    """A point label: an integer when the text is one, else the text."""
    return int(text) if text.strip().lstrip("-").isdigit() else text


def _add_batch(add) -> None:
    p = add(
        "batch",
        "identify every measurement file in a folder tree",
        "Process every .nc, .uff/.unv and .lvm file under DIR (time histories -> FRFs -> "
        "modes), writing OUTDIR/<same folders>/<stem>.modes.nc atomically. Files whose "
        "output is up to date (same input content and options) are skipped, so an "
        "interrupted run resumes. A bad file is reported and skipped. Prints and writes "
        "OUTDIR/batch_summary.csv; exits with 3 when any file failed, 4 when none failed but some "
        "stopped at a cap (status capped).",
    )
    p.add_argument(
        "input", metavar="DIR", help="folder of measurement files (searched recursively)"
    )
    _add_output(p, "output folder (mirrors DIR)")
    p.add_argument(
        "--workers",
        type=ranged(int, 1, 1024),
        default=Default("ami_xr.app.batch:batch", "workers"),
        help="files processed in parallel (processes)",
    )
    p.add_argument(
        "--report", action="store_true", help="also write <stem>.report/ folders (needs matplotlib)"
    )
    p.add_argument("--force", action="store_true", help="redo files whose outputs are up to date")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="no progress bar (files done, on stderr)"
    )
    add_identify_options(p)
    add_frf_options(p)
    p.set_defaults(func=cmd_batch)


def build_parser() -> argparse.ArgumentParser:
    """The ``ami-xr`` argument parser (every option shows its default and units in --help)."""
    from ami_xr import __version__

    parser = argparse.ArgumentParser(
        prog="ami-xr",
        formatter_class=HelpFormatter,
        description="Experimental modal analysis with the Algorithm of Mode Isolation "
        "(Ginsberg & Allen) on labeled xarray data.\n\n"
        "Start with:  ami-xr demo",
        epilog="Exit codes: 0 ok, 1 error (one line on stderr; -v shows the traceback), "
        "2 usage error, 3 batch with failed files, 4 batch with capped (incomplete) results, "
        "130 interrupted.",
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
            formatter_class=HelpFormatter,
            parents=[common],
        )
        p.set_defaults(subcommand_parser=p)
        return p

    for add_command in (_add_demo, _add_simulate, _add_file_commands, _add_combine, _add_batch):
        add_command(add)
    return parser
