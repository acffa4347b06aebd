"""Re-export of the modal basis under its documented path (see :mod:`ami_xr.kernels.modal_basis`).

``from ami_xr.kernels.basis import mode_contribution`` is the import the README and the tests use.
"""

from ami_xr.kernels.modal_basis import mode_contribution, pole_basis

__all__ = ["mode_contribution", "pole_basis"]
