"""The FRF's sign convention: ami_xr's FRFs follow the e^{+i omega t} convention (numpy's FFT,
H = X/F with X(omega) = sum x(t) e^{-i omega t}), where a mode is a pole of the upper half plane
with negative real part and its Nyquist circle turns clockwise as frequency rises. Data exported
with the other convention (e^{-i omega t}) are the complex conjugate: every mode then looks
unstable (a positive real part), so no single-mode fit is accepted.
"""

from __future__ import annotations

from ami_xr import names
from ami_xr.errors import IdentificationError

__all__ = ["CONJUGATE_FIX", "conjugate_error"]

#: What to do with an FRF in the other convention.
CONJUGATE_FIX = (
    f"use ds.assign({names.FRF}=ds.{names.FRF}.conj()) in Python, or "
    "'ami-xr identify --conjugate' (conjugates the FRFs as they are read)"
)


def conjugate_error(function: str, n_frfs: int, n_conjugate: int) -> IdentificationError:
    """The error for FRFs on which no single-mode fit was accepted while their complex
    conjugates give ``n_conjugate`` accepted candidates (over ``n_frfs`` FRFs)."""
    return IdentificationError(
        f"{names.FRF}: {function} accepted no single-mode fit on any of the {n_frfs} FRF(s), but "
        f"their complex conjugates give {n_conjugate} candidate(s): the FRF looks like the "
        "complex conjugate of the e^{+iwt} convention (modes with a positive real part, Nyquist "
        "circles turning counter-clockwise; data exported with e^{-iwt}?): " + CONJUGATE_FIX
    )
