"""CF metadata of the files ami_xr writes: ``Conventions``, ``long_name``, ``units``, flags.

:func:`annotate` runs on every Dataset :func:`ami_xr.io.netcdf.to_netcdf` writes. It only adds
what is missing (attributes a function set are kept) and never changes a value:

* the global attribute ``Conventions = "CF-1.11"`` (the CF version whose rules the files follow:
  ``units`` in UDUNITS spelling, ``long_name``, ``history``, ``flag_masks``/``flag_meanings``,
  label variables), and the recommended global attributes that fit: ``title`` (what the file
  holds and the file it came from, :func:`title`), ``source`` (ami_xr and its version) and, for
  AMI results, ``references`` (:data:`REFERENCES`). ``institution`` and ``comment`` are left to
  the user (annotate cannot know them);
* ``long_name`` on every variable and coordinate (from :data:`LONG_NAMES`, else built from the
  name: ``ami_`` values are "AMI estimate before refinement: ...", ``*_std`` "standard
  deviation of ...", others the name in words);
* ``units`` on every numeric variable and coordinate (from :data:`UNITS`, from the variable a
  derived one comes from, from the Dataset's force units, or ``"1"`` for counts and labels);
  string, boolean and flag variables carry none (CF: units are not for strings or flags);
  ``residual_coefficient`` holds two quantities of different units along ``residual_term``, so
  it carries ``units_lower`` and ``units_upper`` instead of ``units``;
* ``quality_flags`` (int32, dims ``mode``), the bit field it is in memory too, gets the CF
  ``flag_masks`` and ``flag_meanings`` of the one table of :mod:`ami_xr.core.flags`
  (:data:`FLAG_MEANINGS` and :data:`FLAG_MASKS` are its ``MEANINGS`` and ``MASKS``, every flag,
  bit k = 2**k). Files of earlier versions hold the comma-joined text there and the bit field
  in ``quality_flag_mask`` (:data:`QUALITY_FLAG_MASK`); :func:`flags_as_bits` reads them;

* the CF global attribute ``history``: one line per ``ami_xr_history`` record (UTC time,
  function, ami_xr version; :func:`ami_xr.provenance.cf_history`), after any ``history`` text
  the Dataset already had (from another tool);
* mode vectors scaled at the drive point have units ``sqrt(<receptance units>)`` (eq. 8 in the
  displacement convention of :func:`ami_xr.ami.global_fit.receptance_mode_vectors`, whatever the
  FRF type: ``sqrt(m/N)``, s/sqrt(kg)). UDUNITS has integer powers only (it reads ``"m0.5"`` as
  ``0.25``, not as a square root), so no UDUNITS string states them. On disk such a variable
  carries no ``units`` and instead ``units_of_square`` (:data:`ATTR_UNITS_OF_SQUARE`), the
  UDUNITS units of the square (of ``Phi_j Phi_k``), e.g. ``"m/N"``; in memory ``units`` stays
  ``"sqrt(m/N)"``;
* a dimension coordinate that CF does not allow as a coordinate variable (CF 1.3: numeric and
  strictly monotonic), such as string point labels, ``residual_term`` or unsorted integer
  labels, is stored as the CF label (auxiliary coordinate) variable ``<dim>_label`` along the
  dim (:data:`LABEL_SUFFIX`; plain xarray: ``raw.set_xindex("point_label")`` selects by it).
  Float axes (``time``, ``frequency``) are data and stay as they are;
* a ``time`` dimension that is an elapsed time (units ``s`` counted from the start of the
  record, no date: simulated impulse responses, LVM records) is stored as the dimension and
  coordinate variable ``elapsed_time`` (:data:`ELAPSED_TIME`), units ``s``, long_name "time since
  the start of the record", no ``standard_name``. CF names a dimension ``time`` only for a
  time coordinate with a reference date (units ``<unit> since <epoch>``, standard_name
  ``time``); ami_xr's axis has no date, and inventing one (``s since 1970-01-01``) would state
  a false acquisition time. A ``time`` coordinate that does have a date (datetime64, or units
  with ``since``) keeps its name.

These are an on-disk encoding, like the complex pairs: the global attribute ``ami_xr_cf_added``
(JSON) lists what :func:`annotate` added, moved or renamed, and :func:`strip` (run by
:func:`ami_xr.open_dataset`) removes exactly that, so a file read back is identical to the
Dataset written and nothing accumulates over read/write cycles. Plain xarray, netCDF4, ncdump
and CF tools see the metadata.
"""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.core import flags
from ami_xr.errors import AssumptionWarning
from ami_xr.provenance import cf_history

