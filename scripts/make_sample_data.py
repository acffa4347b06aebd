"""Write the paper's benchmark into sample_data/ exactly as the paper processed it.

Cantilever beam with three suspended absorbers (ami_xr.simulate.benchmark, J = 1 Ritz term),
unit impulse at the tip, 60 s record, 2^12 samples, 15 % uniform noise (eq. 15, seed 0):

    benchmark_impulse.nc        noisy impulse responses (point: tip, m1, m2, m3; time)
    benchmark_frf.nc            their FRFs, dt * rfft (frf_source = "impulse_response")
    benchmark_impulse_clean.nc  the same without noise
    benchmark_frf_clean.nc      the same without noise
    benchmark_truth.nc          exact eigenvalues, mode vectors and residues at the points

The files are written by ``ami_xr.to_netcdf``, the writer every ``ami-xr`` output goes through:
CF-1.11 (``Conventions``, ``title``, ``history``, ``long_name`` and UDUNITS units on every
variable, point labels as an auxiliary coordinate, complex values as a trailing real/imag dim).

Every run writes the same arrays up to floating-point rounding, which depends on the CPU
(numpy, BLAS and LAPACK pick their SIMD kernels at run time), and the same attributes apart from
timestamps and the version number. ``--check`` regenerates the files in a temporary folder,
writing nothing, and compares them with the ones in ``--output-dir``:

* the values, decoded, to the tolerance ``RTOL`` (see ``compare``);
* the files as stored (see ``compare_stored``): the same variables, dims, dtypes and every
  global and variable attribute, so a file written by an older writer (no ``Conventions``, a
  string ``point`` dimension coordinate, a unit UDUNITS cannot read) is reported;
* when the IOOS compliance checker is installed (``pip install 'ami_xr[cf]'``), each shipped
  file against ``cf:1.11`` at criteria ``normal`` (see ``cf_problems``); without it this part is
  skipped and the verdict says so.

It exits 0 when they agree and 1 otherwise. Usage::

    python scripts/make_sample_data.py [--output-dir sample_data] [--seed 0] [--noise 0.15]
    python scripts/make_sample_data.py --check [--output-dir sample_data]
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

import ami_xr

DEFAULT_DIR = Path(__file__).resolve().parents[1] / "sample_data"
NOISE = 0.15
SEED = 0
DURATION = 60.0
N_SAMPLES = 2**12
FILES = (
    "benchmark_impulse.nc",
    "benchmark_frf.nc",
    "benchmark_impulse_clean.nc",
    "benchmark_frf_clean.nc",
    "benchmark_truth.nc",
)
# Norm-wise relative tolerance of a regenerated array against the committed one. Every array is
# synthesised from an eigen-decomposition of the beam's state-space model (LAPACK, backward
# stable: eigenvalues and mode vectors relative to ~1e-15 times their condition, ~1e2 for the
# close pair at 65.0 / 65.9 rad/s), then exp(lambda t) over 2^12 samples and an FFT (relative
# ~eps log2 n); the noise of eq. 15 scales with the signal's peak. Rounding on another CPU stays
# below ~1e-13 of each array's largest magnitude (measured: 1.2e-15 absolute, ~1e-14 norm-wise);
# 1e-10 leaves a wide margin and still catches any change to the simulation.
RTOL = 1e-10


def write_sample_data(folder: Path, noise: float = NOISE, seed: int = SEED) -> list[Path]:
    """Simulate the benchmark and write the five files into ``folder``; return their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    params = {"noise": noise, "seed": seed, "duration": DURATION, "n_samples": N_SAMPLES}
    ts, g, truth = ami_xr.simulate.benchmark(**params)
    ts0, g0, _ = ami_xr.simulate.benchmark(**{**params, "noise": 0.0})
    out = []
    for name, ds, p in zip(
        FILES,
        (ts, g, ts0, g0, truth),
        (
            params,
            params,
            {**params, "noise": 0.0},
            {**params, "noise": 0.0},
            {"J": ami_xr.simulate.beam.DEFAULT_J},
        ),
        strict=True,
    ):
        out.append(
            ami_xr.to_netcdf(
                ds, folder / name, function="scripts/make_sample_data.py", parameters=p
            )
        )
    return out


def compare(new_folder: Path, old_folder: Path, rtol: float = RTOL) -> list[str]:
    """Problems found comparing the sample files in two folders (empty list: they agree).

    Float and complex arrays (data variables and coordinates) agree when
    ``max|new - old| <= rtol * max|old|``; every other array (labels, strings, ints) must be
    equal. A missing file, variable or a changed shape or dims is a problem.
    """
    problems = []
    for name in FILES:
        if not (old_folder / name).exists():
            problems.append(f"{old_folder / name}: missing")
            continue
        new = ami_xr.open_dataset(new_folder / name)
        old = ami_xr.open_dataset(old_folder / name)
        for kind, a_names, b_names in (
            ("variable", set(new.data_vars), set(old.data_vars)),
            ("coordinate", set(new.coords), set(old.coords)),
        ):
            if a_names != b_names:
                problems.append(f"{name}: {kind}s differ: {sorted(map(str, a_names ^ b_names))}")
        for var in sorted(set(new.variables) & set(old.variables), key=str):
            a, b = new[var], old[var]
            if a.dims != b.dims or a.shape != b.shape:
                problems.append(f"{name}: {var!s}: dims {a.dims}{a.shape} != {b.dims}{b.shape}")
                continue
            av, bv = np.asarray(a.values), np.asarray(b.values)
            if av.dtype.kind in "fc" and bv.dtype.kind in "fc":
                scale = float(np.max(np.abs(bv), initial=0.0))
                err = float(np.max(np.abs(av - bv), initial=0.0))
                if not err <= rtol * scale:
                    problems.append(
                        f"{name}: {var!s}: max |new - old| = {err:.3g} > {rtol:g} * {scale:.3g}"
                    )
            elif not np.array_equal(av, bv):
                problems.append(f"{name}: {var!s}: values differ")
    return problems


