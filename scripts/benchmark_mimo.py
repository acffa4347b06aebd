"""Multi-reference identification of repeated roots: one, two and three references (issue 13).

    python scripts/benchmark_mimo.py               # 20 noise seeds at 1 % and 5 % noise
    python scripts/benchmark_mimo.py --seeds 50
    python scripts/benchmark_mimo.py --quick       # 2 seeds (a smoke test)
    python scripts/benchmark_mimo.py --plate-only  # the measured-like plate case only

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
* ``t ratio``: mean CPU time of one multi-reference identify over the mean CPU time of the
  SIMO identify of the same points driven at the first reference (2) only; ``t/stk``: over
  the SIMO identify of the references' FRFs stacked as one set of points (what the
  multi-reference path identifies first; issue 41: at most 2 with three references).
* ``err/CRB``: mean ``|fn error| / fn_std`` and ``|zeta error| / zeta_std`` of the found modes
  over ``sqrt(2/pi)`` (1 for an efficient estimator), the std from the multi-reference
  ``ami_xr.cramer_rao_bound`` of the references used (eq. 15 line noise per FRF).

The measured-like case (issue 22): :func:`measured_like_truth` (a 5 x 5 lumped plate, 12
measured points, 3 references on unmeasured masses, 8 modes with 3 close pairs, 2-24 Hz) at
0.1 % and 1 % noise: mean modes found with each reference alone and all together, in how many
seeds all together found at least the best single reference, spurious modes of all together,
and its errors over the multi-reference bound (as ``err/CRB``), and the CPU time of one
identify: one reference (mean over the three), the stacked FRFs as one set, all references, and
all over stacked.

One reference's repeated-root flag (issue 41 item 1; ``--repeated`` prints only this): per
pair of the 6-mass ring (reference 2 alone) and of a 7-mass ring with three pairs (reference
1 alone, each pair split by 0.1 % in turn), at 1 % noise, in how many seeds one reference
resolved it (two modes), flagged it (``repeated_root_suspected``) or missed it, with ``z``, the
shape change of the noise-free pair over the noise (what :mod:`ami_xr.ami.repeated` tests;
an exactly repeated pair is one mode to one reference, ``z`` 0); and modes flagged among single
modes: a beam whose FRFs each see the modes at their own eigenvalue, a chain measured with a
roving transducer, and (where ../shared/data holds it) sdypy-EMA's measured beam, one set of
six FRFs per seed.

    python scripts/benchmark_mimo.py --repeated --seeds 5   # about 2.5 min
    python scripts/benchmark_mimo.py --repeated --quick     # 2 seeds, about 1 min

Written against the public API only (the identifiability ``z`` uses
:func:`ami_xr.ami.repeated.band_shift`).
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

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
    f"{'pair fn':>10}{'pair zeta':>10}{'dpc':>8}{'susp':>5}{'sep':>5}{'t ratio':>8}{'t/stk':>7}"
    "  err/CRB"
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


def _identify(ds, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.process_time()  # CPU time: the machine may be shared
        out = ami_xr.identify(ds, **kwargs)
        return out, time.process_time() - t0


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
                    t_stk = _identify(stacked_simo(ds))[1] if len(refs) > 1 else t_simo
                    sc = ami_xr.simulate.score_modes(out, truth, crb=bounds[refs])
                    row = rows.setdefault(
                        (level, split, refs),
                        {"found": [], "pair": [], "fn": [], "z": [], "pfn": [], "pz": []}
                        | {"dpc": [], "susp": 0, "sep": 0, "t": [], "t_simo": [], "t_stk": []}
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
                    flags = [str(x) for x in ami_xr.flag_text(out["quality_flags"].values)]
                    row["susp"] += sum("repeated_root_suspected" in x for x in flags)
                    row["sep"] += sum("repeated_root_separated" in x for x in flags)
                    row["t"].append(t)
                    row["fn_crb"].extend(sc.frequency_over_crb)
                    row["z_crb"].extend(sc.damping_over_crb)
                    row["t_simo"].append(t_simo)
                    row["t_stk"].append(t_stk)
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
PLATE_TAIL_HZ = 30.0  # modes above the band and below this: unknowns of the wider bound


def plate_model():
    """The plate's modal model (all 25 modes)."""
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
    return ami_xr.simulate.modal_model(m_mat, c_mat, k_mat, point_labels=list(range(1, n + 1)))


