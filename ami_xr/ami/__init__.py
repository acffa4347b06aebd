"""The Algorithm of Mode Isolation on labeled FRF Datasets.

Phases (each a function returning a new Dataset, and a ``ds.ami.<name>`` accessor method):

* :func:`subtract` -- Subtraction Phase (eq. 6) with an automatic statistical stop;
* :func:`isolate` -- Isolation Phase (eq. 7), model-order check, matching into system modes;
* :func:`global_fit` -- Global Mode Vector Phase (eqs. 8-9) with quality flags;
* :func:`identify` -- the three in a row (plus :func:`ami_xr.ami.refine.refine` by default);
* :func:`ami_xr.ami.refine.refine` -- joint maximum-likelihood refinement;
  :func:`ami_xr.ami.crb.cramer_rao_bound` -- the Cramér-Rao bound of the same model.

Each module here checks its inputs, makes one ``xr.apply_ufunc`` call and attaches coordinates and
attributes. The settings of each phase are frozen dataclasses in :mod:`ami_xr.ami.settings`;
the numerical work is in :mod:`ami_xr.core` (array level, numpy) and :mod:`ami_xr.kernels`
(numba). The functions return Datasets and never write files: save with
:func:`ami_xr.to_netcdf`, or pass ``path=`` to the accessor method (``ds.ami.identify(path=...)``).
"""

from ami_xr.ami.global_fit import global_fit
from ami_xr.ami.identify import identify
from ami_xr.ami.isolate import isolate
from ami_xr.ami.subtract import subtract

__all__ = ["subtract", "isolate", "global_fit", "identify"]
