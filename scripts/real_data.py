"""The measured files of ``../shared/data`` through the command line, scored against issue 10.

    python scripts/real_data.py [--data ../shared/data] [--max-modes N] [--beam-sets 0,3]

Runs, in a temporary folder, exactly what a user types (``python -m ami_xr`` = ``ami-xr``):

* ``impact_hammer.lvm``: ``ami-xr frf`` then ``ami-xr identify``;
* ``measurement.uff``: ``ami-xr identify``;
* ``sdypy_ema_beam.npz`` (issue 37; sets ``--beam-sets``, default 0 and 3): each set written as
  accelerance (as measured), mobility and receptance (``ami_xr.convert_quantity``), each through
  ``ami-xr identify``: the same modes in every quantity (frequencies within 0.1 %), sdypy-EMA's
  seven modes within 1 % (or 3 Hz), no pair within 1 % with MAC > 0.9;

and prints for each: the analysis band and the rule that chose it, the caps that ended a phase
(``ami_capped``), the modes with their flags, and the warnings the command printed. For the
hammer test it also lists the **visible resonance peaks** below 4.9 kHz - local maxima of |H| in
dB with a topographic prominence of at least 6 dB (``scipy.signal.find_peaks``) between 50 Hz
and 4.9 kHz, where the force is within 20 dB of its low-frequency level and coherence > 0.99 -
and which of them an identified mode matches (within 1 % or 3 Hz, whichever is wider). For
``measurement.uff`` it lists every pair of modes closer than 1 % in frequency whose MAC exceeds
0.9 (a mode found twice, unless the output says why both are supported).

Targets of issue 10 printed with met / NOT met: hammer - no unflagged mode above the valid band,
at least 15 visible peaks matched; measurement.uff - no such pair.

Issue 20 (the result must not depend on how the data were cut): the hammer FRF is also
identified over 20-4885 Hz twice, ``ami-xr identify h.nc --fmin 20 --fmax 4885`` and
``ami-xr identify`` of the file cut first with ``h.sel(frequency=slice(20, 4885))`` (written
with ``ami_xr.to_netcdf``); for each the band, the modes found and the visible peaks matched,
then whether both give the same modes, and the targets of issue 20: each at least 20 of the
visible peaks with no unflagged mode above its band.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

import ami_xr
from ami_xr import names

REPO = Path(__file__).resolve().parents[1]
PEAK_BAND_HZ = (50.0, 4900.0)
PEAK_PROMINENCE_DB = 6.0
MATCH_REL, MATCH_HZ = 0.01, 3.0
PAIR_REL, PAIR_MAC = 0.01, 0.9
TARGET_PEAKS = 15
CUT_HZ = (20.0, 4885.0)
TARGET_PEAKS_CUT = 20  # issue 20


def ami_xr_cli(*args: str) -> str:
    """Run ``ami-xr ARGS`` in a fresh interpreter; its stderr (warnings) as text."""
    done = subprocess.run(
        [sys.executable, "-m", "ami_xr", *args], capture_output=True, text=True, check=False
    )
    if done.returncode != 0:
        raise SystemExit(f"real_data.py: ami-xr {' '.join(args)} failed:\n{done.stderr}")
    return done.stderr


def visible_peaks(frf_ds) -> np.ndarray:
    """Frequencies (Hz) of the visible resonance peaks of the first FRF (module docstring)."""
    from scipy.signal import find_peaks

    f = frf_ds[names.FREQUENCY].values
    db = 20 * np.log10(np.abs(frf_ds[names.FRF].isel({names.POINT: 0}).values) + 1e-300)
    peaks, _ = find_peaks(db, prominence=PEAK_PROMINENCE_DB)
    keep = (f[peaks] > PEAK_BAND_HZ[0]) & (f[peaks] < PEAK_BAND_HZ[1])
    return f[peaks[keep]]


def matched_peaks(peaks: np.ndarray, fn: np.ndarray) -> list[bool]:
    return [bool(fn.size) and np.min(np.abs(fn - p)) <= max(MATCH_REL * p, MATCH_HZ) for p in peaks]


def mac(a: np.ndarray, b: np.ndarray) -> float:
    return float(abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real))


def suspicious_pairs(modes) -> list[tuple[int, int, float, float]]:
    """Pairs of modes within PAIR_REL in frequency with MAC > PAIR_MAC."""
    fn = modes[names.NATURAL_FREQUENCY].values
    labels = modes[names.MODE].values
    phi = modes[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
    out = []
    for i in range(fn.size):
        for j in range(i + 1, fn.size):
            if abs(fn[i] - fn[j]) <= PAIR_REL * min(fn[i], fn[j]):
                m = mac(phi[:, i], phi[:, j])
                if m > PAIR_MAC:
                    out.append((int(labels[i]), int(labels[j]), abs(fn[i] - fn[j]), m))
    return out


def describe(modes, warnings_text: str) -> None:
    a = modes.attrs
    print(
        f"  band: {a.get('analysis_band_fmin', float('nan')):.1f}-"
        f"{a.get('analysis_band_fmax', float('nan')):.1f} Hz, rule "
        f"{a.get('analysis_band_rule', '?')!r}: {a.get('analysis_band_reason', '')}"
    )
    print(f"  caps: {ami_xr.RunStatus.of(a.get('ami_capped')).text() or 'none'}")
    print(f"  modes: {modes.sizes.get(names.MODE, 0)}")
    print(ami_xr.format_modal_table(modes))
    lines = [ln for ln in warnings_text.splitlines() if "warning" in ln]
    print(f"  the command printed {len(lines)} warning line(s):")
    for ln in lines:
        print(f"    {ln[:160]}")


def above_band(modes) -> tuple[int, float]:
    """Unflagged modes above the band the result records, and that band's upper limit."""
    fn = modes[names.NATURAL_FREQUENCY].values
    fmax = modes.attrs.get("analysis_band_fmax", np.inf)
    flags = (
        ami_xr.flag_text(modes[names.QUALITY_FLAGS].values)
        if names.QUALITY_FLAGS in modes
        else np.full(fn.size, "")
    )
    return int(np.sum((fn > fmax) & (flags == ""))), float(fmax)


