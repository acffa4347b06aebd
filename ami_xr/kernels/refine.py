"""Former home of the refinement kernels, kept as a re-export for existing imports.

The variable-projection kernels live in :mod:`ami_xr.kernels.projection`; the model columns and
the basis with its derivative in :mod:`ami_xr.kernels.modal_basis`. New code imports from there.
"""

from ami_xr.kernels.modal_basis import RESIDUAL_TERMS, basis_and_derivative, model_columns
from ami_xr.kernels.projection import gram, matmul_small, normal_equations, project_points

__all__ = [
    "RESIDUAL_TERMS",
    "basis_and_derivative",
    "gram",
    "matmul_small",
    "model_columns",
    "normal_equations",
    "project_points",
]
