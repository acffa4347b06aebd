"""Inconsistent FRF input is refused before any work, with a message naming the variable.

* an impulse-response frequency axis that disagrees with ``sample_interval``/``record_samples``
  (the benchmark's frequencies multiplied by 2 pi, units still Hz);
* NaN or inf in ``frf`` (named with the points and the count, in every AMI phase);
* duplicate point labels (identify and subtract, as validate does);
* a Dataset that would make an invalid UFF file (``write_uff`` and ``convert``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError, SchemaError
from ami_xr.io.datasets import make_frf_dataset


def _hz_times_2pi(ds):
    out = ds.assign_coords({names.FREQUENCY: ds[names.FREQUENCY].values * 2 * np.pi})
    out[names.FREQUENCY].attrs[names.ATTR_UNITS] = "Hz"
    return out


def _with_nan(ds, where):
    out = ds.copy(deep=True)
    values = out[names.FRF].values
    for i, j in where:
        values[i, j] = np.nan if (i + j) % 2 else np.inf
    return out


# --- the frequency axis of an impulse-response FRF ----------------------------------------------


def test_validate_rejects_frequencies_times_2pi(paper_benchmark_clean):
    _, g, _ = paper_benchmark_clean
    df = 1.0 / (g.attrs[names.ATTR_NSAMPLES] * g.attrs[names.ATTR_DT])
    with pytest.raises(SchemaError, match=r"coordinate 'frequency': expected the rfft grid") as e:
        ami_xr.validate(_hz_times_2pi(g))
    assert f"k * {df!r} Hz" in str(e.value)


def test_validate_accepts_the_grid_and_a_band_of_it(paper_benchmark_clean):
    _, g, _ = paper_benchmark_clean
    ami_xr.validate(g)
    ami_xr.validate(g.sel({names.FREQUENCY: slice(10.0, 120.0)}))
    ami_xr.validate(g.isel({names.FREQUENCY: slice(None, None, 3)}))  # every third line


def test_validate_rejects_lines_above_nyquist_and_a_wrong_record_length(paper_benchmark_clean):
    _, g, _ = paper_benchmark_clean
    short = g.copy()
    short.attrs = {**g.attrs, names.ATTR_NSAMPLES: g.attrs[names.ATTR_NSAMPLES] // 2}
    with pytest.raises(SchemaError, match=r"coordinate 'frequency'.*record_samples 2048"):
        ami_xr.validate(short)


def test_make_frf_dataset_names_the_argument():
    with pytest.raises(SchemaError, match=r"argument 'frequency': expected the rfft grid"):
        make_frf_dataset(
            np.ones((1, 5), complex),
            np.arange(5) * 2 * np.pi,
            frf_source=names.SOURCE_IMPULSE,
            sample_interval=0.25,
            record_samples=4 * 2,
        )


def test_identify_rejects_frequencies_times_2pi_before_any_work(paper_benchmark_clean):
    _, g, _ = paper_benchmark_clean
    with pytest.raises(AmiXrValueError, match=r"'frequency': expected the rfft grid"):
        ami_xr.identify(_hz_times_2pi(g))


# --- NaN / inf in frf: every phase --------------------------------------------------------------


def _phase_inputs(frf_dataset):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sub = ami_xr.subtract(frf_dataset)
        iso = ami_xr.isolate(sub)
    return {
        "identify": (ami_xr.identify, frf_dataset),
        "subtract": (ami_xr.subtract, frf_dataset),
        "isolate": (ami_xr.isolate, sub),
        "global_fit": (ami_xr.global_fit, iso),
    }


@pytest.mark.parametrize("phase", ["identify", "subtract", "isolate", "global_fit"])
def test_every_phase_names_nonfinite_frf_values(frf_dataset, phase):
    function, ds = _phase_inputs(frf_dataset)[phase]
    bad = _with_nan(ds, [(1, 10), (1, 11), (2, 150)])  # points 2 (NaN, inf) and 3 (inf)
    with pytest.raises(AmiXrValueError) as err:
        function(bad)
    msg = str(err.value)
    assert "variable 'frf'" in msg
    assert "found 3 NaN or inf value(s) at 2 point(s)" in msg
    assert "2: 2" in msg and "3: 1" in msg
    assert "SVD" not in msg


def test_all_nan_point_is_named_too(frf_dataset):
    bad = frf_dataset.copy(deep=True)
    bad[names.FRF].values[0, :] = np.nan
    with pytest.raises(AmiXrValueError, match=r"variable 'frf'.*1: 200"):
        ami_xr.identify(bad)


def test_cli_identify_of_nan_frf_is_one_line_exit_1(tmp_path, frf_dataset, capsys):
    from ami_xr.app.cli import main

    path = tmp_path / "nan.nc"
    ami_xr.to_netcdf(_with_nan(frf_dataset, [(0, 5)]), path)
    assert main(["identify", str(path)]) == 1
    err = capsys.readouterr().err
    assert "variable 'frf'" in err and "LinAlgError" not in err and "Traceback" not in err


# --- duplicate point labels ---------------------------------------------------------------------


@pytest.mark.parametrize("function", [ami_xr.identify, ami_xr.subtract])
def test_duplicate_point_labels_are_refused(frf_dataset, function):
    dup = frf_dataset.assign_coords({names.POINT: [1, 3, 3]})
    expected = r"coordinate 'point': expected unique labels, duplicates \[3\]"
    with pytest.raises(AmiXrValueError, match=expected):
        function(dup)


# --- write_uff / convert never write an invalid UFF ---------------------------------------------


def _invalid_for_uff(frf_dataset):
    real = frf_dataset.copy()
    real[names.FRF] = real[names.FRF].real
    return {
        "nan": (_with_nan(frf_dataset, [(0, 3)]), r"variable 'frf': expected finite values"),
        "real": (real, r"variable 'frf': expected complex values"),
        "decreasing": (
            frf_dataset.isel({names.FREQUENCY: slice(None, None, -1)}),
            r"coordinate 'frequency': expected strictly increasing",
        ),
        "duplicate": (
            frf_dataset.assign_coords({names.POINT: ["a", "b", "a"]}),
            r"coordinate 'point': expected unique labels, duplicates \['a'\]",
        ),
        "one line": (
            frf_dataset.isel({names.FREQUENCY: slice(0, 1)}),
            r"coordinate 'frequency': expected at least 2 values",
        ),
    }


@pytest.mark.parametrize("case", ["nan", "real", "decreasing", "duplicate", "one line"])
def test_write_uff_refuses_an_invalid_dataset(tmp_path, frf_dataset, case):
    pytest.importorskip("pyuff")
    ds, match = _invalid_for_uff(frf_dataset)[case]
    out = tmp_path / "out.uff"
    with pytest.raises(SchemaError, match=match):
        ami_xr.write_uff(ds, out)
    assert list(tmp_path.iterdir()) == []


def test_write_uff_reports_every_problem_at_once(tmp_path, frf_dataset):
    pytest.importorskip("pyuff")
    bad = _with_nan(frf_dataset, [(0, 3)]).assign_coords({names.POINT: [1, 1, 2]})
    with pytest.raises(SchemaError) as err:
        ami_xr.write_uff(bad, tmp_path / "out.uff")
    assert len(err.value.problems) == 2


def test_convert_of_nan_frf_to_uff_exits_1_and_writes_nothing(tmp_path, frf_dataset, capsys):
    pytest.importorskip("pyuff")
    from ami_xr.app.cli import main

    src = tmp_path / "nan.nc"
    ami_xr.to_netcdf(_with_nan(frf_dataset, [(2, 7)]), src)
    assert main(["convert", str(src), "-o", str(tmp_path / "out.uff")]) == 1
    assert "variable 'frf': expected finite values" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nan.nc"]