def cut_runs(tmp: Path, h_path: Path, peaks: np.ndarray, extra: list[str]) -> list[str]:
    """The hammer FRF over CUT_HZ with --fmin/--fmax and cut first with .sel (issue 20): prints
    both results and returns the target lines."""
    a, b = CUT_HZ
    with ami_xr.open_dataset(h_path) as h:
        ami_xr.to_netcdf(h.sel({names.FREQUENCY: slice(a, b)}).load(), tmp / "h_cut.nc")
    runs = {
        "fmin/fmax": ("h.nc", ["--fmin", f"{a:g}", "--fmax", f"{b:g}"]),
        ".sel": ("h_cut.nc", []),
    }
    targets, found = [], {}
    for label, (src, opts) in runs.items():
        out = tmp / f"cut_{len(found)}.nc"
        how = f"--fmin {a:g} --fmax {b:g}" if opts else f".sel(frequency=slice({a:g}, {b:g}))"
        print(f"\n== {h_path.name} over {a:g}-{b:g} Hz, {how}: ami-xr identify {src}")
        said = ami_xr_cli("identify", str(tmp / src), "-o", str(out), *opts, *extra)
        with ami_xr.open_dataset(out) as m:
            describe(m, said)
            fn = np.sort(m[names.NATURAL_FREQUENCY].values)
            above, fmax = above_band(m)
        hit = matched_peaks(peaks, fn)
        found[label] = fn
        print(f"  {label}: {fn.size} modes, visible peaks matched {sum(hit)}/{len(peaks)}")
        targets.append(
            verdict(
                f"hammer {a:g}-{b:g} Hz, {label}: >= {TARGET_PEAKS_CUT} peaks, none above band",
                sum(hit) >= TARGET_PEAKS_CUT and above == 0,
                f"{sum(hit)}/{len(peaks)}, {above} above {fmax:.0f} Hz",
            )
        )
    one, two = found.values()
    same = one.size == two.size and np.allclose(one, two, rtol=1e-6, atol=0)
    print(
        f"\n  same modes with --fmin/--fmax and with .sel: {'yes' if same else 'no'} "
        f"({one.size} and {two.size} modes)"
    )
    targets.append(verdict("hammer: the same modes with fmin/fmax and with .sel", same, ""))
    return targets


BEAM_REF_HZ = (176.07, 476.46, 932.29, 1534.79, 2286.32, 3162.16, 4181.72)  # sdypy-EMA's LSCF
QUANTITIES = ("acceleration", "velocity", "displacement")


def beam_quantities(tmp: Path, beam: Path, sets: list[int], extra: list[str]) -> list[str]:
    """Issue 37: sdypy-EMA's measured beam (accelerance) identified by ``ami-xr identify`` as
    accelerance and converted to mobility and receptance: the same modes in every quantity,
    sdypy-EMA's seven within 1 %, no phantom split."""
    import time

    d = np.load(beam)
    targets, same_all, hits_all, pairs_all = [], True, [], 0
    for k in sets:
        ds = ami_xr.make_frf_dataset(
            d["frf"][:, k, :].astype(np.complex128),
            d["freq"],
            response_quantity="acceleration",
            frf_source="measured",
        )
        found = {}
        for q in QUANTITIES:
            path = tmp / f"beam{k}_{q}.nc"
            ami_xr.to_netcdf(ami_xr.convert_quantity(ds, q), path)
            t0 = time.perf_counter()
            ami_xr_cli("identify", str(path), "-o", str(tmp / f"beam{k}_{q}.modes.nc"), *extra)
            secs = time.perf_counter() - t0
            with ami_xr.open_dataset(tmp / f"beam{k}_{q}.modes.nc") as m:
                fn = np.sort(m[names.NATURAL_FREQUENCY].values)
                pairs_all += len(suspicious_pairs(m))
                fitted_in = m.attrs.get("noise_model_quantity", "?")
            found[q] = fn
            hit = matched_peaks(np.array(BEAM_REF_HZ), fn)
            hits_all.append(sum(hit))
            print(
                f"  set {k} as {q:12s} fitted as {fitted_in:12s} {fn.size:2d} modes, "
                f"{sum(hit)}/7 of sdypy-EMA's, {secs:5.1f} s: "
                + " ".join(f"{x:.1f}" for x in fn)
            )
        ref = found[QUANTITIES[0]]
        same = all(
            f.size == ref.size and np.allclose(f, ref, rtol=1e-3) for f in found.values()
        )
        same_all &= same
    targets.append(verdict("beam: the same modes in every quantity", same_all, f"sets {sets}"))
    targets.append(
        verdict(
            "beam: sdypy-EMA's 7 modes within 1 % in every run",
            min(hits_all) == 7,
            f"min {min(hits_all)}/7",
        )
    )
    targets.append(verdict("beam: no phantom split", pairs_all == 0, f"{pairs_all} pair(s)"))
    return targets