__all__ = [
    "CONVENTIONS",
    "ATTR_CONVENTIONS",
    "ATTR_UNITS_OF_SQUARE",
    "LABEL_SUFFIX",
    "REFERENCES",
    "title",
    "QUALITY_FLAG_MASK",
    "FLAG_MEANINGS",
    "FLAG_MASKS",
    "LONG_NAMES",
    "UNITS",
    "annotate",
    "strip",
    "ATTR_CF_ADDED",
    "ELAPSED_TIME",
    "on_disk_name",
    "ATTR_UNITS_LOWER",
    "ATTR_UNITS_UPPER",
    "flag_mask",
    "flags_as_bits",
]

ATTR_CONVENTIONS = "Conventions"
ATTR_CF_HISTORY = "history"
ATTR_CF_ADDED = "ami_xr_cf_added"  # JSON: what annotate added (strip removes it on reading)
CONVENTIONS = "CF-1.11"
ATTR_TITLE = "title"
ATTR_SOURCE = "source"  # CF: method of production (here ami_xr and its version)
ATTR_REFERENCES = "references"
REFERENCES = (
    "J. H. Ginsberg and M. S. Allen, Recent improvements of the Algorithm of Mode Isolation"
)
# on disk instead of units "sqrt(X)" (UDUNITS has no fractional powers): X, the units of the square
ATTR_UNITS_OF_SQUARE = "units_of_square"
_SQRT_UNITS = re.compile(r"^sqrt\((.+)\)$")
LABEL_SUFFIX = "_label"  # a dim coordinate CF cannot hold is stored as <dim>_label
# on disk, a time axis without a date (s from the record start): CF's "time" needs an epoch
ELAPSED_TIME = "elapsed_time"
QUALITY_FLAG_MASK = "quality_flag_mask"  # files before issue 39: the bits beside the text
ATTR_FLAG_MASKS = "flag_masks"
ATTR_FLAG_MEANINGS = "flag_meanings"
# the bits of the one table (ami_xr.core.flags, bit k = 2**k for MEANINGS[k]), not a copy of it
FLAG_MEANINGS = flags.MEANINGS
FLAG_MASKS = flags.MASKS
_FLAG_ATTRS = {ATTR_FLAG_MASKS: FLAG_MASKS, ATTR_FLAG_MEANINGS: " ".join(FLAG_MEANINGS)}

_ONE = names.DIMENSIONLESS_UNITS
UNITS = {
    names.FREQUENCY: names.FREQUENCY_UNITS,
    names.TIME: names.TIME_UNITS,
    names.COHERENCE: _ONE,
    names.EIGENVALUE: names.ANGULAR_UNITS,
    names.NATURAL_FREQUENCY: names.FREQUENCY_UNITS,
    names.DAMPING_RATIO: _ONE,
    names.MPC: _ONE,
    names.MPD: "degree",
    names.COMPLEXITY: _ONE,
    names.MAC: _ONE,
    names.DRIVE_POINT_SNR: _ONE,
    names.POINT_SNR: _ONE,
    names.POINT_EIGENVALUE: names.ANGULAR_UNITS,
    names.EIGENVALUE_SPREAD: names.ANGULAR_UNITS,
    names.SUB_EIGENVALUE: names.ANGULAR_UNITS,
    names.SUB_BAND_LOW: names.FREQUENCY_UNITS,
    names.SUB_BAND_HIGH: names.FREQUENCY_UNITS,
    names.SUB_STOP_STATISTIC: _ONE,
    names.NATURAL_FREQUENCY_ERROR: _ONE,
    names.DAMPING_RATIO_ERROR: _ONE,
    names.MODE_VECTOR_ERROR: _ONE,
    names.RECORD_START: names.TIME_UNITS,
}

