"""Exact modal models of linear systems ``M q'' + C q' + K q = f`` with arbitrary damping.

The state-space (first-order) form ``[[C, M], [M, 0]] x' + [[K, 0], [0, -M]] x = [f, 0]`` with
``x = [q, q']`` has ``2n`` eigenvalues in complex-conjugate pairs. For an underdamped system the
``n`` eigenvalues in the upper half plane, sorted by natural frequency, are the modes. Each
complex mode vector ``Phi_k`` (the displacement part of the state eigenvector) is scaled so that
the paper's residues hold exactly (eqs. 4 and 5)::

    G_jP(w) = sum_k  A_jk / (i w - lam_k) + conj(A_jk) / (i w - conj(lam_k)),
    A_jk    = A_jk^(1) + i A_jk^(2) = lam_k Phi_jk Phi_Pk,

which means ``lam_k Phi_k^T (2 lam_k M + C) Phi_k = 1``. ``Phi_k`` is fixed up to its sign; the
sign is chosen so that ``Re(lam_k Phi_jk) > 0`` at the generalized coordinate ``j`` where
``|Phi_jk|`` is largest (for light damping ``lam_k Phi_k`` is nearly the real undamped mode
divided by sqrt(2), whose largest entry is then positive). Residues do not depend on that sign.

An ``output`` matrix ``T`` (n_points x n) maps generalized coordinates to measured points,
``y = T q``; a force at measured point ``P`` acts on the generalized coordinates as
``T[P]^T f`` (collocated), so the mode vectors at the measured points are ``T Phi`` and eqs. 4-5
hold between measured points.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.provenance import add_history
from ami_xr.simulate.eigen import state_space_modes


# --------------------------------------------------------------------------------------------
# validation helpers
# --------------------------------------------------------------------------------------------
def _labels(point_labels: Sequence[Hashable] | None, n: int) -> list:
    if point_labels is None:
        return list(range(n))
    labels = list(point_labels)
    if len(labels) != n:
        raise AmiXrValueError(
            f"point_labels: expected {n} labels (one per output row), got {len(labels)}"
        )
    if len(set(labels)) != n:
        raise AmiXrValueError(f"point_labels: labels must be unique, got {labels}")
    return labels


def _check_model(model: Any, name: str = "model") -> xr.Dataset:
    if not isinstance(model, xr.Dataset):
        raise AmiXrValueError(
            f"{name}: expected an xarray.Dataset from modal_model(), got {type(model).__name__}"
        )
    missing = [v for v in (names.EIGENVALUE,) if v not in model]
    if names.MODE_VECTOR not in model and names.RESIDUE not in model:
        missing.append(f"{names.MODE_VECTOR} or {names.RESIDUE}")
    if missing:
        raise AmiXrValueError(f"{name}: missing variable(s) {missing}")
    return model


def _drive(model: xr.Dataset, drive_point: Hashable | None) -> Hashable:
    if drive_point is None:
        drive_point = model.attrs.get(names.ATTR_DRIVE_POINT)
        if drive_point is None:
            raise AmiXrValueError(
                "drive_point: not given and the model has no 'drive_point' attribute"
            )
    points = list(model[names.POINT].values)
    if drive_point not in points:
        raise AmiXrValueError(f"drive_point: {drive_point!r} is not one of the points {points}")
    return drive_point


def modal_model(
    M: Any,
    C: Any,
    K: Any,
    *,
    point_labels: Sequence[Hashable] | None = None,
    output: Any = None,
    drive_point: Hashable | None = None,
    response_units: str = "m",
    force_units: str = "N",
) -> xr.Dataset:
    """Exact modal parameters of ``M q'' + C q' + K q = f`` as a truth Dataset.

    Parameters
    ----------
    M, C, K : array_like, shape (n, n)
        Symmetric mass (positive definite), damping and stiffness matrices; damping need not be
        proportional. Every mode must be underdamped.
    point_labels : sequence, optional
        Labels of the measured points (rows of ``output``); default ``0 .. n_points-1``.
    output : array_like, shape (n_points, n), optional
        Selection matrix ``T`` with measured displacements ``y = T q`` (default identity). A
        force at measured point ``P`` acts on the generalized coordinates as ``T[P]^T f``.
    drive_point : label, optional
        If given, the residues for a force at this point are added (see :func:`residues`).
    response_units, force_units : str
        Units of ``y`` and ``f`` (recorded as attributes).

    Returns
    -------
    xarray.Dataset
        ``eigenvalue`` (mode) complex rad/s, ``natural_frequency`` (mode) Hz, ``damping_ratio``
        (mode), ``mode_vector`` (point, mode) complex with ``A_jk = lam_k Phi_jk Phi_Pk``, and with
        ``drive_point`` also ``residue`` (point, mode). Modes are numbered 1..n in order of
        natural frequency.
    """
    lam, phi = state_space_modes(M, C, K)
    n = lam.shape[0]
    if output is None:
        T = np.eye(n)
    else:
        T = np.asarray(output, dtype=np.float64)
        if T.ndim == 1:
            T = T[np.newaxis, :]
        if T.ndim != 2 or T.shape[1] != n or T.shape[0] == 0:
            raise AmiXrValueError(
                f"output: expected a matrix of shape (n_points, {n}), got shape {T.shape}"
            )
        if not np.all(np.isfinite(T)):
            raise AmiXrValueError("output: contains NaN or inf")
    labels = _labels(point_labels, T.shape[0])
    wn = np.abs(lam)
    mode = np.arange(1, n + 1)
    ds = xr.Dataset(
        {
            names.EIGENVALUE: (names.MODE, lam, {names.ATTR_UNITS: names.ANGULAR_UNITS}),
            names.NATURAL_FREQUENCY: (
                names.MODE,
                wn / (2 * np.pi),
                {names.ATTR_UNITS: names.FREQUENCY_UNITS},
            ),
            names.DAMPING_RATIO: (names.MODE, -lam.real / wn, {names.ATTR_UNITS: "1"}),
            names.MODE_VECTOR: (
                (names.POINT, names.MODE),
                T @ phi,
                {names.ATTR_UNITS: f"sqrt({response_units}/{force_units})"},
            ),
        },
        coords={names.POINT: labels, names.MODE: mode},
        attrs={
            names.ATTR_QUANTITY: "displacement",
            names.ATTR_RESPONSE_UNITS: response_units,
            names.ATTR_FORCE_UNITS: force_units,
        },
    )
    ds = add_history(ds, "ami_xr.simulate.modal_model", {"n_dof": n, "n_points": len(labels)})
    if drive_point is not None:
        ds = residues(ds, drive_point)
    return ds


def _residue_kernel(phi: np.ndarray, phi_p: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """eq. 5: ``lam_k Phi_jk Phi_Pk`` on arrays with mode last."""
    return lam * phi * phi_p


def residues(model: xr.Dataset, drive_point: Hashable | None = None) -> xr.Dataset:
    """Add the residues ``A_jk = lam_k Phi_jk Phi_Pk`` (eq. 5) for a force at ``drive_point``.

    Parameters
    ----------
    model : xarray.Dataset
        Output of :func:`modal_model` (needs ``eigenvalue`` and ``mode_vector``).
    drive_point : label, optional
        The paper's P; default the model's ``drive_point`` attribute.

    Returns
    -------
    xarray.Dataset
        A new Dataset: ``model`` plus ``residue`` (point, mode) complex in
        ``<response_units>/(<force_units> s)`` and the ``drive_point`` attribute.
    """
    model = _check_model(model)
    if names.MODE_VECTOR not in model:
        raise AmiXrValueError(f"model: missing variable {names.MODE_VECTOR!r}")
    drive_point = _drive(model, drive_point)
    phi = model[names.MODE_VECTOR]
    lam = model[names.EIGENVALUE]
    phi_drive = phi.sel({names.POINT: drive_point}, drop=True)
    res = _over_modes(_residue_kernel, (phi, phi_drive, lam), names.MODE)
    out = model.copy()
    out.attrs = dict(model.attrs)
    ru = model.attrs.get(names.ATTR_RESPONSE_UNITS, "m")
    fu = model.attrs.get(names.ATTR_FORCE_UNITS, "N")
    out[names.RESIDUE] = res.transpose(names.POINT, names.MODE)
    out[names.RESIDUE].attrs = {names.ATTR_UNITS: f"{ru}/({fu} s)"}
    out.attrs[names.ATTR_DRIVE_POINT] = drive_point
    return out


def _model_residues(model: xr.Dataset, drive_point: Hashable | None) -> xr.Dataset:
    """``model`` with residues for ``drive_point`` (recomputed from mode vectors when possible)."""
    model = _check_model(model)
    if names.MODE_VECTOR in model:
        return residues(model, drive_point)
    have = model.attrs.get(names.ATTR_DRIVE_POINT)
    if drive_point is not None and drive_point != have:
        raise AmiXrValueError(
            f"drive_point: the model holds residues for drive point {have!r} only and no "
            f"mode_vector to recompute them for {drive_point!r}"
        )
    return model


# --------------------------------------------------------------------------------------------
# responses
# --------------------------------------------------------------------------------------------
def _frequency_axis(frequency_hz: Any) -> np.ndarray:
    f = np.asarray(frequency_hz, dtype=np.float64)
    if f.ndim == 0:
        f = f[np.newaxis]
    if f.ndim != 1 or f.size == 0:
        raise AmiXrValueError(f"frequency_hz: expected a 1-D array of frequencies, got {f.shape}")
    if not np.all(np.isfinite(f)) or np.any(f < 0):
        raise AmiXrValueError("frequency_hz: expected finite, non-negative frequencies in Hz")
    if f.size > 1 and np.any(np.diff(f) <= 0):
        raise AmiXrValueError("frequency_hz: expected strictly increasing frequencies")
    return f


def _frf_kernel(residue: np.ndarray, lam: np.ndarray, omega: np.ndarray, power: int) -> np.ndarray:
    """eq. 4 on plain arrays: residue (..., mode), lam (..., mode), omega (f,) -> (..., f).

    Written as a matrix product over modes so memory stays O(modes x frequencies)."""
    iw = 1j * omega
    basis = 1.0 / (iw - lam[..., :, np.newaxis])  # (..., mode, f)
    basis_c = 1.0 / (iw - np.conj(lam)[..., :, np.newaxis])
    a = residue[..., np.newaxis, :]  # (..., 1, mode)
    g = (np.matmul(a, basis) + np.matmul(np.conj(a), basis_c))[..., 0, :]
    return g * iw**power if power else g


def _modal_frf(residue: xr.DataArray, lam: xr.DataArray, f: np.ndarray, quantity: str):
    """The modal sum of ``residue`` (..., mode) and ``lam`` (mode) at ``f`` Hz: (..., frequency)."""
    omega = xr.DataArray(2 * np.pi * f, dims=[names.FREQUENCY])
    power = names.QUANTITY_POWER[quantity]
    return _over_modes(_frf_kernel, (residue, lam, omega), names.FREQUENCY, power=power)


def _over_modes(kernel, args: tuple, out_dim: str, **kwargs: Any) -> xr.DataArray:
    """``kernel`` (complex results) over the mode axis of ``args[:2]`` and the ``out_dim`` of
    ``args[2]`` (the mode again for residues, frequency or time for a modal sum), dask-ready."""
    return xr.apply_ufunc(
        kernel,
        *args,
        kwargs=kwargs,
        input_core_dims=[[names.MODE], [names.MODE], [out_dim]],
        output_core_dims=[[out_dim]],
        dask="parallelized",
        output_dtypes=[np.complex128],
        keep_attrs=False,
    )


def frf(
    model: xr.Dataset,
    frequency_hz: Any,
    drive_point: Hashable | None = None,
    *,
    response_quantity: str = "displacement",
    response_units: str | None = None,
    references: Sequence[Hashable] | None = None,
) -> xr.Dataset:
    """Exact FRFs ``G_jP`` of a modal model on a frequency grid (eq. 4).

    Parameters
    ----------
    model : xarray.Dataset
        Truth Dataset from :func:`modal_model` (or any Dataset with ``eigenvalue`` and
        ``mode_vector``, or ``residue`` plus a ``drive_point`` attribute).
    frequency_hz : array_like
        Strictly increasing, non-negative frequencies in Hz.
    drive_point : label, optional
        The excitation point P (default: the model's ``drive_point`` attribute).
    response_quantity : {"displacement", "velocity", "acceleration"}
        Receptance, mobility (times ``i w``) or accelerance (times ``-w^2``).
    response_units : str, optional
        Default "m", "m/s" or "m/s^2".
    references : sequence of labels, optional
        Multi-reference FRFs: excitation points (each one of the model's points; the model
        needs ``mode_vector``). The result then has ``frf`` dims ``(reference, point,
        frequency)`` with ``G_ij`` the response at point i to a force at reference j (residue
        ``lam_k Phi_ik Phi_jk``), and no ``drive_point`` attribute (give ``drive_point`` None).

    Returns
    -------
    xarray.Dataset
        FRF Dataset of the data model with ``frf_source="analytic"``.
    """
    if response_quantity not in names.QUANTITY_POWER:
        raise AmiXrValueError(
            f"response_quantity: expected one of {tuple(names.QUANTITY_POWER)}, "
            f"got {response_quantity!r}"
        )
    f = _frequency_axis(frequency_hz)
    if references is not None:
        return _multi_reference_frf(
            model, f, references, drive_point, response_quantity, response_units
        )
    model = _model_residues(model, drive_point)
    g = _modal_frf(model[names.RESIDUE], model[names.EIGENVALUE], f, response_quantity)
    drive = {names.ATTR_DRIVE_POINT: model.attrs[names.ATTR_DRIVE_POINT]}
    return _analytic_frf(
        g.transpose(names.POINT, names.FREQUENCY),
        {names.POINT: model[names.POINT].values, names.FREQUENCY: f},
        model,
        (response_quantity, response_units),
        drive,
        {"drive_point": drive[names.ATTR_DRIVE_POINT]},
    )


def _analytic_frf(
    g: xr.DataArray,
    coords: dict[str, Any],
    model: xr.Dataset,
    quantity: tuple[str, str | None],
    first_attrs: dict[str, Any],
    record: dict[str, Any],
) -> xr.Dataset:
    """The FRF Dataset of :func:`frf` around ``g`` (its dims in order, frequency last): the
    ``coords`` (the frequency in Hz, given its units here), units and attributes
    (``first_attrs`` before the common ones) and the history (``record`` first)."""
    response_quantity, response_units = quantity
    f = coords[names.FREQUENCY]
    force_units = model.attrs.get(names.ATTR_FORCE_UNITS, "N")
    ru = response_units or names.SI_RESPONSE_UNITS[response_quantity]
    frequency = (names.FREQUENCY, f, {names.ATTR_UNITS: names.FREQUENCY_UNITS})
    ds = xr.Dataset({names.FRF: g}, coords={**coords, names.FREQUENCY: frequency})
    ds[names.FRF].attrs = {names.ATTR_UNITS: names.frf_units(ru, force_units)}
    ds.attrs = {
        **first_attrs,
        names.ATTR_QUANTITY: response_quantity,
        names.ATTR_FRF_TYPE: names.QUANTITY_TO_FRF_TYPE[response_quantity],
        names.ATTR_RESPONSE_UNITS: ru,
        names.ATTR_FORCE_UNITS: force_units,
        names.ATTR_SOURCE: names.SOURCE_ANALYTIC,
    }
    params = {**record, "response_quantity": response_quantity, "n_frequencies": int(f.size)}
    return add_history(ds, "ami_xr.simulate.frf", params)


def _multi_reference_frf(
    model: Any,
    f: np.ndarray,
    references: Sequence[Hashable],
    drive_point: Hashable | None,
    response_quantity: str,
    response_units: str | None,
) -> xr.Dataset:
    """:func:`frf` for several excitation points: ``frf`` (reference, point, frequency)."""
    model = _check_model(model)
    if drive_point is not None:
        raise AmiXrValueError(
            "drive_point: not used with references (the drive points are the references)"
        )
    if names.MODE_VECTOR not in model:
        raise AmiXrValueError(
            f"model: references need the variable {names.MODE_VECTOR!r} (residues of every "
            "reference)"
        )
    points = model[names.POINT].values.tolist()
    refs = list(np.asarray(references).tolist())
    if not refs or len(set(refs)) != len(refs) or any(r not in points for r in refs):
        raise AmiXrValueError(
            f"references: expected unique labels among the points {points}, got {refs}"
        )
    phi = model[names.MODE_VECTOR]
    lam = model[names.EIGENVALUE]
    phi_ref = phi.sel({names.POINT: refs}).rename({names.POINT: names.REFERENCE})
    residue = (lam * phi * phi_ref).transpose(names.REFERENCE, names.POINT, names.MODE)
    g = _modal_frf(residue, lam, f, response_quantity)
    g = g.transpose(names.REFERENCE, names.POINT, names.FREQUENCY).drop_vars(
        [c for c in g.coords if c not in (names.REFERENCE, names.POINT)]
    )
    return _analytic_frf(
        g,
        {names.REFERENCE: refs, names.POINT: points, names.FREQUENCY: f},
        model,
        (response_quantity, response_units),
        {},
        {"references": refs},
    )


def time_axis(time: Any) -> np.ndarray:
    """Uniform time samples from an array or a ``(duration, n_samples)`` pair.

    ``(duration, n_samples)`` gives ``t = k * duration / n_samples``, ``k = 0 .. n_samples-1``,
    so the record spans ``duration`` and the FFT frequency step is ``1 / duration``.
    """
    if isinstance(time, tuple):
        if len(time) != 2:
            raise AmiXrValueError(f"time: expected (duration, n_samples), got {time!r}")
        duration, n_samples = time
        if not (np.isfinite(duration) and duration > 0):
            raise AmiXrValueError(f"time: duration must be a positive number, got {duration!r}")
        if int(n_samples) != n_samples or n_samples < 2:
            raise AmiXrValueError(f"time: n_samples must be an integer >= 2, got {n_samples!r}")
        n_samples = int(n_samples)
        return np.arange(n_samples) * (float(duration) / n_samples)
    t = np.asarray(time, dtype=np.float64)
    if t.ndim != 1 or t.size < 2:
        raise AmiXrValueError(f"time: expected a 1-D array of >= 2 samples, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise AmiXrValueError("time: contains NaN or inf")
    step = np.diff(t)
    if np.any(step <= 0) or not np.allclose(step, step[0], rtol=1e-9, atol=0):
        raise AmiXrValueError("time: expected uniformly spaced, increasing samples")
    return t


def _impulse_kernel(residue: np.ndarray, lam: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``sum_k A_k exp(lam_k t)`` (h is twice its real part): (..., mode), (..., mode), (n,)."""
    e = np.exp(lam[..., :, np.newaxis] * t)  # (..., mode, n)
    return np.matmul(residue[..., np.newaxis, :], e)[..., 0, :]


def impulse_response(
    model: xr.Dataset,
    time: Any,
    drive_point: Hashable | None = None,
) -> xr.Dataset:
    """Displacement responses to a unit impulse at ``drive_point``.

    ``h_j(t) = 2 Re sum_k A_jk exp(lam_k t)``, exact at every sample.

    Parameters
    ----------
    model : xarray.Dataset
        Truth Dataset from :func:`modal_model`.
    time : array_like or (duration, n_samples)
        Uniform sample times in s, or a record length and sample count
        (``t = k duration / n_samples``).
    drive_point : label, optional
        Default: the model's ``drive_point`` attribute.

    Returns
    -------
    xarray.Dataset
        Time Dataset: ``response`` (point, time) in the model's response units per unit impulse,
        no ``force``, attribute ``excitation="unit_impulse"``.
    """
    t = time_axis(time)
    model = _model_residues(model, drive_point)
    tt = xr.DataArray(t, dims=[names.TIME])
    h = _over_modes(
        _impulse_kernel, (model[names.RESIDUE], model[names.EIGENVALUE], tt), names.TIME
    )
    h = 2.0 * h.real  # (taken outside the kernel: dask would cast a complex meta to float)
    ru = model.attrs.get(names.ATTR_RESPONSE_UNITS, "m")
    fu = model.attrs.get(names.ATTR_FORCE_UNITS, "N")
    ds = xr.Dataset(
        {names.RESPONSE: h.transpose(names.POINT, names.TIME)},
        coords={
            names.POINT: model[names.POINT].values,
            names.TIME: (names.TIME, t, {names.ATTR_UNITS: names.TIME_UNITS}),
        },
    )
    ds[names.RESPONSE].attrs = {names.ATTR_UNITS: ru}
    ds.attrs = {
        names.ATTR_DRIVE_POINT: model.attrs[names.ATTR_DRIVE_POINT],
        names.ATTR_QUANTITY: "displacement",
        names.ATTR_RESPONSE_UNITS: ru,
        names.ATTR_FORCE_UNITS: fu,
        names.ATTR_EXCITATION: names.EXCITATION_UNIT_IMPULSE,
    }
    return add_history(
        ds,
        "ami_xr.simulate.impulse_response",
        {
            "drive_point": ds.attrs[names.ATTR_DRIVE_POINT],
            "n_samples": int(t.size),
            "sample_interval": float(t[1] - t[0]),
        },
    )
