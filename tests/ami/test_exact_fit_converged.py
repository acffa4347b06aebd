"""An exact fit is converged (issue 41): on the noise-free symmetric ring the refinement's last
Levenberg-Marquardt step was rejected against a noise level estimated from a residual near zero,
and every mode came out ``refine_not_converged`` although the fit was exact to rounding."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.core import flags as qf


@pytest.mark.parametrize("references", [[2], [2, 3, 4]])
def test_noise_free_ring_refinement_is_converged(references):
    truth = ami_xr.simulate.symmetric_structure(0.001)
    f = np.linspace(0.05, 50.0, 1000)
    ds = ami_xr.simulate.frf(truth, f, references=references)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = ami_xr.identify(ds)
    assert int(out.attrs[names.ATTR_REFINE_CONVERGED]) == 1
    flags = ",".join(qf.flag_text(out[names.QUALITY_FLAGS].values))
    assert "refine_not_converged" not in flags
    # the fit is exact: every mode of the ring within rounding-level error of the truth
    fn = np.sort(out[names.NATURAL_FREQUENCY].values)
    true_fn = np.sort(truth[names.NATURAL_FREQUENCY].values)
    assert fn.size >= true_fn.size - 1  # one reference may see a repeated pair as one mode
    for x in fn:
        assert np.min(np.abs(true_fn - x)) < 1e-6 * x
