"""Each reference weighted by its own noise (issue 41): errors over the bound of that noise.

    python scripts/benchmark_noise_groups.py            # 30 seeds
    python scripts/benchmark_noise_groups.py --seeds 100

Two references on four points of a three-mode system (6, 9 and 12.5 Hz), analytic FRFs on
400 lines 2-16 Hz with a stored noise model ``frf_line_noise_std``: reference a's noise rises
0.03 -> 30 along the band, reference b's falls 30 -> 0.03 and is ten times larger. The stacked
FRFs are refined (``ami_xr.refine`` from the truth, no mode added or dropped) with one noise
shape for all (no ``noise_group`` coordinate: the median shape) and with a shape per reference
(``noise_group``), and the mean ``|fn error| / std`` over the modes and seeds is printed over
``sqrt(2/pi)`` (1 for an efficient estimator), the std from the Fisher information of that
noise (every FRF line weighted by its own level), with the reported ``natural_frequency_std``
over that bound.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
import xarray as xr

import ami_xr
from ami_xr import names

LAM = np.array([-0.6 + 2j * np.pi * 6.0, -0.8 + 2j * np.pi * 9.0, -1.0 + 2j * np.pi * 12.5])
N_POINT = 4
FREQ = np.linspace(2.0, 16.0, 400)
EFFICIENT = np.sqrt(2.0 / np.pi)  # E|err| / std of an efficient estimator


def _system():
    """Residues (2 references x 4 points, stacked reference-major) of a proportionally damped
    system, the noise std (P, L) of each FRF line and each FRF's group (reference)."""
    rng = np.random.default_rng(7)
    phi = rng.uniform(0.4, 1.0, (N_POINT + 2, LAM.size)) * rng.choice([-1, 1], (N_POINT + 2, 3))
    refs = (N_POINT, N_POINT + 1)  # two unmeasured reference masses
    res = np.concatenate([phi[:N_POINT] * phi[r] for r in refs]) / (2j * LAM.imag)
    t = (FREQ - FREQ[0]) / (FREQ[-1] - FREQ[0])
    rising, falling = 10.0 ** (3 * t - 1.5), 10.0 ** (1.5 - 3 * t)  # 0.03..30 and 30..0.03
    shape = np.concatenate([np.tile(rising, (N_POINT, 1)), np.tile(10 * falling, (N_POINT, 1))])
    group = np.repeat([0, 1], N_POINT)
    return res, 2e-4 * shape, group


def _frf(res):
    s = 2j * np.pi * FREQ[None, :, None]
    lam = LAM[None, None, :]
    a = res[:, None, :]
    return np.sum(a / (s - lam) + np.conj(a) / (s - np.conj(lam)), axis=2)


def _bound(res, sd):
    """Cramér-Rao std of the natural frequencies (Hz): Fisher information of the shared
    eigenvalues with every FRF's residues eliminated, each line weighted by its own noise."""
    s = 2j * np.pi * FREQ[:, None]
    n_mode = LAM.size
    fisher = np.zeros((2 * n_mode, 2 * n_mode))
    for j in range(res.shape[0]):
        a = res[j]
        d1, d2 = 1 / (s - LAM) ** 2, 1 / (s - np.conj(LAM)) ** 2
        e1, e2 = 1 / (s - LAM), 1 / (s - np.conj(LAM))
        cols = []
        for k in range(n_mode):
            cols += [a[k] * d1[:, k] + np.conj(a[k]) * d2[:, k]]
            cols += [1j * a[k] * d1[:, k] - 1j * np.conj(a[k]) * d2[:, k]]
        for k in range(n_mode):
            cols += [e1[:, k] + e2[:, k], 1j * e1[:, k] - 1j * e2[:, k]]
        jac = np.array(cols).T * (np.sqrt(2.0) / sd[j])[:, None]  # per real component
        jr = np.concatenate([jac.real, jac.imag])
        f = jr.T @ jr
        t, c = slice(0, 2 * n_mode), slice(2 * n_mode, None)
        fisher += f[t, t] - f[t, c] @ np.linalg.solve(f[c, c], f[c, t])
    cov = np.linalg.inv(fisher)
    grad = np.zeros((n_mode, 2 * n_mode))
    for k in range(n_mode):
        grad[k, 2 * k : 2 * k + 2] = [LAM[k].real, LAM[k].imag]
    grad /= (2 * np.pi * np.abs(LAM))[:, None]
    return np.sqrt(np.einsum("ka,ab,kb->k", grad, cov, grad))


def _dataset(res, sd, group, seed, groups: bool) -> xr.Dataset:
    rng = np.random.default_rng(seed)
    noise = sd / np.sqrt(2) * (rng.standard_normal(sd.shape) + 1j * rng.standard_normal(sd.shape))
    labels = [f"{r}@{p}" for r in ("a", "b") for p in range(1, N_POINT + 1)]
    coords = {names.POINT: labels, names.FREQUENCY: FREQ, names.MODE: [1, 2, 3]}
    if groups:
        coords["noise_group"] = (names.POINT, group)
    return xr.Dataset(
        {
            names.FRF: ((names.POINT, names.FREQUENCY), _frf(res) + noise),
            names.FRF_LINE_NOISE_STD: ((names.POINT, names.FREQUENCY), sd),
            names.EIGENVALUE: ((names.MODE,), LAM),
            names.RESIDUE: ((names.POINT, names.MODE), res),
        },
        coords=coords,
        attrs={names.ATTR_SOURCE: names.SOURCE_ANALYTIC},
    )


def run(seeds: int, groups: bool) -> tuple[float, float]:
    """Mean error over the bound (over sqrt(2/pi)) and median reported std over the bound."""
    res, sd, group = _system()
    bound = _bound(res, sd)
    fn = np.abs(LAM) / (2 * np.pi)
    ratios, stds = [], []
    for seed in range(seeds):
        ds = _dataset(res, sd, group, seed, groups)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = ami_xr.refine(ds, add_modes=0, drop_modes=False)
        ratios.extend(np.abs(out[names.NATURAL_FREQUENCY].values - fn) / bound)
        stds.extend(out[names.NATURAL_FREQUENCY_STD].values / bound)
    return float(np.mean(ratios) / EFFICIENT), float(np.median(stds))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=30, help="noise seeds (default 30)")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds: expected an integer >= 1, got {args.seeds}")
    t0 = time.perf_counter()
    print(f"Two references, opposite noise shapes, one 10x noisier; {args.seeds} seeds")
    print(f"{'noise shape':<24}{'fn err/bound':>14}{'std/bound':>11}")
    for label, groups in (("one for all (median)", False), ("one per reference", True)):
        err, std = run(args.seeds, groups)
        print(f"{label:<24}{err:>14.2f}{std:>11.2f}")
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
