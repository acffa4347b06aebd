"""The published numbers of Ginsberg & Allen's benchmark (Tables 1-6), typed here once.

The simulator (:mod:`ami_xr.simulate.beam`), the ``ami-xr demo`` comparison and
``scripts/reproduce_paper.py`` all read them from this module. Eigenvalues are in rad/s; mode
vectors are the printed values already multiplied by their ``1e-6`` scale. Rows of the mode
vector tables are ``q1, m1, m2, m3`` (``q1`` is the first Ritz coordinate, not the tip
displacement; see :mod:`ami_xr.simulate.beam`), columns modes 1-4.

Only numpy is imported, so reading a table costs nothing.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "ANALYTICAL_EIGENVALUES",
    "ANALYTICAL_MODE_VECTORS",
    "AMI_PER_FRF_EIGENVALUES",
    "AMI_EIGENVALUES",
    "AMI_EIGENVALUE_ERRORS",
    "AMI_MODE_VECTORS",
    "AMI_MEAN_FREQUENCY_ERROR",
    "AMI_MEAN_DAMPING_ERROR",
    "AMI_MODE_VECTOR_ERRORS",
]

#: Tables 1-2, "Analytical" row: the exact eigenvalues of the benchmark (rad/s).
ANALYTICAL_EIGENVALUES = np.array(
    [-0.45827 + 30.551j, -0.71973 + 48.025j, -0.39311 + 65.0j, -0.59137 + 65.896j]
)

#: Tables 3-6, "Analytical" column: rows q1..q4, columns modes 1..4 (already x 1e-6).
ANALYTICAL_MODE_VECTORS = 1e-6 * np.array(
    [
        [-2.9046 + 93.979j, -17.818 + 308.69j, 3087.1 - 9547.9j, 4087.6 + 7212.4j],
        [1677.5 + 223660j, 2.5513 - 29.414j, -148.09 + 371.8j, -140.6 - 286.58j],
        [-1.6448 + 42.909j, 1682.2 + 223650j, -1204.8 + 3056.2j, -1149.5 - 2284.9j],
        [-1.7555 + 49.645j, -18.479 + 275.7j, -84362 - 152480j, 64054 - 194960j],
    ]
)

#: Tables 1-2: the AMI eigenvalue of each FRF (rows tip, m1, m2, m3; columns modes 1-4), NaN
#: where the paper prints "x" (mode not detected in that FRF). One noise seed at 15 %.
AMI_PER_FRF_EIGENVALUES = np.array(
    [
        [np.nan, np.nan, -0.3513 + 65.046j, -0.46740 + 65.803j],
        [-0.46025 + 30.555j, np.nan, -0.48261 + 65.190j, np.nan],
        [np.nan, -0.71644 + 48.041j, -0.34713 + 64.983j, -0.57261 + 65.789j],
        [np.nan, np.nan, -0.39469 + 65.010j, -0.59237 + 65.915j],
    ]
)

#: Tables 1-2, "Average" row: the paper's AMI result for each mode (rad/s).
AMI_EIGENVALUES = np.array(
    [-0.46025 + 30.555j, -0.71644 + 48.041j, -0.39394 + 65.057j, -0.54413 + 65.836j]
)

#: Tables 1-2, "Error" row as printed: percent error of the real and imaginary parts.
AMI_EIGENVALUE_ERRORS = ("0.43+0.0125i", "-0.46+0.0338i", "0.21+0.0880i", "-7.99-0.0906i")

#: Tables 3-6, "AMI" column: rows q1, m1, m2, m3, columns modes 1..4 (already x 1e-6).
AMI_MODE_VECTORS = 1e-6 * np.array(
    [
        [394.68 + 365.5j, 211.81 + 375.55j, 919.46 - 4051.3j, 1246.7 + 2858.9j],
        [-12153 + 10827j, -13.136 + 56.514j, -113.66 + 388.41j, -100.92 - 273.44j],
        [521.37 + 392.8j, -33957 + 55618j, -983.9 + 3138.5j, -803.4 - 2149j],
        [3700.6 - 17657j, 12513 - 10253j, -86751 - 146340j, 47647 - 194670j],
    ]
)

#: The paper's AMI natural-frequency error (%), averaged over the four modes (one seed).
AMI_MEAN_FREQUENCY_ERROR = 0.056
#: The paper's AMI damping-ratio error (%), averaged over the four modes (one seed).
AMI_MEAN_DAMPING_ERROR = 2.2
#: The paper's AMI mode-vector errors (%) of modes 3 and 4 (modes 1 and 2: over 1000 %).
AMI_MODE_VECTOR_ERRORS = (5.0, 8.4)
