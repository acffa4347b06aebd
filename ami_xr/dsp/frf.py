"""FRF estimation from measured force and response histories: :func:`frf` and :func:`impact_frf`.

:func:`frf` estimates H1, H2 or Hv from random (continuous, shaker) excitation by Welch
averaging; :func:`impact_frf` from hammer hits, each checked (:mod:`ami_xr.dsp.hits`), windowed
with a force and an exponential window and averaged. Both return the ordinary coherence
(multiple coherence with several force channels) and the averaged auto- and cross-spectra, and
share one estimator, ``spectra_to_frf``. :func:`frf_from_options` picks one of the two from an
``excitation`` option, for option dictionaries held as data (batch runs, the CLI).

Processing path (the same for data in memory and data opened lazily from a file)::

    time Dataset --(record by record, time block by time block)--> WelchAccumulator
                 --> Gff, Gfy, Gyy --(one xr.apply_ufunc, per frequency)--> H, coherence

A dask-backed Dataset is read one time chunk at a time (or ``chunk_samples`` at a time); the
samples of a segment that straddles a chunk border are carried to the next chunk, so memory is
bounded by the chunk size and the result equals the in-memory computation. Segments never span
two records. (The accumulation over time is a loop over blocks rather than an ``apply_ufunc``
over ``time``: its state, the carried samples and the running sums, crosses chunk borders, which
``dask="parallelized"`` cannot express; the per-frequency division is the ``apply_ufunc``.)
"""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.caller import warn
from ami_xr.dsp.estimator import (  # noqa: F401 - the undefined-line attributes are read from here
    ATTR_UNDEFINED_LINES,
    ATTR_UNDEFINED_REASON,
    finish,
    setup,
    spectra_to_frf,
)
from ami_xr.dsp.hammer import impact_frf
from ami_xr.dsp.spectral import check_choice, resolve_window
from ami_xr.dsp.timeseries import excitation_of
from ami_xr.errors import AmiXrValueError, AssumptionWarning

EXCITATIONS = ("random", "impact")
AUTO = "auto"  # excitation decided by ami_xr.dsp.timeseries.excitation_of


