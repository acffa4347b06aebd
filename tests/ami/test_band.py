"""The analysis band: chosen from the excitation (force autospectrum, coherence), recorded,
announced, overridable; no mode reported outside it (issue 10, item 2)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.app.cli import main
from ami_xr.dsp import band as bd
from ami_xr.errors import AmiXrValueError, AssumptionWarning

from ..reference import SHARED_DATA

FC = 20.0  # Hz: the force falls as 1 / (1 + (f / FC)^8), 20 dB down at FC * 99^(1/8)
F_FORCE_END = FC * 99 ** (1 / 8)  # 35.5 Hz


def _measured(coherence_end: float = 45.0, dips=()):
    """A simulated FRF made "measured": a band-limited force (FRF noise grows as the force
    falls, so the high band is full of noise peaks) and coherence 0.99 up to ``coherence_end``
    (0.4 above), with one-line antiresonance dips at ``dips`` Hz."""
    ds, truth = ami_xr.simulate.random_system(seed=1, n_points=5, n_frequencies=1024)
    f = ds[names.FREQUENCY].values
    gff = 1.0 / (1.0 + (f / FC) ** 8)
    rng = np.random.default_rng(0)
    peak = float(np.abs(ds[names.FRF]).max())
    noise = rng.standard_normal(ds[names.FRF].shape) + 1j * rng.standard_normal(ds[names.FRF].shape)
    frf = ds[names.FRF] + 1e-3 * peak * noise / np.sqrt(gff)
    coh = np.where(f <= coherence_end, 0.99, 0.4) * np.ones((ds.sizes[names.POINT], 1))
    for d in dips:
        coh[:, np.argmin(np.abs(f - d))] = 0.2
    ds = ds.assign(
        {
            names.FRF: frf,
            names.FORCE_AUTOSPECTRUM: ((names.FREQUENCY,), gff),
            names.COHERENCE: ((names.POINT, names.FREQUENCY), coh),
        }
    )
    return ds, truth


def _identify(ds, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = ami_xr.identify(ds, **kw)
    return out, caught


def test_force_rule_ends_the_band_and_is_recorded_and_announced():
    ds, _ = _measured()
    out, caught = _identify(ds)
    df = float(ds[names.FREQUENCY][1])
    assert out.attrs[names.ATTR_BAND_RULE] == bd.RULE_EXCITATION
    assert out.attrs[names.ATTR_BAND_USER_GIVEN] == ""
    assert abs(out.attrs[names.ATTR_BAND_FMAX] - F_FORCE_END) < 5 * df
    assert out.attrs[names.ATTR_BAND_FMIN] == pytest.approx(df)  # lowest line above 0 Hz
    assert out.attrs[names.ATTR_BAND_FORCE_DROP_DB] == 20.0
    assert out.attrs[names.ATTR_BAND_COHERENCE_MIN] == bd.COHERENCE_MIN
    assert "20 dB" in out.attrs[names.ATTR_BAND_REASON]
    assert float(out[names.FREQUENCY].max()) <= out.attrs[names.ATTR_BAND_FMAX]
    msgs = [str(w.message) for w in caught if issubclass(w.category, AssumptionWarning)]
    band_msgs = [m for m in msgs if "analysis band" in m]
    assert len(band_msgs) == 1 and "fmin/fmax" in band_msgs[0]
    # anything else said is about noise spikes near the band's noisy end (issue 37 item 3)
    assert all("noise explains" in m or "resolve" in m for m in msgs if m not in band_msgs)
    fn = out[names.NATURAL_FREQUENCY].values
    assert fn.size and np.all(fn <= out.attrs[names.ATTR_BAND_FMAX])
    assert np.all(fn >= out.attrs[names.ATTR_BAND_FMIN])


def test_whole_band_finds_noise_modes_the_band_excludes():
    """Without the band the noise above the force's band gives modes there (what the band is
    for); with fmin/fmax given the band is the user's, recorded and not announced."""
    ds, _ = _measured()
    f = ds[names.FREQUENCY].values
    out, caught = _identify(ds, fmin=0.0, fmax=float(f[-1]))
    assert out.attrs[names.ATTR_BAND_RULE] == bd.RULE_USER
    assert out.attrs[names.ATTR_BAND_USER_GIVEN] == "fmin,fmax"
    said = [str(w.message) for w in caught if issubclass(w.category, AssumptionWarning)]
    assert not [m for m in said if "analysis band" in m]
    assert np.any(out[names.NATURAL_FREQUENCY].values > F_FORCE_END + 1.0)


def test_one_limit_given_the_other_from_the_excitation():
    ds, _ = _measured()
    out, _ = _identify(ds, fmin=5.0)
    assert out.attrs[names.ATTR_BAND_USER_GIVEN] == "fmin"
    assert out.attrs[names.ATTR_BAND_FMIN] == 5.0
    assert abs(out.attrs[names.ATTR_BAND_FMAX] - F_FORCE_END) < 0.3
    assert float(out[names.FREQUENCY].min()) >= 5.0
    assert np.all(out[names.NATURAL_FREQUENCY].values >= 5.0)


