"""The demo behind ``ami-xr demo``: identify the paper's benchmark and compare with the paper.

:func:`demo` loads the shipped benchmark FRFs (:func:`find_sample_frf`; simulated when absent),
identifies the modes, prints the modal table next to the paper's AMI averages and the
simulator's exact values (:func:`comparison_table`), and writes ``modes.nc`` and a report
folder. It prints to stdout: it is a walk-through for a person, not a building block.
"""

from __future__ import annotations

import inspect
import os
from pathlib import Path
from typing import Any

__all__ = ["DEFAULT_OUTPUT_DIR", "comparison_table", "demo", "find_sample_frf"]

#: Folder the demo writes into when none is given (relative to the working directory).
DEFAULT_OUTPUT_DIR = "ami_xr_demo"
SAMPLE_FOLDER = "sample_data"
# Noise-free sample files are not the benchmark the paper analysed.
_CLEAN_MARKERS = ("clean", "noise_free", "noisefree")


def _say(*parts: Any) -> None:
    print(*parts, flush=True)


def find_sample_frf() -> Path | None:
    """The shipped benchmark FRF file (noisy, paper's seed), or None when there is none.

    Looked for in ``./sample_data`` (the README runs the demo from the repository root, where a
    plain ``pip install .`` leaves the package in site-packages) and then beside the package
    (an editable install or a source checkout).
    """
    here = Path(__file__).resolve().parents[1]
    for folder in (Path.cwd() / SAMPLE_FOLDER, here / SAMPLE_FOLDER):
        if not folder.is_dir():
            continue
        for pattern in ("*benchmark*frf*.nc", "*frf*.nc"):
            for path in sorted(folder.glob(pattern)):
                if not any(marker in path.name.lower() for marker in _CLEAN_MARKERS):
                    return path
    return None


def comparison_table(identified, exact, paper) -> str:
    """Identified eigenvalues next to the paper's AMI results and the exact values.

    Parameters
    ----------
    identified, exact, paper : array_like of complex
        Eigenvalues in rad/s: identified (any number), exact (the simulator's) and the paper's
        AMI averages (one per exact mode, in the same order).

    Returns
    -------
    str
        An aligned text table: each identified mode beside its nearest exact mode, with the
        natural-frequency and damping-ratio errors (%) of ours and of the paper's.
    """
    import numpy as np

    exact, paper = np.asarray(exact), np.asarray(paper)

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
    for i, lk in enumerate(identified):
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


def _benchmark_frf(simulate: bool, noise: float | None, seed: int | None):
    """The benchmark FRFs: the shipped sample file, else simulated (benchmark's defaults for
    ``noise`` and ``seed`` when None)."""
    import ami_xr
    from ami_xr.errors import AmiXrValueError, DataFileError

    sample = None if simulate else find_sample_frf()
    if sample is not None:
        g = ami_xr.open_dataset(sample)
        try:  # structure only: a stray *frf*.nc in sample_data/ must fail here, in one line
            ami_xr.validate(g, "frf", require_drive_point=False, check_values=False)
        except AmiXrValueError as err:
            detail = "; ".join(getattr(err, "problems", ())) or str(err)
            raise DataFileError(
                f"{sample}: not an FRF file the demo can use ({detail}); move it out of "
                f"{sample.parent} or run the demo with --simulate"
            ) from err
        _say(f"benchmark FRFs: {sample}")
        return g
    defaults = inspect.signature(ami_xr.simulate.benchmark).parameters
    noise = defaults["noise"].default if noise is None else noise
    seed = defaults["seed"].default if seed is None else seed
    _, g, _ = ami_xr.simulate.benchmark(noise=noise, seed=seed)
    _say(f"benchmark FRFs: simulated (noise {noise}, seed {seed})")
    return g


def demo(
    output_dir: str | os.PathLike = DEFAULT_OUTPUT_DIR,
    *,
    simulate: bool = False,
    noise: float | None = None,
    seed: int | None = None,
    report: bool = True,
    identify_options: dict[str, Any] | None = None,
    progress: bool = True,
) -> Path:
    """Identify the paper's benchmark, print the comparison with the paper, write the results.

    Parameters
    ----------
    output_dir : str or path-like, default "ami_xr_demo"
        Folder (created) for ``modes.nc`` and the ``report/`` folder.
    simulate : bool, default False
        Simulate the benchmark even when a sample file is found (:func:`find_sample_frf`).
    noise, seed : optional
        Noise level alpha (eq. 15) and seed when simulating; default those of
        :func:`ami_xr.simulate.benchmark`.
    report : bool, default True
        Also write the report (skipped, with a note, when matplotlib is not installed).
    identify_options : dict, optional
        Keyword arguments of :func:`ami_xr.identify`.
    progress : bool, default True
        Show the elapsed time of the identification on a terminal.

    Returns
    -------
    pathlib.Path
        The ``modes.nc`` written.

    Raises
    ------
    DataFileError
        Before any work: ``output_dir`` is an existing file or not writable, or its
        ``modes.nc`` exists and is read-only (see :func:`ami_xr.io.formats.check_output`); or the
        sample file found is not an FRF file.
    """
    import importlib.util

    import numpy as np

    import ami_xr
    from ami_xr import names
    from ami_xr.io.formats import OUTPUT_FOLDER, OUTPUT_NETCDF, check_output
    from ami_xr.progress import on_terminal
    from ami_xr.simulate.paper import AMI_EIGENVALUES
    from ami_xr.tables import format_modal_table

    options = dict(identify_options or {})
    # Every output is checked before the identification, which is the slow part.
    outdir = check_output(output_dir, OUTPUT_FOLDER, name="output_dir")
    modes_file = outdir / "modes.nc"
    if outdir.is_dir():
        check_output(modes_file, OUTPUT_NETCDF, name="output_dir", writer="demo")
    if report:
        check_output(outdir / "report", OUTPUT_FOLDER, name="output_dir")
    truth = ami_xr.simulate.benchmark_model()
    g = _benchmark_frf(simulate, noise, seed)
    n = g.sizes.get(names.POINT, 0)
    _say(
        f"  {n} points {list(map(str, g[names.POINT].values))} x "
        f"{g.sizes[names.FREQUENCY]} lines, 0-{float(g[names.FREQUENCY][-1]):.4g} Hz, drive point "
        f"{g.attrs.get(names.ATTR_DRIVE_POINT)}\n"
    )
    result = ami_xr.identify(g, progress=on_terminal(progress), **options)
    _say(format_modal_table(result))
    lam = np.atleast_1d(result[names.EIGENVALUE].values) if names.EIGENVALUE in result else []
    _say("\n" + comparison_table(lam, truth[names.EIGENVALUE].values, AMI_EIGENVALUES))
    _say(
        "\nerrors: natural frequency and damping ratio vs the simulator's exact values; "
        "paper AMI = the averages of Tables 1-2 of Ginsberg & Allen (one noise seed)"
    )
    outdir.mkdir(parents=True, exist_ok=True)
    modes_path = ami_xr.to_netcdf(result, modes_file)  # identify recorded itself already
    _say(f"\nwrote {modes_path}")
    if report:
        if importlib.util.find_spec("matplotlib") is None:
            # the report is the one optional part of the demo: say how to get it, do not fail
            _say("no report: it needs matplotlib (pip install 'ami_xr[plot]')")
        else:
            from ami_xr.app.report import report as write_report

            title = "ami_xr demo: paper benchmark"
            _say(f"wrote {write_report(result, outdir / 'report', title=title)}")
    return modes_path