LONG_NAMES = {
    names.FRF: "frequency response function",
    names.COHERENCE: "ordinary coherence",
    names.RESPONSE: "response time history",
    names.FORCE: "force time history",
    names.FREQUENCY: "frequency",
    names.TIME: "time since the start of the record",
    names.POINT: "measurement point (response degree of freedom)",
    names.MODE: "mode number",
    names.MODE_2: "mode number (second index of the MAC matrix)",
    names.RECORD: "record (hit) number",
    names.REFERENCE: "excitation point",
    names.CANDIDATE: "candidate mode of one FRF (subtraction phase)",
    names.RESIDUAL_TERM: "residual term (lower or upper)",
    names.EIGENVALUE: "complex eigenvalue -zeta*wn + i*wd",
    names.NATURAL_FREQUENCY: "undamped natural frequency",
    names.DAMPING_RATIO: "viscous damping ratio",
    names.RESIDUE: "modal residue",
    names.MODE_VECTOR: "mode vector",
    names.FRF_NOISE_STD: "noise standard deviation of one FRF line",
    names.FRF_LINE_NOISE_STD: "noise standard deviation of the FRF estimate at each line",
    names.NATURAL_FREQUENCY_ERROR: "Cramer-Rao bound: expected relative error of the frequency",
    names.DAMPING_RATIO_ERROR: "Cramer-Rao bound: expected relative error of the damping ratio",
    names.MODE_VECTOR_ERROR: "Cramer-Rao bound: expected relative error of the mode vector",
    names.SUB_EIGENVALUE: "eigenvalue of a candidate mode (subtraction phase)",
    names.SUB_RESIDUE: "residue of a candidate mode (subtraction phase)",
    names.SUB_BAND_LOW: "first frequency of the fit band (subtraction phase)",
    names.SUB_BAND_HIGH: "last frequency of the fit band (subtraction phase)",
    names.SUB_STOP_REASON: "why the subtraction phase stopped",
    names.SUB_N_MODES: "number of candidate modes (subtraction phase)",
    names.DETECTED: "mode detected in this FRF",
    names.POINT_EIGENVALUE: "eigenvalue of the mode fitted to this FRF alone",
    names.ISO_ITERATIONS: "isolation phase sweeps",
    names.ISO_CONVERGED: "isolation phase converged",
    names.FRF_SYNTHESIZED: "FRF synthesised from the identified modes",
    names.FRF_RESIDUAL: "measured minus synthesised FRF",
    names.RESIDUAL_COEFFICIENT: "coefficient of the residual term",
    names.MAC: "modal assurance criterion",
    names.DRIVE_POINT_SNR: "peak contribution of the mode at the drive point over the noise floor",
    names.QUALITY_FLAGS: "quality flags of the mode as a bit field (0: none)",
    names.FORCE_AUTOSPECTRUM: "force autospectrum (one-sided density)",
    names.RESPONSE_AUTOSPECTRUM: "response autospectrum (one-sided density)",
    names.CROSS_SPECTRUM: "force-response cross spectrum",
    names.HIT_REJECTED: "impact hit left out of the average",
    names.HIT_REJECT_REASON: "why the hit was left out (empty: used)",
    names.HIT_PEAK_FORCE: "peak force of the hit",
    names.RECORD_START: "start time of the record",
}
for _axis in "xyz":
    LONG_NAMES[f"{names.POINT}_{_axis}"] = f"{_axis} coordinate of the measurement point"


def flag_mask(text: np.ndarray) -> np.ndarray:
    """int32 bit field of comma-joined flag strings (the ``quality_flags`` of files written
    before issue 39; :func:`ami_xr.core.flags.from_text`): a flag not in :data:`FLAG_MEANINGS`,
    e.g. from a foreign file, has no bit and is left out."""
    return flags.from_text(text, unknown="ignore")


def flags_as_bits(ds: xr.Dataset) -> xr.Dataset:
    """``ds`` read from a file, with ``quality_flags`` as the int32 bit field: a file of an
    earlier version holds the comma text (and a ``quality_flag_mask`` beside it, which
    :func:`strip` removed); a flag this version cannot name is left out with a warning."""
    if names.QUALITY_FLAGS not in ds.variables:
        return ds
    var = ds.variables[names.QUALITY_FLAGS]
    if var.dtype.kind not in "USO":
        return ds
    values = np.asarray(var.values).astype(str)
    known = flag_mask(values)
    foreign = sorted(
        {f.strip() for v in values.ravel() for f in v.split(names.FLAG_SEPARATOR)}
        - set(FLAG_MEANINGS)
        - {""}
    )
    if foreign:
        warnings.warn(
            f"{names.QUALITY_FLAGS}: flag(s) {foreign} are not flags of this version of ami_xr "
            "and were left out",
            AssumptionWarning,
            stacklevel=2,
        )
    attrs = {k: v for k, v in var.attrs.items() if k not in _FLAG_ATTRS}
    return ds.assign({names.QUALITY_FLAGS: xr.Variable(var.dims, known, attrs)})


