"""ami_xr.simulate.checks: the argument checks random_system and clustered_system share, each
error naming its argument before any work."""

import numpy as np
import pytest

import ami_xr
from ami_xr.errors import AmiXrValueError
from ami_xr.simulate.checks import (
    SOURCES,
    Sampling,
    check_int,
    check_positive,
    check_range,
    check_sampling,
    sampling_of,
)

GOOD = {
    "source": "analytic",
    "frequency": None,
    "max_frequency_hz": 50.0,
    "n_frequencies": 64,
    "duration": None,
    "n_samples": None,
    "noise": 0.0,
    "noise_kind": "uniform",
    "seed": 0,
}


def test_check_int_bounds_and_types():
    assert check_int(np.int64(5), "n", 2, 8) == 5 and type(check_int(np.int64(5), "n", 2)) is int
    with pytest.raises(AmiXrValueError, match=r"^n: expected an integer in 2\.\.8, got 9$"):
        check_int(9, "n", 2, 8)
    with pytest.raises(AmiXrValueError, match=r"^n: expected an integer >= 2, got 1$"):
        check_int(1, "n", 2)
    for bad in (True, 2.0, "3", None):
        with pytest.raises(AmiXrValueError, match=r"^n: expected an integer, got"):
            check_int(bad, "n", 0)


def test_check_positive_and_range():
    assert check_positive(np.float32(0.5), "x") == 0.5
    for bad in (0, -1.0, np.inf, np.nan, True, [1.0]):
        with pytest.raises(AmiXrValueError, match=r"^x: expected a finite number > 0"):
            check_positive(bad, "x")
    assert check_range((0.01, 0.02), "damping", 0.3) == (0.01, 0.02)
    with pytest.raises(AmiXrValueError, match=r"damping: expected \(low, high\) damping ratios"):
        check_range(0.01, "damping", 0.3)
    with pytest.raises(AmiXrValueError, match=r"damping: expected 0 < low <= high < 0.3"):
        check_range((0.02, 0.01), "damping", 0.3)


def test_check_sampling_returns_the_checked_record():
    s = check_sampling(**{**GOOD, "max_frequency_hz": 20, "seed": np.int64(3)})
    assert isinstance(s, Sampling) and s.max_frequency_hz == 20.0 and s.seed == 3
    assert "seed" not in s.frf_options() and set(s.frf_options()) == set(GOOD) - {"seed"}
    impulse = check_sampling(**{**GOOD, "source": SOURCES[1], "duration": 2, "n_samples": 64})
    assert impulse.duration == 2.0 and impulse.n_samples == 64


def test_sampling_of_takes_the_sampling_arguments_among_a_simulators_locals():
    arguments = {**GOOD, "n_points": 8, "seed": 4, "topology": "chain"}
    assert sampling_of(arguments) == check_sampling(**{**GOOD, "seed": 4})
    with pytest.raises(AmiXrValueError, match=r"^noise: expected a finite number >= 0"):
        sampling_of({**arguments, "noise": -1.0})


@pytest.mark.parametrize(
    "change, match",
    [
        ({"source": "measured"}, r"^source: expected one of"),
        ({"noise": -0.1}, r"^noise: expected a finite number >= 0"),
        ({"noise_kind": "pink"}, r"^noise_kind: expected one of"),
        ({"max_frequency_hz": 0}, r"^max_frequency_hz: expected a finite number > 0"),
        ({"n_frequencies": 1}, r"^n_frequencies: expected an integer >= 2"),
        ({"source": "impulse_response", "frequency": [1.0]}, r"^frequency: not allowed"),
        ({"duration": 1.0}, r"^duration, n_samples: only used with source='impulse_response'"),
        ({"source": "impulse_response", "n_samples": 8}, r"^n_samples: expected an integer >= 16"),
        ({"seed": -1}, r"^seed: expected an integer >= 0"),
    ],
)
def test_both_simulators_refuse_a_bad_sampling_option_alike(change, match):
    with pytest.raises(AmiXrValueError, match=match):
        check_sampling(**{**GOOD, **change})
    with pytest.raises(AmiXrValueError, match=match):
        ami_xr.simulate.random_system(5, **change)
    with pytest.raises(AmiXrValueError, match=match):
        ami_xr.simulate.clustered_system(5, **change)