def measured_like_truth():
    """The plate's truth (modes in the band) and its noise-free multi-reference FRFs."""
    truth = plate_model()
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
    found, t_single = [], []
    for ref in PLATE_REFERENCES:
        out, t = _identify(ds.sel(reference=[ref]))
        found.append(ami_xr.simulate.score_modes(out, truth).n_found)
        t_single.append(t)
    _, t_stacked = _identify(stacked_simo(ds))
    out, t_all = _identify(ds)
    bound = ami_xr.cramer_rao_bound(truth, clean, frf_noise_std=line_noise_std(clean, level))
    sc = ami_xr.simulate.score_modes(out, truth, crb=bound)
    wide = ami_xr.simulate.score_modes(out, truth, crb=bound_with_tail(truth, clean, level))
    return {
        "single": found,
        "all": sc.n_found,
        "spurious": sc.n_spurious,
        "fn_crb": list(sc.frequency_over_crb),
        "z_crb": list(sc.damping_over_crb),
        "fn_tail": list(wide.frequency_over_crb),
        "z_tail": list(wide.damping_over_crb),
        "t_single": t_single,
        "t_stacked": t_stacked,
        "t_all": t_all,
    }


def stacked_simo(ds):
    """The FRFs of every reference as one single-reference Dataset (``point`` labelled
    "reference@point"): what the multi-reference path identifies first, the cost it is
    measured against."""
    g = ds["frf"].stack(pair=("reference", "point")).transpose("pair", "frequency")
    labels = [f"{r}@{p}" for r, p in g["pair"].values]
    out = ds.drop_vars("frf").drop_dims("reference", errors="ignore")
    out = out.drop_dims("point", errors="ignore")
    return out.assign(
        frf=(("point", "frequency"), g.values, g.attrs)
    ).assign_coords(point=labels)


_TAIL_BOUNDS: dict = {}  # per noise level (the truth and lines are fixed)


def bound_with_tail(truth, clean, level: float):
    """The multi-reference bound of the band's modes when the modes above it are unknowns of the
    model too (those below ``PLATE_TAIL_HZ`` as poles with free residues, the rest as lower and
    upper residual terms): the data are made of all 25 modes, and the bound of the band's modes
    alone takes what lies above as known (zero)."""
    if level in _TAIL_BOUNDS:
        return _TAIL_BOUNDS[level]
    full = plate_model()
    keep = np.flatnonzero(full["natural_frequency"].values < PLATE_TAIL_HZ)
    bound = ami_xr.cramer_rao_bound(
        full.isel(mode=keep),
        clean,
        frf_noise_std=line_noise_std(clean, level),
        residual_terms=("lower", "upper"),
    )
    bound = bound.isel(mode=np.arange(truth.sizes["mode"]))
    _TAIL_BOUNDS[level] = bound.assign_coords(mode=truth["mode"].values)
    return _TAIL_BOUNDS[level]


PLATE_HEADER = (
    f"{'noise':>6}"
    + "".join(f"{'ref ' + str(r):>8}" for r in PLATE_REFERENCES)
    + f"{'all':>7}{'all>=best':>10}{'spur':>6}  errors over the multi-reference bound"
    + " (band's modes only | modes above the band unknowns too)"
    + "; CPU s per identify: one reference (mean), stacked, all, all / stacked"
)