def _base(name: str) -> str | None:
    """The variable a derived one comes from (``ami_residue``, ``residue_std`` -> ``residue``)."""
    if name.startswith(names.AMI_PREFIX):
        return name[len(names.AMI_PREFIX) :]
    if name.endswith("_std") and name not in (names.FRF_NOISE_STD, names.FRF_LINE_NOISE_STD):
        return name[: -len("_std")]
    if name == names.MODE_VECTOR_NORMALISED:
        return names.MODE_VECTOR
    return None


def _long_name(name: str) -> str:
    if name in LONG_NAMES:
        return LONG_NAMES[name]
    base = _base(name)
    if base is not None and name.startswith(names.AMI_PREFIX):
        return f"AMI estimate before refinement: {_long_name(base)}"
    if base is not None and name.endswith("_std"):
        return f"standard deviation of the {_long_name(base)}"
    return name.replace("_", " ")


def _units(name: str, var: xr.Variable, ds: xr.Dataset) -> str | None:
    if name in UNITS:
        return UNITS[name]
    base = _base(name)
    if base is not None and base in ds.variables:
        units = ds.variables[base].attrs.get(names.ATTR_UNITS)
        if units is not None:
            return units
        if base in UNITS:
            return UNITS[base]
    if name == names.HIT_PEAK_FORCE and names.FORCE in ds.variables:
        return ds.variables[names.FORCE].attrs.get(names.ATTR_UNITS)
    if var.dtype.kind in "iu":  # counts, mode numbers, integer point labels
        return _ONE
    return None


# residual_coefficient: the basis of the lower and upper terms is (i w)^(p - 2) and (i w)^p for
# an FRF of derivative order p (0 receptance, 1 mobility, 2 accelerance), so the coefficients
# carry the FRF units times these (one units string cannot hold both: see the module docstring)
_RESIDUAL_UNITS = {
    0: ("{u} (rad/s)^2", "{u}"),
    1: ("{u} rad/s", "{u} s/rad"),
    2: ("{u}", "{u} (s/rad)^2"),
}
ATTR_UNITS_LOWER = "units_lower"
ATTR_UNITS_UPPER = "units_upper"


def _residual_units(ds: xr.Dataset) -> dict:
    frf_units = ds[names.FRF].attrs.get(names.ATTR_UNITS) if names.FRF in ds else None
    power = names.QUANTITY_POWER.get(ds.attrs.get(names.ATTR_QUANTITY))
    if not frf_units or power is None:
        return {}
    lower, upper = _RESIDUAL_UNITS[power]
    return {
        ATTR_UNITS_LOWER: lower.format(u=frf_units),
        ATTR_UNITS_UPPER: upper.format(u=frf_units),
    }


def title(ds: xr.Dataset) -> str:
    """A CF ``title`` for ``ds``: what it holds (modal parameters, FRFs, time histories) and the
    file it came from (``source_file``, a file name) when known."""
    variables = ds.variables
    if names.EIGENVALUE in variables:
        what = "Modal parameters"
        if names.ATTR_AMI_PHASE in ds.attrs:
            what += " identified by the Algorithm of Mode Isolation"
    elif names.FRF in variables:
        what = "Frequency response functions"
    elif names.RESPONSE in variables or names.FORCE in variables:
        what = "Force and response time histories"
    else:
        what = "ami_xr data"
    source = ds.attrs.get(names.ATTR_SOURCE_FILE)
    return f"{what} (from {source})" if source else what


def _cf_coordinate(var: xr.Variable) -> bool:
    """Whether ``var`` (1-D, named like its dim) is a CF coordinate variable: numeric, strictly
    monotonic (CF 1.3)."""
    if var.dtype.kind not in "iuf":
        return False
    values = np.asarray(var.values)
    if values.size < 2:
        return True
    step = np.diff(values.astype(np.float64) if values.dtype.kind == "f" else values)
    return bool(np.all(step > 0) or np.all(step < 0))


