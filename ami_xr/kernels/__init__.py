"""Kernel layer: plain ndarrays in, ndarrays out; numpy, numba and math only.

Kernels take batch dims first and the core dim (frequency or time) last. Private ``_name`` kernels
are jitted and assume clean input; public checked wrappers raise
:class:`~ami_xr.errors.AmiXrValueError` (naming the argument) before any jitted code runs, and are
the only entry points of the labeled layer. Jitted helpers that other kernel modules share have
public names and say "jitted, unchecked" in their module docstring. The modules are split by
topic, and each kernel's on-disk cache is stamped with its own file and the kernel modules it
imports (``_numba``): an edit recompiles that topic's kernels and those of the topics that call
it, no others.

Modules (numba policy in ``_numba``):

* ``windows``, ``fft``, ``spectral``, ``impact``: signal processing (windows, impulse -> FRF,
  Welch accumulation, impact hit checks).
* ``modal_basis``: the modal model b(lam, w) (continuous and exact discrete), its derivative,
  residual terms, model columns, synthesis, contribution peaks.
* ``linalg``: small dense solvers (Gaussian elimination, scaled normal equations).
* ``noise``: noise floors and detection thresholds.
* ``single_mode`` / ``two_mode``: single-mode (per FRF, SIMO) and two-mode least squares.
* ``residues``: residues with fixed eigenvalues (eq. 9).
* ``peak``: the peak trial (band, fit, energy drop) and fit bands, shared by the AMI phases.
* ``subtract``: the Subtraction Phase. ``engine``: the one isolation engine (sweeps, merge and
  prune, model-order check) for per-FRF and SIMO isolation; ``groups``: its restarts, in calls
  that return to the caller between restarts (interrupts) and for a split's two-mode fit;
  ``isolate``: its checked wrappers.
* ``projection``: variable-projection refinement kernels; ``columns``: their model columns,
  stacked and weighted in one pass.
"""