def run_measured_like(seeds: int, levels=PLATE_LEVELS) -> list[dict]:
    """Per noise level, the measured-like case over ``seeds``."""
    truth, clean = measured_like_truth()
    _identify(clean.sel(reference=[PLATE_REFERENCES[0]]))  # compile the kernels before timing
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
    fn_t = [x for g in got for x in g["fn_tail"]]
    z_t = [x for g in got for x in g["z_tail"]]
    n = row["n_true"]
    return (
        f"{100 * row['level']:>5g}%"
        + "".join(f"{m:>6.2f}/{n}" for m in single.mean(axis=0))
        + f"{_mean([g['all'] for g in got]):>5.2f}/{n}{every:>7d}/{len(got)}"
        + f"{_mean([g['spurious'] for g in got]):>6.2f}"
        + f"  fn {_mean(fn) / EFFICIENT:.2f} zeta {_mean(z) / EFFICIENT:.2f}"
        + f" | fn {_mean(fn_t) / EFFICIENT:.2f} zeta {_mean(z_t) / EFFICIENT:.2f}"
        + f"; t {_mean([x for g in got for x in g['t_single']]):.2f}"
        + f" {_mean([g['t_stacked'] for g in got]):.2f} {_mean([g['t_all'] for g in got]):.2f}"
        + f" {_mean([g['t_all'] for g in got]) / _mean([g['t_stacked'] for g in got]):.2f}"
    )


def print_plate(seeds: int, per_seed: bool = False) -> None:
    """The measured-like plate's table (and one line per seed with ``per_seed``)."""
    print(
        "Measured-like plate: 12 points, references "
        f"{list(PLATE_REFERENCES)} not measured, 8 modes in 2-24 Hz with 3 close pairs; "
        f"{seeds} seeds per noise level"
    )
    print(PLATE_HEADER)
    for row in run_measured_like(seeds):
        print(format_plate_row(row))
        for i, g in enumerate(row["seeds"] if per_seed else []):
            print(
                f"    seed {i}: found one reference {g['single']} all {g['all']}"
                f" spurious {g['spurious']}; CPU s one reference "
                + " ".join(f"{t:.2f}" for t in g["t_single"])
                + f", stacked {g['t_stacked']:.2f}, all {g['t_all']:.2f}"
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
        f"{_mean(row['t']) / _mean(row['t_stk']):>7.2f}"
        f"  fn {_mean(row['fn_crb']) / EFFICIENT:.2f} zeta {_mean(row['z_crb']) / EFFICIENT:.2f}"
    )


# --- One reference and repeated roots (issue 41 item 1) ----------------------------------------
# The repeated side: the ring above (6 masses, reference 2 alone) and a ring of 7 masses (three
# pairs, reference 1 alone, each pair split in turn), split 0 and 0.1 %, 1 % noise. The single
# side: a beam whose FRFs each see five single modes shifted by their own amount (as
# tests/core/test_model_order_rule.py) and a chain of 6 masses measured with a roving
# transducer (each FRF with the transducer's mass at its point), 0.1 % and 1 % noise.
RING_RUNS = ((6, 2, 1, 0.0), (6, 2, 1, 0.001), (7, 1, 1, 0.0))
RING_RUNS += tuple((7, 1, j, 0.001) for j in (1, 2, 3))
REPEATED_LEVEL = 0.01
BEAM_FN = (176.0, 476.0, 932.0, 1535.0, 2286.0)
SINGLE_RUNS = (
    ("beam, per-FRF shift 0.025 %", "beam", 2.5e-4, 0.001),
    ("beam, per-FRF shift 0.05 %", "beam", 5e-4, 0.001),
    ("chain, no transducer mass", "chain", 0.0, 0.001),
    ("chain, transducer 0.3 % mass", "chain", 0.003, 0.001),
    ("chain, transducer 0.3 % mass", "chain", 0.003, 0.01),
    ("chain, transducer 1 % mass", "chain", 0.01, 0.001),
    ("chain, transducer 1 % mass", "chain", 0.01, 0.01),
)


