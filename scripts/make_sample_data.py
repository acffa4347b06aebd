"""Write the paper's benchmark into sample_data/ exactly as the paper processed it.

Cantilever beam with three suspended absorbers (ami_xr.simulate.benchmark, J = 1 Ritz term),
unit impulse at the tip, 60 s record, 2^12 samples, 15 % uniform noise (eq. 15, seed 0):

    benchmark_impulse.nc        noisy impulse responses (point: tip, m1, m2, m3; time)
    benchmark_frf.nc            their FRFs, dt * rfft (frf_source = "impulse_response")
    benchmark_impulse_clean.nc  the same without noise
    benchmark_frf_clean.nc      the same without noise
    benchmark_truth.nc          exact eigenvalues, mode vectors and residues at the points

Every run writes the same arrays (only the provenance timestamps differ). Usage::

    python scripts/make_sample_data.py [--output-dir sample_data] [--seed 0] [--noise 0.15]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import ami_xr

DEFAULT_DIR = Path(__file__).resolve().parents[1] / "sample_data"
NOISE = 0.15
SEED = 0
DURATION = 60.0
N_SAMPLES = 2**12


def write_sample_data(folder: Path, noise: float = NOISE, seed: int = SEED) -> list[Path]:
    """Simulate the benchmark and write the five files into ``folder``; return their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    params = {"noise": noise, "seed": seed, "duration": DURATION, "n_samples": N_SAMPLES}
    ts, g, truth = ami_xr.simulate.benchmark(**params)
    ts0, g0, _ = ami_xr.simulate.benchmark(**{**params, "noise": 0.0})
    out = []
    for name, ds, p in (
        ("benchmark_impulse.nc", ts, params),
        ("benchmark_frf.nc", g, params),
        ("benchmark_impulse_clean.nc", ts0, {**params, "noise": 0.0}),
        ("benchmark_frf_clean.nc", g0, {**params, "noise": 0.0}),
        ("benchmark_truth.nc", truth, {"J": ami_xr.simulate.beam.DEFAULT_J}),
    ):
        out.append(
            ami_xr.to_netcdf(
                ds, folder / name, function="scripts/make_sample_data.py", parameters=p
            )
        )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=DEFAULT_DIR)
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--noise", type=float, default=NOISE)
    args = parser.parse_args(argv)
    for path in write_sample_data(args.output_dir, args.noise, args.seed):
        print(f"{path}  {path.stat().st_size / 1024:.0f} KiB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
