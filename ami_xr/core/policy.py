"""Every tunable of the model-order step in one frozen record (plain Python).

The model-order step (:mod:`ami_xr.core.order`, with :mod:`ami_xr.core.regions`,
:mod:`ami_xr.core.model_error` and :mod:`ami_xr.core.proposals`) reads its numbers from
:data:`POLICY` only; each field says where its value comes from. The user-facing settings
(``add_pfa``, ``add_modes``, ``drop_modes``, ``max_iter``, ``max_shift``) stay in
:class:`ami_xr.ami.settings.RefineSettings`.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class OrderPolicy:
    """The model-order step's numbers (see the module docstring)."""

    # -- fits --
    # iteration cap of a trial fit; the kept model is polished with the full budget at the end,
    # and an unfinished fit only understates a trial's gain (conservative)
    trial_iterations: int = 10
    # iterations of the screen on all lines of a trial its band cannot judge: enough to show
    # a good start's gain, which it only understates
    screen_iterations: int = 3
    # trials fitted on all lines in one step at most (a step that changes nothing costs this)
    screen_keep: int = 3
    # residual power over data power of an exact fit: noise-free data, rounding level of the
    # variable projection in double precision
    exact_rss: float = 1e-20

    # -- proposals --
    # residual peaks proposed as one extra pole each per step (a cluster refit covers the rest)
    residual_peaks: int = 2
    # a split starts the two poles this many decay rates apart (half the half-power bandwidth:
    # both inside the mode's band, far enough apart for the fit to move them separately)
    split_shift: float = 0.5
    # splits tried per step at most (twice as many cluster refits): the modes whose band holds
    # the most residual power first; one per mode made a 23-mode FRF take minutes
    max_trials: int = 3
    # false-alarm probability of the screens that pick where the residual shows structure
    # (cheap screens before the likelihood ratio: a loose level costs a trial, not a mode)
    screen_pfa: float = 0.1
    # a cluster's local rational fit tries up to this many poles more than its refinable modes
    extra_poles: int = 3
    # a cluster's band covers each of its modes with this many half-power bandwidths to spare
    # (three let one heavily damped mode pull far-off modes into a band the fit cannot resolve)
    cluster_margin: float = 1.5

    # -- the local screen --
    # a trial's band: the lines within this many half-power bandwidths of the modes it changes
    # (a resonance's contribution is within 3 % of its peak level beyond six bandwidths)
    local_widths: float = 6.0
    # a band with more than this share of the lines is no cheaper than all lines
    local_max_share: float = 0.5

    # -- the model error of a measured peak (ami_xr.core.model_error) --
    # the noise level of a line: the median of the residual's second difference over blocks of
    # this many typical half-power bandwidths (a missed mode's bump, a few wide, barely moves it)
    noise_widths: float = 20.0
    # two poles closer than this many standard deviations of a peak's FRF-to-FRF eigenvalue
    # scatter are one mode: the range of up to a dozen draws of a spread is below 4 sigma
    # (uniform: 2 sqrt(3) sigma; normal: about 3.3 sigma for 8 draws)
    scatter_range: float = 4.0
    # a peak's misfit is its eigenvalue's scatter only when per-FRF shifts explain this share
    # of the residual power beyond the noise there (a missed mode beside it leaves most)
    shift_share: float = 0.5
    # the typical scatter is this quantile over the other peaks: the lower quartile, since the
    # model error of measured data moves every mode while an unresolved close pair inflates its
    # own peak only (three of five peaks on the measured-like plate of benchmark_mimo.py)
    scatter_quantile: float = 0.25
    # peaks with a scatter needed for a typical value
    scatter_peaks: int = 3
    # points needed to estimate a scatter (two give one difference, no spread)
    scatter_points: int = 3

    # -- dropping modes --
    # on an exact fit, the weakest modes tried for removal per pass (a noise-free fit has few
    # superfluous modes, and each try is a fit with three times the trial iterations)
    superfluous_tries: int = 3

    # -- close pairs --
    # the band a close pair is judged on: its modes' half-power bandwidths times this on each
    # side (a resonance's contribution has fallen to ~5 % of its peak three bandwidths away)
    pair_widths: float = 3.0
    # the one-pole model error at a close pair must exceed every other peak's by this factor:
    # measured peaks' model errors spread over a decade (measurement.uff)
    pair_excess: float = 2.0


POLICY = OrderPolicy()
