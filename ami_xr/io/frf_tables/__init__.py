"""FRF tables as labs export them: text (``.csv``, ``.txt``, ``.dat``) and MATLAB (``.mat``).

Modules: :mod:`.text` (:func:`read_frf_csv`), :mod:`.matlab` (:func:`read_frf_mat`),
:mod:`.build` (what both share: labels, units, assumptions, the Dataset). Read them through
:func:`ami_xr.open_frf` or ``ami-xr identify|convert FILE``, which choose by the suffix.

Text tables (the accepted layouts)
----------------------------------
1. **A header line** naming the columns; separated by commas, tabs, semicolons or spaces (the
   header line decides; with spaces no name may contain one):

   * one frequency column in Hz: ``frequency``, ``freq`` or ``f`` (any case), optionally with
     the unit: ``freq [Hz]``, ``frequency (Hz)``, ``frequency_hz``;
   * per point two columns ``<point><sep><part>`` (``<sep>`` a space, ``_``, ``.``, ``-`` or
     ``:``): real and imaginary parts (``re``/``real``, ``im``/``imag``/``imaginary``) or
     magnitude and phase (``mag``/``magnitude``/``abs``/``amp``/``amplitude``,
     ``phase``/``ph``/``angle``; phase in degrees, ``[rad]`` after the name for radians). The
     ``<point>`` part is the point label (an integer when every label is one). An FRF unit may
     follow a name in brackets, ``p1_re [m/s^2/N]``.

   ``freq,p1_re,p1_im,p2_re,p2_im`` and ``frequency_hz,1 mag,1 phase`` are two such headers.
2. **No header**: every line numbers only, an odd number of columns: the frequency (Hz), then
   (real, imaginary) pairs, one per point, labelled ``0 .. n - 1``. Said with an
   :class:`~ami_xr.errors.AssumptionWarning` and recorded in the attribute
   ``table_columns_assumed``.

Lines starting with ``#`` are comments. Above the header, ``# key: value`` lines say what the
numbers do not: ``drive_point``, ``response_quantity``, ``frf_type``, ``response_units``,
``force_units`` (the keyword arguments of the same names win). Blank lines are skipped.

MATLAB files
------------
Variables (or fields of the file's one struct) ``frequency``/``freq``/``f`` (Hz) and
``frf``/``H`` (complex, points x lines or lines x points), optionally ``points`` (labels) and
the keys above, or ``frf_units`` such as ``'g/N'``. Files up to v7 are read with
:func:`scipy.io.loadmat`; v7.3 (HDF5) with ``h5py``, an optional extra (``pip install
"ami_xr[matlab]"``); without it the error says to install it or to save the file as v7.

What is assumed
---------------
Where the file and the arguments do not say: the drive point of a one-FRF table is that FRF's
point (attribute ``drive_point_assumed``); the response quantity is displacement (receptance in
m/N, attribute ``response_quantity_assumed``); each with an AssumptionWarning naming the file.
Several FRFs and no drive point: none is set (mode vectors then stay unscaled). The FRFs are
``frf_source = "measured"``.
"""

from ami_xr.io.frf_tables.matlab import read_frf_mat
from ami_xr.io.frf_tables.text import read_frf_csv

__all__ = ["read_frf_csv", "read_frf_mat"]
