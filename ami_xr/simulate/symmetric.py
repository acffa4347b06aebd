"""A symmetric structure with repeated modes: a grounded ring of equal masses (issue 13).

``n`` equal masses ``m`` on a ring, each tied to ground by a spring ``k_g`` and to its two
neighbours by springs ``k_c``. The stiffness matrix is circulant, so its modes are the ring's
harmonics: harmonic ``j`` (``0 <= j <= n/2``) has ``w_j^2 = (k_g + 2 k_c (1 - cos(2 pi j / n)))
/ m`` and, for ``0 < j < n/2``, two modes ``cos(2 pi j i / n)`` and ``sin(2 pi j i / n)`` at the
same frequency (a repeated pair; any rotation of the two is a mode too). With the default
``n = 6``: one mode at harmonic 0 (10 Hz), pairs at harmonics 1 (17.3 Hz) and 2 (26.5 Hz), one
mode at harmonic 3 (30 Hz).

The asymmetry is a stiffness perturbation ``delta v v^T`` with ``v`` the mass-normalised
``cos`` member of the chosen pair: it moves that member only, exactly (the other modes are
``M``-orthogonal to ``v``), to ``w_j (1 + split)``; every other mode, and the ``sin`` member, keep
their frequencies and shapes. (A local change, one spring stiffer, would split every pair and
move the single modes as well.) Damping is stiffness proportional, ``C = beta K`` with
``beta = 2 zeta / w_j``, so the modes are real and the chosen pair has damping ratio ``zeta``
(the split member ``zeta (1 + split)``).

The truth is :func:`~ami_xr.simulate.modal.modal_model` of ``M, C, K``; at an exactly repeated
root its mode vectors are made orthogonal (``state_space_modes``), so the FRFs synthesised
from the truth equal ``(K - w^2 M + i w C)^-1``; the pair's basis in its plane is then one
choice among all rotations.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from typing import Any

import numpy as np
import xarray as xr

from ami_xr.errors import AmiXrValueError
from ami_xr.provenance import add_history
from ami_xr.simulate.modal import modal_model

# Attributes symmetric_structure writes beyond ami_xr.names (simulator-specific).
ATTR_REPEATED_PAIRS = "repeated_pairs"  # mode numbers of every pair, two by two (flat list)
ATTR_SPLIT_PAIR = "split_pair"  # mode numbers of the chosen pair (lower, upper)
ATTR_SPLIT = "split"  # relative split of the chosen pair's natural frequencies
ATTR_SYMMETRY = "symmetry"  # description of the structure


def _number(value: Any, name: str, *, minimum: float = 0.0, strict: bool = True) -> float:
    if isinstance(value, bool) or not np.isscalar(value):
        raise AmiXrValueError(f"{name}: expected a number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError) as exc:
        raise AmiXrValueError(f"{name}: expected a number, got {value!r}") from exc
    if not np.isfinite(x) or (x <= minimum if strict else x < minimum):
        op = ">" if strict else ">="
        raise AmiXrValueError(f"{name}: expected a finite number {op} {minimum:g}, got {value!r}")
    return x


def ring_matrices(
    n_masses: int = 6,
    *,
    mass: float = 1.0,
    ground_stiffness: float = 3948.0,
    coupling_stiffness: float = 7900.0,
) -> tuple[np.ndarray, np.ndarray]:
    """``M`` and ``K`` of the symmetric grounded ring (no asymmetry, no damping)."""
    if isinstance(n_masses, bool) or not isinstance(n_masses, (int, np.integer)) or n_masses < 3:
        raise AmiXrValueError(f"n_masses: expected an integer >= 3, got {n_masses!r}")
    n = int(n_masses)
    m = _number(mass, "mass")
    kg = _number(ground_stiffness, "ground_stiffness")
    kc = _number(coupling_stiffness, "coupling_stiffness")
    k = np.eye(n) * (kg + 2 * kc)
    for i in range(n):
        k[i, (i + 1) % n] -= kc
        k[(i + 1) % n, i] -= kc
    return np.eye(n) * m, k


def symmetric_structure(
    split: float = 0.0,
    *,
    n_masses: int = 6,
    pair: int = 1,
    mass: float = 1.0,
    ground_stiffness: float = 3948.0,
    coupling_stiffness: float = 7900.0,
    damping_ratio: float = 0.01,
    point_labels: Sequence[Hashable] | None = None,
    drive_point: Hashable | None = None,
) -> xr.Dataset:
    """Modal truth of a grounded ring of equal masses with repeated pairs, one pair split.

    Parameters
    ----------
    split : float
        Relative split of the chosen pair's natural frequencies, ``f_upper / f_lower - 1``:
        0 gives an exactly repeated pair, 0.001 a 0.1 % split. Must keep the pair below the
        next mode.
    n_masses : int
        Number of masses (>= 3); there are ``(n - 1) // 2`` pairs.
    pair : int
        Harmonic of the pair to split, ``1 <= pair < n_masses / 2``; its modes are numbered
        ``2 pair`` and ``2 pair + 1``.
    mass, ground_stiffness, coupling_stiffness : float
        ``m`` (kg), ``k_g`` and ``k_c`` (N/m); the defaults give 10, 17.3, 26.5 and 30 Hz.
    damping_ratio : float
        ``zeta`` of the chosen pair (stiffness-proportional damping, ``zeta_k`` proportional to
        the natural frequency), ``0 < zeta < 1`` for every mode.
    point_labels : sequence, optional
        Labels of the masses in ring order (default ``1 .. n``); mass ``i`` sits at the
        angle ``2 pi i / n`` from the first, which lies on a node line of the pair's ``sin``
        member.
    drive_point : label, optional
        Adds residues for a force there (as :func:`~ami_xr.simulate.modal_model`).

    Returns
    -------
    xarray.Dataset
        The truth Dataset of :func:`~ami_xr.simulate.modal_model` (displacement, m/N) with
        attributes ``repeated_pairs`` (mode numbers of every pair, two by two), ``split_pair``
        (the chosen pair's mode numbers), ``split`` and ``symmetry``.
    """
    split = _number(split, "split", strict=False)
    M, K0 = ring_matrices(
        n_masses,
        mass=mass,
        ground_stiffness=ground_stiffness,
        coupling_stiffness=coupling_stiffness,
    )
    n = M.shape[0]
    n_pairs = (n - 1) // 2
    if (
        isinstance(pair, bool)
        or not isinstance(pair, (int, np.integer))
        or not 1 <= pair <= n_pairs
    ):
        raise AmiXrValueError(
            f"pair: expected an integer harmonic 1 .. {n_pairs} (n_masses={n}), got {pair!r}"
        )
    zeta = _number(damping_ratio, "damping_ratio")
    m = M[0, 0]
    harmonics = np.arange(n // 2 + 1)
    w2 = (ground_stiffness + 2 * coupling_stiffness * (1 - np.cos(2 * np.pi * harmonics / n))) / m
    w = np.sqrt(w2)
    if pair < n // 2 and split > 0 and w[pair] * (1 + split) >= w[pair + 1]:
        raise AmiXrValueError(
            f"split: {split!r} moves the pair's upper mode ({w[pair] * (1 + split) / 2 / np.pi:.4g}"
            f" Hz) past the next mode ({w[pair + 1] / 2 / np.pi:.4g} Hz)"
        )
    beta = 2 * zeta / w[pair]
    if beta * w.max() * (1 + split) / 2 >= 1:
        raise AmiXrValueError(f"damping_ratio: {damping_ratio!r} makes the highest mode overdamped")
    i = np.arange(n)
    v = np.cos(2 * np.pi * pair * i / n) * np.sqrt(2.0 / n / m)  # v^T M v = 1
    delta = m * w2[pair] * ((1 + split) ** 2 - 1)
    K = K0 + delta * np.outer(M @ v, M @ v)
    K = (K + K.T) / 2
    C = beta * K
    truth = modal_model(M, C, K, point_labels=point_labels, drive_point=drive_point)
    pairs = [int(x) for j in range(1, n_pairs + 1) for x in (2 * j, 2 * j + 1)]
    truth.attrs[ATTR_REPEATED_PAIRS] = pairs
    truth.attrs[ATTR_SPLIT_PAIR] = [2 * pair, 2 * pair + 1]
    truth.attrs[ATTR_SPLIT] = split
    truth.attrs[ATTR_SYMMETRY] = (
        f"grounded ring of {n} equal masses; harmonic {pair}'s pair split by "
        f"{100 * split:g} % (stiffness delta v v^T on its cos member)"
    )
    return add_history(
        truth,
        "ami_xr.simulate.symmetric_structure",
        {"split": split, "n_masses": n, "pair": int(pair), "damping_ratio": zeta},
    )


__all__: Sequence[str] = ("ring_matrices", "symmetric_structure")
