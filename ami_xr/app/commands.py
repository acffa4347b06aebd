"""The ``ami-xr`` subcommands: each maps its parsed options to one public function and returns
an exit code (:mod:`ami_xr.app.terminal`). Heavy imports happen inside each, so building the
parser (:mod:`ami_xr.app.parser`) imports no numpy."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ami_xr.app.options import frf_options, identify_options, stability_table, value
from ami_xr.app.terminal import (
    EXIT_BATCH_CAPPED,
    EXIT_BATCH_FAILURES,
    EXIT_OK,
    say,
)
from ami_xr.errors import AmiXrValueError


def wrote_frfs(g, path) -> str:
    from ami_xr import names

    size = g.sizes
    return f"wrote FRFs ({size[names.POINT]} points x {size[names.FREQUENCY]} lines) to {path}"


def cmd_demo(args: argparse.Namespace) -> int:
    from ami_xr.app.demo import demo

    demo(
        value(args.output),
        simulate=args.simulate,
        noise=value(args.noise),
        seed=value(args.seed),
        report=not args.no_report,
        identify_options=identify_options(args),
    )
    return EXIT_OK


def cmd_simulate(args: argparse.Namespace) -> int:
    import ami_xr

    if args.time_output and args.system != "beam-absorbers":
        raise AmiXrValueError("--time-output: only the beam-absorbers system has impulse responses")
    common = {"noise": value(args.noise), "seed": value(args.seed)}
    if args.system == "beam-absorbers":
        kwargs = {**common, "duration": value(args.duration), "n_samples": value(args.samples)}
        ts, g, truth = ami_xr.simulate.benchmark(**kwargs)
    else:
        kwargs = {
            "n_points": value(args.points),
            "topology": value(args.topology),
            **common,
            "closely_spaced": args.closely_spaced,
            "weak_mode": args.weak_mode,
            "max_frequency_hz": value(args.max_frequency),
        }
        ts, (g, truth) = None, ami_xr.simulate.random_system(**kwargs)
    params = {"system": args.system, **kwargs}
    # each write's record is the running command's (main), with the simulator's call as a step
    ami_xr.to_netcdf(g, args.output, parameters=params)
    say(wrote_frfs(g, args.output))
    for data, path, what in (
        (ts, args.time_output, "impulse responses"),
        (truth, args.truth_output, "exact modal parameters"),
    ):
        if path:
            ami_xr.to_netcdf(data, path, parameters=params)
            say(f"wrote {what} to {path}")
    return EXIT_OK


def _force_channel(text: str | None) -> int | str | None:
    """``--force-channel``: a column index when it is a number, else a column title."""
    return int(text) if text is not None and text.strip().isdigit() else text


def cmd_frf(args: argparse.Namespace) -> int:
    import ami_xr
    from ami_xr import names
    from ami_xr.dsp.frf import frf_from_options
    from ami_xr.dsp.timeseries import excitation_of
    from ami_xr.io.formats import read_any

    reader = {
        "force_channel": _force_channel(args.force_channel),
        "points": [p.strip() for p in args.points.split(",")] if args.points else None,
        "drive_point": args.drive_point,
    }
    ts = read_any(args.input, want="time", **reader)
    options = frf_options(args)
    if "excitation" not in options:  # auto: the rule ami_xr.frf_from_options applies too
        options["excitation"] = excitation_of(ts)
        impact = options["excitation"] == "impact"
        why = "the force is a short pulse" if impact else "the force is not a short pulse"
        say(f"excitation: {options['excitation']} ({why}; --excitation sets it)")
    g = frf_from_options(ts, options)
    if names.HIT_REJECTED in g:  # impact test: say which hits were left out and why
        rejected = g[names.HIT_REJECTED].values.astype(bool)
        reason = names.HIT_REJECT_REASON
        reasons = g[reason].values if reason in g else [""] * rejected.size
        say(f"hits: {rejected.size}, used {int((~rejected).sum())}")
        for i in range(rejected.size):
            if rejected[i]:
                say(f"  hit {i} rejected: {reasons[i]}")
    given = {k: v for k, v in reader.items() if v is not None}
    # the write's record is the running command's (main), the read and the FRF its steps
    ami_xr.to_netcdf(g, args.output, parameters={**given, **options})
    say(wrote_frfs(g, args.output))
    return EXIT_OK


def _frf_first(path: str) -> str:
    stem = Path(path).stem
    return (
        f"input {path!r} holds time histories, identify needs FRFs: run "
        f"'ami-xr frf {path} -o {stem}_frf.nc' first, then 'ami-xr identify {stem}_frf.nc'"
    )


def cmd_identify(args: argparse.Namespace) -> int:
    import ami_xr
    from ami_xr import names
    from ami_xr.app.cluster import cluster, read_frfs
    from ami_xr.io.formats import LVM_SUFFIX, read_any, write_any
    from ami_xr.progress import on_a_terminal, on_terminal
    from ami_xr.tables import format_modal_table

    if Path(args.input).suffix.lower() == LVM_SUFFIX:  # always time histories: say so unread
        raise AmiXrValueError(_frf_first(args.input))
    from ami_xr.io.kinds import ModesFileError
    from ami_xr.io.reference_modes import compare_modes, format_reference_table
    from ami_xr.io.reference_modes import split_frf_and_modes as split

    given = None  # modes stored with the FRFs: identify the FRFs, compare with those modes
    try:
        ds = read_frfs(args.input, args)  # lazy, chunked along point with --workers/--scheduler
    except ModesFileError as refused:
        both = read_any(args.input)
        if names.FRF not in both:  # modes only: nothing to identify
            raise refused from None
        ds, given = split(both, args.input)
        n = given.sizes[names.MODE]
        say(f"{args.input}: FRFs and {n} modes; the FRFs are identified, the modes compared")
    if names.FRF not in ds and names.TIME in ds.dims:
        raise AmiXrValueError(_frf_first(args.input))
    if args.conjugate:  # the other sign convention (ami_xr.dsp.convention)
        ds = ds.assign({names.FRF: ds[names.FRF].conj()})
    options = identify_options(args)
    # a phase bar on a terminal once the work takes more than a couple of seconds
    with cluster(args):
        result = ami_xr.identify(ds, progress=on_terminal(not args.quiet), **options)
    say(format_modal_table(result))
    if given is not None:
        result = compare_modes(result, given)
        say(format_reference_table(result))
    if args.stability:  # the variants take their own pfa and band; the other options stay
        others = {k: v for k, v in options.items() if k != "pfa"}
        show = not args.quiet and on_a_terminal()  # False, not an error, when stderr is closed
        result = ami_xr.stability(ds, result, progress=show, **others)
        say(stability_table(result))
    if args.output:  # one record, the running command's (main), with identify as its step
        write_any(result, args.output, parameters={"input": args.input, **options})
        say(f"wrote modes to {args.output}")
    from ami_xr.core.flags import run_status  # numpy: not on the --help path

    caps = run_status(result.attrs).text()
    if caps:  # the last line says the result is incomplete (batch: status "capped")
        say(f"incomplete: stopped at cap(s) {caps}; modes may be missing (see the warnings)")
    return EXIT_OK


def cmd_report(args: argparse.Namespace) -> int:
    from ami_xr.app.report import report
    from ami_xr.io.atomic import atomic_folder
    from ami_xr.io.formats import read_any

    ds = read_any(args.input)
    # written into a temporary folder and swapped in whole: never a partial or mixed report
    with atomic_folder(args.output) as tmp:
        index = report(
            ds,
            tmp,
            title=args.title,
            figures=args.figures,
            frequency_range=args.frequency_range,
            reference=args.reference,
        )
    say(f"wrote report to {Path(args.output) / Path(index).name}")
    return EXIT_OK


def cmd_convert(args: argparse.Namespace) -> int:
    from ami_xr.io.formats import read_any, write_any

    src = Path(args.input)
    ds = read_any(src)
    out = write_any(
        ds,
        args.output,
        binary=args.binary,
        parameters={"input": str(src)},  # the running command's record (main)
    )
    say(f"converted {src} -> {out}")
    return EXIT_OK


def cmd_combine(args: argparse.Namespace) -> int:
    import ami_xr
    from ami_xr import names
    from ami_xr.io.formats import check_input, check_output

    for path in args.input:
        check_input(path)
    check_output(args.output, "netcdf", inputs=args.input, name="-o", writer="ami-xr combine")
    g = ami_xr.combine_runs(args.input, drive_point=args.drive_point, layout=args.layout)
    ami_xr.to_netcdf(g, args.output, parameters={"inputs": args.input, "layout": args.layout})
    say(f"{g.attrs['combine_layout']}; drive point {g.attrs.get(names.ATTR_DRIVE_POINT)!r}")
    say(wrote_frfs(g, args.output) + f" from {len(args.input)} runs")
    return EXIT_OK


def cmd_batch(args: argparse.Namespace) -> int:
    from ami_xr.app.batch import batch
    from ami_xr.progress import notice

    workers = value(args.workers)
    if isinstance(workers, int) and workers > 1:  # one worker always has a core
        # the count the workers' compute threads are shared by (the batch imports it then too)
        from ami_xr.kernels.projection import usable_cores

        cores = usable_cores()
        if workers > cores:  # not an error: the results are the same, only slower than expected
            notice(
                f"ami-xr batch: --workers {workers} exceeds the {cores} core(s) this process "
                f"may run on: the workers share them (one compute thread each), so the batch "
                f"is no faster than with --workers {cores}"
            )
    summary = batch(
        args.input,
        args.output,
        workers=value(args.workers),
        identify_options=identify_options(args),
        frf_options=frf_options(args),
        report=args.report,
        force=args.force,
        progress=not args.quiet,
        keep_tracebacks=args.verbose,
    )
    say(summary.format())
    say(f"summary: {summary.csv_path}")
    if args.verbose:
        for row in summary.rows:
            if row.get("traceback"):
                print(f"--- {row['file']}\n{row['traceback']}", file=sys.stderr)
    if summary.n_failed:
        return EXIT_BATCH_FAILURES
    return EXIT_BATCH_CAPPED if summary.n_capped else EXIT_OK
