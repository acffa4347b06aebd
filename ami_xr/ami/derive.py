"""The outputs derived from a fit, built in one place: :func:`derive`.

A phase that fits residues at fixed eigenvalues (the global fit on every FRF, the compressed
path's last pass over the points) hands over a :class:`ResidueFit`; :func:`derive` turns it into
the labeled outputs every such path reports the same way: residues with units, mode vectors in
the displacement convention (:func:`receptance_mode_vectors`),
synthesized FRFs and residuals, the MAC, the drive-point SNR and its flags
(``unscaled_no_drive_point``, ``low_drive_point_snr``), residual coefficients and the labels of
``mode_2`` and ``residual_term``; :func:`derived_from` gives them as Variables, for an output
built once (:func:`ami_xr.ami.common.built`). What stays lazy in the fit (synthesized FRFs of a
dask-backed input) stays lazy here. The quality indicators of the final mode vectors (MPC, MPD,
complexity, normalised vectors) come from :func:`quality_variables`.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import common as c
from ami_xr.ami.settings import FrfAttributes, from_attrs
from ami_xr.core import flags
from ami_xr.core.modal import mac_matrix, mode_vectors, mpc, mpd, phase_normalised
from ami_xr.kernels import modal_basis as kb

__all__ = [
    "ResidueFit",
    "derive",
    "receptance_mode_vectors",
    "receptance_residues",
    "residue_units",
    "mode_vector_units",
    "quality_variables",
]

_ONE = {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}


def residue_units(frf_units: str) -> dict:
    """``units`` of residues: FRF units times rad/s (empty when the FRF has no units)."""
    return {names.ATTR_UNITS: f"{frf_units} {names.ANGULAR_UNITS}"} if frf_units else {}


def mode_vector_units(frf_units: str, scaled: bool) -> dict:
    """``units`` of mode vectors: ``sqrt(FRF units)`` when scaled at the drive point (eq. 8,
    ``Phi_P = sqrt(A_P / lam)``), ``"1"`` when normalised to a unit largest entry."""
    if not scaled:
        return dict(_ONE)
    return {names.ATTR_UNITS: f"sqrt({frf_units})"} if frf_units else {}


# --- the mode-vector convention: displacement (receptance) mode vectors whatever was measured ---
ATTR_MODE_VECTOR_CONVENTION = "convention"  # on MODE_VECTOR
MODE_VECTOR_CONVENTION = (
    "displacement: Phi_j Phi_P = A_jP / lam with A the residues of the receptance (the FRF "
    "residues divided by lam^k, k = 1 for mobility, 2 for accelerance); units sqrt(receptance "
    "units), e.g. sqrt(m/N) = s/sqrt(kg); for a lightly damped normal mode with mass-normalised "
    "real shape psi (1/sqrt(kg)), Phi = i psi / (sqrt(2) omega_d)"
)


def receptance_residues(
    residue: np.ndarray, lam: np.ndarray, attrs, frf_units: str
) -> tuple[np.ndarray, str]:
    """The receptance residues (..., K) of FRF residues (..., K) at the poles ``lam`` (K,), and
    the receptance units (see :func:`receptance_mode_vectors`; every path that turns residues
    into mode vectors or participation factors goes through here)."""
    from ami_xr.dsp.quantity import convert_units  # the one unit rule of convert_quantity

    quantity = attrs.get(names.ATTR_QUANTITY)
    if quantity not in names.QUANTITY_POWER:
        quantity = names.FRF_TYPE_TO_QUANTITY.get(
            from_attrs(FrfAttributes, attrs).frf_type, "displacement"
        )
    k = names.QUANTITY_POWER[quantity]
    units, scale = frf_units, 1.0
    ru, fu = attrs.get(names.ATTR_RESPONSE_UNITS), attrs.get(names.ATTR_FORCE_UNITS)
    if k and ru and fu:
        try:
            base, scale = convert_units(str(ru), k, 0)
            units = names.frf_units(base, str(fu))
        except ValueError:  # units that do not say their derivative: keep them, say so
            units = f"({frf_units}) s^{k}" if frf_units else ""
    elif k:
        units = f"({frf_units}) s^{k}" if frf_units else ""
    return np.asarray(residue) * scale / np.asarray(lam) ** k, units


def receptance_mode_vectors(
    residue: np.ndarray, lam: np.ndarray, drive_index: int | None, attrs, frf_units: str
) -> tuple[np.ndarray, dict]:
    """Mode vectors (P, K) in the displacement convention, and their attributes.

    The residue of ``(i w)^k G`` at a pole ``lam`` is ``lam^k A`` (``(i w)^k = (i w - lam +
    lam)^k``; the polynomial rest is a residual term), so the receptance residues are the FRF's
    residues over ``lam^k`` (times 9.80665 for accelerance in g). Eq. 8 on them gives the same
    mode vectors whether receptance, mobility or accelerance was measured.
    """
    receptance, units = receptance_residues(residue, lam, attrs, frf_units)
    phi = mode_vectors(receptance, lam, drive_index)
    scaled = drive_index is not None
    out = {
        names.ATTR_SCALING: "eq. 8 at the drive point"
        if scaled
        else "unit largest entry (no drive point)",
        ATTR_MODE_VECTOR_CONVENTION: MODE_VECTOR_CONVENTION,
        **mode_vector_units(units, scaled),
    }
    return phi, out


@dataclasses.dataclass(frozen=True)
class ResidueFit:
    """Residues of every FRF at fixed eigenvalues, as a fit leaves them.

    Attributes
    ----------
    eigenvalue : numpy.ndarray
        (n,) complex, rad/s.
    residue : numpy.ndarray
        (P, n) complex, in the FRF's own units times rad/s.
    synthesized : xarray.Variable or xarray.DataArray
        (point, frequency) the model's FRFs (may be dask-backed).
    residual_coefficient : xarray.Variable or xarray.DataArray or None
        (point, residual_term) when residual terms were fitted.
    dt, n_samples :
        The data model's sampling (:func:`ami_xr.core.model.resolve_model`), for the modes'
        contribution peaks.
    noise_floor : numpy.ndarray
        (P,) each FRF's noise floor, the drive-point SNR's denominator.
    mask : numpy.ndarray
        (n,) int32 flag bits the fitting phases decided; :func:`derive` decides the drive
        point's two bits again.
    drive_snr_min : float
        The drive-point SNR below which a mode is flagged ``low_drive_point_snr``.
    """

    eigenvalue: np.ndarray
    residue: np.ndarray
    synthesized: xr.Variable | xr.DataArray
    residual_coefficient: xr.Variable | xr.DataArray | None
    dt: float
    n_samples: int
    noise_floor: np.ndarray
    mask: np.ndarray
    drive_snr_min: float


def _drive_snr(fit: ResidueFit, omega: np.ndarray, drive: int | None):
    """The drive-point SNR of each mode (NaN without a drive point) and the flag bits."""
    lam = fit.eigenvalue
    mask = flags.set_where(fit.mask, names.FLAG_UNSCALED, drive is None)
    if drive is None:
        return np.full(lam.size, np.nan), flags.set_where(mask, names.FLAG_LOW_DRIVE_SNR, False)
    res = np.ascontiguousarray(fit.residue[[drive]])
    peaks = kb.contribution_peaks(omega, fit.dt, fit.n_samples, lam[None, :], res)[0]
    snr = peaks / fit.noise_floor[drive]
    return snr, flags.set_where(mask, names.FLAG_LOW_DRIVE_SNR, ~(snr >= fit.drive_snr_min))


def derive(fit: ResidueFit, data: xr.Dataset) -> xr.Dataset:
    """``data`` (the FRF Dataset the fit ran on, with its mode coordinate) with the outputs of
    ``fit`` assigned: ``residue``, ``mode_vector`` (point, mode), ``frf_synthesized``,
    ``frf_residual`` (point, frequency), ``mac`` (mode, mode_2), ``drive_point_snr``,
    ``quality_flags`` (mode) and ``residual_coefficient`` (point, residual_term) when fitted."""
    coords, new = derived(fit, data)
    return data.assign_coords(coords).assign(new)


def derived(fit: ResidueFit, data: xr.Dataset) -> tuple[dict, dict]:
    """What :func:`derive` assigns to ``data``: the new coordinates (``mode_2``, and
    ``residual_term`` when fitted) and the output variables, by name."""
    omega, points = c.omega_of(data), data[names.POINT].values
    return derived_from(fit, data[names.FRF], data.attrs, omega, data[names.MODE].values, points)


def derived_from(fit: ResidueFit, frf, attrs, omega, modes, points) -> tuple[dict, dict]:
    """:func:`derived` on the parts of the data it reads: the FRF (DataArray or Variable, dims
    (point, frequency) in either order), the attributes, the angular frequencies of the lines,
    the mode labels and the point labels (the drive point is found among them)."""
    frf = _variable(frf)
    units = str(frf.attrs.get(names.ATTR_UNITS, ""))
    drive = c.drive_position(points, attrs)
    lam = fit.eigenvalue
    phi, phi_attrs = receptance_mode_vectors(fit.residue, lam, drive, attrs, units)
    snr, mask = _drive_snr(fit, omega, drive)
    # Variables (a DataArray of a lazy fit gives its own): the outputs take data's coordinates
    synth = _variable(fit.synthesized).transpose(*frf.dims)
    pm = (names.POINT, names.MODE)
    unit = {names.ATTR_UNITS: units}
    new = {
        names.RESIDUE: xr.Variable(pm, fit.residue, residue_units(units)),
        names.MODE_VECTOR: xr.Variable(pm, phi, phi_attrs),
        names.FRF_SYNTHESIZED: xr.Variable(frf.dims, synth.data, unit),
        names.FRF_RESIDUAL: xr.Variable(frf.dims, (frf - synth).data, unit),
        names.MAC: xr.Variable((names.MODE, names.MODE_2), mac_matrix(phi), dict(_ONE)),
        names.DRIVE_POINT_SNR: xr.Variable((names.MODE,), snr, dict(_ONE)),
        names.QUALITY_FLAGS: xr.Variable((names.MODE,), mask),
    }
    coords = {names.MODE_2: xr.Variable((names.MODE_2,), np.asarray(modes))}
    if fit.residual_coefficient is not None:
        coords[names.RESIDUAL_TERM] = xr.Variable(
            (names.RESIDUAL_TERM,), list(names.RESIDUAL_TERM_LABELS)
        )
        rc = _variable(fit.residual_coefficient).transpose(names.POINT, names.RESIDUAL_TERM)
        new[names.RESIDUAL_COEFFICIENT] = xr.Variable(rc.dims, rc.data, rc.attrs)
    return coords, new


def _variable(x) -> xr.Variable:
    """The Variable of a DataArray (its coordinates left behind), or ``x`` itself."""
    return getattr(x, "variable", x)


def quality_variables(mv: xr.Variable) -> dict:
    """The modal quality indicators of the mode vectors ``mv`` (point, mode in either order),
    by name: MPC, MPD, complexity (on ``mode``) and the mode vectors normalised in phase and
    magnitude (largest component 1), as :func:`ami_xr.ami.pipeline.with_quality` adds them."""
    phi = mv.transpose(names.POINT, names.MODE).values
    collinearity = mpc(phi)  # complexity is 1 - MPC: one pass over the points for both
    mode = (names.MODE,)
    normalised = xr.Variable(
        (names.POINT, names.MODE),
        phase_normalised(phi, unit=True),
        {
            names.ATTR_UNITS: "1",
            names.ATTR_LONG_NAME: (
                "mode vector rotated in phase and scaled so that its largest component is 1"
            ),
        },
    ).transpose(*mv.dims)
    return {
        names.MPC: xr.Variable(
            mode,
            collinearity,
            {
                names.ATTR_UNITS: "1",
                names.ATTR_LONG_NAME: "modal phase collinearity (1: real mode)",
            },
        ),
        names.MPD: xr.Variable(
            mode,
            mpd(phi),
            {
                names.ATTR_UNITS: "degree",
                names.ATTR_LONG_NAME: "mean phase deviation from the best straight line",
            },
        ),
        names.COMPLEXITY: xr.Variable(
            mode,
            1.0 - collinearity,
            {names.ATTR_UNITS: "1", names.ATTR_LONG_NAME: "mode complexity 1 - MPC (0: real mode)"},
        ),
        names.MODE_VECTOR_NORMALISED: normalised,
    }
