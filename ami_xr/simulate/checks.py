"""Argument checks the random simulators share (:func:`~ami_xr.simulate.random_system`,
:func:`~ami_xr.simulate.clustered_system`): each raises
:class:`~ami_xr.errors.AmiXrValueError` naming the argument before any work, and
:func:`check_sampling` checks the options of how the FRFs are made (source, grid or record,
noise, seed) in one place."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.simulate.noise import NOISE_KINDS

SOURCES = (names.SOURCE_ANALYTIC, names.SOURCE_IMPULSE)


def check_int(value: Any, name: str, low: int, high: int | None = None) -> int:
    """``value`` as an int in ``low..high`` (no upper bound when ``high`` is None)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise AmiXrValueError(f"{name}: expected an integer, got {value!r}")
    if value < low or (high is not None and value > high):
        rng = f"in {low}..{high}" if high is not None else f">= {low}"
        raise AmiXrValueError(f"{name}: expected an integer {rng}, got {value}")
    return int(value)


def check_positive(value: Any, name: str) -> float:
    """``value`` as a finite float > 0."""
    if isinstance(value, bool) or not np.isscalar(value) or not np.isfinite(value) or value <= 0:
        raise AmiXrValueError(f"{name}: expected a finite number > 0, got {value!r}")
    return float(value)


def check_range(value: Any, name: str, limit: float) -> tuple[float, float]:
    """A ``(low, high)`` range of damping ratios with ``0 < low <= high < limit``."""
    try:
        lo, hi = (float(d) for d in value)
    except (TypeError, ValueError):
        raise AmiXrValueError(
            f"{name}: expected (low, high) damping ratios, got {value!r}"
        ) from None
    if not (0 < lo <= hi < limit):
        raise AmiXrValueError(f"{name}: expected 0 < low <= high < {limit}, got {value!r}")
    return lo, hi


class Sampling(NamedTuple):
    """How a simulator makes its FRFs, checked (:func:`check_sampling`)."""

    source: str
    frequency: Any
    max_frequency_hz: float
    n_frequencies: int
    duration: float | None
    n_samples: int | None
    noise: float
    noise_kind: str
    seed: int | None

    def frf_options(self) -> dict[str, Any]:
        """The keyword arguments of :func:`~ami_xr.simulate.random.system_frfs` (all but the
        seed, which seeds the system too: the noise gets a seed drawn from it)."""
        return {k: v for k, v in self._asdict().items() if k != "seed"}


def check_sampling(
    *,
    source: str,
    frequency: Any,
    max_frequency_hz: Any,
    n_frequencies: Any,
    duration: Any,
    n_samples: Any,
    noise: Any,
    noise_kind: str,
    seed: Any,
) -> Sampling:
    """The FRF options of the random simulators, checked: ``source`` analytic (a frequency
    grid: ``frequency`` or ``n_frequencies`` lines up to ``max_frequency_hz``) or impulse
    response (a record: ``duration``, ``n_samples``), noise level >= 0 and kind, seed >= 0."""
    if source not in SOURCES:
        raise AmiXrValueError(f"source: expected one of {SOURCES}, got {source!r}")
    if isinstance(noise, bool) or not np.isscalar(noise) or not np.isfinite(noise) or noise < 0:
        raise AmiXrValueError(f"noise: expected a finite number >= 0, got {noise!r}")
    if noise_kind not in NOISE_KINDS:
        raise AmiXrValueError(f"noise_kind: expected one of {NOISE_KINDS}, got {noise_kind!r}")
    fmax = check_positive(max_frequency_hz, "max_frequency_hz")
    n_frequencies = check_int(n_frequencies, "n_frequencies", 2)
    if source == names.SOURCE_IMPULSE and frequency is not None:
        raise AmiXrValueError(
            "frequency: not allowed with source='impulse_response' (the grid is k / duration; "
            "set duration and n_samples instead)"
        )
    if source == names.SOURCE_ANALYTIC and (duration is not None or n_samples is not None):
        raise AmiXrValueError("duration, n_samples: only used with source='impulse_response'")
    if duration is not None:
        duration = check_positive(duration, "duration")
    if n_samples is not None:
        n_samples = check_int(n_samples, "n_samples", 16)
    if seed is not None:
        seed = check_int(seed, "seed", 0)
    return Sampling(
        source, frequency, fmax, n_frequencies, duration, n_samples, noise, noise_kind, seed
    )


def sampling_of(arguments: Mapping[str, Any]) -> Sampling:
    """:func:`check_sampling` of the sampling arguments (the fields of :class:`Sampling`) among
    a simulator's ``arguments``: its ``locals()``, taken before it rebinds any of those names
    (the simulators share these nine keyword arguments; they are listed once, here)."""
    return check_sampling(**{k: arguments[k] for k in Sampling._fields})