def test_antiresonance_dips_do_not_cut_the_band_but_lost_coherence_does():
    f = _measured()[0][names.FREQUENCY].values
    ok, _ = bd.valid_lines(f, None, np.where(f < 25.0, 0.99, 0.4)[None, :])
    band_end = f[np.flatnonzero(~ok[1:])[0]]  # first failing line above 0 Hz
    assert abs(band_end - 25.0) < 0.2
    ds, _ = _measured(coherence_end=25.0, dips=(8.0, 12.5, 17.0))
    out, _ = _identify(ds)
    assert abs(out.attrs[names.ATTR_BAND_FMAX] - 25.0) < 0.2


def test_no_excitation_information_whole_band_said_in_attrs():
    ds, _ = ami_xr.simulate.random_system(seed=1, n_points=5, n_frequencies=1024)
    out, caught = _identify(ds)
    f = ds[names.FREQUENCY].values
    assert out.attrs[names.ATTR_BAND_RULE] == bd.RULE_WHOLE
    assert "no excitation information" in out.attrs[names.ATTR_BAND_REASON]
    assert (out.attrs[names.ATTR_BAND_FMIN], out.attrs[names.ATTR_BAND_FMAX]) == (f[0], f[-1])
    assert out.sizes[names.FREQUENCY] == f.size
    assert not [w for w in caught if issubclass(w.category, AssumptionWarning)]


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(fmin=30.0, fmax=10.0), "fmin, fmax"),
        (dict(fmin=-1.0), "fmin"),
        (dict(fmax="x"), "fmax"),
    ],
)
def test_bad_limits_name_the_argument(kw, match):
    ds, _ = _measured()
    with pytest.raises(AmiXrValueError, match=match):
        ami_xr.identify(ds, **kw)


def test_subtract_takes_the_band_too():
    ds, _ = _measured()
    with pytest.warns(AssumptionWarning, match="subtract: analysis band"):
        s = ami_xr.subtract(ds)
    assert s.attrs[names.ATTR_BAND_RULE] == bd.RULE_EXCITATION
    s2 = ami_xr.subtract(ds, fmax=10.0)
    assert float(s2[names.FREQUENCY].max()) <= 10.0


def test_cli_fmin_fmax(tmp_path, capsys):
    ds, _ = _measured()
    src, dst = tmp_path / "in.nc", tmp_path / "out.nc"
    ami_xr.to_netcdf(ds, src)
    assert main(["identify", str(src), "-o", str(dst), "--fmin", "2", "--fmax", "30", "-q"]) == 0
    out = ami_xr.open_dataset(dst)
    assert (out.attrs[names.ATTR_BAND_FMIN], out.attrs[names.ATTR_BAND_FMAX]) == (2.0, 30.0)
    assert out.attrs[names.ATTR_BAND_USER_GIVEN] == "fmin,fmax"
    assert main(["identify", str(src), "-o", str(dst), "-q"]) == 0
    err = capsys.readouterr().err
    assert "warning: AssumptionWarning: identify: analysis band" in err


@pytest.mark.slow
@pytest.mark.skipif(not (SHARED_DATA / "impact_hammer.lvm").exists(), reason="no shared data")
def test_hammer_band_and_no_mode_above_it(tmp_path):
    h, m = tmp_path / "h.nc", tmp_path / "m.nc"
    assert main(["frf", str(SHARED_DATA / "impact_hammer.lvm"), "-o", str(h)]) == 0
    assert main(["identify", str(h), "-o", str(m), "-q"]) == 0
    out = ami_xr.open_dataset(m)
    assert out.attrs[names.ATTR_BAND_RULE] == bd.RULE_EXCITATION
    # the cut-invariant excitation rule (relative windows, maximum reference) ends at 4867 Hz
    assert 4800.0 < out.attrs[names.ATTR_BAND_FMAX] < 6500.0
    assert np.all(out[names.NATURAL_FREQUENCY].values <= out.attrs[names.ATTR_BAND_FMAX])
    assert out.sizes[names.MODE] >= 15


def test_no_mode_beyond_the_measured_lines_on_the_whole_band():
    """A system whose next mode lies just above the last line (system 6 of
    scripts/bench_peers.py): its tail is in the data and the refinement fits it; it is not
    reported, the user is told and the file records it."""
    kw = {"seed": 47463575, "max_frequency_hz": 1000.0}
    _, truth = ami_xr.simulate.random_system(43, "chain", n_frequencies=2, **kw)
    fn = np.sort(truth[names.NATURAL_FREQUENCY].values)
    last = 0.5 * (fn[3] + fn[4])  # between the 4th and the 5th mode
    g, _ = ami_xr.simulate.random_system(
        43, "chain", noise=0.05, frequency=np.linspace(0.0, last, 3527), **kw
    )
    with pytest.warns(AssumptionWarning, match="beyond the measured lines"):
        out = ami_xr.identify(g)
    assert out[names.NATURAL_FREQUENCY].values.max() <= last
    dropped = out.attrs[names.ATTR_BAND_DROPPED]
    assert dropped and all(float(x) > last for x in dropped.split(","))
