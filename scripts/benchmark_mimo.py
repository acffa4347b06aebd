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
* ``err/CRB``: mean ``|fn error| / fn_std`` and ``|zeta error| / zeta_std`` of the found modes
  over ``sqrt(2/pi)`` (1 for an efficient estimator), the std from the multi-reference
  ``ami_xr.cramer_rao_bound`` of the references used (eq. 15 line noise per FRF).

The measured-like case (issue 22): :func:`measured_like_truth` (a 5 x 5 lumped plate, 12
measured points, 3 references on unmeasured masses, 8 modes with 3 close pairs, 2-24 Hz) at
0.1 % and 1 % noise: mean modes found with each reference alone and all together, in how many
seeds all together found at least the best single reference, spurious modes of all together,
and its errors over the multi-reference bound (as ``err/CRB``).

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
EFFICIENT = np.sqrt(2 / np.pi)  # E|err| / std of an efficient unbiased estimator

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
            f = np.linspace(F_MAX / N_LINES, F_MAX, N_LINES)
            clean = ami_xr.simulate.frf(truth, f, references=list(REFERENCES))
            bounds = {
                refs: ami_xr.cramer_rao_bound(
                    truth,
                    clean.sel(reference=list(refs)),
                    frf_noise_std=line_noise_std(clean.sel(reference=list(refs)), level),
                )
                for refs in CONFIGS
            }
            for seed in range(seeds):
                full = noisy_frf(truth, level, 1000 * seed + int(round(1e4 * level)))
                _, t_simo = _identify(select_reference(full, REFERENCES[0]))
                for refs in CONFIGS:
                    ds = full.sel(reference=list(refs))
                    out, t = _identify(ds)
                    sc = ami_xr.simulate.score_modes(out, truth, crb=bounds[refs])
                    row = rows.setdefault(
                        (level, split, refs),
                        {"found": [], "pair": [], "fn": [], "z": [], "pfn": [], "pz": []}
                        | {"dpc": [], "susp": 0, "sep": 0, "t": [], "t_simo": []}
                        | {"fn_crb": [], "z_crb": []},
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
                    row["fn_crb"].extend(sc.frequency_over_crb)
                    row["z_crb"].extend(sc.damping_over_crb)
                    row["t_simo"].append(t_simo)
    return [{"level": k[0], "split": k[1], "refs": k[2], **v} for k, v in rows.items()]


def line_noise_std(ds, level: float):
    """Per-line noise of eq. 15 on Re and Im along frequency (uniform): ``sqrt(E|e|^2)`` per
    FRF, ``level sqrt((max|Re G|^2 + max|Im G|^2) / 3)``."""
    g = ds["frf"]
    return level * np.sqrt(
        (np.abs(g.real).max("frequency") ** 2 + np.abs(g.imag).max("frequency") ** 2) / 3
    )


# The measured-like case: a lumped plate of 5 x 5 equal masses (springs 1.2 % stiffer along y,
# so the (i, j) and (j, i) modes form close pairs), grounded, proportional plus three local
# dashpots (non-proportional damping, zeta 0.9-1.2 %); 12 measured points and 3 references on
# unmeasured masses (no drive point), 2-24 Hz at 0.04 Hz: 8 modes with pairs at 12.1/12.2,
# 20.0/20.1 and 22.3/22.4 Hz (modal overlap 0.3-1.1).
PLATE = (5, 5)
PLATE_REFERENCES = (2, 13, 19)
PLATE_POINTS = (1, 4, 5, 7, 9, 11, 12, 15, 17, 21, 23, 25)
PLATE_BAND = (2.0, 24.0, 551)
PLATE_LEVELS = (0.001, 0.01)


def measured_like_truth():
    """The plate's truth (modes in the band) and its noise-free multi-reference FRFs."""
    nx, ny = PLATE
    n = nx * ny
    k_mat = np.zeros((n, n))
    kx, ky, kg = 1.0e4, 1.012e4, 2.0e3

    def spring(a, b, k):
        k_mat[a, a] += k
        k_mat[b, b] += k
        k_mat[a, b] -= k
        k_mat[b, a] -= k

    for i in range(nx):
        for j in range(ny):
            k_mat[i * ny + j, i * ny + j] += kg
            if i + 1 < nx:
                spring(i * ny + j, (i + 1) * ny + j, kx)
            if j + 1 < ny:
                spring(i * ny + j, i * ny + j + 1, ky)
    m_mat = np.eye(n)
    c_mat = 1.5e-4 * k_mat + 0.3 * m_mat
    for d in (3, 10, 22):
        c_mat[d, d] += 2.0
    truth = ami_xr.simulate.modal_model(m_mat, c_mat, k_mat, point_labels=list(range(1, n + 1)))
    f = np.linspace(*PLATE_BAND)
    ds = ami_xr.simulate.frf(truth, f, references=list(PLATE_REFERENCES))
    ds = ds.sel(point=list(PLATE_POINTS))
    inside = np.flatnonzero(truth["natural_frequency"].values < f[-1] - 0.5)
    return truth.isel(mode=inside), ds


def measured_like_seed(truth, clean, level: float, seed: int) -> dict:
    """One noise seed of the measured-like case: modes found with each reference alone and all
    together, and the errors of all together over the multi-reference bound."""
    rng = np.random.default_rng(7919 * seed + int(round(1e5 * level)))
    g = clean["frf"]
    re = ami_xr.simulate.add_noise(g.real, level, rng=rng, dim="frequency")
    im = ami_xr.simulate.add_noise(g.imag, level, rng=rng, dim="frequency")
    ds = clean.assign(frf=(re + 1j * im).assign_attrs(g.attrs))
    found = []
    for ref in PLATE_REFERENCES:
        out, _ = _identify(ds.sel(reference=[ref]))
        found.append(ami_xr.simulate.score_modes(out, truth).n_found)
    out, _ = _identify(ds)
    bound = ami_xr.cramer_rao_bound(truth, clean, frf_noise_std=line_noise_std(clean, level))
    sc = ami_xr.simulate.score_modes(out, truth, crb=bound)
    return {
        "single": found,
        "all": sc.n_found,
        "spurious": sc.n_spurious,
        "fn_crb": list(sc.frequency_over_crb),
        "z_crb": list(sc.damping_over_crb),
    }


PLATE_HEADER = (
    f"{'noise':>6}"
    + "".join(f"{'ref ' + str(r):>8}" for r in PLATE_REFERENCES)
    + f"{'all':>7}{'all>=best':>10}{'spur':>6}  errors over the multi-reference bound"
)


def run_measured_like(seeds: int, levels=PLATE_LEVELS) -> list[dict]:
    """Per noise level, the measured-like case over ``seeds``."""
    truth, clean = measured_like_truth()
    rows = []
    for level in levels:
        got = [measured_like_seed(truth, clean, level, seed) for seed in range(seeds)]
        rows.append({"level": level, "seeds": got, "n_true": truth.sizes["mode"]})
    return rows


def format_plate_row(row: dict) -> str:
    got = row["seeds"]
    single = np.array([g["single"] for g in got], dtype=float)
    every = sum(g["all"] >= max(g["single"]) for g in got)
    fn = [x for g in got for x in g["fn_crb"]]
    z = [x for g in got for x in g["z_crb"]]
    n = row["n_true"]
    return (
        f"{100 * row['level']:>5g}%"
        + "".join(f"{m:>6.2f}/{n}" for m in single.mean(axis=0))
        + f"{_mean([g['all'] for g in got]):>5.2f}/{n}{every:>7d}/{len(got)}"
        + f"{_mean([g['spurious'] for g in got]):>6.2f}"
        + f"  fn {_mean(fn) / EFFICIENT:.2f} zeta {_mean(z) / EFFICIENT:.2f}"
    )


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
        f"  fn {_mean(row['fn_crb']) / EFFICIENT:.2f} zeta {_mean(row['z_crb']) / EFFICIENT:.2f}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="noise seeds (default 20)")
    parser.add_argument("--quick", action="store_true", help="2 seeds (a smoke test)")
    parser.add_argument(
        "--ring-only", action="store_true", help="leave out the measured-like plate case"
    )
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
    if args.ring_only:
        print(f"({time.perf_counter() - t0:.0f} s)")
        return 0
    print()
    print(
        "Measured-like plate: 12 points, references "
        f"{list(PLATE_REFERENCES)} not measured, 8 modes in 2-24 Hz with 3 close pairs; "
        f"{seeds} seeds per noise level"
    )
    print(PLATE_HEADER)
    for row in run_measured_like(seeds):
        print(format_plate_row(row))
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
