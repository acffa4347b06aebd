"""The per-FRF ("paper") isolation runs the paper's plain sweeps in the shared engine
(``IsolateParams.paper_sweeps``): on the noise-free benchmark of Ginsberg & Allen its modes stay
as accurate as before the engine was unified (issue 19).

With the SIMO measures (re-ordering every sweep, bands inside a window, two-state cycle
averaging, pinning of a re-added mode) the per-FRF isolation kept, at G_m3, a mode that the
model-order check fitted at 65.53 rad/s to a residual band spanning 10-214 rad/s; the paper's
mean over the FRFs then moved modes 3 and 4 by 0.12 % and 0.14 % in frequency and 3 % and 21 %
in damping (before the unification, and again now: at most 0.021 % and 0.38 %).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami.isolate import kernel_params
from ami_xr.ami.settings import IsolateSettings, SubtractSettings


def _matched_errors(lam, lam_true):
    """Relative errors (%) of natural frequency and damping of the nearest identified mode."""
    fn_err = []
    zeta_err = []
    for lt in lam_true:
        li = lam[np.argmin(np.abs(lam - lt))]
        fn_err.append(100 * abs(abs(li) - abs(lt)) / abs(lt))
        zeta_err.append(100 * abs(-li.real / abs(li) + lt.real / abs(lt)) / (-lt.real / abs(lt)))
    return np.array(fn_err), np.array(zeta_err)


def test_paper_method_noise_free_benchmark_is_accurate():
    _, frf, truth = ami_xr.simulate.benchmark(noise=0.0, seed=1000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ami_xr.identify(frf, method="paper")
    lam = res[names.EIGENVALUE].values
    fn_err, zeta_err = _matched_errors(lam, truth[names.EIGENVALUE].values)
    # measured: f_n 0.0000, 0.0209, 0.0001, 0.0005 %; zeta 0.000, 0.371, 0.006, 0.223 % (the
    # continuous basis on data of the discrete model leaves these); the bounds keep a margin
    # of about 2 but fail on the 0.12-0.16 % and 3-21 % of the regression
    assert np.all(fn_err < 0.05), fn_err
    assert np.all(zeta_err < 1.0), zeta_err


@pytest.mark.parametrize(("method", "paper"), [("per_frf", True), ("simo", False)])
def test_kernel_params_select_the_paper_sweeps_for_per_frf_only(method, paper):
    settings = IsolateSettings(method=method)
    params = kernel_params(SubtractSettings(), settings)
    assert params.paper_sweeps is paper
    # the per-FRF isolation stops on the paper's relative change alone
    assert (params.se_fraction == 0.0) is paper
