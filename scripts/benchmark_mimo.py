"""Multi-reference identification of repeated roots: one, two and three references (issue 13).

    python scripts/benchmark_mimo.py               # 20 noise seeds at 1 % and 5 % noise
    python scripts/benchmark_mimo.py --seeds 50
    python scripts/benchmark_mimo.py --quick       # 2 seeds (a smoke test)

The structure is :func:`ami_xr.simulate.symmetric_structure`: a grounded ring of 6 equal masses
(points 1..6) with modes at 10 Hz, a pair at 17.3 Hz (modes 2, 3), a pair at 26.5 Hz (modes 4,
5) and 30 Hz; the first pair is exactly repeated (split 0) or split by 0.1 % (split 0.001), the
second stays exactly repeated. Damping is stiffness proportional, 1 % at the first pair. The
analytic FRFs (receptance, 1000 lines 0.05..50 Hz) of the references 2, 3 and 4 -- drive points,
each a measured point; point 2 sees both members of each pair -- get eq. 15 noise (uniform, on
the real and the imaginary part of every FRF along frequency, as ``random_system`` does, with
:func:`ami_xr.simulate.add_noise`); the configurations use the references [2], [2, 3] and
[2, 3, 4] of the same noisy FRFs, identified with ``ami_xr.identify`` (multi-reference path,
defaults). Per configuration (noise, split, references), over the seeds:

* ``found``: true modes matched, mean per seed out of 6 (one-to-one, nearest first, within half
  the half-power bandwidth ``|lam_id - lam| < |Re lam|``: :func:`ami_xr.simulate.score_modes`;
  an exactly repeated pair counts as both found when two modes are reported there).
* ``pair``: share of seeds with both members of the first pair (modes 2 and 3) found.
* ``fn err``, ``zeta err``: mean relative error of natural frequency and damping ratio of the
  found modes (all modes); ``pair fn``, ``pair zeta``: the same over the first pair's members.
* ``dpc``: mean ``drive_point_consistency`` (0 with one drive point).
* ``susp``, ``sep``: modes flagged ``repeated_root_suspected`` / ``repeated_root_separated``,
  summed over the seeds.
* ``t ratio``: mean time of one multi-reference identify over the mean time of the SIMO
  identify of the same points driven at the first reference (2) only.
* ``err/CRB``: there is no multi-reference Cramér-Rao bound yet (``ami_xr.cramer_rao_bound``
  takes one reference), so the errors cannot be put over it: the column says
  ``n/a (no multi-reference CRB)``.

Written against the public API only.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import ami_xr
from ami_xr.io.datasets import select_reference

REFERENCES = (2, 3, 4)
CONFIGS = ((2,), (2, 3), (2, 3, 4))
SPLITS = (0.0, 0.001)
NOISE_LEVELS = (0.01, 0.05)
N_LINES = 1000
F_MAX = 50.0
NO_CRB = "n/a (no multi-reference CRB)"

HEADER = (
    f"{'noise':>5}{'split':>7}{'refs':>8}{'found':>7}{'pair':>6}{'fn err':>10}{'zeta err':>10}"
    f"{'pair fn':>10}{'pair zeta':>10}{'dpc':>8}{'susp':>5}{'sep':>5}{'t ratio':>8}  err/CRB"
)


def noisy_frf(truth, level: float, seed: int):
    """Analytic FRFs of all ``REFERENCES`` with eq. 15 on Re and Im of every FRF."""
    f = np.linspace(F_MAX / N_LINES, F_MAX, N_LINES)
    ds = ami_xr.simulate.frf(truth, f, references=list(REFERENCES))
    g = ds["frf"]
    rng = np.random.default_rng(seed)
    re = ami_xr.simulate.add_noise(g.real, level, rng=rng, dim="frequency")
    im = ami_xr.simulate.add_noise(g.imag, level, rng=rng, dim="frequency")
    return ds.assign(frf=(re + 1j * im).assign_attrs(g.attrs))


def _identify(ds):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        out = ami_xr.identify(ds)
        return out, time.perf_counter() - t0


def run(seeds: int, levels=NOISE_LEVELS) -> list[dict]:
    """One row per (noise, split, references): the accumulated scores over ``seeds``."""
    rows = {}
    truths = {s: ami_xr.simulate.symmetric_structure(s) for s in SPLITS}
    _identify(noisy_frf(truths[0.0], levels[0], 0))  # compile the kernels before timing
    for level in levels:
        for split, truth in truths.items():
            pair = [m - 1 for m in truth.attrs["split_pair"]]
            for seed in range(seeds):
                full = noisy_frf(truth, level, 1000 * seed + int(round(1e4 * level)))
                _, t_simo = _identify(select_reference(full, REFERENCES[0]))
                for refs in CONFIGS:
                    ds = full.sel(reference=list(refs))
                    out, t = _identify(ds)
                    sc = ami_xr.simulate.score_modes(out, truth)
                    row = rows.setdefault(
                        (level, split, refs),
                        {"found": [], "pair": [], "fn": [], "z": [], "pfn": [], "pz": []}
                        | {"dpc": [], "susp": 0, "sep": 0, "t": [], "t_simo": []},
                    )
                    row["found"].append(sc.n_found)
                    row["pair"].append(bool(sc.found[pair].all()))
                    row["fn"].extend(sc.frequency_error)
                    row["z"].extend(sc.damping_error)
                    in_pair = np.isin(sc.true_index, pair)
                    row["pfn"].extend(sc.frequency_error[in_pair])
                    row["pz"].extend(sc.damping_error[in_pair])
                    row["dpc"].extend(np.asarray(out["drive_point_consistency"].values).ravel())
                    flags = [str(x) for x in np.asarray(out["quality_flags"].values)]
                    row["susp"] += sum("repeated_root_suspected" in x for x in flags)
                    row["sep"] += sum("repeated_root_separated" in x for x in flags)
                    row["t"].append(t)
                    row["t_simo"].append(t_simo)
    return [{"level": k[0], "split": k[1], "refs": k[2], **v} for k, v in rows.items()]


def _mean(x) -> float:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else float("nan")


def format_row(row: dict) -> str:
    refs = ",".join(map(str, row["refs"]))
    return (
        f"{100 * row['level']:>4g}%{100 * row['split']:>6g}%{refs:>8}"
        f"{_mean(row['found']):>5.2f}/6{_mean(row['pair']):>6.2f}"
        f"{_mean(row['fn']):>10.2e}{_mean(row['z']):>10.2e}"
        f"{_mean(row['pfn']):>10.2e}{_mean(row['pz']):>10.2e}{_mean(row['dpc']):>8.4f}"
        f"{row['susp']:>5d}{row['sep']:>5d}{_mean(row['t']) / _mean(row['t_simo']):>8.2f}"
        f"  {NO_CRB}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="noise seeds (default 20)")
    parser.add_argument("--quick", action="store_true", help="2 seeds (a smoke test)")
    args = parser.parse_args(argv)
    seeds = 2 if args.quick else args.seeds
    if seeds < 1:
        parser.error(f"--seeds: expected an integer >= 1, got {seeds}")
    t0 = time.perf_counter()
    rows = run(seeds)
    print(
        f"Symmetric ring, 6 points, references among {list(REFERENCES)}; first pair split 0 and "
        f"0.1 %; {seeds} seeds per noise level; eq. 15 noise on every FRF"
    )
    print(HEADER)
    for row in rows:
        print(format_row(row))
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