def _noisy(ds, level: float, seed: int):
    """``ds`` with eq. 15 noise on Re and Im of every FRF along frequency."""
    g = ds["frf"]
    rng = np.random.default_rng(seed)
    re = ami_xr.simulate.add_noise(g.real, level, rng=rng, dim="frequency")
    im = ami_xr.simulate.add_noise(g.imag, level, rng=rng, dim="frequency")
    return ds.assign(frf=(re + 1j * im).assign_attrs(g.attrs))


def pair_identifiability(truth, reference, modes, level: float) -> float:
    """The expected ``z`` of :func:`ami_xr.ami.repeated.band_shift` for the pair ``modes``
    (indices) at one reference and eq. 15 noise ``level``: its statistic ``T`` on the
    noise-free FRFs, fitted by one pole at the pair's mean eigenvalue, over the standard
    deviation of ``T`` for noise alone (noise adds its mean). The flag needs ``z_min``; an
    exactly repeated pair gives 0."""
    from ami_xr.ami import repeated as rp

    f = np.linspace(F_MAX / N_LINES, F_MAX, N_LINES)
    omega = 2 * np.pi * f
    clean = ami_xr.simulate.frf(truth, f, references=[reference])
    noise_var = line_noise_std(clean, level).values.ravel() ** 2
    res = ami_xr.simulate.residues(truth, drive_point=reference)["residue"]
    res = res.transpose("point", "mode").values[:, modes]
    lam = truth["eigenvalue"].values[modes]
    data = sum(np.outer(res[:, i], 1 / (1j * omega - lam[i])) for i in range(len(modes)))
    mean = lam.mean()
    b = 1 / (1j * omega - mean)
    near = np.abs(omega - mean.imag) <= 2 * abs(mean.real)
    one = data[:, near] @ np.conj(b[near]) / np.vdot(b[near], b[near])
    got = rp.band_shift(
        data - np.outer(one, b),
        omega,
        np.array([mean]),
        one[:, None],
        b[None],
        (b**2)[None],
        noise_var=noise_var,
    )
    dof = res.shape[0] - (2 if rp.POLICY.transducer_mass else 1)
    return float(got[1][0]) + np.sqrt(dof)  # z = (T - dof) / sqrt(dof): T / sqrt(dof)


def pair_outcome(out, lam) -> str:
    """"resolved" (two modes within the pair's band), "flagged" (one, flagged
    ``repeated_root_suspected``) or "missed"."""
    got = np.asarray(out["eigenvalue"].values)
    near = np.abs(got - lam) < 2 * abs(lam.real)
    if near.sum() >= 2:
        return "resolved"
    flagged = np.array(["repeated_root_suspected" in str(x) for x in ami_xr.flag_text(out["quality_flags"].values)])
    return "flagged" if np.any(flagged & near) else "missed"


def run_repeated_pairs(seeds: int) -> list[dict]:
    """Per ring run and pair: its identifiability and outcomes over ``seeds``."""
    rows = []
    f = np.linspace(F_MAX / N_LINES, F_MAX, N_LINES)
    for n, ref, pair, split in RING_RUNS:
        truth = ami_xr.simulate.symmetric_structure(split, n_masses=n, pair=pair)
        pairs = np.reshape(np.asarray(truth.attrs["repeated_pairs"]) - 1, (-1, 2))
        if split:
            pairs = pairs[[pair - 1]]  # the split pair; the others are the split-0 runs'
        # the 6-mass ring's noise as in the table above (drawn on the references 2, 3, 4)
        drawn = list(REFERENCES) if n == 6 else [ref]
        clean = ami_xr.simulate.frf(truth, f, references=drawn)
        runs = {"": [], "no refine": []}
        for seed in range(seeds):
            ds = _noisy(clean, REPEATED_LEVEL, 1000 * seed + 100).sel(reference=[ref])
            runs[""].append(_identify(ds)[0])
            runs["no refine"].append(_identify(ds, refine=False)[0])
        for modes in pairs:
            lam = truth["eigenvalue"].values[modes].mean()
            z = pair_identifiability(truth, ref, list(modes), REPEATED_LEVEL)
            for how, outs in runs.items():
                got = [pair_outcome(out, lam) for out in outs]
                rows.append(
                    {"n": n, "ref": ref, "split": split, "fn": abs(lam) / 2 / np.pi, "z": z}
                    | {"how": how}
                    | {k: got.count(k) for k in ("resolved", "flagged", "missed")}
                )
    return rows


