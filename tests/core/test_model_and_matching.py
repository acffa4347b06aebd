"""The array-level core (ami_xr/core): model-order choice, mode matching, and its layering (no
xarray)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ami_xr import names
from ami_xr.errors import IdentificationError


def test_resolve_model_choices():
    from ami_xr.core.model import resolve_model

    impulse = {names.ATTR_SOURCE: names.SOURCE_IMPULSE, names.ATTR_DT: 0.01}
    assert resolve_model(impulse).name == names.MODEL_DISCRETE
    assert resolve_model(impulse).n_samples == 0
    assert resolve_model(impulse, "exact").name == names.MODEL_CONTINUOUS  # no record length
    full = {**impulse, names.ATTR_NSAMPLES: 256}
    assert resolve_model(full, "exact") == resolve_model(full)
    stored = {**full, names.ATTR_AMI_MODEL: names.MODEL_CONTINUOUS}
    assert resolve_model(stored).name == names.MODEL_CONTINUOUS
    assert resolve_model(stored, "exact").name == names.MODEL_DISCRETE
    assert resolve_model({}).dt == 0.0
    with pytest.raises(IdentificationError, match="sample_interval"):
        resolve_model({}, names.MODEL_DISCRETE)
    with pytest.raises(IdentificationError, match="model"):
        resolve_model({}, "bogus")


def test_core_has_no_xarray():
    import ast
    import pathlib

    import ami_xr.core

    for path in pathlib.Path(ami_xr.core.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                mods = [a.name for a in node.names] if isinstance(node, ast.Import) else []
                mods.append(getattr(node, "module", None) or "")
                assert not any(m.split(".")[0] == "xarray" for m in mods), path.name


@settings(max_examples=60, deadline=None)
@given(
    st.integers(1, 6),
    st.integers(1, 5),
    st.integers(0, 2**32 - 1),
)
def test_match_modes_properties(n_points, n_slots, seed):
    """Estimates of one FRF never share a mode; modes are numbered by frequency; every finite
    estimate gets a mode; a NaN slot gets none."""
    from ami_xr.core.matching import gather, match_modes, n_labels, weighted_average

    rng = np.random.default_rng(seed)
    wn = rng.uniform(10.0, 100.0, n_slots)
    lam = -0.01 * wn + 1j * wn
    est = lam[None, :] * (1 + 1e-3 * rng.standard_normal((n_points, n_slots)))
    est[rng.random((n_points, n_slots)) < 0.3] = np.nan
    snr = rng.uniform(1.0, 10.0, est.shape)
    label = match_modes(est, snr, 0.5)
    # integer labels and a boolean mask: no arithmetic
    assert np.array_equal(label >= 0, np.isfinite(est))
    for j in range(n_points):
        used = label[j][label[j] >= 0]
        assert used.size == np.unique(used).size
    k = n_labels(label)
    weight = np.nan_to_num(gather(snr + 0j, label, k).real) ** 2
    centre, _ = weighted_average(gather(est, label, k), weight)
    # the matcher orders modes by its own running centres; this weighted average of the same
    # estimates differs from those by rounding only (sums of <= 6 terms), so 1e-9 relative slack; a
    # wrong order is off by the spread of the estimates (~1e-3)
    assert np.all(np.diff(np.abs(centre)) >= -1e-9 * np.abs(centre[1:]))