def _labels_to_aux(out: xr.Dataset, added: dict) -> xr.Dataset:
    """Dim coordinates CF cannot hold -> label variables ``<dim>_label`` (see the docstring)."""
    renamed = {}
    for dim in list(out.dims):
        if dim not in out.coords or out[dim].ndim != 1:
            continue
        var = out.variables[dim]
        label = f"{dim}{LABEL_SUFFIX}"
        # labels only: float axes (time, frequency) are data and stay, complex is rejected by
        # the netCDF encoder, datetimes are encoded by xarray
        if var.dtype.kind in "fcmM" or _cf_coordinate(var) or label in out.variables:
            continue
        out = out.drop_vars(dim).assign_coords(
            {label: xr.Variable((dim,), var.values, dict(var.attrs), dict(var.encoding))}
        )
        renamed[label] = str(dim)
    if renamed:
        added["labels"] = renamed
    return out


def _is_elapsed(ds: xr.Dataset) -> bool:
    """Whether ``ds`` has a ``time`` dim without a date (see the module docstring)."""
    if names.TIME not in ds.dims or ELAPSED_TIME in ds.variables or ELAPSED_TIME in ds.dims:
        return False
    if names.TIME not in ds.variables:
        return True
    var = ds.variables[names.TIME]
    return var.dtype.kind not in "mM" and " since " not in str(var.attrs.get(names.ATTR_UNITS))


def on_disk_name(marker: object, name: str) -> str:
    """The name a variable or dim ``name`` has in a file whose ``ami_xr_cf_added`` global
    attribute is ``marker`` (``"time"`` -> ``"elapsed_time"`` where :func:`annotate` renamed it;
    ``name`` for files without the marker)."""
    try:
        renamed = json.loads(str(marker)).get("renamed", {})
    except (TypeError, ValueError, AttributeError):
        return name
    found = (
        [disk for disk, own in renamed.items() if own == name] if isinstance(renamed, dict) else []
    )
    return str(found[0]) if found else name


def annotate(ds: xr.Dataset) -> xr.Dataset:
    """``ds`` with CF metadata added where missing (see the module docstring); a shallow copy."""
    from ami_xr import __version__

    out = ds.copy()
    out.attrs = {k: v for k, v in ds.attrs.items() if k != ATTR_CF_ADDED}
    added: dict = {"variables": [], "attrs": {}, "global": {}}
    if names.QUALITY_FLAGS in ds:
        # the bit field with its CF table (a Dataset built by hand may still hold the text)
        var = out[names.QUALITY_FLAGS].variable
        out[names.QUALITY_FLAGS] = var.copy(data=flags.decode(var.values))
        out[names.QUALITY_FLAGS].attrs.update(_FLAG_ATTRS)
        added["attrs"][names.QUALITY_FLAGS] = [
            k for k in _FLAG_ATTRS if k not in ds[names.QUALITY_FLAGS].attrs
        ]
    moved = {}
    for name in list(out.variables):
        var = out.variables[name]
        attrs = dict(var.attrs)
        new = {names.ATTR_LONG_NAME: _long_name(str(name))}
        if name == names.RESIDUAL_COEFFICIENT:
            new.update(_residual_units(out))
        flag = ATTR_FLAG_MASKS in attrs
        if var.dtype.kind in "iufc" and names.ATTR_UNITS not in attrs and not flag:
            units = _units(str(name), var, out)
            if units is not None:
                new[names.ATTR_UNITS] = units
        new = {k: v for k, v in new.items() if k not in attrs}
        if new and name not in added["variables"]:
            added["attrs"][str(name)] = sorted({*added["attrs"].get(str(name), []), *new})
        attrs = {**attrs, **new}
        root = _SQRT_UNITS.match(str(attrs.get(names.ATTR_UNITS, "")))
        if root and ATTR_UNITS_OF_SQUARE not in attrs:
            # mode vectors: UDUNITS has no square roots, state the units of the square
            moved[str(name)] = attrs.pop(names.ATTR_UNITS)
            attrs[ATTR_UNITS_OF_SQUARE] = root.group(1)
        var.attrs = attrs
    if moved:
        added["units_of_square"] = moved
    out = _labels_to_aux(out, added)
    if _is_elapsed(out):  # CF's dim "time" must have a date; this axis has none
        out = out.rename({names.TIME: ELAPSED_TIME})
        added["renamed"] = {ELAPSED_TIME: names.TIME}
    previous = out.attrs.get(ATTR_CONVENTIONS)
    conventions = str(previous or "").replace(",", " ").split()
    kept = [c for c in conventions if not c.startswith("CF-")]
    out.attrs[ATTR_CONVENTIONS] = " ".join([CONVENTIONS, *kept])
    added["global"][ATTR_CONVENTIONS] = previous
    recommended = {ATTR_TITLE: title(ds), ATTR_SOURCE: f"ami_xr {__version__}"}
    if names.ATTR_AMI_PHASE in ds.attrs:
        recommended[ATTR_REFERENCES] = REFERENCES
    for key, value in recommended.items():
        if not out.attrs.get(key):  # CF: a non-empty string; the user's own is kept
            added["global"][key] = out.attrs.get(key)
            out.attrs[key] = value
    lines = cf_history(ds)
    if lines:
        previous = out.attrs.get(ATTR_CF_HISTORY)
        text = "\n".join(lines)
        out.attrs[ATTR_CF_HISTORY] = f"{str(previous).rstrip()}\n{text}" if previous else text
        added["global"][ATTR_CF_HISTORY] = previous
    out.attrs[ATTR_CF_ADDED] = json.dumps(added)
    return out


