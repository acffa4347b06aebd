"""The isolation engine's entry point (:mod:`.engine`): every group's restarts, in calls that
return to the caller between restarts when asked (an interrupt is handled there) and for the
model-order check's two-mode fits (compiled only when a split is tried); the results are those
of one pass.

A caller allocates :func:`new_result` and :func:`new_resume` and calls :func:`isolate_groups`
until it returns ``DONE``, running :func:`split_fit` when it returns ``SPLIT_WANTED`` (the
checked wrappers in :mod:`.isolate` do this).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ami_xr.kernels._numba import jit
from ami_xr.kernels.engine import (
    AT_CONVERGED,
    AT_FINISHED,
    AT_GROUP,
    AT_IN_CHECK,
    AT_LAST,
    AT_N,
    AT_N_TRIED,
    AT_RESTART,
    AT_SPLIT,
    AT_SPLIT_CODE,
    AT_STARTED,
    AT_TRY,
    AT_WH,
    AT_WL,
    DONE,
    PAUSED,
    SPLIT_FITTED,
    SPLIT_NONE,
    SPLIT_WANTED,
    IsolateResult,
    ModeSet,
    Work,
    merge_prune,
    new_work,
    order_check,
    sweeps,
)
from ami_xr.kernels.peak import nearest_within
from ami_xr.kernels.two_mode import fit_two


class Resume(NamedTuple):
    """Where :func:`isolate_groups` goes on after it returned early (arrays, updated in place):
    the group and restart it was at, that group's state, and a two-mode fit it asked for."""

    counts: np.ndarray
    """(16,) int64: the ``AT_GROUP``, ``AT_STARTED``, ... entries below."""
    masked: np.ndarray
    """(F,) bool: lines the model-order check has tried."""
    tried: np.ndarray
    """(max_modes + 4,) complex: modes the order check added."""
    fails: np.ndarray
    """(max_modes,) int64: failed fits of each mode."""
    split_lam: np.ndarray
    """(2,) complex: the two eigenvalues of the two-mode fit asked for."""
    split_res: np.ndarray
    """(P, 2) complex: its residues."""
    work: Work
    """The work arrays (``data`` the first group's; each group's own is put in by the kernel)."""


def new_resume(data: np.ndarray, max_modes: int) -> Resume:
    """A :class:`Resume` record for the groups ``data`` (G, P, F), at its start."""
    n_g, n_p, n_f = data.shape
    m = int(max_modes)
    first = data[0] if n_g else np.zeros((n_p, n_f), dtype=np.complex128)
    return Resume(
        counts=np.zeros(16, dtype=np.int64),
        masked=np.zeros(n_f, dtype=np.bool_),
        tried=np.empty(m + 4, dtype=np.complex128),
        fails=np.zeros(m, dtype=np.int64),
        split_lam=np.empty(2, dtype=np.complex128),
        split_res=np.empty((n_p, 2), dtype=np.complex128),
        work=new_work(first, m),
    )


def new_result(n_g: int, n_p: int, max_modes: int) -> IsolateResult:
    """An :class:`IsolateResult` of ``n_g`` groups of ``n_p`` FRFs, NaN-padded, to fill."""
    nan = complex(np.nan, np.nan)
    return IsolateResult(
        lam=np.full((n_g, max_modes), nan),
        res=np.full((n_g, n_p, max_modes), nan),
        n_modes=np.zeros(n_g, dtype=np.int64),
        iterations=np.zeros(n_g, dtype=np.int64),
        converged=np.zeros(n_g, dtype=np.bool_),
    )