def frf(
    ds: xr.Dataset,
    estimator: str = "H1",
    *,
    force: xr.DataArray | None = None,
    fs: float | None = None,
    window: str | np.ndarray = "hann",
    nperseg: int | None = None,
    noverlap: int | None = None,
    nfft: int | None = None,
    detrend: str | bool = "constant",
    average: str = "linear",
    n_average: int = 8,
    chunk_samples: int | None = None,
    workers: int = 1,
) -> xr.Dataset:
    """Estimate FRFs (H1, H2 or Hv) and coherence from random (continuous) excitation by Welch
    averaging. Hammer tests go through :func:`impact_frf`.

    Data that look like hammer hits (the force is a short pulse:
    :func:`ami_xr.dsp.timeseries.excitation_of`, the rule the CLI's ``--excitation auto`` uses)
    give an :class:`~ami_xr.errors.AssumptionWarning` naming the segments averaged and pointing
    to :func:`impact_frf`: Welch segments of a hit average mostly silence and use overloaded and
    double hits unchecked. A warning, not an error: Welch over whole hits (``nperseg`` = the
    record, ``noverlap=0``, ``window="boxcar"``, ``detrend="none"``) is a valid expert choice, and
    the random estimate stays reachable for every input. :func:`frf_from_options` without an
    ``excitation`` (and ``ami-xr frf``) picks :func:`impact_frf` for such data by the same rule.

    Parameters
    ----------
    ds : xarray.Dataset
        Time Dataset: ``response`` ([record,] point, time), ``force`` ``([record,] [reference,]
        time)``, ``time`` coordinate in s (uniform). May be dask-backed (opened lazily with
        :func:`ami_xr.open_dataset`); it is then read one time chunk at a time. Records are
        averaged together; no segment spans two records.
    estimator : {"H1", "H2", "Hv"}
        ``H1 = Gfy/Gff`` (unbiased by output noise), ``H2 = Gyy/Gyf`` (unbiased by input noise),
        ``Hv`` total least squares (between them). Several force channels: H1 only (MIMO).
    force : xarray.DataArray, optional
        Force histories recorded separately (replaces ``ds.force``); must have the same samples
        and sampling rate as the responses.
    fs : float, optional
        Sampling rate in Hz; checked against the time coordinate when both are present.
    window : str or ndarray
        Welch window: a name known to :func:`ami_xr.kernels.windows.get_window` or an array of
        ``nperseg`` samples (``None`` also means ``"hann"``).
    nperseg, noverlap, nfft : int, optional
        Segment length (default 256 samples, or the record if shorter), overlap (default
        ``nperseg // 2``) and FFT length (default ``nperseg``), as in ``scipy.signal.csd``.
    detrend : {"constant", "linear", "none"} or False
        Removed from each segment before windowing (``None`` also means ``"constant"``).
    average : {"linear", "exponential"}
        Linear: plain mean over all segments. Exponential: running average with time constant
        ``n_average`` segments (linear over the first ``n_average``). Not the ``average`` of
        ``scipy.signal.csd``/``welch`` (``"mean"`` or ``"median"`` of the segments): the name
        follows the averaging types of FFT analysers (linear, exponential); scipy's ``"mean"``
        is our ``"linear"``, and a median average is not offered.
    n_average : int
        Time constant of exponential averaging, in segments.
    chunk_samples : int, optional
        Samples per block read from a lazy Dataset (default: its dask chunks along ``time``).
    workers : int
        Threads of ``scipy.fft``.

    Returns
    -------
    xarray.Dataset
        FRF Dataset: ``frf`` ([reference,] point, frequency) complex, ``coherence`` (point,
        frequency; multiple coherence with several force channels), ``force_autospectrum``
        ([reference,] frequency), ``response_autospectrum`` (point, frequency),
        ``cross_spectrum`` ([reference,] point, frequency) (one-sided densities),
        ``frf_line_noise_std`` (dims of ``frf``, units of ``frf``: the standard deviation of the
        complex estimate per line from the coherence and the effective number of averages
        ``n_d``, ``sqrt((1 - coh) |H|^2 / (coh (n_d - q)))`` for ``q`` force channels, Bendat &
        Piersol's random error; with ``n_d < q + 1`` the roughness estimate of
        :func:`ami_xr.estimate_frf_noise`, left out below 5 lines; attr ``noise_model`` says
        which), attrs ``frf_source="estimated"``, ``estimator``, ``n_averages``. With several
        force channels the ``reference`` labels are those of the force's ``reference``
        coordinate (default 0, 1, ...): give the labels of the excitation points, so that a
        reference on a measured point marks its drive point; the ``drive_point`` attribute is
        then dropped.

    Raises
    ------
    AmiXrValueError
        Bad input, each naming the argument: missing force, different lengths or sampling
        rates, NaN samples, ``nperseg`` longer than the record, ``noverlap >= nperseg``, unknown
        window, estimator, detrend or average.
    """
    s = setup(
        ds,
        estimator=estimator,
        force=force,
        fs=fs,
        segments=(nperseg, noverlap, nfft, 256),
        detrend="constant" if detrend is None else detrend,
        average=average,
        n_average=n_average,
        chunk_samples=chunk_samples,
        workers=workers,
    )
    window = "hann" if window is None else window
    w = resolve_window(window, s.nperseg)
    records = np.arange(s.force.sizes[names.RECORD])
    if excitation_of(ds if force is None else xr.Dataset({names.FORCE: force})) == "impact":
        n_seg = records.size * (1 + (s.force.sizes[names.TIME] - s.nperseg) // s.nperseg_step)
        warnings.warn(
            f"ds: the force is a short pulse (hammer hits), but ami_xr.frf averages Welch "
            f"segments of random excitation ({n_seg} segments of {s.nperseg} samples, no hit "
            "checks); use ami_xr.impact_frf (ami-xr frf --excitation impact)",
            AssumptionWarning,
            stacklevel=2,
        )
    if nperseg is None:
        _warn_few_lines(s.nperseg, s.nfft, s.force.sizes[names.TIME], s.fs)
    out = spectra_to_frf(ds, s, (w, w), records, {}, {})
    label = window if isinstance(window, str) else "array"
    return finish(out, s, "ami_xr.frf", label, {"n_records_used": records.size})


#: Fewer lines than this from the default segment length is said (issue 24 item 8): the
#: identification's bands then hold a handful of lines each.
FEW_LINES = 257
#: Welch segments the suggested ``nperseg`` keeps in a record (about twice that with the
#: default half overlap), so the averages still tame the noise.
SUGGESTED_SEGMENTS = 8


def _warn_few_lines(nperseg: int, nfft: int, n_time: int, fs: float) -> None:
    """The default ``nperseg`` leaves fewer than :data:`FEW_LINES` lines although the record
    holds :data:`SUGGESTED_SEGMENTS` segments of a longer power of two: say so and what to
    pass. (The damping is not known here: :func:`ami_xr.identify` gives the ``nperseg`` that
    resolves its lightest-damped mode, :mod:`ami_xr.ami.resolution`.)"""
    lines = nfft // 2 + 1
    suggested = 2 ** int(np.floor(np.log2(max(n_time / SUGGESTED_SEGMENTS, 1.0))))
    if lines >= FEW_LINES or suggested <= nperseg:
        return
    warn(
        f"frf: the default nperseg={nperseg} gives {lines} lines {fs / nfft:.4g} Hz apart from "
        f"a record of {n_time} samples ({n_time / fs:.4g} s); identification wants a few "
        f"hundred lines: pass nperseg={suggested} ({suggested // 2 + 1} lines "
        f"{fs / suggested:.4g} Hz apart, {SUGGESTED_SEGMENTS} segments or more; "
        "ami-xr frf --nperseg); identify then flags a mode whose half-power bandwidth spans "
        "fewer than 3 lines (under_resolved) and names the nperseg that resolves it",
        AssumptionWarning,
    )


def frf_from_options(ds: xr.Dataset, options: Mapping[str, Any]) -> xr.Dataset:
    """:func:`frf` or :func:`impact_frf` by ``options["excitation"]`` (``"random"``,
    ``"impact"``, or ``"auto"``, the default: :func:`~ami_xr.dsp.timeseries.excitation_of`
    decides from the force, the rule of ``ami-xr frf``), with the other options as keyword
    arguments.

    For option dictionaries held as data (``ami_xr.batch``'s ``frf_options``, the CLI): an option
    of the other function raises :class:`AmiXrValueError` naming it unless it is None (unset), and
    so does an option of neither.
    """
    options = dict(options)
    excitation = options.pop("excitation", AUTO)
    excitation = check_choice(excitation, "excitation", (*EXCITATIONS, AUTO))
    if excitation == AUTO:
        excitation = excitation_of(ds)
    function, other = (impact_frf, frf) if excitation == "impact" else (frf, impact_frf)
    own = set(inspect.signature(function).parameters) - {"ds"}
    foreign = set(inspect.signature(other).parameters) - own - {"ds"}
    kwargs = {}
    for name, value in options.items():
        if name in own:
            kwargs[name] = value
        elif name not in foreign:
            raise AmiXrValueError(f"{name}: not an option of ami_xr.{function.__name__}")
        elif value is not None:
            raise AmiXrValueError(
                f"{name}: not used with excitation={excitation!r} (an option of "
                f"ami_xr.{other.__name__})"
            )
    return function(ds, **kwargs)