def strip(ds: xr.Dataset) -> xr.Dataset:
    """Inverse of :func:`annotate` on a Dataset read from a file (no-op without the marker)."""
    raw = ds.attrs.get(ATTR_CF_ADDED)
    if raw is None:
        return ds
    try:
        added = json.loads(raw)
        variables = [v for v in added["variables"] if v in ds.variables]
        out = ds.drop_vars(variables).copy()  # new Variable objects: ds keeps its attrs
        for disk, own in added.get("renamed", {}).items():
            if disk in out.dims and own not in out.dims and own not in out.variables:
                out = out.rename({disk: own})
        for label, dim in added.get("labels", {}).items():
            if label in out.variables and dim not in out.variables:
                var = out.variables[label]
                restored = xr.Variable((dim,), var.values, dict(var.attrs), dict(var.encoding))
                out = out.drop_vars(label).assign_coords({dim: restored})
        for name, units in added.get("units_of_square", {}).items():
            if name in out.variables:
                var = out.variables[name]
                attrs = {k: v for k, v in var.attrs.items() if k != ATTR_UNITS_OF_SQUARE}
                var.attrs = {**attrs, names.ATTR_UNITS: units}
        for name, keys in added["attrs"].items():
            if name in out.variables:
                var = out.variables[name]
                var.attrs = {k: v for k, v in var.attrs.items() if k not in keys}
        attrs = {k: v for k, v in out.attrs.items() if k != ATTR_CF_ADDED}
        for key, previous in added["global"].items():
            if previous is None:
                attrs.pop(key, None)
            else:
                attrs[key] = previous
    except (TypeError, ValueError, KeyError, AttributeError):
        return ds  # a damaged marker: keep everything
    out.attrs = attrs
    return out


def compliance_report(path) -> tuple[bool, str] | None:
    """Run the IOOS compliance checker's ``cf:1.11`` at criteria ``normal`` on the file ``path``
    (the optional extra ``ami_xr[cf]``): ``(passed with no issue, the checker's report)``, or
    None when the checker is not installed. Used by ``tests/io/test_cf_compliance.py`` and
    ``scripts/make_sample_data.py --check``."""
    import contextlib
    import io

    try:
        from compliance_checker.runner import CheckSuite, ComplianceChecker
    except ImportError:
        return None
    CheckSuite.load_all_available_checkers()
    report, errors_text = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(report), contextlib.redirect_stderr(errors_text):
        passed, errors = ComplianceChecker.run_checker(
            str(path),
            ["cf:1.11"],
            verbose=0,
            criteria="normal",
            output_filename="-",
            output_format="text",
        )
    text = report.getvalue() + errors_text.getvalue()
    return bool(passed and not errors and "All tests passed!" in text), text