def verdict(name: str, ok: bool, detail: str) -> str:
    return f"  {name:58s} {detail:28s} {'met' if ok else 'NOT met'}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(REPO.parent / "shared" / "data"))
    ap.add_argument("--max-modes", type=int, default=None, help="passed to ami-xr identify")
    ap.add_argument(
        "--beam-sets", default="0,3", help="sets of sdypy_ema_beam.npz (0-6), '' for none"
    )
    args = ap.parse_args(argv)
    data = Path(args.data)
    hammer, uff = data / "impact_hammer.lvm", data / "measurement.uff"
    for f in (hammer, uff):
        if not f.is_file():
            print(f"real_data.py: {f} not found (give --data)", file=sys.stderr)
            return 2
    extra = ["--max-modes", str(args.max_modes)] if args.max_modes else []
    targets = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        print(f"== {hammer.name}: ami-xr frf, ami-xr identify {' '.join(extra)}")
        said = ami_xr_cli("frf", str(hammer), "-o", str(tmp / "h.nc"))
        said += ami_xr_cli("identify", str(tmp / "h.nc"), "-o", str(tmp / "hm.nc"), *extra)
        with ami_xr.open_dataset(tmp / "h.nc") as h, ami_xr.open_dataset(tmp / "hm.nc") as hm:
            describe(hm, said)
            fn = hm[names.NATURAL_FREQUENCY].values
            peaks = visible_peaks(h)
            hit = matched_peaks(peaks, fn)
            print(
                f"  visible peaks {PEAK_BAND_HZ[0]:.0f}-{PEAK_BAND_HZ[1]:.0f} Hz "
                f"(prominence >= {PEAK_PROMINENCE_DB:g} dB): {len(peaks)}, matched {sum(hit)}"
            )
            print(
                "    "
                + "  ".join(
                    f"{p:.0f}{'' if m else '(missed)'}" for p, m in zip(peaks, hit, strict=True)
                )
            )
            fmax = hm.attrs.get("analysis_band_fmax", np.inf)
            flags = (
                ami_xr.flag_text(hm[names.QUALITY_FLAGS].values)
                if names.QUALITY_FLAGS in hm
                else np.full(fn.size, "")
            )
            above = int(np.sum((fn > fmax) & (flags == "")))
        targets.append(
            verdict(
                "hammer: no unflagged mode above the valid band",
                above == 0,
                f"{above} above {fmax:.0f} Hz",
            )
        )
        targets.append(
            verdict(
                f"hammer: >= {TARGET_PEAKS} visible peaks below 4.9 kHz found",
                sum(hit) >= TARGET_PEAKS,
                f"{sum(hit)}/{len(peaks)}",
            )
        )

        print(f"\n== {uff.name}: ami-xr identify {' '.join(extra)}")
        said = ami_xr_cli("identify", str(uff), "-o", str(tmp / "um.nc"), *extra)
        with ami_xr.open_dataset(tmp / "um.nc") as um:
            describe(um, said)
            pairs = suspicious_pairs(um)
        print(f"  pairs within {PAIR_REL:.0%} in frequency with MAC > {PAIR_MAC}: {len(pairs)}")
        for i, j, df, m in pairs:
            print(f"    modes {i} and {j}: {df:.2f} Hz apart, MAC {m:.3f}")
        targets.append(
            verdict(
                "measurement.uff: no pair within 1 % with MAC > 0.9",
                not pairs,
                f"{len(pairs)} pair(s)",
            )
        )
        cut_targets = cut_runs(tmp, tmp / "h.nc", peaks, extra)
        beam, beam_targets = data / "sdypy_ema_beam.npz", []
        sets = [int(x) for x in args.beam_sets.split(",") if x.strip()]
        if sets and beam.is_file():
            print(f"\n== {beam.name}: as accelerance, mobility, receptance: ami-xr identify")
            beam_targets = beam_quantities(tmp, beam, sets, extra)
    print("\nTargets (issue 10)")
    print("\n".join(targets))
    print("\nTargets (issue 20)")
    print("\n".join(cut_targets))
    if beam_targets:
        print("\nTargets (issue 37)")
        print("\n".join(beam_targets))
    return 0


if __name__ == "__main__":
    sys.exit(main())
