"""scripts/real_data.py: the scoring helpers on made-up data, and one run on the measured files
(skipped where ../shared/data is absent)."""

from __future__ import annotations

import runpy

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from tests.reference import REPO, SHARED_DATA

SCRIPT = runpy.run_path(str(REPO / "scripts" / "real_data.py"), run_name="real_data")


def test_visible_peaks_finds_prominent_maxima_inside_the_band():
    f = np.arange(0.0, 6000.0, 1.0)
    h = np.ones_like(f, dtype=complex)
    for f0, height in ((30.0, 10.0), (200.0, 10.0), (1000.0, 1.5), (3000.0, 10.0), (5500.0, 10.0)):
        h += height / (1 + ((f - f0) / 3.0) ** 2)
    ds = ami_xr.make_frf_dataset(h[None, :], f, points=["a"], drive_point="a")
    # 30 Hz and 5.5 kHz lie outside 50-4900 Hz; 1 kHz rises 2.5 / 1 = 8 dB, 200 and 3000 Hz 21 dB
    np.testing.assert_array_equal(SCRIPT["visible_peaks"](ds), [200.0, 1000.0, 3000.0])


def test_matched_peaks_uses_one_percent_or_three_hertz():
    peaks = np.array([100.0, 1000.0, 4000.0])
    assert SCRIPT["matched_peaks"](peaks, np.array([102.9, 1009.0, 4041.0])) == [True, True, False]
    assert SCRIPT["matched_peaks"](peaks, np.array([])) == [False, False, False]


def test_suspicious_pairs_are_close_in_frequency_and_alike_in_shape():
    phi = np.array([[1.0, 1.0, 1.0], [0.5, 0.52, -1.0], [0.2, 0.19, 0.3]], dtype=complex)
    modes = xr.Dataset(
        {
            names.NATURAL_FREQUENCY: (names.MODE, [100.0, 100.5, 100.8]),
            names.MODE_VECTOR: ((names.POINT, names.MODE), phi),
        },
        coords={names.MODE: [1, 2, 3], names.POINT: ["a", "b", "c"]},
    )
    pairs = SCRIPT["suspicious_pairs"](modes)
    assert [(i, j) for i, j, _, _ in pairs] == [(1, 2)]  # mode 3 is close but another shape
    assert pairs[0][3] > 0.99


@pytest.mark.slow
@pytest.mark.skipif(not SHARED_DATA.is_dir(), reason="../shared/data (measured files) is absent")
def test_real_data_script_runs_both_files_and_prints_the_targets(capsys):
    assert SCRIPT["main"](["--data", str(SHARED_DATA), "--beam-sets", "0"]) == 0
    out = capsys.readouterr().out
    assert "== impact_hammer.lvm" in out and "== measurement.uff" in out
    assert "rule 'excitation'" in out  # the hammer band comes from the force and coherence
    assert "visible peaks 50-4900 Hz" in out
    targets = out.split("Targets (issue 10)")[1].split("Targets (issue 20)")[0].strip().splitlines()
    assert len(targets) == 3 and all(t.endswith(("met", "NOT met")) for t in targets)
    # issue 20: the hammer FRF over 20-4885 Hz with --fmin/--fmax and cut first with .sel
    assert "--fmin 20 --fmax 4885: ami-xr identify h.nc" in out
    assert ".sel(frequency=slice(20, 4885)): ami-xr identify h_cut.nc" in out
    assert "same modes with --fmin/--fmax and with .sel: yes" in out
    cut = out.split("Targets (issue 20)")[1].split("Targets (issue 37)")[0].strip().splitlines()
    assert len(cut) == 3 and all(t.endswith(("met", "NOT met")) for t in cut)
    assert cut[2].endswith(" met") and not cut[2].endswith("NOT met")  # the same modes
    # issue 37: sdypy-EMA's beam as accelerance, mobility and receptance, the same modes
    assert "== sdypy_ema_beam.npz" in out
    beam = out.split("Targets (issue 37)")[1].strip().splitlines()
    assert len(beam) == 3 and beam[0].endswith(" met") and not beam[0].endswith("NOT met")
