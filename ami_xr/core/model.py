"""Which modal model describes an FRF: the exact discrete-time basis or the continuous eq. 4.

One function decides it for every phase, for :func:`ami_xr.refine`, the Cramér-Rao bound and the
plots. It reads only a mapping of attributes (a Dataset's ``attrs``), so it needs no xarray.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ami_xr import names
from ami_xr.errors import IdentificationError

# Values of the ``model`` argument of resolve_model.
MODEL_CHOICES = ("auto", names.MODEL_DISCRETE, names.MODEL_CONTINUOUS, "exact")
RESIDUAL_TERMS = names.RESIDUAL_TERM_LABELS  # canonical order


@dataclass(frozen=True)
class DataModel:
    """The basis of the modal model of an FRF.

    Attributes
    ----------
    name : {"discrete", "continuous"}
    dt : float
        Sample interval in s of the impulse response whose ``dt * DFT`` the FRF is; 0.0 for the
        continuous model (the kernels read ``dt <= 0`` as continuous).
    n_samples : int
        Record length of that impulse response; 0 when unknown (no truncation factor) or
        continuous.
    """

    name: str
    dt: float = 0.0
    n_samples: int = 0

    @property
    def discrete(self) -> bool:
        return self.name == names.MODEL_DISCRETE


CONTINUOUS = DataModel(names.MODEL_CONTINUOUS)


def resolve_model(attrs: Mapping[str, Any], model: str = "auto") -> DataModel:
    """The modal model of an FRF Dataset with attributes ``attrs``.

    Parameters
    ----------
    attrs : mapping
        The Dataset's attributes (``frf_source``, ``sample_interval``, ``record_samples`` and,
        after :func:`ami_xr.subtract`, ``ami_model``).
    model : {"auto", "discrete", "continuous", "exact"}
        "auto": the basis the AMI phases chose (``ami_model``) when there is one, else the
        discrete basis when the FRF is ``dt * DFT`` of a sampled impulse response
        (``frf_source == "impulse_response"`` with ``sample_interval``), else eq. 4.
        "exact": the model that is exact for the data whatever the phases chose -- discrete
        only when source, sample interval and record length are all known (the joint
        refinement and the Cramér-Rao bound fit the whole band, where the truncation factor
        matters). "discrete" needs ``sample_interval``.

    Returns
    -------
    DataModel

    Raises
    ------
    IdentificationError
        ``model`` not one of the choices, or "discrete" without ``sample_interval``.
    """
    if model not in MODEL_CHOICES:
        raise IdentificationError(f"model: expected one of {MODEL_CHOICES}, got {model!r}")
    impulse = attrs.get(names.ATTR_SOURCE) == names.SOURCE_IMPULSE
    dt = attrs.get(names.ATTR_DT)
    if model == "exact":
        n = attrs.get(names.ATTR_NSAMPLES)
        if impulse and dt is not None and n is not None:
            return DataModel(names.MODEL_DISCRETE, float(dt), int(n))
        return CONTINUOUS
    if model == "auto":
        stored = attrs.get(names.ATTR_AMI_MODEL)
        if stored in names.AMI_MODELS:
            model = stored
        else:
            model = names.MODEL_DISCRETE if impulse and dt else names.MODEL_CONTINUOUS
    if model == names.MODEL_DISCRETE:
        if not dt or not float(dt) > 0:
            raise IdentificationError(
                f"model: 'discrete' needs the attribute {names.ATTR_DT!r} (sample interval in s)"
            )
        return DataModel(model, float(dt), int(attrs.get(names.ATTR_NSAMPLES, 0) or 0))
    return CONTINUOUS


def resolve_residual_terms(
    residual_terms: str | Sequence[str], attrs: Mapping[str, Any], fitted_before: bool
) -> tuple[str, ...]:
    """Residual terms of the joint model, in canonical order ("lower", "upper").

    ``"auto"``: none where the modal model is exact (impulse-response and analytic FRFs of
    receptance or mobility) unless the global fit used them (``fitted_before``), both otherwise.
    An accelerance is never exact without them: ``(i w)^2 / (i w - lam) = i w + lam +
    lam^2 / (i w - lam)``, so the modes of a complete model leave the constant
    ``sum_k 2 Re(A_k lam_k)`` (the inverse mass), which only the upper residual term holds (the
    ``i w`` terms cancel: the residues sum to zero). Without it the fit spends poles on that
    constant, differently on the compressed and the full path (issue 39). The value is assumed
    checked.
    """
    if residual_terms == "auto":
        exact = attrs.get(names.ATTR_SOURCE) in (
            names.SOURCE_IMPULSE,
            names.SOURCE_ANALYTIC,
        ) and attrs.get(names.ATTR_FRF_TYPE) != "accelerance"
        terms: tuple[str, ...] = () if exact and not fitted_before else RESIDUAL_TERMS
    elif isinstance(residual_terms, str):
        terms = (residual_terms,)
    else:
        terms = tuple(residual_terms)
    return tuple(t for t in RESIDUAL_TERMS if t in terms)