def beam_frf(shift: float, level: float, seed: int):
    """Five single modes (0.2 % damping) at 6 points; FRF ``j`` sees every mode shifted by its
    own relative amount, uniform in +-``shift``; complex Gaussian noise ``level`` times each
    FRF's largest value (tests/core/test_model_order_rule.py's beam)."""
    rng = np.random.default_rng(seed)
    freq = np.arange(50.0, 2600.0, 0.25)
    omega = 2 * np.pi * freq
    phi = rng.standard_normal((6, len(BEAM_FN)))

    def lam_of(fn):
        wn = 2 * np.pi * np.asarray(fn)
        return -0.002 * wn + 1j * wn * np.sqrt(1 - 0.002**2)

    frf = np.zeros((6, freq.size), complex)
    for j in range(6):
        lam = lam_of(np.asarray(BEAM_FN) * (1 + shift * rng.uniform(-1, 1)))
        res = lam * phi[j] * phi[0]
        frf[j] = np.sum(
            res[:, None] / (1j * omega - lam[:, None])
            + np.conj(res)[:, None] / (1j * omega - np.conj(lam)[:, None]),
            axis=0,
        )
    scale = level * np.abs(frf).max(axis=1, keepdims=True)
    frf += scale * (rng.standard_normal(frf.shape) + 1j * rng.standard_normal(frf.shape))
    return ami_xr.make_frf_dataset(frf, freq, drive_point=0, response_quantity="displacement")


def chain_frf(mass: float, level: float, seed: int):
    """A grounded chain of 6 unit masses (springs 1e4 N/m, damping 2e-4 K + 0.5 M: single modes
    at 15.9-34.6 Hz); FRF ``p`` measured with a transducer of ``mass`` kg at point ``p``."""
    n = 6
    k = np.eye(n) * 1e4
    for i in range(n - 1):
        k[np.ix_([i, i + 1], [i, i + 1])] += 1e4 * np.array([[1.0, -1.0], [-1.0, 1.0]])
    m = np.eye(n)
    c = 2e-4 * k + 0.5 * m
    f = np.linspace(0.1, 60.0, 1200)
    ds = ami_xr.simulate.frf(ami_xr.simulate.modal_model(m, c, k, drive_point=0), f)
    rows = []
    for p in range(n):
        mp = m.copy()
        mp[p, p] += mass
        loaded = ami_xr.simulate.modal_model(mp, c, k, drive_point=0)
        rows.append(ami_xr.simulate.frf(loaded, f)["frf"].values[p])
    return _noisy(ds.assign(frf=ds["frf"].copy(data=np.stack(rows))), level, seed)


# sdypy-EMA's measured beam (MIT; see /work/shared/data/README.md): 7 sets of 6 accelerances,
# 11 well-separated single modes; left out where the shared data folder is absent
MEASURED_BEAM = Path(__file__).resolve().parents[2] / "shared" / "data" / "sdypy_ema_beam.npz"


def measured_beam_flags(n_sets: int) -> dict | None:
    """Modes flagged and identified over the first ``n_sets`` sets of the measured beam."""
    if not MEASURED_BEAM.is_file():
        return None
    data = np.load(MEASURED_BEAM)
    flagged = total = 0
    for k in range(min(n_sets, data["frf"].shape[1])):
        frf = data["frf"][:, k, :].astype(complex)
        ds = ami_xr.make_frf_dataset(
            frf, data["freq"], drive_point=0, response_quantity="acceleration"
        )
        out, _ = _identify(ds)
        total += out.sizes["mode"]
        flagged += sum("repeated_root_suspected" in str(x) for x in ami_xr.flag_text(out["quality_flags"].values))
    label = f"measured beam, {min(n_sets, data['frf'].shape[1])} sets"
    return {"label": label, "level": float("nan"), "flagged": flagged, "modes": total}