def split_fit(iso: np.ndarray, scene, st: Resume) -> None:
    """The two-mode fit :func:`isolate_groups` asked for (it returned ``SPLIT_WANTED``): on
    the band it left in ``st`` of the isolated data ``iso``, with the FRF weights of
    ``st.work``; results and code into ``st`` for the kernel's next call. In Python, so that
    :func:`~.two_mode.fit_two` compiles only when some isolation tries a split."""
    c = st.counts
    wl, wh = int(c[AT_WL]), int(c[AT_WH])
    ws = scene.grid.omega[(wl + wh) // 2]
    code = fit_two(
        iso, scene.grid, wl, wh, ws, scene.limits, st.work.wts, st.split_lam, st.split_res
    )
    c[AT_SPLIT_CODE] = code
    c[AT_SPLIT] = SPLIT_FITTED


@jit(inline="always")
def _start_group(lam0, res0, n0, g, modes, masked, c, work, m):
    """Group ``g``'s starting modes into ``modes`` (its slots of the result) and a fresh state
    in ``masked``, the counts ``c`` and ``work``. Arrays and small records, not the whole
    :class:`Resume`: a record passed into inlined code is reference-counted array by array."""
    n_p = modes.res.shape[0]
    n = min(n0[g], m)
    for k in range(n):
        modes.lam[k] = lam0[g, k]
        for j in range(n_p):
            modes.res[j, k] = res0[g, j, k]
    work.wts[:] = 1.0
    work.wts_all[:, :] = 1.0
    work.power[:] = 0.0
    work.back[:] = complex(np.nan, np.nan)
    work.pinned[:] = False
    modes.fails[:] = 0
    masked[:] = False
    c[AT_STARTED], c[AT_RESTART], c[AT_N], c[AT_N_TRIED] = 1, 0, n, 0
    c[AT_LAST], c[AT_FINISHED], c[AT_CONVERGED], c[AT_IN_CHECK] = 0, 0, 0, 0
    c[AT_TRY], c[AT_SPLIT] = 0, SPLIT_NONE


@jit
def isolate_groups(data, lam0, res0, n0, scene, params, out, st, budget):
    """Isolation with the model-order check of every group ``data[g]`` (P, F) (noise units),
    from the first ``n0[g]`` of the eigenvalues ``lam0[g]`` and residues ``res0[g]``, into
    ``out`` (:func:`new_result`), with the state ``st`` (:func:`new_resume`).

    A restart follows every change of the model (merge, prune, added or split mode). A mode the
    order check adds and then loses (merged into a neighbour the sweeps ran it into, or pruned
    after its fits failed: a weak mode beside a strong one takes up the strong one's residual)
    is, when the check adds it again, kept at its order-check fit (pinned, not re-fitted) and
    the order check ends after the next sweeps (the residual next to a pinned mode holds the
    error of its fit, not new modes): otherwise (and with ``paper_sweeps``, as in the paper) the
    loop cycles until the restart budget is spent. ``converged``: the last sweeps met their
    stopping rule and no change is pending.

    Returns ``(status, iso)``. ``DONE``: every group is done. ``SPLIT_WANTED``: the order check
    asks for a two-mode fit of the isolated data ``iso`` (:func:`split_fit`). ``PAUSED`` (only
    with ``budget > 0``): the restarts of this call have cost ``budget`` (sweeps times FRFs
    times lines; at least one restart per call). Called again with the same arguments it goes on
    where it stopped; the results are those of one uninterrupted pass.
    """
    n_g, n_p, n_f = data.shape
    m = params.max_modes
    c = st.counts
    w = st.work
    masked = st.masked
    tried = st.tried
    spent = 0
    while c[AT_GROUP] < n_g:
        g = c[AT_GROUP]
        # the group's own FRFs (a view) in the shared work arrays
        work = Work(
            data[g], w.xn, w.rtmp, w.wts, w.wts_all, w.br, w.bi, w.bcr, w.bci, w.tr, w.ti,
            w.power, w.back, w.pinned, w.basis_lo, w.basis_hi,
        )  # fmt: skip
        modes = ModeSet(out.lam[g], out.res[g], st.fails)
        if c[AT_STARTED] == 0:
            _start_group(lam0, res0, n0, g, modes, masked, c, work, m)
        n = c[AT_N]
        while c[AT_RESTART] < m + 4:
            if c[AT_IN_CHECK] == 0:
                if budget > 0 and spent >= budget:
                    c[AT_N] = n
                    return PAUSED, np.empty((0, 0), dtype=np.complex128)
                c[AT_RESTART] += 1
                it, converged = sweeps(scene, params, modes, n, work)
                c[AT_CONVERGED] = converged
                spent += (it + 1) * n_p * n_f
                out.iterations[g] += it
                n, changed = merge_prune(scene, params, modes, n, work.pinned)
                if changed:
                    continue
                if n >= m or c[AT_LAST] != 0:
                    c[AT_FINISHED] = 1
                    break
            n, added, ks, iso = order_check(
                scene, params, modes, n, work, masked, c, st.split_lam, st.split_res
            )
            if ks == SPLIT_WANTED:
                c[AT_IN_CHECK] = 1
                c[AT_N] = n
                return SPLIT_WANTED, iso
            c[AT_IN_CHECK] = 0
            if not added:
                c[AT_FINISHED] = 1
                break
            if ks >= 0:
                continue
            # an added mode near one added before (and lost since: no mode is near that one)
            new = modes.lam[n - 1]
            one, none = np.int64(1), np.int64(-1)  # typed ints: one specialisation each
            n_tried = c[AT_N_TRIED]
            for t in range(0 if params.paper_sweeps else n_tried):
                again = nearest_within(tried[t : t + 1], one, new, params.merge_tol, none) >= 0
                if again and nearest_within(modes.lam, n - 1, tried[t], params.merge_tol, none) < 0:
                    work.pinned[n - 1] = True
                    c[AT_LAST] = 1
                    break
            if n_tried < tried.shape[0]:
                tried[n_tried] = new
                c[AT_N_TRIED] = n_tried + 1
        out.n_modes[g] = n
        out.converged[g] = c[AT_CONVERGED] != 0 and c[AT_FINISHED] != 0
        c[AT_GROUP] += 1
        c[AT_STARTED] = 0
    return DONE, np.empty((0, 0), dtype=np.complex128)
