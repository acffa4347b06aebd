"""Mode shapes of UFF dataset 55: normal modes (analysis type 2) and complex modes (type 3).

See :mod:`ami_xr.io.uff` for the mapping. Shared by :func:`ami_xr.io.uff.read.read_uff` for a
modes-only file (:func:`read_modes`) and for modes stored with FRFs (:func:`with_modes`).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AssumptionWarning, DataFileError
from ami_xr.io.uff.codes import MODES_ID1, dof_map, point_label

__all__ = [
    "MODE_ANALYSIS_TYPES",
    "MODAL_MASS",
    "HYSTERETIC_DAMPING",
    "ATTR_MODES_SKIPPED",
    "ATTR_ANALYSIS_TYPE",
    "read_modes",
    "with_modes",
]

NORMAL_MODES = 2  # analysis type 2: frequency, modal mass, viscous and hysteretic damping
COMPLEX_MODES = 3  # analysis type 3: complex eigenvalue (first order), modal A and B
MODE_ANALYSIS_TYPES = (NORMAL_MODES, COMPLEX_MODES)
COMPONENTS = ("r1", "r2", "r3", "r4", "r5", "r6")  # pyuff's keys of the values per node

MODAL_MASS = "modal_mass"  # (mode) of normal modes, as the file states it (0: not given)
HYSTERETIC_DAMPING = "hysteretic_damping_ratio"  # (mode) of normal modes, when the file gives one
ATTR_MODES_SKIPPED = "uff_modes_skipped"  # why dataset-55 modes were not merged with the FRFs
ATTR_ANALYSIS_TYPE = "uff_analysis_type"  # which dataset-55 analysis type the modes came from

_ANALYSIS_NAMES = {
    NORMAL_MODES: (
        "normal modes (dataset 55 analysis type 2): eigenvalue from the frequency and the "
        "viscous damping ratio, lam = -zeta*wn + i*wn*sqrt(1 - zeta^2); real mode shapes as "
        "written"
    ),
    COMPLEX_MODES: "complex modes (dataset 55 analysis type 3): eigenvalue as written; mode "
    "shapes with a modal A divided by sqrt(A lam), so that lam Phi_j Phi_k is the residue",
}


def _where(m: dict, k: int) -> str:
    return f"dataset 55 of mode {m.get('mode_n', k + 1)} (load case {m.get('load_case', '?')})"


def _eigenvalue(m: dict, k: int, path: Path) -> tuple[complex, float, float]:
    """Eigenvalue (rad/s), natural frequency (Hz) and damping ratio of one dataset 55."""
    if int(m.get("analysis_type", 0)) == NORMAL_MODES:
        fn = float(m.get("freq", np.nan))
        zeta = float(m.get("modal_damp_vis", 0.0))
        if not (np.isfinite(fn) and fn >= 0.0):
            raise DataFileError(
                f"{path}: {_where(m, k)}: frequency {fn!r} Hz; expected a finite value >= 0"
            )
        if not (np.isfinite(zeta) and -1.0 < zeta < 1.0):
            raise DataFileError(
                f"{path}: {_where(m, k)}: viscous damping ratio {zeta!r}; expected a ratio "
                "between -1 and 1 (an oscillating mode)"
            )
        wn = 2 * np.pi * fn
        # 0.0 - ...: an undamped mode has real part +0.0, not -0.0
        return complex(0.0 - zeta * wn, wn * np.sqrt(1.0 - zeta**2)), fn, zeta
    lam = complex(m.get("eig", np.nan))
    wn = abs(lam)
    zeta = -lam.real / wn if wn > 0 else np.nan
    return lam, wn / (2 * np.pi), zeta


def _mode_numbers(modes: list[dict]) -> list[int]:
    numbers = [int(m.get("mode_n", k + 1)) for k, m in enumerate(modes)]
    return numbers if len(set(numbers)) == len(numbers) else list(range(1, len(modes) + 1))


def _modal_variables(modes: list[dict], vectors: np.ndarray, path: Path) -> dict:
    """eigenvalue, natural_frequency, damping_ratio and mode_vector, plus modal_mass and
    hysteretic_damping_ratio when the file holds normal modes (and states a hysteretic one)."""
    parameters = [_eigenvalue(m, k, path) for k, m in enumerate(modes)]
    eig = np.array([p[0] for p in parameters], dtype=np.complex128)
    vectors = vectors * _modal_a_scale(modes, eig)[np.newaxis, :]
    fn = np.array([p[1] for p in parameters], dtype=np.float64)
    zeta = np.array([p[2] for p in parameters], dtype=np.float64)
    out = {
        names.EIGENVALUE: (names.MODE, eig, {names.ATTR_UNITS: names.ANGULAR_UNITS}),
        names.NATURAL_FREQUENCY: (names.MODE, fn, {names.ATTR_UNITS: names.FREQUENCY_UNITS}),
        names.DAMPING_RATIO: (names.MODE, zeta, {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}),
        names.MODE_VECTOR: ((names.POINT, names.MODE), vectors),
    }
    normal = [int(m.get("analysis_type", 0)) == NORMAL_MODES for m in modes]
    if not any(normal):
        return out

    def field(key: str) -> np.ndarray:
        return np.array(
            [float(m.get(key, 0.0)) if n else np.nan for m, n in zip(modes, normal, strict=True)]
        )

    out[MODAL_MASS] = (
        names.MODE,
        field("modal_m"),
        {
            names.ATTR_LONG_NAME: "modal mass of the normal mode shape as written in the file "
            "(dataset 55, record 8, field 2; 0: not given), in the file's units",
        },
    )
    hysteretic = field("modal_damp_his")
    if np.any(np.nan_to_num(hysteretic) != 0.0):
        out[HYSTERETIC_DAMPING] = (
            names.MODE,
            hysteretic,
            {
                names.ATTR_UNITS: names.DIMENSIONLESS_UNITS,
                names.ATTR_LONG_NAME: "modal hysteretic damping ratio (dataset 55, record 8, "
                "field 4); not included in damping_ratio or eigenvalue",
            },
        )
        if np.all(zeta[np.asarray(normal)] == 0.0):
            warnings.warn(
                f"{path.name}: the normal modes state hysteretic damping but no viscous damping "
                f"ratio: damping_ratio is 0 and the hysteretic ratio is kept in "
                f"{HYSTERETIC_DAMPING!r}",
                AssumptionWarning,
                stacklevel=4,
            )
    return out


def _modal_a_scale(modes: list[dict], eig: np.ndarray) -> np.ndarray:
    """Per mode, the factor that turns a complex mode shape scaled by its modal A into ami_xr's
    mode vector: residues ``psi_j psi_k / a`` (first-order form) equal ``lam Phi_j Phi_k``
    (eq. 8) for ``Phi = psi / sqrt(a lam)``. 1 where the file states no modal A (0), for normal
    modes, and for the files :func:`~ami_xr.io.uff.write_uff` wrote (``a = 1/lam`` exactly, but
    written with 6 digits)."""
    out = np.ones(len(modes), dtype=np.complex128)
    for k, m in enumerate(modes):
        a = complex(m.get("modal_a", 0j) or 0j)
        own = str(m.get("id1", "")).strip() == MODES_ID1
        if int(m.get("analysis_type", 0)) != COMPLEX_MODES or a == 0 or own:
            continue
        if not (np.isfinite(a.real) and np.isfinite(a.imag)) or eig[k] == 0:
            continue
        out[k] = 1.0 / np.sqrt(a * eig[k])
    return out


def _analysis_attrs(modes: list[dict]) -> dict:
    types = sorted({int(m.get("analysis_type", 0)) for m in modes})
    return {ATTR_ANALYSIS_TYPE: "; ".join(_ANALYSIS_NAMES[t] for t in types)}


def _listed_dofs(modes: list[dict], path: Path) -> list[tuple[int, int]]:
    """Every (node, direction) the datasets list: each node with all the values it carries
    (3 translations, or 3 translations and 3 rotations), zero or not, in node order.

    A file :func:`~ami_xr.io.uff.write_uff` wrote pads the components of the points it does not
    hold with zeros (ID line 1 says so): there only the DOFs non-zero in some mode are kept."""
    dofs: set[tuple[int, int]] = set()
    for k, m in enumerate(modes):
        per_node = int(m.get("n_data_per_node", 3))
        if per_node not in (3, 6):
            raise DataFileError(
                f"{path}: {_where(m, k)} holds {per_node} value(s) per node (data "
                f"characteristic {m.get('data_ch')}); expected 3 (translations X, Y, Z) or 6 "
                "(translations and rotations)"
            )
        own = str(m.get("id1", "")).strip() == MODES_ID1
        for c in range(1, per_node + 1):
            values = np.asarray(m[COMPONENTS[c - 1]])
            for node, v in zip(m["node_nums"], values, strict=True):
                if not own or v != 0:
                    dofs.add((int(node), c))
    return sorted(dofs)


def read_modes(modes: list[dict], path: Path) -> tuple[xr.Dataset, dict]:
    """Modal Dataset of the dataset-55 records ``modes``, and the node of each point label.

    Points are every DOF the file lists (see :func:`_listed_dofs`); a node a mode does not list
    is 0 there (the UFF specification lets a writer leave out all-zero nodes).
    """
    dofs = _listed_dofs(modes, path)
    labels = [point_label(n, d) for n, d in dofs]
    vectors = np.zeros((len(dofs), len(modes)), dtype=np.complex128)
    for k, m in enumerate(modes):
        row = {int(n): i for i, n in enumerate(m["node_nums"])}
        for i, (node, c) in enumerate(dofs):
            key = COMPONENTS[c - 1]
            if node in row and key in m:
                vectors[i, k] = np.asarray(m[key])[row[node]]
    ds = xr.Dataset(
        _modal_variables(modes, vectors, path),
        coords={names.POINT: labels, names.MODE: _mode_numbers(modes)},
        attrs={names.ATTR_SOURCE_FILE: path.name, **_analysis_attrs(modes)},
    )
    return ds, {lab: n for lab, (n, _) in zip(labels, dofs, strict=True)}


def with_modes(ds: xr.Dataset, modes: list[dict], path: Path) -> xr.Dataset:
    """The FRF Dataset with the dataset-55 modes at its points (the mapping of
    :func:`ami_xr.io.uff.write_uff`: component ``|direction|`` of the point's node, sign flipped
    for a negative direction, Z for a scalar DOF). Modes that miss a point are not merged: a
    warning and the attribute ``uff_modes_skipped`` say so."""
    labels = ds[names.POINT].values.tolist()
    dof = dof_map(labels)
    vectors = np.zeros((len(labels), len(modes)), dtype=np.complex128)
    missing = []
    for k, m in enumerate(modes):
        nodes = [int(n) for n in m["node_nums"]]
        for i, lab in enumerate(labels):
            node, direction, _ = dof[lab]
            axis = abs(direction) if direction != 0 else 3
            values = m.get(f"r{axis}")
            if values is None or node not in nodes:
                missing.append(lab)
                continue
            sign = -1.0 if direction < 0 else 1.0
            vectors[i, k] = sign * np.asarray(values)[nodes.index(node)]
    if missing:
        why = (
            f"{len(modes)} mode shape(s) (dataset 55) not merged with the FRFs: no value at "
            f"point(s) {sorted(set(map(str, missing)))}; read them with read_uff(path, "
            "kind='modes')"
        )
        warnings.warn(f"{path.name}: {why}", AssumptionWarning, stacklevel=3)
        return ds.assign_attrs({ATTR_MODES_SKIPPED: why})
    return (
        ds.assign_coords({names.MODE: _mode_numbers(modes)})
        .assign(_modal_variables(modes, vectors, path))
        .assign_attrs(_analysis_attrs(modes))
    )