def run_single_modes(seeds: int) -> list[dict]:
    """Per single-mode case: modes flagged and modes identified, summed over ``seeds``; the
    measured beam's sets (as many as seeds, at most 7) where the shared data are present."""
    rows = []
    for label, kind, amount, level in SINGLE_RUNS:
        flagged = total = 0
        for seed in range(seeds):
            ds = beam_frf(amount, level, seed) if kind == "beam" else chain_frf(amount, level, seed)
            out, _ = _identify(ds)
            total += out.sizes["mode"]
            flagged += sum("repeated_root_suspected" in str(x) for x in ami_xr.flag_text(out["quality_flags"].values))
        rows.append({"label": label, "level": level, "flagged": flagged, "modes": total})
    measured = measured_beam_flags(seeds)
    return rows + ([measured] if measured else [])


def print_repeated(seeds: int) -> None:
    """The section's two tables (repeated pairs; single modes)."""
    print(
        f"One reference, repeated pairs: rings, eq. 15 noise {100 * REPEATED_LEVEL:g} %, "
        f"{seeds} seeds; z: the noise-free pair's shape change over the noise (flag: z > 6)"
    )
    print(
        f"{'masses':>6}{'ref':>4}{'split':>7}{'pair Hz':>9}{'z':>8}{'':>11}"
        "  resolved flagged missed"
    )
    ok = {True: [0, 0], False: [0, 0]}
    for r in run_repeated_pairs(seeds):
        print(
            f"{r['n']:>6}{r['ref']:>4}{100 * r['split']:>6g}%{r['fn']:>9.2f}{r['z']:>8.1f}"
            f"{r['how']:>11}  {r['resolved']:>8}{r['flagged']:>8}{r['missed']:>7}"
        )
        if r["how"]:
            continue  # the totals count identify's defaults
        tally = ok[r["z"] > 6.0]
        tally[0] += r["resolved"] + r["flagged"]
        tally[1] += r["resolved"] + r["flagged"] + r["missed"]
    for known, (hit, n) in ok.items():
        what = "identifiable (z > 6)" if known else "not identifiable with one reference"
        print(f"  pairs {what}: flagged or resolved {hit}/{n}")
    print()
    print(f"One reference, single modes: {seeds} seeds; modes flagged / modes identified")
    for r in run_single_modes(seeds):
        noise = "as measured" if np.isnan(r["level"]) else f"noise {100 * r['level']:>4g} %"
        print(f"  {r['label']:<30} {noise:<12}  {r['flagged']:>3}/{r['modes']}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="noise seeds (default 20)")
    parser.add_argument("--quick", action="store_true", help="2 seeds (a smoke test)")
    parser.add_argument(
        "--ring-only", action="store_true", help="leave out the measured-like plate case"
    )
    parser.add_argument(
        "--plate-only", action="store_true", help="only the measured-like plate case"
    )
    parser.add_argument(
        "--repeated",
        action="store_true",
        help="only one reference's repeated-root flag: repeated pairs and single modes",
    )
    parser.add_argument(
        "--per-seed", action="store_true", help="the plate case: one line per seed too"
    )
    args = parser.parse_args(argv)
    seeds = 2 if args.quick else args.seeds
    if seeds < 1:
        parser.error(f"--seeds: expected an integer >= 1, got {seeds}")
    t0 = time.perf_counter()
    if args.repeated:
        print_repeated(seeds)
        print(f"({time.perf_counter() - t0:.0f} s)")
        return 0
    if args.plate_only:
        print_plate(seeds, args.per_seed)
        print(f"({time.perf_counter() - t0:.0f} s)")
        return 0
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
    print_plate(seeds, args.per_seed)
    print()
    print_repeated(seeds)
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
