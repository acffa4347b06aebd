"""Labeled signal processing on time Datasets (the public functions are re-exported by ami_xr).

* :mod:`~ami_xr.dsp.windows` -- ``apply_window`` (force, exponential, hann, ... on time data).
* :mod:`~ami_xr.dsp.impulse` -- ``impulse_to_frf``: sampled impulse responses to FRFs.
* :mod:`~ami_xr.dsp.frf` -- ``frf`` (random excitation, Welch) and ``frf_from_options``, which
  picks ``frf`` or ``impact_frf`` by an ``excitation`` option.
* :mod:`~ami_xr.dsp.hammer` -- ``impact_frf`` (hammer hits; re-exported by ``dsp.frf``).
* :mod:`~ami_xr.dsp.estimator` -- the estimator both share: setup, spectra to H and coherence,
  the noise of the estimate, the FRF Dataset.
* :mod:`~ami_xr.dsp.hits` -- ``check_hits``: overload, double impact and weak force per hit.
* :mod:`~ami_xr.dsp.noise_model` -- ``estimate_frf_noise``: ``frf_noise_std`` per line of a bare
  FRF (roughness between adjacent lines); ``noise_std_of`` for the identification phases.
* :mod:`~ami_xr.dsp.spectral` -- the streaming Welch engine and array-level ``csd``, ``welch``,
  ``coherence`` (scipy.signal's parameters).
* :mod:`~ami_xr.dsp.timeseries` -- checks of the time Datasets FRF estimation reads.
* :mod:`~ami_xr.dsp.quantity` -- ``convert_quantity``: receptance, mobility, accelerance.

Nothing is imported here, so ``ami_xr.dsp.frf`` is always the module (``ami_xr.frf`` the
function).
"""
