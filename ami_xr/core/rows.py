"""Per-point fits and syntheses on a block of FRF rows, for FRF sets held as chunks of points.

Every function here takes a block of rows (..., F) or of per-point coefficients (..., n) and
returns a result for those rows only, so that a phase can run it on each chunk of points of a
lazily opened FRF set (one task per chunk on the dask workers) and gather only what is per point
and small (residues, coefficients), while what has the size of the FRF (the synthesized FRFs,
the residuals) is made again per chunk from those small results when it is needed. Called on
the whole numpy array it gives the eager path's result (a row's result does not depend on the
other rows of its block).

Plain numpy on plain arrays; the compiled work is in :mod:`ami_xr.kernels`.
"""

from __future__ import annotations

import numpy as np

from ami_xr.kernels import modal_basis as kb
from ami_xr.kernels import residues as kr

__all__ = ["fit_rows", "synthesize_rows", "n_coefficients", "refined_rows"]


def n_coefficients(n_modes: int, residual_kind: int) -> int:
    """Complex coefficients per FRF of the residue fit: a residue per mode, and a lower and an
    upper residual term when ``residual_kind >= 0``."""
    return int(n_modes) + (2 if residual_kind >= 0 else 0)


def _flat(block: np.ndarray) -> tuple[np.ndarray, tuple[int, ...]]:
    """``block`` (..., X) as contiguous complex rows (R, X) and its leading shape."""
    block = np.asarray(block)
    shape = block.shape[:-1]
    return np.ascontiguousarray(block.reshape(-1, block.shape[-1]), dtype=np.complex128), shape


def fit_rows(
    g: np.ndarray,
    *,
    omega: np.ndarray,
    lam: np.ndarray,
    use: np.ndarray,
    dt: float | None,
    n_samples: int | None,
    kind: int,
) -> np.ndarray:
    """Residues (and residual coefficients) of the FRFs ``g`` (..., F) at the fixed eigenvalues
    ``lam`` (n,), fitted on the lines ``use`` (eq. 9, :func:`ami_xr.kernels.residues.
    residues_fixed`): (..., n) or, with ``kind >= 0`` (the residual terms' FRF kind), (..., n + 2)
    with the lower and upper coefficients last."""
    g2, shape = _flat(g)
    coef = kr.residues_fixed(g2, omega, lam, use, dt, n_samples, kind)
    return coef.reshape(shape + (coef.shape[-1],))


def synthesize_rows(
    coef: np.ndarray,
    *,
    omega: np.ndarray,
    lam: np.ndarray,
    dt: float | None,
    n_samples: int | None,
    kind: int,
) -> np.ndarray:
    """The model FRFs (..., F) on the lines ``omega`` of the coefficients ``coef`` of
    :func:`fit_rows` (..., n [+ 2]) at the eigenvalues ``lam`` (n,)."""
    c2, shape = _flat(coef)
    n_k = lam.size
    res = np.ascontiguousarray(c2[:, :n_k])
    synth = kb.synthesize(omega, lam[None, :], res, dt, n_samples)
    if kind >= 0:
        synth = synth + kb.synthesize_residual_terms(omega, np.ascontiguousarray(c2[:, n_k:]), kind)
    return synth.reshape(shape + (omega.size,))


def refined_rows(
    residue: np.ndarray,
    residual_coefficient: np.ndarray,
    *,
    omega: np.ndarray,
    mu: np.ndarray,
    residual_terms: tuple[str, ...],
    residual_kind: int,
    dt: float,
    n_samples: int,
) -> np.ndarray:
    """The refined model FRFs (..., F) of the rows' residues (..., K) and residual coefficients
    (..., 2) at the data's poles ``mu``: :func:`ami_xr.core.refine.synthesize` on those rows."""
    from ami_xr.core.refine import synthesize  # the refinement's own model, one definition

    res, shape = _flat(residue)
    rc, _ = _flat(residual_coefficient)
    synth, _ = synthesize(omega, mu, res, rc, residual_terms, residual_kind, dt, n_samples)
    return synth.reshape(shape + (omega.size,))
