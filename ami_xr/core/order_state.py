"""The model-order step's state as values (plain arrays, no xarray).

One record per mode (:class:`Modes`: each field a row per mode, the AMI modes first) replaces
the parallel arrays the steps of :mod:`ami_xr.core.order` used to delete from one by one: a
step keeps, drops or appends modes through :meth:`Modes.take`, :meth:`Modes.without` and
:meth:`Modes.appended`, so that no field can fall out of step with the others. A proposal of the
model completion is a :class:`Trial`; :class:`State` holds the fit and the record.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ami_xr.core import varpro


@dataclass
class Modes:
    """What the refinement knows of each mode beside its fitted eigenvalue (row ``k``: mode
    ``k`` of the fit). The AMI modes come first; ``origin`` and ``res0`` have a row for them
    only (modes the completion added follow)."""

    free: np.ndarray  # (K,) bool: refinable (not frozen where it left its region)
    lam0: np.ndarray  # (K,) complex: the centre of the mode's region (AMI's value, or added)
    at_ami: np.ndarray  # (K,) bool: frozen at its AMI eigenvalue (a fallback)
    supported: np.ndarray  # (K,) bool: kept resolved by the close-pair test
    merged_fn: np.ndarray  # (K,) Hz of a duplicate merged into the mode (NaN: none)
    origin: np.ndarray  # (K_ami,) AMI index of each AMI mode kept
    res0: np.ndarray  # (P, K_ami) AMI residues of the AMI modes kept

    @classmethod
    def start(cls, free, lam0, res0, origin, at_ami=None) -> Modes:
        """The record of a fit's modes as the refinement starts (nothing merged or tested)."""
        free = np.asarray(free, bool)
        k = free.size
        at_ami = np.zeros(k, bool) if at_ami is None else np.asarray(at_ami, bool)
        return cls(
            free.copy(),
            np.asarray(lam0).copy(),
            at_ami.copy(),
            np.zeros(k, bool),
            np.full(k, np.nan),
            np.asarray(origin).copy(),
            np.asarray(res0).copy(),
        )

    @property
    def n_modes(self) -> int:
        return self.free.size

    @property
    def n_ami(self) -> int:
        return self.origin.size

    def take(self, keep) -> Modes:
        """The modes ``keep`` (indices in increasing order or a boolean mask), in that order."""
        idx = np.asarray(keep)
        idx = np.flatnonzero(idx) if idx.dtype == bool else idx.astype(int)
        if idx.size > 1 and np.any(np.diff(idx) <= 0):
            raise ValueError("Modes.take: `keep` must be increasing (the AMI modes stay first)")
        ami = idx[idx < self.n_ami]
        return Modes(
            self.free[idx],
            self.lam0[idx],
            self.at_ami[idx],
            self.supported[idx],
            self.merged_fn[idx],
            self.origin[ami],
            self.res0[:, ami],
        )

    def without(self, removed) -> Modes:
        """Every mode but ``removed`` (indices)."""
        return self.take(np.setdiff1d(np.arange(self.n_modes), np.asarray(removed, int)))

    def appended(self, lam0: np.ndarray) -> Modes:
        """The modes plus new ones (added by the completion: free, no AMI reference) whose
        regions are centred on ``lam0``."""
        lam0 = np.asarray(lam0)
        n = lam0.size
        return replace(
            self,
            free=np.append(self.free, np.ones(n, bool)),
            lam0=np.append(self.lam0, lam0),
            at_ami=np.append(self.at_ami, np.zeros(n, bool)),
            supported=np.append(self.supported, np.zeros(n, bool)),
            merged_fn=np.append(self.merged_fn, np.full(n, np.nan)),
        )


class Trial(NamedTuple):
    """A proposal of the model completion: the data poles to start from, the region centres
    of every mode, the number of modes it adds (negative: removes) and the indices of the
    present modes it removes."""

    start: np.ndarray
    ref: np.ndarray
    n_add: int
    removed: np.ndarray


class Fitted(NamedTuple):
    """A fit of :func:`ami_xr.core.regions.fit_modes`."""

    fit: varpro.FitResult
    free: np.ndarray
    n_iter: int
    start_cost: float | None


class State:
    """The model being refined: the fit and the record of its modes (:class:`Modes`), read
    and changed as ``state.modes``; ``n_iter`` counts the iterations, ``changed`` says whether
    the model changed, ``capped`` whether the additions stopped at their cap."""

    __slots__ = ("fit", "modes", "n_iter", "changed", "capped")

    def __init__(self, fit, free, lam0, res0, origin, n_iter, at_ami=None, changed=False):
        self.fit = fit
        self.modes = Modes.start(free, lam0, res0, origin, at_ami)
        self.n_iter = int(n_iter)
        self.changed = bool(changed)
        self.capped = False  # the mode additions stopped at add_modes, not by the statistics

    def accept(self, fitted, modes: Modes) -> None:
        """Take a new model: its fit and the record of its modes (the model changed)."""
        self.fit = fitted
        self.modes = modes
        self.changed = True
