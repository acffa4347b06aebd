"""Simulated test systems with exactly known modal parameters.

* :mod:`~ami_xr.simulate.modal` -- any linear system ``M, C, K`` (non-proportional damping):
  exact eigenvalues, mode vectors and residues (eqs. 2-5), analytic FRFs (eq. 4) and impulse
  responses.
* :mod:`~ami_xr.simulate.eigen` -- the state-space eigensolution behind ``modal_model``.
* :mod:`~ami_xr.simulate.noise` -- the paper's noise model (eq. 15).
* :mod:`~ami_xr.simulate.beam` -- the paper's benchmark, a cantilever beam with three
  suspended spring-mass-dashpot absorbers.
* :mod:`~ami_xr.simulate.random` -- random lumped-mass chains and grids for tests.
* :mod:`~ami_xr.simulate.symmetric` -- a grounded ring of equal masses with repeated pairs of
  modes, one pair split by a chosen relative amount (multi-reference benchmarks).
* :mod:`~ami_xr.simulate.cluster` -- systems with clusters of three or four modes at a chosen
  modal overlap, non-proportionally damped (issue 20 benchmarks).
* :mod:`~ami_xr.simulate.catalogue` -- the fixed benchmark catalogues (random systems, overlap
  cases) and the scoring of identified modes against the truth.
"""

from ami_xr.simulate.beam import (
    DRIVE_POINT as BENCHMARK_DRIVE_POINT,
)
from ami_xr.simulate.beam import (
    POINT_LABELS as BENCHMARK_POINTS,
)
from ami_xr.simulate.beam import (
    beam_absorbers,
    benchmark,
    benchmark_model,
    frf_from_impulse,
    paper_tables,
)
from ami_xr.simulate.catalogue import catalogue, cluster_catalogue, score_modes
from ami_xr.simulate.cluster import clustered_system, overlap_factor
from ami_xr.simulate.modal import (
    frf,
    impulse_response,
    modal_model,
    residues,
    state_space_modes,
)
from ami_xr.simulate.noise import add_noise
from ami_xr.simulate.random import contrast, mode_peaks, random_system
from ami_xr.simulate.symmetric import symmetric_structure

__all__ = [
    "BENCHMARK_DRIVE_POINT",
    "BENCHMARK_POINTS",
    "add_noise",
    "beam_absorbers",
    "catalogue",
    "cluster_catalogue",
    "clustered_system",
    "contrast",
    "benchmark",
    "benchmark_model",
    "frf",
    "frf_from_impulse",
    "impulse_response",
    "modal_model",
    "overlap_factor",
    "mode_peaks",
    "paper_tables",
    "random_system",
    "residues",
    "score_modes",
    "state_space_modes",
    "symmetric_structure",
]