#: Text that differs between two runs of the same code: UTC timestamps (ISO 8601, as the
#: provenance writes them) and the version number in the provenance.
_VOLATILE = (
    (re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(?:\.\d+)?(?:Z|[+-]\d\d:\d\d)?"), "<time>"),
    (re.compile(r"(ami_xr[ _]version\W+|ami_xr )\d+(?:\.\d+)*\S*?(?=[\s\")]|$)"), r"\1<version>"),
)


def _stable(value) -> object:
    """An attribute value with its run-dependent text masked (see ``_VOLATILE``)."""
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    if isinstance(value, str):
        for pattern, mask in _VOLATILE:
            value = pattern.sub(mask, value)
        return value
    return np.asarray(value).tolist()


def _stored(path: Path) -> xr.Dataset:
    """The file as stored: no CF decoding, no masking, nothing of ami_xr's decoding."""
    with xr.open_dataset(path, decode_cf=False, mask_and_scale=False) as ds:
        return ds.load()


def _attr_problems(where: str, new: dict, old: dict) -> list[str]:
    problems = []
    for key in sorted(set(new) | set(old)):
        if key not in old:
            problems.append(f"{where}: attribute {key!r} missing (expected {new[key]!r:.60})")
        elif key not in new:
            problems.append(f"{where}: attribute {key!r} is not written by this code")
        elif _stable(new[key]) != _stable(old[key]):
            problems.append(
                f"{where}: attribute {key!r} is {old[key]!r:.60}, this code writes {new[key]!r:.60}"
            )
    return problems


def compare_stored(new_folder: Path, old_folder: Path) -> list[str]:
    """Problems found comparing the sample files in two folders as stored on disk (empty list:
    they agree): the same variables with the same dims and dtypes, and the same global and
    variable attributes apart from timestamps and version numbers. The values are ``compare``'s.
    """
    problems = []
    for name in FILES:
        if not (old_folder / name).exists():
            continue  # compare reports it
        new, old = _stored(new_folder / name), _stored(old_folder / name)
        problems += _attr_problems(f"{name}", new.attrs, old.attrs)
        if set(new.variables) != set(old.variables):
            problems.append(
                f"{name}: stored variables differ: only in the file "
                f"{sorted(map(str, set(old.variables) - set(new.variables)))}, only written "
                f"by this code {sorted(map(str, set(new.variables) - set(old.variables)))}"
            )
        for var in sorted(set(new.variables) & set(old.variables), key=str):
            a, b = new[var], old[var]
            if a.dims != b.dims or a.dtype.kind != b.dtype.kind:
                problems.append(
                    f"{name}: {var!s}: stored as {b.dims} {b.dtype}, this code writes "
                    f"{a.dims} {a.dtype}"
                )
            problems += _attr_problems(f"{name}: {var!s}", a.attrs, b.attrs)
    return problems


def cf_problems(folder: Path) -> list[str] | None:
    """Each sample file in ``folder`` against the IOOS compliance checker's ``cf:1.11`` at
    criteria ``normal`` (as tests/io/test_cf_compliance.py runs it): one problem per file that
    does not pass, with the checker's report. None when the checker is not installed."""
    from ami_xr.io.cf import compliance_report

    problems = []
    for name in FILES:
        path = folder / name
        if not path.exists():
            continue  # compare reports it
        result = compliance_report(path)
        if result is None:
            return None
        passed, text = result
        if not passed:
            problems.append(f"{name}: not CF-1.11 (IOOS compliance checker):\n{text.strip()}")
    return problems


def check(folder: Path) -> int:
    """Regenerate in a temporary folder, compare with ``folder``, print the verdict."""
    with tempfile.TemporaryDirectory() as tmp:
        write_sample_data(Path(tmp))
        problems = compare(Path(tmp), folder) + compare_stored(Path(tmp), folder)
    cf = cf_problems(folder)
    problems += cf or []
    for problem in problems:
        print(problem, file=sys.stderr)
    if problems:
        print(
            f"{folder}: the sample data do NOT agree with this code ({len(problems)} problems); "
            f"regenerate them: python scripts/make_sample_data.py --output-dir {folder}"
        )
        return 1
    checked = (
        "CF-1.11 checked by the IOOS compliance checker"
        if cf is not None
        else "CF check skipped: compliance_checker is not installed"
    )
    print(
        f"{folder}: all {len(FILES)} sample files agree with this code (values to tolerance "
        f"{RTOL:g}, attributes and layout as stored; {checked})"
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=DEFAULT_DIR)
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--noise", type=float, default=NOISE)
    parser.add_argument(
        "--check",
        action="store_true",
        help="compare --output-dir with a regeneration; write nothing",
    )
    args = parser.parse_args(argv)
    if args.check:
        return check(args.output_dir)
    for path in write_sample_data(args.output_dir, args.noise, args.seed):
        print(f"{path}  {path.stat().st_size / 1024:.0f} KiB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
