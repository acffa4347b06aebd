"""Array-level modal analysis (numpy only, no xarray): what the labeled layer ``ami_xr.ami`` wraps.

* :mod:`ami_xr.core.model` -- which modal basis describes an FRF (discrete or continuous);
* :mod:`ami_xr.core.matching` -- matching eigenvalue estimates into modes, averaging them;
* :mod:`ami_xr.core.modal` -- natural frequency, damping ratio, mode vectors (eq. 8), MAC,
  standard errors of the modal quantities;
* :mod:`ami_xr.core.varpro` -- variable projection and Levenberg-Marquardt (the optimiser);
* :mod:`ami_xr.core.refine` -- the joint maximum-likelihood refinement with its model-order
  tests, returning a :class:`~ami_xr.core.refine.RefineResult`.
"""
